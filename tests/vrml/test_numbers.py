"""Numbers written as text read back exactly, in the shortest text: ``format_number`` and
``format_numbers`` (the writer's and the ADT format's)."""

from __future__ import annotations

import numpy as np
import pytest

from vtts.vrml.fields import _seven_digits, format_number, format_numbers

EDGES = [0.0, -0.0, 1.0, -1.0, 100.0, 1e15, 1e16, 1e22, 123456789012345678.0, 1e-4, 1e-5,
         0.0001234, 2.5e-7, 5e-324, 1.7976931348623157e308, 0.1, -3.25]  # fmt: skip


def _values() -> np.ndarray:
    rng = np.random.default_rng(1)
    spread = rng.normal(size=4000) * 10.0 ** rng.integers(-30, 30, 4000)
    return np.concatenate([spread, EDGES])


def test_float64_rows_read_back_exactly_in_the_shortest_text():
    values = _values().reshape(-1, 3)
    lines = format_numbers(values)
    back = np.array([[float(x) for x in line.split()] for line in lines])
    assert np.array_equal(back, values)
    assert np.array_equal(np.signbit(back), np.signbit(values))  # -0 stays -0
    # no longer than Python's shortest round-trip repr of the number
    for line, row in zip(lines, values.tolist(), strict=True):
        assert all(len(t) <= len(repr(x)) for t, x in zip(line.split(), row, strict=True))


WHOLE = [(1.0, "1"), (-0.0, "-0"), (1e16, "1e+16"), (2.5e-7, "2.5e-07"), (100.0, "100"),
         (0.5, "0.5")]  # fmt: skip


@pytest.mark.parametrize(("value", "text"), WHOLE)
def test_whole_numbers_lose_their_point(value, text):
    assert format_number(value) == text
    assert format_numbers(np.array([value, value]), per_line=2)[0] == f"{text} {text}"


def test_float32_numbers_are_written_at_their_own_precision():
    values = np.array([0.1, 1.5, 3.0], np.float32)
    assert format_numbers(values, per_line=3) == ["0.1 1.5 3"]


def test_integers_and_grouping():
    assert format_numbers(np.arange(8), per_line=4) == ["0 1 2 3", "4 5 6 7"]
    assert format_numbers(np.arange(3), per_line=2) == ["0", "1", "2"]


def test_numbers_of_seven_digits_are_written_as_repr_writes_them():
    """Arrays of numbers rounded to 7 significant digits or fewer (a fitted head's tables) take
    a faster format: the same text as repr's, trimmed."""
    rng = np.random.default_rng(2)
    for exponent in range(-14, 5):
        values = rng.choice([-1, 1], (300, 3)) * rng.uniform(0.1, 10, (300, 3)) * 10.0**exponent
        digits = rng.integers(1, 8) - 1 - np.floor(np.log10(np.abs(values)))
        values = np.round(values * 10.0**digits) / 10.0**digits
        values[::7] = 0.0
        values[::11] = -0.0
        values[::13] = np.round(values[::13] * 10.0**-exponent)  # whole numbers
        assert _seven_digits(values), exponent  # the faster format is the one tested
        lines = format_numbers(values)
        expected = [" ".join(format_number(x) for x in row) for row in values.tolist()]
        assert lines == expected
