"""Landmarks every frame: the face mesh's points as observations of the estimate
(:mod:`vtts.analysis.landmark_term`), followed from frame to frame, and the tracking mode's
working size."""

from __future__ import annotations

import itertools
from pathlib import Path

import numpy as np
import pytest

from vtts.analysis.landmark_pose import feature_vertices
from vtts.analysis.landmark_term import (
    HUBER,
    LandmarkSystem,
    landmark_points,
    unknown_values,
)
from vtts.analysis.track import scaled_face, shrink, track, working_scale
from vtts.analysis.tracker import Tracker
from vtts.analysis.video import read_video
from vtts.animate.fapstream import hold
from vtts.face import load_model
from vtts.fap.coding import decode, encode
from vtts.fit.landmarks import default_detector, detect_faces

DATA = Path(__file__).parents[1] / "data"
CARPHONE = DATA / "video" / "carphone_qcif.mp4"
AKIYO = DATA / "video" / "akiyo_cif.mp4"


def _frames(path: Path, n: int) -> list[np.ndarray]:
    return list(itertools.islice(read_video(path).frames(), n))


def _system(across=None, sigma=1.0) -> LandmarkSystem:
    """Two points at the origin, one unknown that moves both along x by a pixel a unit."""
    jacobian = np.array([[1.0], [0.0], [1.0], [0.0]])
    target = np.array([[3.0, 4.0], [3.0, 4.0]])
    return LandmarkSystem(np.zeros((2, 2)), jacobian, target, np.full(2, sigma), np.zeros(1),
                          across, weight=1.0)  # fmt: skip


def test_the_residual_is_the_landmarks_less_the_points_moved_linearly():
    term = _system()
    assert np.allclose(term.residual(np.zeros(1)), [[3, 4], [3, 4]])
    assert np.allclose(term.residual(np.array([3.0])), [[0, 4], [0, 4]])
    assert term.moved(np.array([2.0])) == pytest.approx(2.0)
    assert term.error(np.zeros(1)) == pytest.approx(5.0)


def test_an_observation_of_one_direction_says_nothing_across_it():
    """An eyelid point is seen across the eye only: its residual along the lid is no error."""
    across = np.array([[0.0, 1.0], [0.0, 0.0]])  # the first point seen along y only
    term = _system(across, sigma=10.0)  # within Huber's reach
    r = term.residual(np.zeros(1))
    assert np.allclose(r, [[0, 4], [3, 4]])
    ata, atb = term.normal_equations(np.zeros(1))
    # only the second point's x says where the unknown goes: the solution is 3, as it says
    assert np.linalg.solve(ata, atb) == pytest.approx([3.0])
    assert ata[0, 0] == pytest.approx(0.01)  # one row of weight 1 / sigma²


def test_a_far_landmark_pulls_with_a_bounded_force():
    near, far = _system(), _system()
    far.target = far.target * 100.0
    _, b_near = near.normal_equations(np.zeros(1))
    ata_far, b_far = far.normal_equations(np.zeros(1))
    # Huber: beyond HUBER sigma the pull stops growing with the distance
    assert b_far[0] == pytest.approx(2 * HUBER * 300 / np.hypot(300, 400))
    assert b_far[0] < 2 * b_near[0]
    assert ata_far[0, 0] < 1.0


def test_the_held_columns_are_left_out():
    term = _system()
    ata, atb = term.normal_equations(np.zeros(1), held=np.array([True]))
    assert not ata.any() and not atb.any()


def test_a_pyramid_level_sees_the_term_in_its_own_pixels():
    term = _system()
    ata, atb = term.normal_equations(np.zeros(1))
    ata2, atb2 = term.normal_equations(np.zeros(1), factor=2.0, density=0.25)
    # the same solution (the unknown's units do not change with the level); the weight
    # relative to the photometric rows does
    assert np.linalg.solve(ata2, atb2) == pytest.approx(np.linalg.solve(ata, atb))
    assert term.cost(np.zeros(1), 2.0, 0.25) == pytest.approx(term.cost(np.zeros(1)) / 16)


def test_a_bundled_head_is_observed_at_its_landmarks_another_head_at_its_feature_points():
    from vtts.analysis import Estimator

    cybatt = Estimator(load_model("cybatt"), size=(176, 144))
    points = landmark_points(cybatt.geometry, cybatt.model.tables.feature_points)
    assert len(points) > 100 and points.landmark is not None
    assert np.allclose(points.targets.sum(1), 1.0)
    small = Estimator(load_model(str(DATA / "models" / "head.wrl")), size=(176, 144))
    features = landmark_points(small.geometry, small.model.tables.feature_points)
    defined = feature_vertices(small.geometry, small.model.tables.feature_points)
    assert len(features) == len(defined) and features.landmark is None


