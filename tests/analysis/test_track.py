"""Real camera video: a head fitted to the first face (``--model auto``), a given model placed
on the landmarks, re-initialization, and the command's outputs (the fitted head, the head
translation in the ``.fbs``)."""

from __future__ import annotations

import itertools
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from vtts.analysis import Estimator
from vtts.analysis.landmark_pose import feature_vertices, landmark_pose, project
from vtts.analysis.track import FITTED_IGNORED, Tracked, track
from vtts.analysis.tracker import Tracker
from vtts.analysis.video import read_video
from vtts.cli import main
from vtts.errors import AnalysisError
from vtts.face import load_model
from vtts.fap.coding import decode, read_header
from vtts.fit.landmarks import detect_faces

DATA = Path(__file__).parents[1] / "data"
CARPHONE = DATA / "video" / "carphone_qcif.mp4"
HEAD = str(DATA / "models" / "head.wrl")


def vtts(*args: str, cwd: Path | None = None) -> subprocess.CompletedProcess:
    exe = Path(sys.executable).with_name("vtts")
    return subprocess.run([str(exe), *args], capture_output=True, text=True, timeout=300, cwd=cwd)


def _frames(n: int) -> list[np.ndarray]:
    return list(itertools.islice(read_video(CARPHONE).frames(), n))


@pytest.fixture(scope="module")
def carphone_track(tmp_path_factory, fits):
    folder = tmp_path_factory.mktemp("track")
    with fits.sharing():
        return track(_frames(3), fps=25.0, model_path=folder / "car-model.wrl"), folder


def test_a_head_is_fitted_to_the_first_face_and_tracked(carphone_track):
    tracked, folder = carphone_track
    assert [p.name for p in tracked.fitted] == [
        "car-model.wrl",
        "car-model.adt",
        "car-model-face.png",
        "car-model-frame.png",
    ]
    assert all(p.is_file() for p in tracked.fitted)
    assert tracked.model.name == "car-model"
    analysis = tracked.analysis
    assert [fe.index for fe in analysis.frames] == [0, 1, 2]
    psnr = analysis.psnr()
    # the head textured with its first frame gives that frame back (a bundled head reaches
    # 15-17 dB on this video)
    assert psnr[0] > 35.0, psnr
    assert psnr.min() > 22.0, psnr
    # the camera is the fit's: the head barely moves in three frames of a talking man
    head = np.array([fe.params[47:50] for fe in analysis.frames])
    assert np.abs(head).max() < 6000, head  # AU: under 3.5 degrees
    assert tracked.restarts == []


def test_the_stream_carries_the_translation_in_es_units(carphone_track):
    tracked, _ = carphone_track
    stream = tracked.analysis.stream("car", fapu=tracked.model.fapu)
    t = np.array([fe.translation for fe in tracked.analysis.frames])
    assert stream.translation is not None
    assert np.allclose(stream.translation * tracked.model.fapu.es, t)
    assert tracked.analysis.stream("car").translation is None  # without the model's units


def test_a_given_model_is_placed_on_the_landmarks():
    """Render a head at a known pose, find its landmarks, and place the head from zero."""
    model = load_model("cybatt")
    est = Estimator(model, size=(352, 288), unknowns=(48, 49, 50, "tx", "ty", "tz"))
    est.params[48] = 3000  # head yaw, AU
    est.translation[:] = (0.4, -0.2, 0.0)
    frame = est.reconstruct()
    truth = est.translation.copy(), est.params.copy()
    faces = detect_faces(frame)
    assert faces
    points = feature_vertices(est.geometry, model.tables.feature_points)
    assert len(points) >= 6
    est.params[:] = 0
    est.translation[:] = 0
    error = landmark_pose(est, faces[0].landmarks)
    assert error < 3.0
    assert np.allclose(est.translation[:2], truth[0][:2], atol=0.08), est.translation
    # where the feature points land in the image is what the landmarks decide
    index = np.array(list(points.values()))
    placed, _ = project(est.geometry.positions(est.params, est.translation)[index], est.camera)
    true, _ = project(est.geometry.positions(truth[1], truth[0])[index], est.camera)
    assert np.median(np.linalg.norm(placed - true, axis=1)) < 3.0


def test_a_model_without_feature_points_cannot_be_placed():
    model = load_model(HEAD)
    model.tables.feature_points.clear()
    est = Estimator(model, size=(176, 144), unknowns=(48, 49, 50, "tx", "ty", "tz"))
    with pytest.raises(AnalysisError, match="feature points"):
        landmark_pose(est, np.zeros((468, 3)))


@pytest.mark.usefixtures("shared_fit")
def test_frames_before_the_first_face_copy_its_estimate(tmp_path):
    blank = np.zeros((144, 176, 3), np.uint8)
    frames = [blank, blank, *_frames(1)]
    tracked = track(frames, fps=25.0, model_path=tmp_path / "m.wrl")
    assert tracked.first == 2
    psnr = tracked.analysis.psnr()
    assert np.isnan(psnr[:2]).all() and np.isfinite(psnr[2])
    assert [fe.index for fe in tracked.analysis.frames] == [0, 1, 2]
    assert np.array_equal(tracked.analysis.frames[0].params, tracked.analysis.frames[2].params)


