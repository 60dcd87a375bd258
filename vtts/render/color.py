"""Background colors as the command line writes them: a name, ``#rrggbb``, ``r,g,b`` (0–1), or
``transparent`` (no background: RGBA images whose alpha is the heads' coverage)."""

from __future__ import annotations

import math
import re

from vtts.errors import RenderError

#: The background that leaves the heads on nothing (alpha 0 around them).
TRANSPARENT = "transparent"
#: The background of a talking photo: the photo a fitted head was fitted to, the head drawn into
#: it (:mod:`vtts.render.talking_photo`; the commands' ``--background photo``).
PHOTO = "photo"

#: Color names → RGB (0–1). Green and blue are the chroma-key colors of video compositing.
COLORS: dict[str, tuple[float, float, float]] = {
    "black": (0.0, 0.0, 0.0),
    "white": (1.0, 1.0, 1.0),
    "gray": (0.5, 0.5, 0.5),
    "grey": (0.5, 0.5, 0.5),
    "red": (1.0, 0.0, 0.0),
    "green": (0.0, 1.0, 0.0),
    "blue": (0.0, 0.0, 1.0),
    "yellow": (1.0, 1.0, 0.0),
    "cyan": (0.0, 1.0, 1.0),
    "magenta": (1.0, 0.0, 1.0),
}

_HEX = re.compile(r"#([0-9a-fA-F]{6})")


#: The forms :func:`parse_color` accepts, as error messages list them.
FORMS = f"a name ({', '.join(COLORS)}), #rrggbb, or r,g,b with each number within 0–1"


def parse_color(text: str) -> tuple[float, float, float]:
    """An RGB color (each 0–1) from a name of :data:`COLORS`, ``#rrggbb`` or ``r,g,b`` floats
    in 0–1 (``0.2,0.5,0.3``)."""
    rgb = _rgb(text)
    if rgb is None:
        raise RenderError(f"not a color: {text!r}; write {FORMS}")
    return rgb


def is_photo(text: str | None) -> bool:
    """Whether a ``--background`` is :data:`PHOTO`."""
    return isinstance(text, str) and text.strip().lower() == PHOTO


def parse_background(text: str) -> tuple[float, float, float] | str:
    """:data:`TRANSPARENT` for ``"transparent"``, else the RGB color of :func:`parse_color`
    (:data:`PHOTO` is the commands' to read: :func:`is_photo`)."""
    if text.strip().lower() == TRANSPARENT:
        return TRANSPARENT
    rgb = _rgb(text)
    if rgb is None:
        raise RenderError(
            f"not a background: {text!r}; write {FORMS}; or {TRANSPARENT}; or {PHOTO} (a fitted "
            "head's own photo)"
        )
    return rgb


def _rgb(text: str) -> tuple[float, float, float] | None:
    t = text.strip().lower()
    if t in COLORS:
        return COLORS[t]
    m = _HEX.fullmatch(t)
    if m:
        v = m.group(1)
        return (int(v[0:2], 16) / 255, int(v[2:4], 16) / 255, int(v[4:6], 16) / 255)
    parts = t.split(",")
    if len(parts) != 3:
        return None
    try:
        r, g, b = (float(p) for p in parts)
    except ValueError:
        return None
    if not all(math.isfinite(c) and 0 <= c <= 1 for c in (r, g, b)):
        return None
    return (r, g, b)