def test_the_landmarks_find_a_head_that_moved_further_than_the_solves_reach():
    """A head turned and moved far from where the estimate starts: the jump onto the rendered
    frame's landmarks brings it within the solves' reach (without the landmarks the pyramid runs
    off to 16 dB), and the estimate lands on it."""
    model = load_model("cybatt")
    tracker = Tracker(model, size=(352, 288), unknowns=(48, 49, 50, "tx", "ty", "tz", 3))
    tracker.params[48] = 6000  # yaw, AU
    tracker.translation[:] = (0.5, -0.3, 0.0)
    frame = tracker.reconstruct()
    truth = unknown_values(tracker)
    faces = detect_faces(frame)
    assert faces
    tracker.params[:] = 0
    tracker.translation[:] = 0
    tracker.observe(faces[0])
    before = tracker.landmark_error()
    tracker._jump_to_landmarks()
    assert before > 40 and tracker.landmark_error() < 3.0, (before, tracker.landmark_error())
    tracker.params[:] = 0
    tracker.translation[:] = 0
    fe = tracker.estimate(frame, 0, 0.0, faces[0])
    found = unknown_values(tracker)
    assert abs(found[1] - truth[1]) < 200, found  # yaw within 0.12 degrees
    assert np.allclose(found[3:6], truth[3:6], atol=0.01), found
    assert fe.psnr > 40 and fe.landmark_px < 1.5, (fe.psnr, fe.landmark_px)


def _turned_away(finish: bool) -> tuple[Tracker, np.ndarray, object]:
    """A tracker of cybatt (the accurate mode's with ``finish``), the frame it renders with the
    head turned and moved far, and that frame's face; the tracker left at neutral."""
    tracker = Tracker(load_model("cybatt"), size=(352, 288),
                      unknowns=(48, 49, 50, "tx", "ty", "tz", 3), finish=finish)  # fmt: skip
    tracker.params[48] = 6000  # yaw, AU
    tracker.translation[:] = (0.5, -0.3, 0.0)
    frame = tracker.reconstruct()
    (face,) = detect_faces(frame)
    tracker.params[:] = 0
    tracker.translation[:] = 0
    tracker.observe(face)
    return tracker, frame, face


def test_the_accurate_mode_jumps_further_onto_far_landmarks():
    """A frame that starts far from its landmarks (a head moving fast, every second frame): the
    accurate mode's jump takes up to FAR_JUMP_STEPS steps and lands nearer them than the
    tracking mode's JUMP_STEPS; both take the same steps from a near start."""
    from vtts.analysis.estimator import JUMP_FAR_PX, JUMP_STEPS
    from vtts.analysis.tracker import FAR_JUMP_STEPS

    accurate, _, _ = _turned_away(finish=True)
    tracking, _, face = _turned_away(finish=False)
    assert (accurate.far_jump_steps, tracking.far_jump_steps) == (FAR_JUMP_STEPS, JUMP_STEPS)
    assert accurate.landmark_error() > JUMP_FAR_PX
    accurate._jump_to_landmarks()
    tracking._jump_to_landmarks()
    assert accurate.landmark_error() < 0.8 * tracking.landmark_error(), (
        accurate.landmark_error(), tracking.landmark_error())  # fmt: skip
    # from where the tracking mode's jump ended (near): the same steps, the same estimate
    accurate.params[:], accurate.translation[:] = tracking.params, tracking.translation
    accurate.observe(face)
    tracking.observe(face)
    assert tracking.landmark_error() < JUMP_FAR_PX
    accurate._jump_to_landmarks()
    tracking._jump_to_landmarks()
    assert np.array_equal(unknown_values(accurate), unknown_values(tracking))


@pytest.mark.parametrize("moving", [False, True])
def test_the_accurate_mode_starts_a_far_frame_where_the_head_stood(moving):
    """The head's motion between the last two estimates is carried on over the next frame,
    unless (the accurate mode) that start lies far from the frame's landmarks and standing
    still lies nearer: a jerky head that stopped. The tracking mode carries the motion on."""
    from vtts.analysis.estimator import JUMP_FAR_PX

    shown = np.array([0.5, -0.3, 0.0])  # where the frame shows the head
    step = np.array([0.2, 0.0, 0.0])  # its motion between the last two estimates
    last = shown - step if moving else shown  # moving: it goes on to the frame's place
    for finish in (True, False):
        tracker, _, face = _turned_away(finish)
        tracker.params[48] = 6000
        carried = last + step
        tracker.translation[:] = carried
        far = tracker.landmark_term().error(unknown_values(tracker))
        assert (far > JUMP_FAR_PX) != moving  # the carried start: far where the head stopped
        tracker.observe(face)
        tracker._history = [(0, tracker.params.copy(), last - step),
                            (2, tracker.params.copy(), last.copy())]  # fmt: skip
        tracker.translation[:] = last
        tracker._start_near_landmarks(4)
        expected = last if finish and not moving else carried
        assert tracker.translation == pytest.approx(expected), (finish, moving)


def test_follow_finds_the_face_from_the_last_frames_landmarks_without_the_detector():
    first, second = _frames(AKIYO, 2)
    detector = default_detector()
    (face,) = detector.detect(first)
    followed = detector.follow(second, face.landmarks)
    assert followed is not None
    (found,) = detector.detect(second)
    distance = np.linalg.norm(followed.landmarks[:, :2] - found.landmarks[:, :2], axis=1)
    assert np.median(distance) < 1.0
    assert followed.presence > 0.9
    assert detector.follow(np.zeros_like(second), face.landmarks) is None


