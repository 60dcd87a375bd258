"""The tracking mode (:class:`vtts.analysis.tracker.Tracker`): its pieces against their exact
counterparts, a lit synthetic head followed to the accurate estimator's precision, and a head
fitted to camera video followed with about one rendering in two frames."""

from __future__ import annotations

import itertools
import subprocess
import sys
from pathlib import Path

import imageio_ffmpeg
import numpy as np
import pytest
from scipy.ndimage import map_coordinates

import vtts
import vtts.analysis.tracker as tracker_module
from vtts.analysis import DEFAULT_UNKNOWNS, PYRAMID, TABLE1_FAPS, Analysis, Estimator
from vtts.analysis.quality import sequence_psnr, stream_psnr
from vtts.analysis.solve import normal_equations
from vtts.analysis.synthetic import random_truth, render_sequence, table1_truth
from vtts.analysis.track import FITTED_IGNORED, Tracked, track
from vtts.analysis.tracker import (
    STAGES,
    Tracker,
    _bilinear,
    _gradients_at,
    _system,
    _window_around,
    _with_gradients,
)
from vtts.analysis.unknowns import JAW_AND_CORNERS
from vtts.analysis.video import read_video
from vtts.cli import main

DATA = Path(__file__).parents[1] / "data"
CARPHONE = DATA / "video" / "carphone_qcif.mp4"
EXE = Path(sys.executable).with_name("vtts")


@pytest.mark.parametrize("light", [True, False])
def test_system_is_the_accurate_estimators_normal_equations(light):
    rng = np.random.default_rng(3)
    n, k = 400, 9
    du, dv = (rng.normal(size=(n, k)).astype(np.float32) for _ in range(2))
    gx, gy, r, color = (rng.normal(size=(n, 3)).astype(np.float32) for _ in range(4))
    w = rng.random(n).astype(np.float32)
    a1, b1 = _system(du, dv, gx, gy, r, color if light else None, w)
    a2, b2 = normal_equations(du, dv, gx, gy, r, color if light else None, w)
    assert a1.shape == a2.shape == ((k + 6, k + 6) if light else (k, k))
    np.testing.assert_allclose(a1, a2, rtol=1e-5, atol=1e-4 * np.abs(a2).max())
    np.testing.assert_allclose(b1, b2, rtol=1e-5, atol=1e-4 * np.abs(b2).max())


def test_bilinear_samples_as_scipy_does_and_clamps_outside():
    rng = np.random.default_rng(4)
    image = rng.random((20, 30, 2)).astype(np.float32)
    x = rng.uniform(0, 29, 50)
    y = rng.uniform(0, 19, 50)
    got = _bilinear(image, x, y)
    for c in range(2):
        want = map_coordinates(image[..., c], [y, x], order=1)
        np.testing.assert_allclose(got[:, c], want, rtol=1e-5, atol=1e-6)
    # outside: the border pixel
    out = _bilinear(image, np.array([-3.0, 40.0]), np.array([-1.0, 25.0]))
    np.testing.assert_allclose(out, [image[0, 0], image[19, 29]])


def test_the_gradients_at_the_samples_are_those_of_the_whole_image():
    rng = np.random.default_rng(5)
    image = (rng.random((9, 13, 3)) * 255).astype(np.float32)
    rows, cols = np.meshgrid(np.arange(9), np.arange(13), indexing="ij")
    rows, cols = rows.ravel(), cols.ravel()  # the border's pixels among them
    whole = _with_gradients(image)[rows, cols]
    gx, gy = _gradients_at(image, rows, cols)
    assert gx.dtype == gy.dtype == np.float32
    assert np.array_equal(gx, whole[:, 3:6]) and np.array_equal(gy, whole[:, 6:9])


def test_the_samples_are_projected_once_for_an_estimate(cybatt):
    tracker = _tracked_to_frame_1(Tracker(cybatt, size=(176, 144), unknowns=TABLE1_FAPS))
    samples = tracker._samples
    u, v = tracker._project(samples)
    again = tracker._project(samples)
    assert again[0] is u and again[1] is v  # the stages' shift, then the solve
    tracker.params[48] += 2000
    moved = tracker._project(samples)
    assert not np.array_equal(moved[0], u)
    tracker.params[48] -= 2000
    back = tracker._project(samples)
    assert back[0] is not u and np.array_equal(back[0], u)


