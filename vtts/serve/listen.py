"""A session's voice input (``listen``): PCM that the client sends as it has it — a microphone, a
realtime voice model, a call — becomes the head's face as it arrives, the voice's own phones
recognized with no text (:class:`~vtts.speech.recognize.LiveRecognizer`), their visemes made
into frames (:class:`~vtts.animate.voice.VoiceTrack`) with the model's blinks and head motion
(:class:`~vtts.animate.voice.LiveHabits`), as ``vtts play --audio -`` does.

:class:`Listener` is the computation, without the socket: :meth:`Listener.feed` takes the
client's next bytes and returns what can be sent now — the face frames newly known and the
audio they cover (the voice sent back, so that a page plays sound and face on one clock, as for
``say``): audio is released only as far as the face frames sent, never ahead of them.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from vtts.errors import ServeError

__all__ = ["Heard", "Listener"]


@dataclass
class Heard:
    """What a piece of voice gives: ``face`` ``(frames, K)`` float32 (the session's ``params``)
    from frame ``first_frame`` on (at ``first_frame / fps`` s of the utterance's clock), and
    ``audio`` ``(n,)`` int16 from sample ``first_sample`` on."""

    first_frame: int
    face: np.ndarray
    first_sample: int
    audio: np.ndarray


class Listener:
    """One utterance of voice at ``rate`` Hz (s16le mono) for ``model``, its face at ``fps``
    over the parameters ``params`` (``(K,)`` ints), behaviour seeded by ``seed``; ``autonomous``
    False leaves the blinks and head motion out; ``decoder`` a recognizer's decoder made ahead
    (:meth:`vtts.serve.server.Server.decoder`)."""

    def __init__(self, model, params: np.ndarray, rate: int, fps: float, seed: int,
                 autonomous: bool = True, decoder=None) -> None:  # fmt: skip
        from vtts.animate.voice import LiveHabits, VoiceTrack
        from vtts.errors import SpeechError
        from vtts.speech.recognize import LiveRecognizer

        try:
            self.recognizer = LiveRecognizer(rate, decoder=decoder)
        except SpeechError as e:
            raise ServeError(str(e)) from None
        self.rate = int(rate)
        self.fps = float(fps)
        self.params = np.asarray(params)
        self.track = VoiceTrack(self.fps)
        self.habits = LiveHabits(model, self.fps, seed=seed) if autonomous else None
        if self.habits is not None:
            self.habits(0)  # its first block made now, not when the voice is waiting for it
        self._carry = b""  # half a sample from the last piece
        self._held = np.zeros(0, np.int16)  # audio received, not yet sent
        self.samples_in = 0  # samples received
        self.samples_out = 0  # samples released
        self.frames_out = 0

    def feed(self, data: bytes) -> Heard:
        """The client's next bytes of PCM → what can be sent now."""
        data = self._carry + bytes(data)
        whole = len(data) // 2 * 2
        self._carry = data[whole:]
        pcm = np.frombuffer(data[:whole], dtype="<i2").astype(np.int16)
        self.samples_in += pcm.size
        self._held = np.concatenate([self._held, pcm])
        return self._release(self.track.add(self.recognizer.feed(pcm)), final=False)

    def finish(self) -> Heard:
        """The rest, the voice having ended: the last frames and every sample held."""
        frames = self.track.add(self.recognizer.finish()) + self.track.finish()
        return self._release(frames, final=True)

    def _release(self, frames: list[np.ndarray], *, final: bool) -> Heard:
        first = self.frames_out
        rows = []
        for i, p in enumerate(frames, start=first):
            if self.habits is not None:
                p = p + self.habits(i)
            rows.append(p[self.params])
        self.frames_out += len(frames)
        face = np.asarray(rows, np.float32).reshape(len(rows), len(self.params))
        # the sound up to the last frame sent (all of it at the end)
        upto = self.samples_in if final else min(
            self.samples_in, int(self.frames_out / self.fps * self.rate)
        )  # fmt: skip
        n = max(upto - self.samples_out, 0)
        audio, self._held = self._held[:n], self._held[n:]
        heard = Heard(first, face, self.samples_out, audio)
        self.samples_out += n
        return heard
