"""Facial Animation Parameter Units (FAPU): what one unit of a FAP means on a given face.

A low-level FAP value is a displacement measured in a FAPU, a distance of the neutral face divided
by 1024, so that one FAP stream moves faces of any size alike (ISO/IEC 14496-2, Table C-2):

========  ======================================================================  ===============
FAPU      neutral-face distance (… / 1024)                                        feature points
========  ======================================================================  ===============
IRISD     iris diameter, by definition the distance between upper and lower        3.1, 3.3
          eyelid (IRISD0)
ES        eye separation: distance between the pupils (ES0)                        3.5, 3.6
ENS       eye–nose separation: from the eyes' line to the bottom of the nose       3.5, 3.6, 9.15
          (ENS0)
MNS       mouth–nose separation: from the bottom of the nose to the mouth line     9.15, 2.2
          (MNS0)
MW        mouth width: distance between the mouth corners (MW0)                    8.3, 8.4
AU        angle unit: 1e-5 rad (rotations: eyeballs, tongue roll, head)            —
========  ======================================================================  ===============

Lengths are in the model's own length units.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from vtts.errors import FapError
from vtts.fap.table import FAPS, N_FAPS, fap, positive_number

#: The angle unit of the rotation FAPs, in radians.
AU = 1e-5

#: A FAPU is a neutral-face distance divided by this.
FAPU_DIVISOR = 1024.0

_DISTANCES = ("irisd", "es", "ens", "mns", "mw")


@dataclass(frozen=True)
class Fapu:
    """The five length FAPUs of one neutral face, in model length units per FAP unit.

    Each field is a neutral-face distance / 1024 (``irisd = IRISD0 / 1024`` and so on), so a FAP
    value ``v`` of a FAP measured in ES moves its feature point by ``v * es`` model units.
    All must be finite and positive.
    """

    irisd: float
    es: float
    ens: float
    mns: float
    mw: float

    def __post_init__(self) -> None:
        for name in _DISTANCES:
            object.__setattr__(
                self, name, positive_number(f"FAPU {name.upper()}", getattr(self, name))
            )

    @classmethod
    def from_distances(cls, *, irisd: float, es: float, ens: float, mns: float, mw: float) -> Fapu:
        """FAPUs from the neutral-face distances IRISD0, ES0, ENS0, MNS0, MW0 (model units)."""
        given = {"irisd": irisd, "es": es, "ens": ens, "mns": mns, "mw": mw}
        return cls(
            **{k: positive_number(f"{k.upper()}0", v) / FAPU_DIVISOR for k, v in given.items()}
        )

    @classmethod
    def from_feature_points(cls, points: Mapping[str, ArrayLike]) -> Fapu:
        """FAPUs measured on the MPEG-4 feature points of a neutral face.

        ``points`` maps feature-point names (``"3.1"``) to positions, each ``(3,)`` or ``(2,)``
        float in model units, in the MPEG-4 neutral-face frame (y up, x towards the face's left,
        z towards the viewer). The distances follow ISO/IEC 14496-2 Annex C (Table C-2 and the
        feature-point figure; as drawn in Pandzic & Forchheimer, *MPEG-4 Facial Animation*, 2002,
        ch. 2), measured along the axis each FAPU is defined on:

        - IRISD0 = |y(3.1) − y(3.3)|: top and bottom of the left eyelid (neutral eyelids are
          tangent to the iris, so this is the iris diameter);
        - ES0 = |x(3.5) − x(3.6)|: the pupils;
        - ENS0 = |mean(y(3.5), y(3.6)) − y(9.15)|: the eyes' line to the bottom middle of the nose;
        - MNS0 = |y(9.15) − y(2.2)|: the bottom of the nose to the middle of the inner upper lip
          contour (the mouth line of a closed mouth);
        - MW0 = |x(8.3) − x(8.4)|: the left and right mouth corners.

        Axis-aligned differences (not Euclidean distances) keep the nose's depth out of ENS0 and
        MNS0. Raises :class:`FapError` naming a missing or malformed point, or a zero distance.
        """

        def point(name: str) -> np.ndarray:
            if name not in points:
                raise FapError(f"feature point {name} is missing (needed for the FAPUs)")
            try:
                p = np.asarray(points[name], dtype=np.float64)
            except (TypeError, ValueError):
                raise FapError(
                    f"feature point {name} must be 2 or 3 numbers, got {points[name]!r}"
                ) from None
            if p.shape not in ((2,), (3,)) or not np.all(np.isfinite(p)):
                raise FapError(
                    f"feature point {name} must be 2 or 3 finite numbers, got {points[name]!r}"
                )
            return p

        p31, p33 = point("3.1"), point("3.3")
        p35, p36 = point("3.5"), point("3.6")
        p915, p22 = point("9.15"), point("2.2")
        p83, p84 = point("8.3"), point("8.4")
        eyes_y = (p35[1] + p36[1]) / 2.0
        distances = {
            "irisd": float(abs(p31[1] - p33[1])),
            "es": float(abs(p35[0] - p36[0])),
            "ens": float(abs(eyes_y - p915[1])),
            "mns": float(abs(p915[1] - p22[1])),
            "mw": float(abs(p83[0] - p84[0])),
        }
        for name, d in distances.items():
            if not d > 0:
                raise FapError(
                    f"FAPU {name.upper()}0 measured on the feature points is {d}: "
                    "the points of a neutral face must be apart"
                )
        return cls.from_distances(**distances)

    def unit(self, key: int | str) -> float:
        """Model length units (radians for AU FAPs) moved by one unit of FAP ``key``.

        ``key`` is a FAP number 3–68 or name; FAPs 1 (viseme) and 2 (expression) have no unit
        and raise :class:`FapError`.
        """
        d = fap(key)
        if d.fapu is None:
            raise FapError(
                f"FAP {d.number} ({d.name}) is a high-level FAP and has no FAPU; "
                "units exist for FAPs 3–68"
            )
        if d.fapu == "AU":
            return AU
        return float(getattr(self, d.fapu.lower()))

    def scales(self) -> np.ndarray:
        """``(68,) float64``: :meth:`unit` of every FAP, index k = FAP k+1 (0 for FAPs 1, 2).

        Multiplying a FAP value vector by this gives displacements in model units (radians for
        the AU FAPs).
        """
        out = np.zeros(N_FAPS, dtype=np.float64)
        for d in FAPS:
            if d.fapu is not None:
                out[d.number - 1] = self.unit(d.number)
        return out
