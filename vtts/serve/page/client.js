// The JavaScript client of vtts serve: one session over a WebSocket, its audio played through Web
// Audio and its face frames kept on the audio's clock. Another page can use it alone:
//
//   import { Session } from '/vtts/client.js';
//   const session = await Session.connect(location.origin, { model: 'cybatt' });
//   session.on('audiostart', (e) => …); session.on('end', …); session.on('error', …);
//   session.off(name, fn) removes a handler;
//   session.say('Hello <smile> there.');  session.append('more '); session.flush();
//   session.stop();
//   session.frameAt()   // the face's parameter values now (Float32Array of N_PARAMS), or null
//
//   session.listen(16000); session.sendAudio(int16Array); …; session.flush();   // a voice in
//   await session.microphone(); … session.stopMicrophone();                 // the user's voice
//
// Events: opened, clause, listening, word, bookmark, audiostart (the first sample of an utterance is played;
// e.at is its performance.now() time), end (its last sample), stopped, error, underrun.
// The protocol is docs/serve.md's, version 1.

export const VERSION = 1;
export const N_PARAMS = 90;
const AUDIO = 1;
const FACE = 2;
// How far ahead of now the first sample of an utterance is scheduled (s): Web Audio needs a
// render quantum or two to start a source on time.
const LEAD = 0.02;

class Utterance {
  constructor(number) {
    this.number = number;
    this.t0 = null; // the AudioContext time of its sample 0
    this.rate = 0;
    this.faces = []; // { start, fps, frames, count, values }
    this.sources = [];
    this.samples = null; // set by "end"
    this.timers = [];
    this.started = false;
    this.underruns = 0;
  }
}

export class Session {
  constructor(url) {
    this.url = url;
    this.handlers = new Map();
    this.utterances = new Map(); // number → Utterance
    this.queueEnd = 0; // the AudioContext time where the last scheduled audio ends
    this.dropUpTo = 0; // media of utterances up to this number are dropped (stopped ones)
    // stops sent and not yet answered: until the answer, everything that comes belongs to what
    // was stopped (the server answers a stop before it speaks any later text)
    this.pendingStops = 0;
    this.opened = null;
    this.params = null;
    this.mic = null; // the microphone while it is the voice (microphone())
    this.stats = { underruns: 0, underrunSeconds: 0 };
    this.context = new AudioContext({ latencyHint: 'interactive' });
    this.analyser = this.context.createAnalyser();
    this.analyser.fftSize = 256;
    this.output = this.context.createGain();
    this.output.connect(this.analyser);
    this.analyser.connect(this.context.destination);
  }

  // Connect to the server at `origin` (http://HOST:PORT) and open a session with `options`
  // ({ model, voice, engine, rate, pitch, seed }); resolves once it is open.
  static async connect(origin, options = {}) {
    const session = new Session(origin.replace(/^http/, 'ws') + '/session');
    await session.open(options);
    return session;
  }

  on(name, fn) {
    if (!this.handlers.has(name)) this.handlers.set(name, []);
    this.handlers.get(name).push(fn);
    return this;
  }

  off(name, fn) {
    const list = this.handlers.get(name) || [];
    const i = list.indexOf(fn);
    if (i >= 0) list.splice(i, 1);
    return this;
  }

  emit(name, detail) {
    for (const fn of this.handlers.get(name) || []) {
      try { fn(detail); } catch (e) { console.error(e); }
    }
  }

  open(options) {
    return new Promise((resolve, reject) => {
      const ws = new WebSocket(this.url);
      ws.binaryType = 'arraybuffer';
      this.ws = ws;
      let opened = false;
      ws.onopen = () => ws.send(JSON.stringify({ type: 'open', version: VERSION, ...options }));
      ws.onmessage = (event) => {
        if (typeof event.data !== 'string') { this.media(event.data); return; }
        const m = JSON.parse(event.data);
        if (!opened && m.type === 'opened') {
          opened = true;
          this.opened = m;
          this.params = Int32Array.from(m.params);
          resolve(m);
        } else if (!opened && m.type === 'error') {
          reject(new Error(m.message));
        }
        this.control(m);
      };
      ws.onerror = () => { if (!opened) reject(new Error(`cannot reach ${this.url}`)); };
      ws.onclose = (e) => {
        if (!opened) reject(new Error(`the server closed the session (${e.code} ${e.reason})`));
        else this.emit('error', { code: 'closed', message: `the session closed (${e.code} ${e.reason})` });
      };
    });
  }

