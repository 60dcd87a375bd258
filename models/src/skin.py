"""How the modeler moves the skin for each low-level FAP.

Candide-3's own FAP units move only the one to three feature-point vertices of a FAP; pulled
alone they make spikes. Here every skin FAP moves a region: the feature point by one FAPU per
unit (in the FAP's direction, as Candide's unit says), its neighbours by the weights below, in
the manner of Candide's regional animation units (lip stretcher, brow raisers, cheek raiser).
The refined face (``S @ candide``) then spreads each region smoothly.

Weights are written for the face's left side (+x) and the midline; a right-side FAP is its left
twin mirrored, a midline FAP is completed by mirroring.
"""

from __future__ import annotations

import numpy as np

# FAP → (FAPU, direction of the feature point at positive values, {Candide vertex: weight},
#        symmetric about the midline)
LEFT_OR_MIDLINE: dict[int, tuple[str, tuple[float, float, float], dict[int, float], bool]] = {
    4: ("MNS", (0, -1, 0.1), {87: 1, 81: 0.55, 7: 0.55, 79: 0.25, 33: 0.45, 88: 0.1}, True),
    5: ("MNS", (0, 1, 0.1), {40: 1, 83: 0.55, 8: 0.55, 85: 0.25, 9: 0.12, 88: 0.1}, True),
    6: ("MW", (1, 0, -0.4), {88: 1, 31: 0.9, 81: 0.45, 83: 0.45, 79: 0.3, 85: 0.3, 90: 0.45,
                             27: 0.1, 26: 0.05}, False),
    8: ("MNS", (0, -1, 0.1), {81: 1, 79: 0.55, 87: 0.3, 88: 0.25, 33: 0.3}, False),
    10: ("MNS", (0, 1, 0.1), {83: 1, 85: 0.55, 40: 0.3, 88: 0.25, 8: 0.2}, False),
    12: ("MNS", (0, 1, -0.2), {88: 1, 31: 0.95, 81: 0.35, 83: 0.35, 79: 0.3, 85: 0.3, 90: 0.55,
                               27: 0.22, 26: 0.08}, False),
    16: ("MNS", (0, 0, 1), {8: 1, 40: 1, 83: 0.6, 85: 0.6, 9: 0.25, 88: 0.15}, True),
    17: ("MNS", (0, 0, 1), {7: 1, 87: 1, 33: 1, 79: 0.6, 81: 0.6, 88: 0.15}, True),
    18: ("MNS", (0, 1, 0.15), {9: 1, 32: 0.5, 10: 0.45, 8: 0.35, 85: 0.2, 40: 0.1}, True),
    31: ("ENS", (0, 1, 0), {17: 1, 16: 0.45, 18: 0.45, 3: 0.3, 2: 0.15, 13: 0.15, 1: 0.1,
                            19: 0.2, 103: 0.25}, False),
    33: ("ENS", (0, 1, 0), {16: 1, 18: 1, 17: 0.35, 15: 0.4, 13: 0.3, 19: 0.3, 95: 0.15,
                            103: 0.15}, False),
    35: ("ENS", (0, 1, 0), {15: 1, 16: 0.45, 18: 0.45, 14: 0.2, 13: 0.15, 95: 0.25, 29: 0.08},
         False),
    37: ("ES", (-1, 0, 0.15), {17: 1, 16: 0.5, 18: 0.5, 3: 0.05, 19: 0.1}, False),
    39: ("ES", (1, 0, 0.45), {90: 1, 27: 0.7, 28: 0.3, 30: 0.35, 31: 0.25, 26: 0.1}, False),
    41: ("ENS", (0, 1, 0.15), {27: 1, 90: 0.55, 28: 0.3, 24: 0.3, 101: 0.35, 109: 0.2, 29: 0.2,
                               26: 0.2, 31: 0.15}, False),
    51: ("MNS", (0, -1, 0.1), {7: 1, 33: 0.8, 79: 0.45, 87: 0.6, 81: 0.3, 31: 0.05}, True),
    52: ("MNS", (0, 1, 0.1), {8: 1, 85: 0.5, 40: 0.6, 83: 0.3, 9: 0.3}, True),
    53: ("MW", (1, 0, -0.4), {31: 1, 88: 0.85, 90: 0.5, 79: 0.35, 85: 0.35, 81: 0.35, 83: 0.35,
                              27: 0.12}, False),
    55: ("MNS", (0, -1, 0.1), {79: 1, 81: 0.6, 33: 0.4, 7: 0.2, 31: 0.2}, False),
    57: ("MNS", (0, 1, 0.1), {85: 1, 83: 0.6, 8: 0.3, 31: 0.2, 9: 0.1}, False),
    59: ("MNS", (0, 1, -0.2), {31: 1, 88: 0.9, 90: 0.6, 79: 0.3, 85: 0.3, 27: 0.25, 26: 0.08},
         False),
    61: ("ENS", (1, 0, 0), {26: 1, 111: 1, 25: 0.5, 75: 0.2}, False),
    63: ("ENS", (0, 1, 0), {5: 1, 75: 1, 6: 0.6, 111: 0.4, 25: 0.3, 26: 0.2, 94: 0.1}, True),
    64: ("ENS", (-1, 0, 0), {5: 1, 75: 0.8, 6: 0.5, 94: 0.3, 111: 0.2}, True),
}  # fmt: skip

#: Right-side FAPs: their left twins.
RIGHT_OF = {n + 1: n for n in (6, 8, 10, 12, 31, 33, 35, 37, 39, 41, 53, 55, 57, 59, 61)}

SKIN_FAPS = sorted([*LEFT_OR_MIDLINE, *RIGHT_OF])


def region(weights: dict[int, float], direction, symmetric: bool, mirror) -> np.ndarray:
    """``(113, 3)``: each vertex of ``weights`` moved by its weight along ``direction``; with
    ``symmetric`` the mirrored vertices too (direction mirrored)."""
    d = np.zeros((113, 3))
    direction = np.asarray(direction, dtype=np.float64)
    for v, w in weights.items():
        d[v] = w * direction
        if symmetric and mirror(v) != v:
            d[mirror(v)] = w * direction * [-1, 1, 1]
    return d


def skin_field(number: int, mirror) -> tuple[np.ndarray, str]:
    """``((113, 3), FAPU name)``: the Candide displacement per FAP unit over the FAPU
    (``mirror`` maps a Candide vertex to its twin across the midline)."""
    if number in RIGHT_OF:
        unit, direction, weights, _ = LEFT_OR_MIDLINE[RIGHT_OF[number]]
        left = region(weights, direction, False, mirror)
        out = np.zeros_like(left)
        for v in range(113):
            out[mirror(v)] += left[v] * [-1, 1, 1]
        return out, unit.lower()
    unit, direction, weights, symmetric = LEFT_OR_MIDLINE[number]
    return region(weights, direction, symmetric, mirror), unit.lower()