def test_the_window_keeps_its_size_while_the_face_fits():
    rows, cols = np.array([50, 90]), np.array([100, 160])
    # the face's box with 16 pixels each side is 93 x 73: a 128 x 96 window keeps its size
    assert _window_around(rows, cols, (128, 96), (352, 288)) == (66, 22, 128, 96)
    # a far larger one is made smaller (steps of 32), a too small one larger
    assert _window_around(rows, cols, (352, 288), (352, 288))[2:] == (96, 96)
    assert _window_around(rows, cols, (64, 64), (352, 288))[2:] == (96, 96)
    # never beyond the frame
    x0, y0, w, h = _window_around(np.array([0, 140]), np.array([0, 170]), (64, 64), (176, 144))
    assert (x0, y0) == (0, 0) and w <= 176 and h <= 144


@pytest.fixture(scope="module")
def cybatt():
    return vtts.load_model("cybatt")


def test_a_lit_synthetic_head_is_followed_as_the_accurate_estimator_does(cybatt):
    """cybatt is lit: its shading changes with the pose, so the tracker finishes each frame
    with the accurate estimator's pyramid and comes as close to the truth as it. Both follow
    from the first frame, neutral, as if they had estimated it (both start a track with the
    accurate estimator, from neutral: they would end there); of the frames after it the
    tracker renders most in the first two, later ones less."""
    truth = table1_truth(100)[::5][:4]  # Table 1's pace, every 5th frame, at CIF
    frames = render_sequence(cybatt, truth[1:], size=(352, 288))
    tracker = Tracker(cybatt, size=(352, 288), unknowns=TABLE1_FAPS)
    accurate = Estimator(cybatt, size=(352, 288), unknowns=TABLE1_FAPS)
    for est in (tracker, accurate):  # as if tracked
        est._history = [(0, est.params.copy(), est.translation.copy())]
    idx = [f - 1 for f in TABLE1_FAPS]
    for i, frame in enumerate(frames, 1):
        t = tracker.estimate(frame, i)
        a = accurate.estimate(frame, i)
        err_t = np.abs(t.params[idx] - truth[i, idx])
        err_a = np.abs(a.params[idx] - truth[i, idx])
        # within a few units of the truth, and of what the accurate mode gets
        assert err_t.max() <= max(8.0, 2 * err_a.max()), (i, err_t, err_a)
        # at most one per solve on the samples, the pyramid's, and one after
        most = sum(st.iterations for st in STAGES) + sum(lv.iterations for lv in PYRAMID) + 1
        assert 1 <= tracker.renderings <= most, tracker.renderings


def test_on_a_lit_face_the_jaw_and_lip_corners_are_searched_on_the_rendered_image(cybatt):
    """Where the jaw opens wide the lips uncover the teeth, and the solves stall with the jaw
    and the lip corners two or three units off (seed 9's ninth analyzed frame: the solves'
    last steps a few thousandths of a pixel, the face at 42 dB). On a lit face the tracker
    searches them on the rendered image, as the eyelids, and finds them. The frame is tracked
    from the seventh and eighth frames' truth, as if tracked there: the solves stall on it so
    too (without the search, two units off)."""
    truth = random_truth(9, 100)[::5][:9]
    frame = render_sequence(cybatt, truth[-1:], size=(352, 288))[0]
    tracker = Tracker(cybatt, size=(352, 288), unknowns=TABLE1_FAPS)
    tracker.params[:] = truth[7]
    tracker._history = [(i * 5, truth[i].copy(), np.zeros(3)) for i in (6, 7)]  # as if tracked
    found = tracker.estimate(frame, 40)
    assert tracker._samples.lit >= tracker_module.LIT_SHARE
    assert tracker.refined == (19, 20)  # the wider search is for a lit frame only
    assert tracker.search_steps == dict.fromkeys(JAW_AND_CORNERS, tracker_module.LIT_REFINE_STEPS)
    idx = [fap - 1 for fap in JAW_AND_CORNERS]
    error = np.abs(found.params[idx] - truth[-1, idx])
    assert error.max() <= 1.0, error


def _carphone(n: int) -> list[np.ndarray]:
    return list(itertools.islice(read_video(CARPHONE).frames(), n))


