"""espeak-ng through its C API (ctypes), run as a short-lived worker process.

Stdlib only, and never imported by the parent: :mod:`vtts.speech.tts` runs this file with
``python -I -S`` and talks JSON to it. Why a fresh process per request: the first synthesis in a
process is identical from run to run, but later ones in the same process are not — espeak-ng
keeps static state between calls (the pitch flutter index, the roughness cycle count, the
automatic gain and libc's ``rand()`` for breath noise), so the same text synthesized twice in one
process comes back with phoneme boundaries a few samples apart and different audio. A worker also
keeps espeak's global state, and any crash in it, out of the caller.

Request (one JSON object on stdin)::

    {"op": "synth", "text": str, "voice": str, "rate": int|null, "pitch": int|null,
     "flags": int, "ipa": true|false|"auto"}
    {"op": "voices"}

and optionally ``"library"``: the shared library to load instead of ``libespeak-ng.so.1``.

Response on stdout: one JSON line, then (``synth``) ``nsamples`` int16 samples in native byte
order. ``{"ok": false, "kind": "missing"|"init"|"voice"|"synth", "message": …}`` on failure.
Events are ``[type, text_position, length, sample, payload]`` with payload the phoneme mnemonic
(PHONEME), the mark name (MARK) or the number (WORD, SENTENCE, END).
"""

from __future__ import annotations

import ctypes
import json
import sys

LIBRARY = "libespeak-ng.so.1"

# speak_lib.h
AUDIO_OUTPUT_SYNCHRONOUS = 2
INITIALIZE_PHONEME_EVENTS = 0x0001
INITIALIZE_PHONEME_IPA = 0x0002
POS_CHARACTER = 1
PARAM_RATE = 1
PARAM_PITCH = 3
EVENT_LIST_TERMINATED = 0
EVENT_WORD = 1
EVENT_SENTENCE = 2
EVENT_MARK = 3
EVENT_PLAY = 4
EVENT_END = 5
EVENT_MSG_TERMINATED = 6
EVENT_PHONEME = 7
EVENT_SAMPLERATE = 8


class _EventId(ctypes.Union):
    _fields_ = [
        ("number", ctypes.c_int),
        ("name", ctypes.c_char_p),
        ("string", ctypes.c_char * 8),
    ]


class _Event(ctypes.Structure):
    _fields_ = [
        ("type", ctypes.c_int),
        ("unique_identifier", ctypes.c_uint),
        ("text_position", ctypes.c_int),
        ("length", ctypes.c_int),
        ("audio_position", ctypes.c_int),  # ms, truncated; ``sample`` is exact
        ("sample", ctypes.c_int),
        ("user_data", ctypes.c_void_p),
        ("id", _EventId),
    ]


class _Voice(ctypes.Structure):
    _fields_ = [
        ("name", ctypes.c_char_p),
        ("languages", ctypes.c_void_p),  # (priority byte, NUL-terminated name)*, then a 0 byte
        ("identifier", ctypes.c_char_p),
        ("gender", ctypes.c_ubyte),
        ("age", ctypes.c_ubyte),
        ("variant", ctypes.c_ubyte),
        ("xx1", ctypes.c_ubyte),
        ("score", ctypes.c_int),
        ("spare", ctypes.c_void_p),
    ]


_CALLBACK = ctypes.CFUNCTYPE(
    ctypes.c_int, ctypes.POINTER(ctypes.c_short), ctypes.c_int, ctypes.POINTER(_Event)
)


class Failure(Exception):
    def __init__(self, kind: str, message: str, **extra) -> None:
        super().__init__(message)
        self.kind = kind
        self.extra = extra


def load_library(override: str | None = None) -> ctypes.CDLL:
    errors = []
    for name in _library_names(override):
        try:
            lib = ctypes.CDLL(name)
        except OSError as e:
            errors.append(str(e))
            continue
        _declare(lib)
        return lib
    raise Failure("missing", "; ".join(errors) or f"{LIBRARY} not found")


def _library_names(override: str | None):
    """The names to load: ``override``, else :data:`LIBRARY`, then what ``find_library`` finds —
    looked for only when ``LIBRARY`` does not load: ``ctypes.util`` imports ``subprocess`` and
    ``shutil`` and ``find_library`` runs ``ldconfig``, most of a worker's start-up."""
    if override:
        yield override
        return
    yield LIBRARY
    import ctypes.util

    found = ctypes.util.find_library("espeak-ng")
    if found and found != LIBRARY:
        yield found


