"""FAPU: units of the FAPs on a given neutral face."""

from __future__ import annotations

import math

import numpy as np
import pytest

from vtts.errors import FapError
from vtts.fap import AU, FAPS, Fapu

# A neutral face in the MPEG-4 frame (y up, x to the face's left, z to the viewer), in mm.
POINTS = {
    "3.1": (32.0, 45.0, 20.0),  # top of the left eyelid
    "3.3": (32.0, 33.0, 20.0),  # bottom of the left eyelid: IRISD0 = 12
    "3.5": (32.0, 40.0, 18.0),  # left pupil
    "3.6": (-32.0, 38.0, 18.0),  # right pupil: ES0 = 64, eyes' line at y = 39
    "9.15": (0.0, 0.0, 40.0),  # bottom middle of the nose: ENS0 = 39
    "2.2": (0.0, -20.0, 35.0),  # middle of the inner upper lip contour: MNS0 = 20
    "8.3": (25.0, -22.0, 30.0),  # left mouth corner
    "8.4": (-27.0, -22.0, 30.0),  # right mouth corner: MW0 = 52
}


def test_from_distances_divides_by_1024() -> None:
    f = Fapu.from_distances(irisd=10.24, es=64, ens=40.96, mns=20.48, mw=51.2)
    assert f == Fapu(irisd=0.01, es=0.0625, ens=0.04, mns=0.02, mw=0.05)
    assert all(isinstance(v, float) for v in (f.irisd, f.es, f.ens, f.mns, f.mw))


def test_from_feature_points() -> None:
    f = Fapu.from_feature_points(POINTS)
    assert f.irisd == pytest.approx(12 / 1024)
    assert f.es == pytest.approx(64 / 1024)
    assert f.ens == pytest.approx(39 / 1024)
    assert f.mns == pytest.approx(20 / 1024)
    assert f.mw == pytest.approx(52 / 1024)


def test_from_2d_feature_points() -> None:
    f = Fapu.from_feature_points({k: np.array(v[:2]) for k, v in POINTS.items()})
    assert f == Fapu.from_feature_points(POINTS)


@pytest.mark.parametrize("missing", sorted(POINTS))
def test_missing_feature_point(missing: str) -> None:
    points = {k: v for k, v in POINTS.items() if k != missing}
    with pytest.raises(FapError, match=rf"feature point {missing} is missing"):
        Fapu.from_feature_points(points)


@pytest.mark.parametrize("bad", [(1.0,), (1.0, 2.0, 3.0, 4.0), (np.nan, 0.0, 0.0), "abc", None])
def test_malformed_feature_point(bad: object) -> None:
    with pytest.raises(FapError, match=r"feature point 8\.3 must be 2 or 3"):
        Fapu.from_feature_points({**POINTS, "8.3": bad})  # type: ignore[dict-item]


def test_degenerate_feature_points() -> None:
    with pytest.raises(FapError, match="MW0 measured on the feature points is 0"):
        Fapu.from_feature_points({**POINTS, "8.4": POINTS["8.3"]})


@pytest.mark.parametrize("bad", [0.0, -1.0, math.inf, math.nan, "x"])
def test_invalid_fapu_values(bad: object) -> None:
    with pytest.raises(FapError, match="FAPU MW must be"):
        Fapu(irisd=1, es=1, ens=1, mns=1, mw=bad)  # type: ignore[arg-type]
    with pytest.raises(FapError, match="MW0 must be"):
        Fapu.from_distances(irisd=1, es=1, ens=1, mns=1, mw=bad)  # type: ignore[arg-type]


def test_unit() -> None:
    f = Fapu(irisd=1.0, es=2.0, ens=3.0, mns=4.0, mw=5.0)
    assert f.unit(3) == 4.0  # open_jaw: MNS
    assert f.unit("stretch_l_cornerlip") == 5.0  # MW
    assert f.unit(19) == 1.0  # IRISD
    assert f.unit(37) == 2.0  # squeeze_l_eyebrow: ES
    assert f.unit(31) == 3.0  # ENS
    assert f.unit("head_yaw") == AU == 1e-5


@pytest.mark.parametrize("key", [1, 2, "viseme"])
def test_unit_of_high_level_faps_raises(key: int | str) -> None:
    with pytest.raises(FapError, match="high-level FAP and has no FAPU"):
        Fapu(1, 1, 1, 1, 1).unit(key)


def test_unit_of_unknown_fap_raises() -> None:
    with pytest.raises(FapError, match="unknown FAP 69"):
        Fapu(1, 1, 1, 1, 1).unit(69)


def test_scales() -> None:
    f = Fapu(irisd=1.0, es=2.0, ens=3.0, mns=4.0, mw=5.0)
    s = f.scales()
    assert s.shape == (68,) and s.dtype == np.float64
    assert s[0] == 0.0 and s[1] == 0.0
    for d in FAPS[2:]:
        assert s[d.number - 1] == f.unit(d.number)
    assert s[2] == 4.0 and s[47] == AU


def test_fapu_is_frozen() -> None:
    with pytest.raises(AttributeError):
        Fapu(1, 1, 1, 1, 1).mw = 2.0  # type: ignore[misc]