def _track_carphone(folder: Path, fits, n: int, tracking: bool) -> tuple[Tracked, list[bool]]:
    """``track`` of Carphone's first ``n`` frames at 30 frames/s (the fit of the first frame
    shared: ``fits.sharing``), and the ``finish`` of each :class:`Tracker` it made."""
    made = []
    init = Tracker.__init__

    def spy(self, *args, **kwargs):
        init(self, *args, **kwargs)
        made.append(self.finish)

    with fits.sharing(), pytest.MonkeyPatch.context() as mp:
        mp.setattr(Tracker, "__init__", spy)
        tracked = track(_carphone(n), fps=30.0, model_path=folder / "car.wrl", tracking=tracking)
    return tracked, made


@pytest.fixture(scope="module")
def accurate_track(tmp_path_factory, fits) -> tuple[Tracked, list[bool]]:
    """Carphone's first six frames in the accurate mode (:func:`_track_carphone`)."""
    return _track_carphone(tmp_path_factory.mktemp("accurate"), fits, 6, tracking=False)


@pytest.fixture(scope="module")
def tracking_track(tmp_path_factory, fits) -> tuple[Tracked, list[bool]]:
    """Carphone's first four frames in the tracking mode (:func:`_track_carphone`)."""
    return _track_carphone(tmp_path_factory.mktemp("tracking"), fits, 4, tracking=True)


def test_a_head_made_for_the_video_is_tracked_with_few_renderings(accurate_track, monkeypatch):
    """The fitted head's face is unlit: the samples of one rendering serve several frames, no
    polish, and the face PSNR stays with the accurate mode's. (Six frames: one rendering's
    samples serve the five after the first.)"""
    frames = _carphone(6)
    accurate, model = accurate_track[0], accurate_track[0].model  # the head it wrote, loaded
    tracker = Tracker(model, size=(176, 144), camera=accurate.analysis.camera,
                      ignore=FITTED_IGNORED, robust=True)  # fmt: skip
    estimates, renderings, searched = [], [], set()
    search = Tracker._search

    def search_spy(self, frame, windows, steps):
        searched.update(windows)
        return search(self, frame, windows, steps)

    monkeypatch.setattr(Tracker, "_search", search_spy)
    for i, frame in enumerate(frames):
        estimates.append(tracker.estimate(frame, i, i / 30.0))
        renderings.append(tracker.renderings)
    assert tracker._samples is not None and tracker._samples.lit < 0.5
    # unlit: the jaw and the lip corners (unknowns here) are left to the solves, not searched
    assert not searched & set(JAW_AND_CORNERS), searched
    monkeypatch.setattr(Tracker, "_search", search)
    assert np.mean(renderings[1:]) <= 1.0, renderings
    assert max(renderings[1:]) <= 2, renderings
    # the decoder's measure (the model rendered from the stream): as good as the accurate mode
    tracked = Analysis(estimates, tracker.unknowns, 30.0, tracker.camera, model.name)
    psnr = [
        sequence_psnr(stream_psnr(frames, a.stream("c", fapu=model.fapu), model, video_fps=30.0))
        for a in (tracked, accurate.analysis)
    ]
    assert psnr[0] >= psnr[1] - 1.0, psnr
    # with the eyelids among the unknowns: on this unlit face the solves on the samples hold
    # them (their columns are zero), and the search on the rendered image finds them (from
    # the first frame as the fit left it, as if estimated: its accurate start has no samples)
    lids = Tracker(model, size=(176, 144), camera=accurate.analysis.camera,
                   ignore=FITTED_IGNORED, robust=True,
                   unknowns=(*DEFAULT_UNKNOWNS, 19, 20))  # fmt: skip
    lids._history = [(0, lids.params.copy(), lids.translation.copy())]
    columns = [lids.unknowns.index(19), lids.unknowns.index(20)]
    seen = []
    original = tracker_module._system

    def spy(du, dv, *rest):
        seen.append(bool(np.any(du[:, columns]) or np.any(dv[:, columns])))
        return original(du, dv, *rest)

    monkeypatch.setattr(tracker_module, "_system", spy)
    for i, frame in enumerate(frames[1:4], 1):
        lids.estimate(frame, i, i / 30.0)
    assert seen and not any(seen)


def test_track_with_tracking_uses_the_tracker(tracking_track):
    tracked = tracking_track[0]
    assert len(tracked.analysis.frames) == 4
    assert not tracked.restarts
    assert np.all(tracked.analysis.psnr() > 20.0), tracked.analysis.psnr()


