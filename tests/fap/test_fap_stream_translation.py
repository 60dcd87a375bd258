"""FapStream.translation: the head's translation in ES units, kept by every stream operation and
named when a .fap file cannot carry it."""

from __future__ import annotations

import dataclasses
import warnings
from typing import Any

import numpy as np
import pytest

from vtts.errors import FapError, VttsWarning
from vtts.fap import FapStream, FapWarning, format_fap, parse_fap, read_fap, write_fap
from vtts.fap.stream import MAX_TRANSLATION, TRANSLATION_AXES


def make(n: int = 4, **kw: Any) -> FapStream:
    mask = np.zeros((n, 68), dtype=bool)
    mask[:, 2] = True
    values = np.zeros((n, 68))
    values[:, 2] = np.arange(n) * 10.0
    return FapStream(fps=kw.pop("fps", 25.0), name="s", values=values, mask=mask, **kw)


def walk(n: int, seed: int = 0) -> np.ndarray:
    return np.cumsum(np.random.default_rng(seed).normal(0, 20, size=(n, 3)), axis=0)


def test_default_is_none_and_axes() -> None:
    s = make()
    assert s.translation is None
    assert TRANSLATION_AXES == ("tx", "ty", "tz")
    assert "translation" not in repr(s)


def test_translation_is_copied_and_converted() -> None:
    t = np.arange(12, dtype=np.int32).reshape(4, 3)
    s = make(translation=t)
    t[0, 0] = 99
    assert s.translation.dtype == np.float64 and s.translation.shape == (4, 3)
    assert s.translation[0, 0] == 0.0
    assert repr(s).endswith(", translation)")
    assert make(0, translation=np.zeros((0, 3))).translation.shape == (0, 3)


@pytest.mark.parametrize(
    ("translation", "message"),
    [
        (np.zeros((3, 3)), r"shape \(4, 3\) like the frames, got \(3, 3\)"),
        (np.zeros((4, 2)), r"shape \(4, 3\)"),
        (np.zeros(12), r"shape \(4, 3\)"),
        ([[0, 0, 0]] * 3 + [[0, float("nan"), 0]], r"translation\[3, 1\] \(ty\) must be finite"),
        ([[0, 0, float("inf")]] * 4, r"translation\[0, 2\] \(tz\) must be finite"),
        ([[0, 0, 0]] * 3 + [[-2 * MAX_TRANSLATION, 0, 0]], r"within ±1e\+06 ES units"),
        ([["a", 0, 0]] * 4, "numeric array"),
    ],
)
def test_validation(translation: Any, message: str) -> None:
    with pytest.raises(FapError, match=message):
        make(translation=translation)


def test_bound_is_inclusive() -> None:
    t = np.full((4, 3), MAX_TRANSLATION)
    assert make(translation=-t).translation.min() == -MAX_TRANSLATION


def test_equality_and_replace() -> None:
    t = walk(4)
    a, b = make(translation=t), make(translation=t.copy())
    assert a == b
    assert a != make() and make() != a
    c = make(translation=t + np.array([0, 0, 1e-9]))
    assert a != c
    d = dataclasses.replace(a, name="other")
    assert np.array_equal(d.translation, t) and d.translation is not a.translation
    assert dataclasses.replace(a, translation=None) == make()


def test_resample_interpolates_translation_linearly() -> None:
    t = walk(10, seed=1)
    s = make(10, translation=t)
    up = s.resample(50.0)
    assert up.translation.shape == (20, 3)
    assert np.array_equal(up.translation[::2], t)  # frames that fall on input frames are copies
    assert np.allclose(up.translation[1:-1:2], (t[:-1] + t[1:]) / 2)
    assert np.array_equal(up.translation[-1], t[-1])  # past the last input frame: held
    same = s.resample(25.0)
    assert same == s
    assert make(10).resample(30.0).translation is None
    down = s.resample(12.5)
    assert np.array_equal(down.translation, t[::2])
    assert make(0, translation=np.zeros((0, 3))).resample(30).translation.shape == (0, 3)


def test_format_fap_warns_and_leaves_translation_out() -> None:
    s = make(translation=walk(4))
    with pytest.warns(FapWarning, match="head translation is not written") as w:
        text = format_fap(s)
    assert len(w) == 1 and isinstance(w[0].message, VttsWarning) and w[0].message.file is None
    assert parse_fap(text) == dataclasses.replace(s, translation=None)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        format_fap(make())  # no translation: no warning


def test_write_fap_warns_naming_the_file(tmp_path) -> None:
    path = tmp_path / "out.fap"
    s = make(translation=walk(4))
    with pytest.warns(FapWarning, match=r"\.fap file has no place for it") as w:
        write_fap(s, path)
    assert len(w) == 1 and w[0].message.file == str(path)
    assert read_fap(path) == dataclasses.replace(s, translation=None)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        write_fap(make(), tmp_path / "plain.fap")