def test_working_size():
    (first,) = _frames(AKIYO, 1)
    (face,) = detect_faces(first)
    assert working_scale(face) == 1  # Akiyo's eyes are 34 pixels apart
    small = shrink(first, 2)
    assert small.shape == (144, 176, 3) and small.dtype == np.uint8
    assert small[0, 0, 0] == round(first[:2, :2, 0].astype(float).mean())
    half = scaled_face(face, 2)
    assert np.allclose(half.landmarks, face.landmarks / 2)
    big = type(face)(face.box, face.score, face.keypoints, face.landmarks * 3, face.presence)
    assert working_scale(big) == 2


@pytest.fixture(scope="module")
def with_a_gap(tmp_path_factory, fits):
    """Carphone's frames 0–3 with frame 2 blanked: the landmarks lose the face there."""
    frames = _frames(CARPHONE, 4)
    frames[2] = np.zeros_like(frames[2])
    with fits.sharing():
        return track(frames, fps=25.0, model_path=tmp_path_factory.mktemp("gap") / "m.wrl",
                     tracking=True)  # fmt: skip


def test_every_frame_is_placed_on_its_landmarks(with_a_gap):
    error = np.array([fe.landmark_px for fe in with_a_gap.analysis.frames])
    seen = [0, 1, 3]
    assert np.all(error[seen] < 1.5), error
    assert with_a_gap.restarts == []


def test_a_frame_where_the_landmarks_lose_the_face_holds_the_head(with_a_gap):
    frames = with_a_gap.analysis.frames
    assert with_a_gap.unseen == [2] and with_a_gap.held == [2]
    assert np.array_equal(frames[2].params, frames[1].params)
    assert np.isnan(frames[2].psnr) and np.isnan(frames[2].landmark_px)
    assert np.isfinite(frames[3].psnr)  # found again in the next frame
    assert [fe.held for fe in frames] == [False, False, True, False]
    # the coded stream says so: the frame sets no FAP, and a decoder holds the last values
    stream = with_a_gap.analysis.stream()
    assert not stream.mask[2].any() and stream.mask[[0, 1, 3]][:, 2:].any(axis=1).all()
    decoded = decode(encode(stream))
    assert not decoded.mask[2].any()
    held = hold(decoded)[0]
    assert np.array_equal(held[2], held[1])


@pytest.mark.usefixtures("shared_fit")
def test_the_working_size_estimates_the_same_head(tmp_path):
    """Akiyo tracked at half size: the same head, the full size's camera in the analysis."""
    frames = _frames(AKIYO, 2)
    full = track(frames, fps=25.0, model_path=tmp_path / "a.wrl", tracking=True)
    half = track(frames, fps=25.0, model_path=tmp_path / "b.wrl", tracking=True, scale=2)
    assert (full.scale, half.scale) == (1, 2)
    a, b = full.analysis, half.analysis
    assert b.camera.fx == pytest.approx(a.camera.fx) and b.camera.cx == pytest.approx(a.camera.cx)
    for fa, fb in zip(a.frames, b.frames, strict=True):
        assert np.allclose(fa.translation, fb.translation, atol=0.02)
        assert np.abs(fa.params[47:50] - fb.params[47:50]).max() < 2500


@pytest.mark.usefixtures("shared_fit")
def test_the_accurate_mode_works_at_the_working_size_too(tmp_path):
    """Akiyo twice as large (her eyes 69 pixels apart): the accurate mode estimates her at half
    size, as the tracking mode does, through the full size's camera."""
    frames = [np.repeat(np.repeat(f, 2, axis=0), 2, axis=1) for f in _frames(AKIYO, 2)]
    tracked = track(frames, fps=25.0, model_path=tmp_path / "big.wrl")
    assert tracked.scale == 2 and not tracked.restarts
    at_full = track(frames[:1], fps=25.0, model_path=tmp_path / "full.wrl", scale=1)
    assert at_full.scale == 1
    for a, b in ((tracked.analysis.camera, at_full.analysis.camera),):
        assert (a.fx, a.cx, a.cy) == pytest.approx((b.fx, b.cx, b.cy))
    assert all(np.isfinite(fe.psnr) for fe in tracked.analysis.frames)


def test_bad_landmarks_to_follow_and_a_bad_working_scale_are_clear_errors(tmp_path):
    from vtts.errors import AnalysisError, FitError

    (frame,) = _frames(CARPHONE, 1)
    with pytest.raises(FitError, match=r"landmarks to follow must be \(468, 2\) finite pixels"):
        default_detector().follow(frame, np.zeros((10, 2)))
    with pytest.raises(FitError, match="finite"):
        default_detector().follow(frame, np.full((468, 2), np.nan))
    for scale in (0, 1.5):
        with pytest.raises(AnalysisError, match="working scale must be a whole factor"):
            track([frame], fps=25.0, model_path=tmp_path / "m.wrl", scale=scale)
    assert not list(tmp_path.iterdir())