def test_the_cli_tracks_frames_from_stdin_by_default_and_refuses_both_modes(tmp_path, capsys):
    ffmpeg = imageio_ffmpeg.get_ffmpeg_exe()
    raw = subprocess.run(
        [ffmpeg, "-v", "error", "-i", str(CARPHONE), "-frames:v", "3", "-f", "rawvideo",
         "-pix_fmt", "rgb24", "-"], capture_output=True, check=True).stdout  # fmt: skip
    r = subprocess.run(
        [str(EXE), "analyze", "-", "--size", "176x144", "-o", str(tmp_path / "s.fap")],
        input=raw, capture_output=True, timeout=300,
    )  # fmt: skip
    assert r.returncode == 0, r.stderr.decode()
    assert b"tracking mode" in r.stdout, r.stdout
    # the usage error, in this process (an analyze process's exit status 2 for one:
    # test_analyze_cli.py)
    with pytest.raises(SystemExit) as refused:
        main(["analyze", str(CARPHONE), "-o", str(tmp_path / "x.fap"), "--track", "--accurate"])
    assert refused.value.code == 2 and "not allowed with argument" in capsys.readouterr().err


def _tracked_to_frame_1(tracker: Tracker) -> Tracker:
    """``tracker`` after Table 1's second frame (QCIF), tracked to from the first (neutral, the
    tracker's start) as if that had been estimated."""
    frame = render_sequence(tracker.model, table1_truth(10)[1:2], size=(176, 144))[0]
    tracker._history = [(0, tracker.params.copy(), tracker.translation.copy())]  # as if tracked
    tracker.estimate(frame, 1)
    return tracker


def test_between_frames_renders_only_samples_that_moved(cybatt):
    tracker = _tracked_to_frame_1(Tracker(cybatt, size=(176, 144), unknowns=TABLE1_FAPS))
    samples = tracker._samples
    tracker.between_frames()  # polished: the samples are where the estimate is
    assert tracker._samples is samples
    tracker.params[48] += 20000  # a turn of the head (0.2 rad) moves them pixels away
    tracker.between_frames()
    assert tracker._samples is not samples
    assert tracker._shift(tracker._samples) < 1e-3
    Estimator(cybatt, size=(176, 144)).between_frames()  # the accurate mode has nothing to do


def test_no_rendering_ahead_after_a_frame_the_head_outran(cybatt):
    """In the tracking mode with landmarks, a frame whose solves had to render (the head moved
    further than the samples serve) renders nothing between frames: the next would outrun that
    rendering too, and renders after its jump."""
    tracker = _tracked_to_frame_1(Tracker(cybatt, size=(176, 144), unknowns=TABLE1_FAPS))
    samples = tracker._samples
    tracker._observed = (np.zeros((468, 2)), 100.0)  # as if observed on its landmarks
    tracker.params[48] += 20000  # the samples moved pixels away
    tracker._outrun = True
    tracker.between_frames()
    assert tracker._samples is samples
    tracker._outrun = False  # a frame its samples served: render ahead as before
    tracker.between_frames()
    assert tracker._samples is not samples


def test_the_lost_rule_caps_its_reference_in_the_tracking_mode_only():
    from vtts.analysis.track import LOST_REFERENCE_CAP_DB, _lost

    recent = [45.0, 44.0, 43.0]  # the frames next to the one the head was fitted to
    assert _lost(31.0, recent)  # the accurate mode: 12 dB below the median
    assert not _lost(31.0, recent, LOST_REFERENCE_CAP_DB)  # tracking: a natural fall
    assert _lost(20.0, recent, LOST_REFERENCE_CAP_DB)  # … but not this


def test_a_face_that_left_the_window_is_found_in_the_whole_frame_or_dropped(cybatt):
    tracker = _tracked_to_frame_1(Tracker(cybatt, size=(176, 144), unknowns=(*TABLE1_FAPS, "tx")))
    assert tracker._box[2:] != (176, 144)  # a window around the face
    width = np.ptp(tracker.geometry.positions(tracker.params, tracker.translation)[:, 0])
    tracker.translation[0] += width / 2  # the head moves sideways out of its window
    tracker.between_frames()
    assert tracker._samples is not None and tracker._shift(tracker._samples) < 1e-3
    tracker.translation[0] += 50 * width  # and out of view altogether: no error between frames
    tracker.between_frames()
    assert tracker._samples is None