def test_no_face_at_all_is_a_clear_error(tmp_path):
    blank = np.zeros((144, 176, 3), np.uint8)
    with pytest.raises(AnalysisError, match="no face found in any of the 2 frames"):
        track([blank, blank], fps=25.0, model_path=tmp_path / "m.wrl")
    assert not list(tmp_path.iterdir())


def test_the_fitted_heads_made_up_parts_are_drawn_but_not_matched(carphone_track):
    tracked, _ = carphone_track
    est = Estimator(tracked.model, size=(176, 144), ignore=FITTED_IGNORED)
    plain = Estimator(tracked.model, size=(176, 144))
    _, ids = est.render(1)
    _, all_ids = plain.render(1)
    assert 0 < (ids >= 0).sum() < (all_ids >= 0).sum()


@pytest.mark.usefixtures("shared_fit")
def test_analyze_fits_writes_the_head_and_codes_the_translation(tmp_path, capsys):
    """The command's outputs, in this process (the analyze process's own: the other tests here
    and test_analyze_cli.py)."""
    clip = tmp_path / "clip"
    clip.mkdir()
    from PIL import Image

    for i, frame in enumerate(_frames(2)):
        Image.fromarray(frame).save(clip / f"f{i}.png")
    assert main(["analyze", str(clip), "-o", str(tmp_path / "talk.fbs"), "--quiet"]) == 0, (
        capsys.readouterr().err
    )
    for name in (
        "talk.fbs",
        "talk-model.wrl",
        "talk-model.adt",
        "talk-model-face.png",
        "talk-model-frame.png",
    ):
        assert (tmp_path / name).is_file(), name
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".")]  # no staging left
    data = (tmp_path / "talk.fbs").read_bytes()
    assert read_header(data).translation
    assert decode(data).translation is not None
    capsys.readouterr()
    main(["check", str(tmp_path / "talk.fbs")])
    out = capsys.readouterr().out
    assert "head translation" in out, out
    assert main(["check", str(tmp_path / "talk-model.wrl")]) == 0, capsys.readouterr().err


@pytest.mark.parametrize(
    "args, fragment, process",
    [
        (["--camera", "300,300,88,72"], "--camera is for a given --model", True),
        (["--face", "0"], "--face must be 1", False),
        (
            ["--face", "3"],
            "--face 3: frame 0, the one the head is fitted to, shows 1 face(s)",
            False,
        ),
        (["--rate", "12.5"], "--rate sets the rate of a coded .fbs", False),
        (["--model", "auto", "--model", "cybatt"], "fits one model, got 2", False),
        (
            ["--model", "cybatt", "--texture", "mean"],
            "the texture of the head --model auto",
            False,
        ),
    ],
)
def test_analyze_auto_bad_input(tmp_path, capsys, args, fragment, process):
    """``process``: in a ``vtts`` process (its exit status and stderr), else through
    :func:`vtts.cli.main` in this one (the same status and message)."""
    clip = tmp_path / "clip"
    clip.mkdir()
    from PIL import Image

    Image.fromarray(_frames(1)[0]).save(clip / "f0.png")
    argv = ["analyze", str(clip), "-o", str(tmp_path / "talk.fap"), "--quiet", *args]
    if process:
        r = vtts(*argv)
        status, stderr = r.returncode, r.stderr
    else:
        status, stderr = main(argv), capsys.readouterr().err
    assert status == 1, stderr
    assert fragment in stderr, stderr
    assert "Traceback" not in stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == ["clip"]


@pytest.mark.usefixtures("shared_fit")
def test_a_frame_that_loses_the_model_is_started_again_from_its_landmarks(tmp_path, monkeypatch):
    from vtts.errors import VttsError

    real = Tracker.estimate  # the accurate mode's estimator too (finish=True)
    calls = []

    def estimate(self, frame, index=0, time=0.0, *observed):
        calls.append(index)
        if index == 1 and calls.count(1) == 1:
            self.translation[:] = (100.0, 0.0, 0.0)  # thrown out of view
            raise VttsError("the model covers only 0 pixels at 1/1 size")
        return real(self, frame, index, time, *observed)

    monkeypatch.setattr(Tracker, "estimate", estimate)
    tracked = track(_frames(2), fps=25.0, model_path=tmp_path / "m.wrl")
    assert tracked.restarts == [1]
    assert calls == [0, 1, 1]
    assert tracked.analysis.psnr()[1] > 22.0
    assert abs(tracked.analysis.frames[1].translation[0]) < 1.0


