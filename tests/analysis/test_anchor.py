"""The frame a video's head is made from (:mod:`vtts.analysis.anchor`) and the track from it
backwards and forwards (``track(..., anchor=)``)."""

from __future__ import annotations

import itertools
from pathlib import Path

import numpy as np
import pytest

from vtts.analysis.anchor import anchor_frame, choose_anchor
from vtts.analysis.quality import coverage, face_psnr_rgb
from vtts.analysis.track import track
from vtts.analysis.video import read_video
from vtts.errors import AnalysisError
from vtts.face import N_PARAMS, load_model
from vtts.render import FaceRenderer

CARPHONE = Path(__file__).parents[1] / "data" / "video" / "carphone_qcif.mp4"


@pytest.fixture(scope="module")
def frames() -> list[np.ndarray]:
    return list(itertools.islice(read_video(CARPHONE).frames(), 100))


def test_the_typical_face_is_chosen(frames):
    # one frame of the man turned (frame 80) among four of him facing the camera (frame 20)
    clip = [frames[80], frames[20], frames[20].copy(), frames[20].copy(), frames[20].copy()]
    index, frame = anchor_frame(clip, len(clip))
    assert index in (1, 2, 3, 4) and np.array_equal(frame, frames[20])
    clip = [frames[20], frames[80], frames[80].copy(), frames[80].copy()]
    assert anchor_frame(clip, len(clip))[0] in (1, 2, 3)
    # frames without a face: none to choose
    blank = np.full_like(frames[0], 128)
    assert anchor_frame([blank] * 4, 4) is None
    assert choose_anchor([blank] * 4, 25.0, 4) is None


def test_the_anchor_is_a_frame_analyzed_within_the_first_seconds(frames, monkeypatch):
    import vtts.analysis.anchor as anchor

    index = choose_anchor(frames, 25.0, len(frames), step=3)
    assert index is not None and index % 3 == 0 and 0 <= index < len(frames)
    monkeypatch.setattr(anchor, "ANCHOR_SECONDS", 0.5)  # 12 frames at 25 frames/s
    seen = []

    def counted():
        for frame in frames:
            seen.append(1)
            yield frame

    index = choose_anchor(counted(), 25.0, None, step=2)
    assert index is not None and index % 2 == 0 and index < 12
    assert len(seen) <= 12  # nothing read past the frames it looks at
    # at a rate: a frame the rate analyzes (30 fps at 12.5 Hz: 0, 2, 5, 7, 10)
    index = choose_anchor(frames, 30.0, len(frames), rate=12.5)
    assert index in (0, 2, 5, 7, 10)


def _render(model, size) -> np.ndarray:
    with FaceRenderer(model, size=size, viewpoint="photo", background="transparent") as r:
        return r.render(np.zeros(N_PARAMS))


@pytest.mark.usefixtures("shared_fit")
def test_the_track_goes_back_from_the_anchor_and_on_from_it(frames, tmp_path):
    clip = frames[:6]  # four frames back from the anchor, one on
    order = []
    tracked = track(clip, fps=25.0, model_path=tmp_path / "m.wrl", anchor=4,
                    on_estimate=lambda fe: order.append(fe.index))  # fmt: skip
    # every frame once, in order, as they are written
    assert order == [fe.index for fe in tracked.analysis.frames] == list(range(6))
    assert tracked.first == 0
    psnr = tracked.analysis.psnr()
    assert psnr[4] > 35.0, psnr  # the frame the head was made from
    assert psnr.min() > 22.0, psnr
    # the head is made from frame 4: drawn at the fit's view it gives frame 4 back
    model = load_model(str(tracked.fitted[0]))
    rendered = _render(model, (176, 144))
    mask = coverage(rendered)
    assert face_psnr_rgb(frames[4], rendered, mask) > 40.0
    assert face_psnr_rgb(frames[4], rendered, mask) > face_psnr_rgb(frames[0], rendered, mask)
    # the estimates before the anchor came from the track backwards: the head moves little
    head = np.array([fe.params[47:50] for fe in tracked.analysis.frames])
    assert np.abs(head).max() < 8000, head


@pytest.mark.usefixtures("shared_fit")
def test_an_anchor_with_a_step_and_without_one(frames, tmp_path):
    # (the heads fitted to frame 4, as the test before fits it: a fit shared)
    tracked = track(frames[:7], fps=25.0, model_path=tmp_path / "a.wrl", step=2, anchor=4)
    assert [fe.index for fe in tracked.analysis.frames] == [0, 2, 4, 6]
    # at 12.5 Hz of a 25 fps video: every second frame, the same estimates to the bit
    at = track(frames[:7], fps=25.0, model_path=tmp_path / "r.wrl", rate=12.5, anchor=4)
    assert at.analysis.fps == 12.5 == tracked.analysis.fps
    for x, y in zip(at.analysis.frames, tracked.analysis.frames, strict=True):
        assert x.index == y.index and np.array_equal(x.params, y.params)
    # of a 30 fps one: the frames a 12.5 Hz stream shows, which it carries as they are
    at = track(frames[:8], fps=30.0, model_path=tmp_path / "s.wrl", rate=12.5, anchor=2)
    assert [fe.index for fe in at.analysis.frames] == [0, 2, 5, 7]
    assert at.analysis.fps == 12.5 and at.analysis.stream().resample(12.5).n_frames == 4
    # an anchor at the first frame is the track without one (a clip that starts at frame 4)
    a = track(frames[4:7], fps=25.0, model_path=tmp_path / "b.wrl", anchor=0)
    b = track(frames[4:7], fps=25.0, model_path=tmp_path / "c.wrl")
    for x, y in zip(a.analysis.frames, b.analysis.frames, strict=True):
        assert np.array_equal(x.params, y.params)


@pytest.mark.parametrize(
    "kwargs, fragment",
    [
        ({"anchor": 3, "step": 2}, "must be a frame analyzed"),
        ({"anchor": 4, "rate": 12.5, "fps": 30.0}, "must be a frame analyzed"),
        ({"rate": 12.5, "step": 2}, "not both"),
        ({"anchor": -2}, "must be a frame analyzed"),
        ({"anchor": 40}, "past the video's end"),
        ({"anchor": 2, "model": "head"}, "needs a head to fit"),
    ],
)
def test_bad_anchors_are_clear_errors(frames, tmp_path, kwargs, fragment):
    if kwargs.get("model") == "head":
        kwargs = {**kwargs, "model": load_model(str(Path(__file__).parents[1] / "data" /
                                                     "models" / "head.wrl"))}  # fmt: skip
    with pytest.raises(AnalysisError, match=fragment):
        track(frames[:6], model_path=tmp_path / "m.wrl", **{"fps": 25.0, **kwargs})


def test_an_anchor_without_a_face_is_a_clear_error(frames, tmp_path):
    clip = [frames[0], frames[1], np.full_like(frames[0], 128), frames[3]]
    with pytest.raises(AnalysisError, match="frame 2, the frame to fit the head on, shows no"):
        track(clip, fps=25.0, model_path=tmp_path / "m.wrl", anchor=2)
