"""Temporal Definition Tables: how a personalized model behaves in time (Ostermann & Haratsch,
section 3.3.2).

Per expression: onset and offset durations (s), the shape of the onset/offset curves, the climax
amplitude (a factor on the requested amplitude) and the default climax duration. Per autonomous
behaviour (blink, nod, head motion, gaze): mean interval between occurrences (s), its jitter (s,
standard deviation), the duration of one occurrence (s) and its amplitude in the FAP units of the
FAPs that perform it (blink: FAPs 19–22 in IRISD units; nod: FAP 48 in AU; head motion: FAPs
48–50 in AU; gaze: FAPs 23–26 in AU).
"""

from __future__ import annotations

from dataclasses import dataclass, field, fields, replace

import numpy as np

from vtts.errors import AdtError

#: Curve shapes for onset and offset, as functions of x in [0, 1] rising from 0 to 1.
SHAPES = {
    "linear": lambda x: x,
    "smooth": lambda x: 0.5 - 0.5 * np.cos(np.pi * x),
    "exponential": lambda x: (1.0 - np.exp(-5.0 * x)) / (1.0 - np.exp(-5.0)),
}

EXPRESSION_NAMES = ("joy", "sadness", "anger", "fear", "disgust", "surprise")
BEHAVIOURS = ("blink", "nod", "head_motion", "gaze")


def _check_nonneg(obj, names: tuple[str, ...]) -> None:
    for n in names:
        v = getattr(obj, n)
        if not np.isfinite(v) or v < 0:
            raise AdtError(f"{n} must be a non-negative number of seconds, got {v}")


@dataclass(frozen=True)
class ExpressionTiming:
    """How one expression unfolds: ``onset``/``offset`` in s, ``shape`` a key of :data:`SHAPES`,
    ``climax`` the amplitude factor at the climax, ``duration`` the default climax length in s."""

    onset: float = 0.4
    offset: float = 0.6
    shape: str = "smooth"
    climax: float = 1.0
    duration: float = 2.0

    def __post_init__(self) -> None:
        _check_nonneg(self, ("onset", "offset", "duration"))
        if self.shape not in SHAPES:
            raise AdtError(
                f"expression shape must be one of {', '.join(SHAPES)}, got {self.shape!r}"
            )
        if not 0.0 <= self.climax <= 2.0:
            raise AdtError(f"expression climax must be within 0–2, got {self.climax}")

    def envelope(
        self, t: np.ndarray, start: float, duration: float | None = None, amplitude: float = 1.0
    ) -> np.ndarray:
        """Weight of the expression at times ``t`` (s) for a request starting at ``start`` (s)
        with a climax of ``duration`` s (the default when None) and ``amplitude`` (0–1).

        ``(n,) float64``: 0 before ``start``, rising over ``onset``, ``amplitude·climax`` for the
        climax, falling to 0 over ``offset``."""
        t = np.asarray(t, dtype=np.float64)
        d = self.duration if duration is None else float(duration)
        shape = SHAPES[self.shape]
        peak = amplitude * self.climax
        x = t - start
        up = np.clip(x / self.onset, 0.0, 1.0) if self.onset > 0 else (x >= 0).astype(float)
        down_x = x - self.onset - d
        down = (
            np.clip(1.0 - down_x / self.offset, 0.0, 1.0)
            if self.offset > 0
            else (down_x < 0).astype(float)
        )
        w = np.where(x < self.onset, shape(up), np.where(down_x > 0, shape(down), 1.0))
        return np.where(x < 0, 0.0, peak * w)

    def total(self, duration: float | None = None) -> float:
        """Length in s of a whole request (onset + climax + offset)."""
        return self.onset + (self.duration if duration is None else duration) + self.offset


@dataclass(frozen=True)
class Habit:
    """An autonomous behaviour's time constants: ``interval`` (mean s between occurrences),
    ``jitter`` (s, standard deviation of the interval), ``duration`` (s per occurrence),
    ``amplitude`` (FAP units of the FAPs that perform it)."""

    interval: float
    jitter: float
    duration: float
    amplitude: float

    def __post_init__(self) -> None:
        _check_nonneg(self, ("interval", "jitter", "duration"))
        if self.interval <= 0:
            raise AdtError(f"habit interval must be positive, got {self.interval}")