def _declare(lib: ctypes.CDLL) -> None:
    lib.espeak_Initialize.argtypes = [ctypes.c_int, ctypes.c_int, ctypes.c_char_p, ctypes.c_int]
    lib.espeak_Initialize.restype = ctypes.c_int
    lib.espeak_SetSynthCallback.argtypes = [_CALLBACK]
    lib.espeak_SetSynthCallback.restype = None
    lib.espeak_SetVoiceByName.argtypes = [ctypes.c_char_p]
    lib.espeak_SetVoiceByName.restype = ctypes.c_int
    lib.espeak_SetParameter.argtypes = [ctypes.c_int, ctypes.c_int, ctypes.c_int]
    lib.espeak_SetParameter.restype = ctypes.c_int
    lib.espeak_Synth.argtypes = [
        ctypes.c_void_p,
        ctypes.c_size_t,
        ctypes.c_uint,
        ctypes.c_int,
        ctypes.c_uint,
        ctypes.c_uint,
        ctypes.POINTER(ctypes.c_uint),
        ctypes.c_void_p,
    ]
    lib.espeak_Synth.restype = ctypes.c_int
    lib.espeak_Synchronize.argtypes = []
    lib.espeak_Synchronize.restype = ctypes.c_int
    lib.espeak_ListVoices.argtypes = [ctypes.c_void_p]
    lib.espeak_ListVoices.restype = ctypes.POINTER(ctypes.POINTER(_Voice))
    lib.espeak_SetVoiceByProperties.argtypes = [ctypes.POINTER(_Voice)]
    lib.espeak_SetVoiceByProperties.restype = ctypes.c_int
    lib.espeak_GetCurrentVoice.argtypes = []
    lib.espeak_GetCurrentVoice.restype = ctypes.POINTER(_Voice)


def _text(value: bytes | None) -> str:
    return value.decode("utf-8", "replace") if value else ""


def _languages(address: int | None) -> list[list]:
    """The ``languages`` field: ``[[priority, name], ...]``."""
    out: list[list] = []
    if not address:
        return out
    offset = 0
    while True:
        priority = ctypes.c_ubyte.from_address(address + offset).value
        if priority == 0:
            return out
        name = ctypes.string_at(address + offset + 1)
        out.append([priority, _text(name)])
        offset += len(name) + 2


def _voice_dict(v: _Voice) -> dict:
    return {
        "name": _text(v.name),
        "languages": _languages(v.languages),
        "identifier": _text(v.identifier),
        "gender": int(v.gender),
        "age": int(v.age),
    }


