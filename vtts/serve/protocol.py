"""The messages of ``vtts serve``'s WebSocket, version :data:`VERSION` (``docs/serve.md``).

Control messages are JSON text, one object each, with a ``type``. Media are binary messages,
little-endian, that start with a common header::

    u8  kind          1 = audio, 2 = face
    u8  version       VERSION
    u16 reserved      0
    u32 utterance     the utterance's number in its session (from 1)
    u32 clause        the clause's number in its utterance (from 0)

then, for audio: ``u32 first`` (the index of the chunk's first sample on the utterance's audio
clock) and int16 mono samples at the session's rate; for a face: ``f64 start`` (the time of the
first frame on the utterance's audio clock, s), ``f32 fps``, ``u16 frames``, ``u16 count``, then
``frames × count`` float32 parameter values (row-major: frame by frame), the session's
parameters (the ``params`` the ``opened`` message lists) in that order.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass

import numpy as np

#: The protocol's version: a client asks for it in ``open``; another is refused.
VERSION = 1
AUDIO, FACE = 1, 2
HEADER = struct.Struct("<BBHII")
AUDIO_HEADER = struct.Struct("<I")
FACE_HEADER = struct.Struct("<dfHH")

#: Control messages a client may send, each with the fields it may have (besides ``type``).
CLIENT_MESSAGES: dict[str, frozenset[str]] = {
    "open": frozenset({"version", "model", "voice", "engine", "rate", "pitch", "seed"}),
    "say": frozenset({"text"}),
    "append": frozenset({"text"}),
    "flush": frozenset(),
    "stop": frozenset(),
    "listen": frozenset({"rate", "autonomous"}),
}
#: Sample rates a ``listen`` takes, Hz.
LISTEN_RATES = (8000, 192000)


@dataclass(frozen=True)
class AudioChunk:
    """``samples`` ``(n,)`` int16 of clause ``clause`` of utterance ``utterance``, the first at
    sample ``first`` of the utterance's audio clock."""

    utterance: int
    clause: int
    first: int
    samples: np.ndarray


@dataclass(frozen=True)
class FaceFrames:
    """``values`` ``(frames, count)`` float32 of the session's parameters; frame ``k`` at
    ``start + k / fps`` s of the utterance's audio clock."""

    utterance: int
    clause: int
    start: float
    fps: float
    values: np.ndarray

    def times(self) -> np.ndarray:
        """``(frames,)`` float64: each frame's time on the utterance's audio clock, s."""
        return self.start + np.arange(len(self.values)) / self.fps


def pack_audio(utterance: int, clause: int, first: int, samples: np.ndarray) -> bytes:
    """An audio message (int16 samples, little-endian)."""
    return (
        HEADER.pack(AUDIO, VERSION, 0, utterance, clause)
        + AUDIO_HEADER.pack(first)
        + np.asarray(samples, dtype="<i2").tobytes()
    )


def pack_face(utterance: int, clause: int, start: float, fps: float, values: np.ndarray) -> bytes:
    """A face message: ``values`` ``(frames, count)`` (at most 65,535 of each)."""
    v = np.ascontiguousarray(values, dtype="<f4")
    return (
        HEADER.pack(FACE, VERSION, 0, utterance, clause)
        + FACE_HEADER.pack(start, fps, v.shape[0], v.shape[1])
        + v.tobytes()
    )


class ProtocolError(ValueError):
    """A binary message that is not one of :data:`VERSION`'s."""


def unpack(data: bytes) -> AudioChunk | FaceFrames:
    """The media message ``data``; :class:`ProtocolError` when it is not one."""
    if len(data) < HEADER.size:
        raise ProtocolError(f"a media message has a {HEADER.size}-byte header, got {len(data)}")
    kind, version, _, utterance, clause = HEADER.unpack_from(data)
    if version != VERSION:
        raise ProtocolError(f"media of protocol version {version}, expected {VERSION}")
    body = HEADER.size
    if kind == AUDIO:
        (first,) = AUDIO_HEADER.unpack_from(data, body)
        raw = data[body + AUDIO_HEADER.size :]
        if len(raw) % 2:
            raise ProtocolError("audio samples are 2 bytes each, got an odd length")
        return AudioChunk(utterance, clause, first, np.frombuffer(raw, dtype="<i2"))
    if kind == FACE:
        start, fps, frames, count = FACE_HEADER.unpack_from(data, body)
        raw = data[body + FACE_HEADER.size :]
        if len(raw) != 4 * frames * count:
            raise ProtocolError(f"a face of {frames}×{count} values has {len(raw)} bytes")
        values = np.frombuffer(raw, dtype="<f4").reshape(frames, count)
        return FaceFrames(utterance, clause, start, fps, values)
    raise ProtocolError(f"unknown media kind {kind}")