#: What a model without its own temporal table does.
DEFAULT_EXPRESSION = ExpressionTiming()
DEFAULT_HABITS = {
    "blink": Habit(interval=4.0, jitter=1.5, duration=0.2, amplitude=1024.0),
    "nod": Habit(interval=9.0, jitter=3.0, duration=0.8, amplitude=6000.0),
    "head_motion": Habit(interval=3.0, jitter=1.0, duration=2.5, amplitude=3000.0),
    "gaze": Habit(interval=2.5, jitter=1.0, duration=0.15, amplitude=8000.0),
}


@dataclass
class TemporalTables:
    """A model's temporal tables: expression timings by name and habits by behaviour name.

    Only what the model defines is stored; :meth:`expression` and :meth:`habit` fall back to
    :data:`DEFAULT_EXPRESSION` and :data:`DEFAULT_HABITS`."""

    expressions: dict[str, ExpressionTiming] = field(default_factory=dict)
    habits: dict[str, Habit] = field(default_factory=dict)

    def expression(self, name: str) -> ExpressionTiming:
        return self.expressions.get(name, DEFAULT_EXPRESSION)

    def habit(self, name: str) -> Habit:
        if name in self.habits:
            return self.habits[name]
        try:
            return DEFAULT_HABITS[name]
        except KeyError:
            raise AdtError(
                f"unknown behaviour '{name}' (behaviours: {', '.join(BEHAVIOURS)})"
            ) from None

    def __bool__(self) -> bool:
        return bool(self.expressions or self.habits)

    # ---- the .adt text lines -----------------------------------------------------------------

    def lines(self) -> list[str]:
        """The ``#TemporalDefinitionTables`` section body, one line per entry."""
        out = []
        for name, t in self.expressions.items():
            out.append(f"expression {name}: " + _settings(t))
        for name, h in self.habits.items():
            out.append(f"{name}: " + _settings(h))
        return out

    def set_entry(self, words: list[str], settings: dict[str, str | float]) -> None:
        """Add one parsed line: ``words`` is ``["expression", "joy"]`` or ``["blink"]``."""
        if words[0] == "expression":
            if len(words) != 2 or words[1] not in EXPRESSION_NAMES:
                raise AdtError(
                    f"'expression' needs one of {', '.join(EXPRESSION_NAMES)}, got "
                    f"{' '.join(words[1:]) or 'nothing'}"
                )
            self.expressions[words[1]] = _build(ExpressionTiming, settings, DEFAULT_EXPRESSION)
            return
        if len(words) != 1 or words[0] not in BEHAVIOURS:
            raise AdtError(
                f"unknown temporal entry '{' '.join(words)}' (expected 'expression NAME' or one "
                f"of {', '.join(BEHAVIOURS)})"
            )
        self.habits[words[0]] = _build(Habit, settings, DEFAULT_HABITS[words[0]])


def _settings(obj) -> str:
    parts = []
    for f in fields(obj):
        v = getattr(obj, f.name)
        parts.append(f"{f.name} {v if isinstance(v, str) else _num(v)}")
    return " ".join(parts)


def _num(v: float) -> str:
    return str(int(v)) if float(v).is_integer() else repr(float(v))


def _build(cls, settings: dict[str, str | float], default):
    known = {f.name: f.type for f in fields(cls)}
    for k, v in settings.items():
        if k not in known:
            raise AdtError(f"unknown setting '{k}' (settings: {', '.join(known)})")
        if k != "shape" and isinstance(v, str):
            raise AdtError(f"setting '{k}' takes a number, got {v!r}")
        if k == "shape" and not isinstance(v, str):
            raise AdtError(f"setting 'shape' takes one of {', '.join(SHAPES)}, got {v!r}")
    return replace(default, **settings)