  send(message) {
    if (this.ws.readyState !== WebSocket.OPEN) throw new Error('the session is closed');
    this.ws.send(JSON.stringify(message));
  }

  say(text) { this.context.resume(); this.output.gain.value = 1; this.send({ type: 'say', text }); }
  append(text) { this.context.resume(); this.send({ type: 'append', text }); }
  flush() { this.send({ type: 'flush' }); }

  // An utterance of a voice from elsewhere (a microphone, a realtime voice model): its PCM sent
  // with sendAudio() as it comes (Int16Array, mono at `rate` Hz), ended by flush() or stop().
  // The server sends back the face as it recognizes the voice, and the voice with it: they play
  // here on one clock like a say's (muted with { mute: true }, e.g. for the user's own voice).
  listen(rate, { autonomous = true, mute = false } = {}) {
    this.context.resume();
    this.output.gain.value = mute ? 0 : 1;
    this.send({ type: 'listen', rate, autonomous });
  }

  // The microphone as the voice (getUserMedia): a listen at the AudioContext's rate, muted here
  // (the user hears themselves), the face following; stopMicrophone() ends it (a flush).
  async microphone() {
    const stream = await navigator.mediaDevices.getUserMedia({ audio: { channelCount: 1 } });
    await this.context.audioWorklet.addModule(new URL('./capture.js', import.meta.url));
    const source = this.context.createMediaStreamSource(stream);
    const node = new AudioWorkletNode(this.context, 'vtts-capture');
    const silent = this.context.createGain();
    silent.gain.value = 0;
    const rate = this.context.sampleRate;
    const piece = Math.round(rate * 0.02); // 20 ms a message
    let buffer = new Int16Array(piece);
    let n = 0;
    this.listen(rate, { mute: true });
    node.port.onmessage = (e) => {
      if (this.mic === null || this.ws.readyState !== WebSocket.OPEN) return;
      for (const v of e.data) {
        buffer[n++] = Math.max(-32768, Math.min(32767, Math.round(v * 32767)));
        if (n === piece) { this.sendAudio(buffer); buffer = new Int16Array(piece); n = 0; }
      }
    };
    source.connect(node);
    node.connect(silent); // a worklet runs only as part of a graph that reaches the output
    silent.connect(this.context.destination);
    this.mic = { stream, source, node, silent };
    return rate;
  }

  stopMicrophone() {
    const mic = this.mic;
    if (!mic) return;
    this.mic = null;
    for (const track of mic.stream.getTracks()) track.stop();
    mic.source.disconnect(); mic.node.disconnect(); mic.silent.disconnect();
    this.flush();
  }

  sendAudio(pcm) {
    if (this.ws.readyState !== WebSocket.OPEN) throw new Error('the session is closed');
    this.ws.send(pcm instanceof Int16Array ? pcm.buffer.slice(pcm.byteOffset, pcm.byteOffset + pcm.byteLength) : pcm);
  }

  // Silence now: every scheduled source stops, the face goes back to rest, and the server drops
  // the rest of the text.
  stop() {
    this.pendingStops += 1;
    for (const u of this.utterances.values()) this.silence(u);
    this.utterances.clear();
    this.queueEnd = 0;
    this.send({ type: 'stop' });
  }

  silence(u) {
    for (const s of u.sources) { try { s.stop(); } catch (e) { /* not started */ } }
    for (const t of u.timers) clearTimeout(t);
    u.sources = [];
  }

  utterance(number) {
    if (number <= this.dropUpTo || this.pendingStops > 0) return null;
    let u = this.utterances.get(number);
    if (!u) { u = new Utterance(number); this.utterances.set(number, u); }
    return u;
  }

  control(m) {
    if (m.type === 'clause' || m.type === 'listening') {
      const u = this.utterance(m.utterance);
      if (u === null) return;
      u.rate = m.rate;
      this.emit(m.type, m);
    } else if (m.type === 'end') {
      const u = this.utterance(m.utterance);
      if (u === null) return;
      u.samples = m.samples;
      this.schedule(u, 'end', m.samples, { utterance: m.utterance, duration: m.duration });
      if (u.t0 === null) { this.emit('end', { utterance: m.utterance, duration: 0 }); this.utterances.delete(u.number); }
    } else if (m.type === 'stopped') {
      this.dropUpTo = Math.max(this.dropUpTo, m.utterance);
      this.pendingStops = Math.max(0, this.pendingStops - 1);
      this.emit('stopped', m);
    } else if (m.type === 'error') {
      this.emit('error', m);
    }
  }

