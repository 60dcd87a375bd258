"""Which frames are analyzed (:mod:`vtts.analysis.frame_times`): every step-th, or the frames a
stream coded at a rate shows."""

from __future__ import annotations

import pytest

from vtts.analysis.frame_times import analysis_fps, analyzed, check_rate, nearest_frame
from vtts.errors import AnalysisError


def _frames(n: int, fps: float, step: int = 1, rate: float | None = None) -> list[int]:
    return [i for i in range(n) if analyzed(i, fps, step, rate)]


def test_every_step_th_frame_without_a_rate():
    assert _frames(9, 30.0, 2) == [0, 2, 4, 6, 8]
    assert _frames(7, 25.0) == list(range(7))
    assert analysis_fps(30.0, 2) == 15.0


def test_at_a_rate_the_frames_a_coded_stream_shows():
    # 12.5 Hz of a 30 fps video: the frames at 0, 2.4, 4.8, 7.2, 9.6, 12, … rounded; two of
    # every five of them are frames every second frame leaves out
    assert _frames(25, 30.0, rate=12.5) == [0, 2, 5, 7, 10, 12, 14, 17, 19, 22, 24]
    assert analysis_fps(30.0, rate=12.5) == 12.5
    # of a 25 fps video: every second frame, as a step of 2
    assert _frames(50, 25.0, rate=12.5) == _frames(50, 25.0, 2)
    # the frame the measure compares each decoded frame with (bench_people: round(j / rate ·
    # fps)) is the frame analyzed for it, at Carphone's 29.97 fps too
    fps = 30000 / 1001
    shown = [round(j / 12.5 * fps) for j in range(48)]
    assert [nearest_frame(j, fps, 12.5) for j in range(48)] == shown
    assert _frames(shown[-1] + 1, fps, rate=12.5) == shown
    # the rate of the video itself: every frame
    assert _frames(10, 30.0, rate=30.0) == list(range(10))


@pytest.mark.parametrize(
    "fps, step, rate, fragment",
    [
        (30.0, 1, 40.0, "within 0–30 Hz"),
        (30.0, 1, 0.0, "within 0–30 Hz"),
        (30.0, 1, float("nan"), "within 0–30 Hz"),
        (30.0, 2, 12.5, "not both"),
    ],
)
def test_bad_rates_are_clear_errors(fps, step, rate, fragment):
    with pytest.raises(AnalysisError, match=fragment):
        check_rate(fps, step, rate)
    check_rate(fps, step, None)  # a step alone is checked by the caller