def test_a_lit_face_renders_within_a_frame_sooner(cybatt):
    """Frames of an unlit face (a head made for the video) render within their solves after
    RERENDER_PX; a lit face's, whose frames end with the accurate finest level anyway, after
    LIT_RERENDER_PX at most."""
    from types import SimpleNamespace

    tracker = Tracker(cybatt, size=(176, 144), unknowns=TABLE1_FAPS)
    assert tracker.rerender == tracker_module.RERENDER_PX > tracker_module.LIT_RERENDER_PX
    unlit = SimpleNamespace(lit=0.0)
    lit = SimpleNamespace(lit=1.0)
    assert tracker._rerender(unlit) == tracker_module.RERENDER_PX
    assert tracker._rerender(lit) == tracker_module.LIT_RERENDER_PX
    tracker.rerender = 2.0  # a smaller choice holds for both
    assert tracker._rerender(lit) == tracker._rerender(unlit) == 2.0


@pytest.fixture(scope="module")
def carphone_head(accurate_track):
    """A head fitted to Carphone's first frame, and the camera it looks through."""
    tracked = accurate_track[0]
    return tracked.model, tracked.analysis.camera


def test_the_accurate_mode_starts_each_frame_on_the_last_frames_final_rendering(
    carphone_head, monkeypatch
):
    """With ``finish`` (the accurate mode of ``track``) a frame after the first is solved on
    the samples of the last frame's final rendering — no rendering for them, none of the
    pyramid's coarse levels — then by the finest level, a rendering after every solve; its
    final rendering gives the next frame's samples, taken at the integer FAPs it shows."""
    model, camera = carphone_head
    frames = _carphone(5)
    est = Tracker(model, size=(176, 144), camera=camera, ignore=FITTED_IGNORED, robust=True,
                  finish=True)  # fmt: skip
    factors, sampled = [], []
    window, sample = Tracker._render_window, Tracker._sample

    def window_spy(self, factor, whole=False):
        factors.append((factor, whole))
        return window(self, factor, whole)

    def sample_spy(self, step=1):
        sampled.append(step)
        return sample(self, step)

    monkeypatch.setattr(Tracker, "_render_window", window_spy)
    monkeypatch.setattr(Tracker, "_sample", sample_spy)
    est.estimate(frames[0], 0)
    assert {f for f, _ in factors} == {4, 2, 1}  # the first frame: the whole pyramid
    for i, frame in enumerate(frames[1:], 1):
        factors.clear()
        found = est.estimate(frame, i, i / 30.0)
        finest = [f for f, whole in factors if not whole]
        assert set(finest) == {1}, factors  # no coarse level; the final rendering the last
        assert est.renderings == len(factors), (est.renderings, factors)
        assert found.iterations > len(finest) - 1  # the samples' solves too
        s = est._samples
        values = np.r_[found.params[[u - 1 for u in est.unknowns if not isinstance(u, str)]],
                       found.translation]  # fmt: skip
        order = [u for u in est.unknowns if not isinstance(u, str)] + ["tx", "ty", "tz"]
        assert np.array_equal(s.at, values[[order.index(u) for u in est.unknowns]])
    assert not sampled  # every frame's samples came from the one before
    # the same samples as a rendering of them at that estimate gives
    kept = s
    est.params[:], est.translation[:] = found.params, found.translation
    fresh = sample(est, est.sample_step)
    for s in (fresh, kept):  # to the frame's pixels (the windows may lie a pixel apart)
        s.rows, s.cols = s.rows + s.box[0].start, s.cols + s.box[1].start
    np.testing.assert_array_equal(fresh.rows, kept.rows)
    np.testing.assert_array_equal(fresh.cols, kept.cols)
    np.testing.assert_allclose(fresh.point, kept.point, atol=1e-4)
    np.testing.assert_allclose(fresh.motion, kept.motion, rtol=1e-4, atol=1e-6)
    colors = [s.raw[s.rows - s.box[0].start, s.cols - s.box[1].start] for s in (fresh, kept)]
    np.testing.assert_allclose(*colors, atol=1.0)  # a window's rasterization, a gray level