  // The performance.now() time at which the AudioContext plays its time t.
  performanceTime(t) {
    const stamp = this.context.getOutputTimestamp();
    if (stamp.contextTime === undefined || !stamp.performanceTime) {
      return performance.now() + (t - this.context.currentTime) * 1000;
    }
    return stamp.performanceTime + (t - stamp.contextTime) * 1000;
  }

  // Call emit(name) when sample `sample` of the utterance is played.
  schedule(u, name, sample, detail) {
    if (u.t0 === null) return;
    const when = u.t0 + sample / u.rate;
    const at = this.performanceTime(when);
    u.timers.push(setTimeout(() => {
      this.emit(name, { ...detail, at });
      if (name === 'end') this.utterances.delete(u.number);
    }, Math.max(0, at - performance.now())));
  }

  media(buffer) {
    const view = new DataView(buffer);
    const kind = view.getUint8(0);
    const number = view.getUint32(4, true);
    const u = this.utterance(number);
    if (u === null) return;
    if (kind === FACE) {
      const start = view.getFloat64(12, true);
      const fps = view.getFloat32(20, true);
      const frames = view.getUint16(24, true);
      const count = view.getUint16(26, true);
      const values = new Float32Array(buffer.slice(28, 28 + 4 * frames * count));
      u.faces.push({ start, fps, frames, count, values });
    } else if (kind === AUDIO) {
      const first = view.getUint32(12, true);
      const pcm = new Int16Array(buffer.slice(16));
      this.play(u, first, pcm);
    }
  }

  play(u, first, pcm) {
    const ctx = this.context;
    const now = ctx.currentTime;
    if (u.t0 === null) {
      u.t0 = Math.max(now + LEAD, this.queueEnd);
      this.schedule(u, 'audiostart', 0, { utterance: u.number });
    }
    let when = u.t0 + first / u.rate;
    if (when < now + 0.005) {
      // an underrun: the audio came late; the utterance's clock (its face too) moves on by the gap
      const gap = now + 0.005 - when;
      u.t0 += gap;
      when += gap;
      u.underruns += 1;
      this.stats.underruns += 1;
      this.stats.underrunSeconds += gap;
      this.emit('underrun', { utterance: u.number, gap });
    }
    const samples = new Float32Array(pcm.length);
    for (let i = 0; i < pcm.length; i++) samples[i] = pcm[i] / 32768;
    const audio = ctx.createBuffer(1, Math.max(pcm.length, 1), u.rate);
    audio.copyToChannel(samples, 0);
    const source = ctx.createBufferSource();
    source.buffer = audio;
    source.connect(this.output);
    source.start(when);
    u.sources.push(source);
    source.onended = () => { const i = u.sources.indexOf(source); if (i >= 0) u.sources.splice(i, 1); };
    this.queueEnd = Math.max(this.queueEnd, when + pcm.length / u.rate);
  }

  // The utterance being heard now and its time (s, on its audio clock), or null.
  current() {
    const t = this.context.currentTime;
    for (const u of this.utterances.values()) {
      if (u.t0 === null || t < u.t0) continue;
      const end = u.samples !== null ? u.samples / u.rate : Infinity;
      if (t - u.t0 <= end) return { u, time: t - u.t0 };
    }
    return null;
  }

  // The face's parameter values now (Float32Array of N_PARAMS; the frame at or before the audio's
  // time, so never ahead of the sound), with `frameTime` and `audioTime`; null at rest.
  frameAt() {
    const now = this.current();
    if (now === null) return null;
    const { u, time } = now;
    for (const f of u.faces) {
      const k = Math.floor((time - f.start) * f.fps + 1e-9);
      if (k < 0 || k >= f.frames) continue;
      const out = new Float32Array(N_PARAMS);
      const row = f.values.subarray(k * f.count, (k + 1) * f.count);
      for (let j = 0; j < f.count; j++) out[this.params[j]] = row[j];
      return { values: out, frameTime: f.start + k / f.fps, audioTime: time, utterance: u.number };
    }
    return null;
  }

  // The loudness of what is playing now (RMS of the last 256 samples, 0 when silent).
  level() {
    const data = new Float32Array(this.analyser.fftSize);
    this.analyser.getFloatTimeDomainData(data);
    let sum = 0;
    for (const v of data) sum += v * v;
    return Math.sqrt(sum / data.length);
  }
}