class Engine:
    """One espeak-ng instance with a callback that collects audio and events."""

    def __init__(self, lib: ctypes.CDLL) -> None:
        self.lib = lib
        self.rate = 0
        self.chunks: list[bytes] = []
        self.events: list[list] = []
        # The CFUNCTYPE object must outlive every call into espeak: keep it on the instance.
        self._callback = _CALLBACK(self._on_synth)

    def initialize(self, options: int) -> None:
        rate = self.lib.espeak_Initialize(AUDIO_OUTPUT_SYNCHRONOUS, 0, None, options)
        if rate <= 0:
            raise Failure(
                "init", f"espeak_Initialize failed ({rate}): is espeak-ng-data installed?"
            )
        self.rate = rate
        self.lib.espeak_SetSynthCallback(self._callback)

    def _on_synth(self, wav, numsamples, events) -> int:
        if numsamples > 0 and wav:
            self.chunks.append(ctypes.string_at(wav, numsamples * ctypes.sizeof(ctypes.c_short)))
        i = 0
        while True:
            e = events[i]
            kind = e.type
            if kind == EVENT_LIST_TERMINATED:
                break
            if kind == EVENT_PHONEME:
                payload = e.id.string.decode("utf-8", "ignore")  # IPA may be cut at 8 bytes
            elif kind in (EVENT_MARK, EVENT_PLAY):
                payload = _text(e.id.name)
            else:
                payload = e.id.number
            self.events.append([kind, e.text_position, e.length, e.sample, payload])
            i += 1
        return 0

    def set_voice(self, voice: str) -> dict:
        # By name, file or identifier first; then by language as the espeak-ng command does, so
        # that a language such as "en-gb" (its voice file is "gmw/en") selects a voice too. A
        # "+variant" suffix is kept in both cases.
        if self.lib.espeak_SetVoiceByName(voice.encode("utf-8")) != 0:
            language, _, variant = voice.partition("+")
            encoded = language.encode("utf-8")
            spec = _Voice(languages=ctypes.cast(ctypes.c_char_p(encoded), ctypes.c_void_p))
            if self.lib.espeak_SetVoiceByProperties(ctypes.byref(spec)) != 0:
                raise Failure("voice", f"unknown voice {voice!r}", voices=self.list_voices())
            if variant:
                current = self.lib.espeak_GetCurrentVoice()
                identifier = _text(current.contents.identifier) if current else ""
                full = f"{identifier.partition('+')[0]}+{variant}".encode()
                if not identifier or self.lib.espeak_SetVoiceByName(full) != 0:
                    raise Failure(
                        "voice", f"unknown voice variant {variant!r}", voices=self.list_voices()
                    )
        current = self.lib.espeak_GetCurrentVoice()
        found = _voice_dict(current.contents) if current else {"languages": [], "identifier": ""}
        variant = voice.partition("+")[2]
        if variant and not found["identifier"].endswith("+" + variant):
            # espeak ignores an unknown variant silently; say so instead.
            raise Failure("voice", f"unknown voice variant {variant!r}", voices=self.list_voices())
        return found

    def set_parameters(self, rate: int | None, pitch: int | None) -> None:
        if rate is not None:
            self.lib.espeak_SetParameter(PARAM_RATE, int(rate), 0)
        if pitch is not None:
            self.lib.espeak_SetParameter(PARAM_PITCH, int(pitch), 0)

    def synth(self, text: str, flags: int) -> None:
        self.chunks.clear()
        self.events.clear()
        data = text.encode("utf-8") + b"\0"
        buf = ctypes.create_string_buffer(data, len(data))
        status = self.lib.espeak_Synth(buf, len(data), 0, POS_CHARACTER, 0, flags, None, None)
        if status != 0:
            raise Failure("synth", f"espeak_Synth failed with status {status}")
        status = self.lib.espeak_Synchronize()
        if status != 0:
            raise Failure("synth", f"espeak_Synchronize failed with status {status}")

    def list_voices(self) -> list[dict]:
        table = self.lib.espeak_ListVoices(None)
        out = []
        i = 0
        while table and table[i]:
            out.append(_voice_dict(table[i].contents))
            i += 1
        return out


def _is_english(voice: dict) -> bool:
    langs = voice.get("languages") or []
    return bool(langs) and (langs[0][1] == "en" or langs[0][1].startswith("en-"))


def synth(request: dict) -> tuple[dict, bytes]:
    lib = load_library(request.get("library"))
    engine = Engine(lib)
    engine.initialize(INITIALIZE_PHONEME_EVENTS)
    voice = engine.set_voice(request["voice"])
    engine.set_parameters(request.get("rate"), request.get("pitch"))
    engine.synth(request["text"], int(request["flags"]))
    audio = b"".join(engine.chunks)
    events = list(engine.events)
    rate = engine.rate
    ipa_mode = request.get("ipa", "auto")
    ipa = None
    if ipa_mode is True or (ipa_mode == "auto" and not _is_english(voice)):
        # Same text again with IPA phoneme names; only the names are used (this second run is
        # not the first in the process, so its times may differ by a few samples).
        engine.initialize(INITIALIZE_PHONEME_EVENTS | INITIALIZE_PHONEME_IPA)
        engine.set_voice(request["voice"])
        engine.set_parameters(request.get("rate"), request.get("pitch"))
        engine.synth(request["text"], int(request["flags"]))
        names = [e[4] for e in engine.events if e[0] == EVENT_PHONEME]
        if len(names) == sum(1 for e in events if e[0] == EVENT_PHONEME):
            ipa = names
    header = {
        "ok": True,
        "rate": rate,
        "nsamples": len(audio) // 2,
        "voice": voice,
        "events": events,
        "ipa": ipa,
    }
    return header, audio


def voices(request: dict) -> tuple[dict, bytes]:
    lib = load_library(request.get("library"))
    engine = Engine(lib)
    engine.initialize(INITIALIZE_PHONEME_EVENTS)
    return {"ok": True, "voices": engine.list_voices()}, b""


def main() -> int:
    out = sys.stdout.buffer
    try:
        request = json.loads(sys.stdin.buffer.read().decode("utf-8"))
        op = {"synth": synth, "voices": voices}[request["op"]]
        header, payload = op(request)
    except Failure as f:
        header, payload = {"ok": False, "kind": f.kind, "message": str(f), **f.extra}, b""
    out.write(json.dumps(header, ensure_ascii=True).encode("ascii") + b"\n")
    out.write(payload)
    out.flush()
    return 0


if __name__ == "__main__":
    sys.exit(main())
