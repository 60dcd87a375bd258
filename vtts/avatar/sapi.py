"""The 22 SAPI visemes (Microsoft Speech API; Azure's ``viseme_id``) of MPEG-4 visemes and phones.

Azure's text to speech reports a viseme event with one of 22 ids, the SAPI visemes, each the
mouth shape of a group of English phones (IPA):

====  ==============  ====  ==============  ====  ===============
 0    silence          8    o               16    ʃ tʃ dʒ ʒ
 1    æ ə ʌ            9    aʊ              17    ð
 2    ɑ               10    ɔɪ              18    f v
 3    ɔ               11    aɪ              19    d t n θ
 4    ɛ ʊ             12    h               20    k g ŋ
 5    ɝ               13    ɹ               21    p b m
 6    j i ɪ           14    l
 7    w u             15    s z
====  ==============  ====  ==============  ====  ===============

The SAPI groups split some MPEG-4 visemes (viseme 8 "n, l" is 19 or 14; the vowels 10–14 are
several ids) and join others (θ is 19 with t, d). :func:`sapi_viseme` therefore reads the phone
when there is one: as an espeak-ng English name (through the IPA that
``vtts/data/phoneme_visemes.tsv`` gives it), as ARPAbet, or as IPA — the first reading whose
SAPI id is one of those its MPEG-4 viseme allows (:data:`ALLOWED`; so a ``D`` that the source
meant as ARPAbet d, MPEG-4 viseme 4, is not read as espeak-ng's ð). Without a phone, or when no
reading fits, the MPEG-4 viseme's usual id (:data:`FROM_MPEG4`) is taken.
"""

from __future__ import annotations

from collections.abc import Mapping
from functools import cache
from types import MappingProxyType

from vtts.errors import AvatarError

#: The usual SAPI viseme of each MPEG-4 viseme 0–14.
FROM_MPEG4: tuple[int, ...] = (0, 21, 18, 17, 19, 20, 16, 15, 19, 13, 2, 4, 6, 3, 4)

#: The SAPI visemes a phone of each MPEG-4 viseme may have.
ALLOWED: Mapping[int, frozenset[int]] = MappingProxyType(
    {
        0: frozenset({0}),
        1: frozenset({21}),
        2: frozenset({18}),
        3: frozenset({17, 19}),
        4: frozenset({19}),
        5: frozenset({20, 12}),
        6: frozenset({16}),
        7: frozenset({15}),
        8: frozenset({19, 14}),
        9: frozenset({13, 5}),
        10: frozenset({1, 2, 9, 11}),
        11: frozenset({1, 4, 5}),
        12: frozenset({6}),
        13: frozenset({3, 8, 10, 2}),
        14: frozenset({4, 7, 8}),
    }
)

#: IPA (without stress, length or diacritics) → SAPI viseme; longest match first.
IPA: Mapping[str, int] = MappingProxyType(
    {
        "aʊ": 9, "ɔɪ": 10, "oɪ": 10, "aɪ": 11, "eɪ": 4, "oʊ": 8, "əʊ": 8, "tʃ": 16, "dʒ": 16,
        "æ": 1, "ə": 1, "ʌ": 1, "a": 1, "ɐ": 1, "ɑ": 2, "ɔ": 3, "ɒ": 3, "ɛ": 4, "ʊ": 4, "e": 4,
        "ɝ": 5, "ɚ": 5, "ɜ": 5, "j": 6, "i": 6, "ɪ": 6, "ᵻ": 6, "w": 7, "u": 7, "o": 8, "h": 12,
        "ɹ": 13, "r": 13, "ɻ": 13, "l": 14, "ɫ": 14, "s": 15, "z": 15, "ʃ": 16, "ʒ": 16,
        "ð": 17, "f": 18, "v": 18, "d": 19, "t": 19, "n": 19, "θ": 19, "ɾ": 19, "ʔ": 19,
        "k": 20, "g": 20, "ɡ": 20, "ŋ": 20, "p": 21, "b": 21, "m": 21,
    }
)  # fmt: skip

#: ARPAbet (stress digits removed) → SAPI viseme.
ARPABET: Mapping[str, int] = MappingProxyType(
    {
        "AA": 2, "AE": 1, "AH": 1, "AX": 1, "AO": 3, "AW": 9, "AY": 11, "EH": 4, "ER": 5,
        "AXR": 5, "EY": 4, "IH": 6, "IX": 6, "IY": 6, "OW": 8, "OY": 10, "UH": 4, "UW": 7,
        "UX": 7, "B": 21, "M": 21, "EM": 21, "P": 21, "CH": 16, "JH": 16, "SH": 16, "ZH": 16,
        "D": 19, "T": 19, "N": 19, "EN": 19, "TH": 19, "DX": 19, "NX": 19, "Q": 19, "DH": 17,
        "F": 18, "V": 18, "G": 20, "K": 20, "NG": 20, "HH": 12, "L": 14, "EL": 14, "R": 13,
        "S": 15, "Z": 15, "W": 7, "WH": 7, "Y": 6,
    }
)  # fmt: skip


@cache
def _espeak_ipa() -> dict[str, str]:
    """espeak-ng English phoneme name → its first IPA in ``phoneme_visemes.tsv``."""
    from vtts.resources import package_data

    out: dict[str, str] = {}
    text = package_data("phoneme_visemes.tsv").read_text(encoding="utf-8")
    for line in text.splitlines()[1:]:
        cells = line.split("\t")
        if len(cells) >= 4 and cells[0] == "espeak-en" and cells[3] not in ("", "-"):
            out[cells[1]] = cells[3].split()[0]
    return out


def _ipa_sapi(symbol: str) -> int | None:
    from vtts.speech.phonemes import ipa_key

    key = ipa_key(symbol)
    for n in range(min(len(key), 2), 0, -1):
        if key[:n] in IPA:
            return IPA[key[:n]]
    return None


def _readings(phoneme: str) -> list[int | None]:
    ipa = _espeak_ipa().get(phoneme)
    arpa = phoneme.upper().rstrip("012")
    return [
        _ipa_sapi(ipa) if ipa else None,
        ARPABET.get(arpa) if phoneme.isascii() and phoneme.rstrip("012").isupper() else None,
        _ipa_sapi(phoneme),
    ]


def sapi_viseme(viseme: int, phoneme: str = "") -> int:
    """The SAPI viseme (0–21) of a phone of MPEG-4 viseme ``viseme`` (0–14) written ``phoneme``
    (espeak-ng English, ARPAbet or IPA; empty: the viseme's usual id). See the module
    documentation."""
    if isinstance(viseme, bool) or not isinstance(viseme, int) or not 0 <= viseme <= 14:
        raise AvatarError(f"MPEG-4 visemes are 0–14, got {viseme!r}")
    phoneme = phoneme.strip()
    if phoneme and viseme:
        for found in _readings(phoneme):
            if found is not None and found in ALLOWED[viseme]:
                return found
    return FROM_MPEG4[viseme]