def test_the_accurate_mode_matches_as_well_as_the_pyramid_with_fewer_renderings(
    carphone_head,
):
    """Carphone's first frames: the samples' solves standing in for the coarse levels leave
    the face PSNR where the whole pyramid of renderings puts it, for fewer renderings."""
    model, camera = carphone_head
    frames = _carphone(5)
    options = dict(size=(176, 144), camera=camera, ignore=FITTED_IGNORED, robust=True)
    finish = Tracker(model, finish=True, **options)
    pyramid = Estimator(model, **options)
    drawn = []
    synthesize = pyramid._synthesize

    def counted(*args, **kwargs):
        drawn.append(1)
        return synthesize(*args, **kwargs)

    pyramid._synthesize = counted
    psnr, renderings = [], []
    for i, frame in enumerate(frames):
        drawn.clear()
        a = finish.estimate(frame, i, i / 30.0)
        b = pyramid.estimate(frame, i, i / 30.0)
        if i:
            psnr.append((a.psnr, b.psnr))
            renderings.append((finish.renderings, len(drawn)))
    a, b = np.array(psnr).T
    assert a.mean() >= b.mean() - 0.5 and a.min() >= b.min() - 1.5, psnr
    ours, theirs = np.array(renderings).sum(axis=0)
    assert ours <= 0.7 * theirs, renderings


def test_track_runs_the_accurate_mode_with_finish(accurate_track, tracking_track):
    assert accurate_track[1] == [True] and tracking_track[1] == [False]


def test_the_accurate_mode_estimates_a_lit_face_with_the_whole_pyramid(cybatt):
    """A lit face's shading changes with every move, so the samples' colors go stale: the
    accurate mode (``finish``) estimates its frames as the estimator does, to the bit. Both
    start at the first frame's truth (a first frame is the estimator's in both; from neutral it
    takes the most renderings); the second frame after it carries the motion on."""
    truth = random_truth(3, 100)[::5][:3]
    frames = render_sequence(cybatt, truth, size=(352, 288))
    options = dict(size=(352, 288), unknowns=TABLE1_FAPS, robust=True)
    finish = Tracker(cybatt, finish=True, **options)
    pyramid = Estimator(cybatt, **options)
    finish.params[:] = pyramid.params[:] = truth[0]
    for i, frame in enumerate(frames):
        a, b = finish.estimate(frame, i * 5), pyramid.estimate(frame, i * 5)
        np.testing.assert_array_equal(a.params, b.params)
        np.testing.assert_array_equal(a.translation, b.translation)
        assert finish._samples is None  # none taken from a lit face's rendering


def _finish_carphone(model, camera, frames, monkeypatch, tolerance=None, reuse=True, **options):
    """Carphone's ``frames`` in the accurate mode, the finest level's stop rule at
    ``tolerance`` (None: :data:`~vtts.analysis.tracker.FINISH_TOLERANCE_PX`), the final rendering
    taken from the finest level's (``reuse``) or not, ``options`` for the :class:`Tracker`:
    each frame after the first's estimate, renderings and finest-level steps (pixels)."""
    with monkeypatch.context() as mp:
        if tolerance is not None:
            mp.setattr(tracker_module, "FINISH_TOLERANCE_PX", tolerance)
        if not reuse:
            mp.setattr(Tracker, "_rendered_at_estimate", lambda self: None)
        steps: list[float] = []
        solve = Tracker._solve

        def spy(self, image, lv, *args):
            moved = solve(self, image, lv, *args)
            steps.append(moved)
            return moved

        mp.setattr(Tracker, "_solve", spy)
        est = Tracker(model, size=(176, 144), camera=camera, ignore=FITTED_IGNORED, robust=True,
                      finish=True, **options)  # fmt: skip
        est.estimate(frames[0], 0)
        out = []
        for i, frame in enumerate(frames[1:], 1):
            steps.clear()
            found = est.estimate(frame, i, i / 30.0)
            out.append((found, est.renderings, list(steps)))
    return out


def test_the_accurate_mode_stops_after_a_step_too_small_to_render(carphone_head, monkeypatch):
    """The finest level of the accurate mode ends after a step that moved no unknown's image by
    ``FINISH_TOLERANCE_PX``: kept without a rendering to judge it. A frame goes on while its
    steps are larger (the head moving) and stops at the first that small (converged), where the
    old rule (0.003 pixels) went on rendering steps of hundredths of a pixel; the estimates
    match as well."""
    model, camera = carphone_head
    frames = _carphone(4)
    now = _finish_carphone(model, camera, frames, monkeypatch)
    before = _finish_carphone(model, camera, frames, monkeypatch, tolerance=0.0)
    tolerance = tracker_module.FINISH_TOLERANCE_PX
    fewer = 0
    for (a, drawn_a, steps_a), (b, drawn_b, _) in zip(now, before, strict=True):
        assert all(m >= tolerance for m in steps_a[:-1]), steps_a
        assert steps_a[-1] < tolerance, steps_a  # it stopped on the small step
        fewer += drawn_b - drawn_a
        assert abs(a.psnr - b.psnr) < 0.1, (a.psnr, b.psnr)
    assert fewer >= 1, (now, before)