@pytest.fixture(scope="module")
def held_track(tmp_path_factory, fits) -> tuple[Tracked, dict[int, int]]:
    """Carphone's first four frames tracked with frame 2's estimate failing, the head thrown
    out of view, and no restart from the landmarks to be had: the track and, for each frame,
    how many estimates' motion the estimator held at its start."""
    import vtts.analysis.track as track_module
    from vtts.errors import VttsError

    real = Tracker.estimate  # the accurate mode's estimator too (finish=True)
    history_at_start = {}

    def estimate(self, frame, index=0, time=0.0, *observed):
        history_at_start[index] = len(self._history)
        if index == 2:
            self.translation[:] = (100.0, 0.0, 0.0)
            raise VttsError("the model covers only 0 pixels at 1/1 size")
        return real(self, frame, index, time, *observed)

    folder = tmp_path_factory.mktemp("held")
    with fits.sharing(), pytest.MonkeyPatch.context() as mp:
        mp.setattr(Tracker, "estimate", estimate)
        mp.setattr(track_module, "_restart", lambda *a, **k: (None, False))
        tracked = track(_frames(4), fps=25.0, model_path=folder / "m.wrl")
    return tracked, history_at_start


def test_a_frame_that_cannot_be_restarted_holds_the_last_estimate(held_track):
    tracked = held_track[0]
    assert tracked.held == [2] and tracked.restarts == []
    frames = tracked.analysis.frames
    assert np.array_equal(frames[2].params, frames[1].params)
    assert np.isnan(frames[2].psnr) and np.isfinite(frames[3].psnr)
    assert abs(frames[3].translation[0]) < 1.0  # frame 3 starts from frame 1's state


@pytest.mark.usefixtures("shared_fit")
def test_a_head_that_ran_away_is_placed_again_from_the_neutral_face(tmp_path, monkeypatch):
    """A frame whose estimate ends with the head turned past MAX_TURN_AU (and its FAPs off) —
    a good PSNR notwithstanding — is re-initialized from the landmarks, starting from the
    neutral face and pose rather than from where the estimate ran to."""
    import vtts.analysis.track as track_module

    real = Tracker.estimate  # the accurate mode's estimator too (finish=True)
    calls = []
    placed_from = []

    def estimate(self, frame, index=0, time=0.0, *observed):
        calls.append(index)
        fe = real(self, frame, index, time, *observed)
        if index == 1 and calls.count(1) == 1:
            self.params[47] = 3 * track_module.MAX_TURN_AU  # pitched by 3.6 rad
            self.params[2] = 900.0  # and the jaw with it
        return fe

    real_pose = track_module.landmark_pose

    def pose(estimator, landmarks, *args, **kwargs):
        placed_from.append((estimator.params.copy(), estimator.translation.copy()))
        return real_pose(estimator, landmarks, *args, **kwargs)

    monkeypatch.setattr(Tracker, "estimate", estimate)
    monkeypatch.setattr(track_module, "landmark_pose", pose)
    tracked = track(_frames(3), fps=25.0, model_path=tmp_path / "m.wrl")
    assert tracked.restarts == [1] and tracked.held == []
    assert calls == [0, 1, 1, 2]
    params, translation = placed_from[-1]
    assert not params.any() and not translation.any()  # the neutral face and pose
    frames = tracked.analysis.frames
    assert all(abs(f.params[47]) < track_module.MAX_TURN_AU for f in frames)
    assert tracked.analysis.psnr()[1] > 22.0


@pytest.mark.parametrize(
    ("rotation", "shift", "away"),
    [
        ((0.0, 0.0, 0.0), (0.0, 0.0, 0.0), False),
        ((60_000.0, -60_000.0, 30_000.0), (0.01, 0.02, -0.3), False),
        ((0.0, 130_000.0, 0.0), (0.0, 0.0, 0.0), True),
        ((0.0, 0.0, -130_000.0), (0.0, 0.0, 0.0), True),
        ((0.0, 0.0, 0.0), (0.0, 0.0, -0.6), True),
        ((0.0, 0.0, 0.0), (0.4, 0.4, 0.0), True),
    ],
)
def test_a_head_runs_away_beyond_a_turn_or_a_shift(rotation, shift, away):
    """``shift``: the translation in units of the camera's distance from the head."""
    import vtts.analysis.track as track_module

    estimator = Estimator(load_model(HEAD), size=(176, 144))
    assert estimator.distance > 0
    estimator.params[47:50] = rotation
    estimator.translation[:] = np.array(shift) * estimator.distance
    assert track_module._run_away(estimator) is away


def test_a_held_frame_carries_no_motion_on(held_track):
    """After a hold the next frame starts afresh: the motion of the two estimates before the
    hold would otherwise be carried on, growing with the frames held."""
    tracked, history_at_start = held_track
    assert tracked.held == [2]
    assert history_at_start[2] == 2  # frames 0 and 1 carried their motion to frame 2
    assert history_at_start[3] == 0  # not past the hold
