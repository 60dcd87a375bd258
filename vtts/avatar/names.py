"""Morph target names as avatar files spell them, matched to ARKit's 52 and Oculus's 15.

Apple spells ``eyeBlinkLeft``; exporters and rigs write ``eyeBlink_L``, ``EyeBlink_Left``,
``eye_blink_left``, ``EYEBLINKLEFT``, and prefix the name with the blend shape node or mesh it came
from (``blendShape1.eyeBlinkLeft``, ``Face|eyeBlinkLeft``, ``head:eyeBlinkLeft``). Oculus visemes
come as ``viseme_PP``, ``Viseme_PP``, ``visemePP`` or ``V_PP``. :func:`name_key` reduces each to one
key (lower case, no prefix, no separators, ``L``/``R``/``Lt``/``Rt`` spelled ``left``/``right``),
and :func:`match_names` maps a file's names onto the canonical ones by that key; :func:`eye_side`
tells which eyeball a mesh or node name names (``EyeLeft``, ``eye_L``, ``L_EYEBALL``).
"""

from __future__ import annotations

import re
from collections.abc import Iterable

from vtts.avatar.arkit import ARKIT_NAMES, OCULUS_VISEMES

#: Where a prefix ends: Maya's blend shape node (``blendShape1.``), Blender's and FBX's
#: separators (``Face|``, ``head:``), paths (``Mesh/``).
_PREFIX = re.compile(r"^.*[.|:/\\]")
#: The words of a name: camelCase humps, digits, and runs between separators.
_WORD = re.compile(r"[A-Z]+(?![a-z])|[A-Z]?[a-z]+|[0-9]+")
#: The key of an eyeball's name (its side spelled ``l``/``r``): ``eyel``, ``lefteye``, ``eyeball``…
_EYE_KEY = re.compile(r"^(?:(left|l)?eye(?:ball)?(left|l|right|r)?|(right|r)eye(?:ball)?)$")
_SIDES = {"l": "left", "lt": "left", "left": "left", "r": "right", "rt": "right", "right": "right"}


def name_key(name: str) -> str:
    """The matching key of a morph target name: ``"blendShape1.EyeBlink_L"`` → ``"eyeblinkleft"``,
    ``"viseme_PP"`` and ``"V_PP"`` → ``"visemepp"``."""
    text = _PREFIX.sub("", str(name).strip())
    words = [w.lower() for w in _WORD.findall(text)]
    words = [_SIDES.get(w, w) for w in words]
    if len(words) > 1 and words[0] == "v":  # V_PP, V_aa: an Oculus viseme
        words[0] = "viseme"
    return "".join(words)


def _canonical() -> dict[str, str]:
    return {name_key(n): n for n in (*ARKIT_NAMES, *OCULUS_VISEMES)}


def canonical_name(name: str) -> str | None:
    """The ARKit or Oculus name that ``name`` spells (``"mouthSmile_L"`` → ``"mouthSmileLeft"``),
    or None."""
    return _canonical().get(name_key(name))


def match_names(names: Iterable[str]) -> tuple[dict[str, str], list[str]]:
    """``(matched, unknown)``: ``matched`` maps each name of ``names`` that spells an ARKit shape
    or an Oculus viseme to its canonical name (the first spelling wins when two spell the same
    shape: the later ones are listed as unknown), ``unknown`` lists the others in order."""
    table = _canonical()
    matched: dict[str, str] = {}
    taken: set[str] = set()
    unknown: list[str] = []
    for n in names:
        c = table.get(name_key(n))
        if c is None or c in taken:
            if n not in unknown:
                unknown.append(n)
            continue
        matched[n] = c
        taken.add(c)
    return matched, unknown


def eye_side(name: str | None) -> str | None:
    """``"left"``/``"right"`` when ``name`` names an eyeball (``EyeLeft``, ``eye_L``,
    ``LeftEye``, ``Eye.R``, ``eyeball_l``), else None."""
    if not name:
        return None
    key = name_key(str(name).replace(".", "_"))
    m = _EYE_KEY.match(key.replace("left", "l").replace("right", "r"))
    if not m:
        return None
    side = m.group(1) or m.group(2) or m.group(3)
    if side is None:
        return None
    return "left" if side.startswith("l") else "right"