def test_the_accurate_mode_ends_on_the_finest_levels_last_rendering(carphone_head, monkeypatch):
    """A frame whose finest level ended on a rendering (its last step settled, or taken back to
    the one before) ends without drawing the face again: that rendering stands for the final
    one (the FAPs half a unit from the integers the stream carries). The same estimate (the
    next frames start from samples of that rendering), its face PSNR within hundredths of a
    dB, a rendering fewer a frame."""
    model, camera = carphone_head
    frames = _carphone(4)
    # the old stop rule: the level ends on a rendering on these frames; no search on the
    # rendered image (the eyelids', which the iris model takes over on camera video) after it
    options = dict(tolerance=0.0, refine=())
    reused = _finish_carphone(model, camera, frames, monkeypatch, **options)
    drawn = _finish_carphone(model, camera, frames, monkeypatch, reuse=False, **options)
    np.testing.assert_array_equal(reused[0][0].params, drawn[0][0].params)
    for (a, drawn_a, _), (b, drawn_b, _) in zip(reused, drawn, strict=True):
        assert abs(a.psnr - b.psnr) < 0.05, (a.psnr, b.psnr)
        assert drawn_a == drawn_b - 1, (drawn_a, drawn_b)


def test_the_accurate_mode_smooths_the_frame_in_a_worker_thread(carphone_head, monkeypatch):
    """The accurate mode's whole frame, smoothed for its finest level, is made in a worker
    thread while the stages run: the same estimates, to the bit, as made in the frame's own
    thread."""
    import threading
    from concurrent.futures import Future

    class InThread:
        def submit(self, fn, *args):
            done: Future = Future()
            done.set_result(fn(*args))
            return done

    made_in = []
    smoothed = tracker_module._smoothed

    def spy(frame, sigma):
        made_in.append(threading.current_thread() is threading.main_thread())
        return smoothed(frame, sigma)

    model, camera = carphone_head
    frames = _carphone(3)
    monkeypatch.setattr(tracker_module, "_smoothed", spy)
    worker = _finish_carphone(model, camera, frames, monkeypatch)
    assert made_in and not any(made_in)
    monkeypatch.setattr(tracker_module, "_smoothing", InThread)
    made_in.clear()
    inline = _finish_carphone(model, camera, frames, monkeypatch)
    assert made_in and all(made_in)
    for (a, drawn_a, _), (b, drawn_b, _) in zip(worker, inline, strict=True):
        np.testing.assert_array_equal(a.params, b.params)
        np.testing.assert_array_equal(a.translation, b.translation)
        assert a.psnr == b.psnr and drawn_a == drawn_b


class _Falls:
    """An estimator whose frames match at the face PSNRs given (dB), the head where it started."""

    unknowns = ()
    distance = 1.0

    def __init__(self, psnrs):
        self.psnrs = psnrs
        self.params = np.zeros(68)
        self.translation = np.zeros(3)

    def estimate(self, frame, index, time, *observed):
        from vtts.analysis.result import FrameEstimate

        return FrameEstimate(index, time, self.params.copy(), psnr=self.psnrs[index])

    def snapshot(self):
        return ()


def test_a_fall_that_the_landmarks_confirm_becomes_the_reference(monkeypatch):
    """A frame lost on its PSNR whose estimate from its landmarks does no better is not lost:
    the fall is the frame's (the face's look changed), and the frames after it at the same level
    are not re-initialized each in turn (fails with the reference kept: every frame restarts)."""
    from types import SimpleNamespace

    import vtts.analysis.track as track_module

    psnrs = [30.0] * 5 + [22.0] * 5  # a 8 dB fall that lasts
    tried = []

    def restart(estimator, frame, index, *args, **kwargs):
        tried.append(index)
        return None, True  # an estimate was made, no better than the frame's own

    monkeypatch.setattr(track_module, "_restart", restart)
    estimator, run = _Falls(psnrs), track_module._Run()
    result = SimpleNamespace(scale=1, restarts=[], held=[], unseen=[])
    for i in range(len(psnrs)):
        track_module._follow(estimator, run, None, i, i / 25, None, False, result)
    assert tried == [5]
    assert result.restarts == [] and result.held == []
