// The AudioWorklet of Session.microphone() (client.js): each render quantum of the microphone's
// first channel (128 float samples at the AudioContext's rate) is posted to the page.
class Capture extends AudioWorkletProcessor {
  process(inputs) {
    const channel = inputs[0] && inputs[0][0];
    if (channel) this.port.postMessage(channel.slice(0));
    return true;
  }
}

registerProcessor('vtts-capture', Capture);
