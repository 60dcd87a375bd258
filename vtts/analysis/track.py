"""Tracking a real person through a camera video: the model, its start and its recoveries.

:func:`track` drives the estimator (a :class:`~vtts.analysis.tracker.Tracker`: in the accurate
mode one that ends every frame with the finest level of the accurate
:class:`~vtts.analysis.estimator.Estimator`'s pyramid, ``finish``; in the tracking mode one that
renders about once a frame) over a camera video where nothing is known in advance (Eisert &
Girod's "Camera sequences"):

1. **The model.** Without one (``model=None``, ``vtts analyze --model auto``), a personalized
   head is fitted to the first frame where a face is found, with ``adi fit``'s code
   (:func:`vtts.fit.fit_photo`, the neck and ears painted from the frame too), made for the
   video (:func:`vtts.fit.with_frame`: what the frame shows of the head is textured with the
   frame itself, unlit, so that the head gives the frame back), and written (``OUT-model.wrl``,
   ``.adt``, ``-face.png``, ``-frame.png``, its ``photo`` Viewpoint the video's camera).
   The estimator then looks through that camera, so the head starts exactly where the fit put
   it; frames before the first face copy its estimate.
   A given model starts at frame 0 where the camera frames it and, when a face is found there
   whose landmarks its feature points miss by more than :data:`PLACED_PX`, is placed on them
   (:func:`~vtts.analysis.landmark_pose.landmark_pose`).
2. **What the model does not know.** The match is robust (Tukey's biweight: background at the
   outline, teeth, a hand, highlights have no say beyond
   :data:`~vtts.analysis.estimator.ROBUST_LIMIT` gray levels) and, for a fitted head, leaves out
   the parts that do not move with the face or whose outline is not the person's
   (:data:`FITTED_IGNORED`: the hair cap, the ears, the neck); they are still drawn and hide
   what lies behind them.
3. **Losing the track.** A frame whose face PSNR falls :data:`LOST_DB` below the median of the
   last good frames (in the tracking mode, that median capped at
   :data:`LOST_REFERENCE_CAP_DB`), or under :data:`LOST_FLOOR_DB`, is re-initialized from its
   landmarks — the head rotation and translation placed on them — and estimated again; the
   better of the two estimates is kept. When the frame's own estimate is the better, the fall
   is the frame's (the face's look changed, the landmarks confirm the track): the recent
   frames start again from it, and the frames after it at that level are not lost. A frame
   whose head ran away (turned or moved beyond :data:`MAX_TURN_AU`, :data:`MAX_SHIFT`) is
   re-initialized too, placed from the neutral face and pose. A frame where that fails too
   holds the last good estimate.
4. **Several faces.** ``face`` picks one (1 = the largest, as ``adi fit --face``); later
   re-initializations take the face nearest to where the tracked head was.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from vtts.analysis.estimator import DEFAULT_UNKNOWNS, Estimator
from vtts.analysis.frame_times import analysis_fps, analyzed, check_rate
from vtts.analysis.landmark_pose import landmark_pose, placement_error
from vtts.analysis.result import Analysis, FrameEstimate
from vtts.analysis.solve import subsample
from vtts.analysis.tracker import Tracker
from vtts.analysis.unknowns import HEAD_MOTION
from vtts.errors import AnalysisError, FitError, VttsError, VttsWarning
from vtts.face import FaceModel
from vtts.render.camera import Camera
from vtts.threads import one_blas_thread

#: The meshes of a fitted head that the estimator draws but does not match: the neck, which
#: follows the head's rotation near the skull only (:mod:`vtts.fit.neck`) but the head's
#: translation wholly, and whose outline is the generic cylinder's, and the hair cap and ears,
#: whose outline is the generic skull's, not the person's (at the outline they cover the
#: background). Matching them as well was tried and not kept (docs/analysis.md, "Camera video",
#: robust matching).
FITTED_IGNORED = ("HAIR", "NECK", "L_EAR", "R_EAR")

#: A frame is lost when its face PSNR falls this far (dB) below the median of the recent frames…
LOST_DB = 6.0
#: … or below this (dB) at all.
LOST_FLOOR_DB = 12.0
#: In the tracking mode the reference for :data:`LOST_DB` is at most this (dB): near the frame
#: a head was fitted to, the PSNR falls fast as the person moves, and a re-initialization (an
#: accurate estimate) would stall a live stream for a frame that is not lost. The accurate mode
#: keeps the plain median, whose early re-initialization pays there (docs/analysis.md,
#: "Tracking mode", step 5).
LOST_REFERENCE_CAP_DB = 30.0
#: A frame is lost, too, when the head has **run away**: its estimated rotation (FAPs 48–50:
#: pitch, yaw, roll) further than this (angle units, 1e-5 rad: 1.2 rad, 69°) from where the
#: model started, …
MAX_TURN_AU = 120_000.0
#: … or its translation further than this share of the camera's distance from the head (its
#: image half or twice the size it started at). A track that drifted off the face can run away
#: with the motion carried on from frame to frame, under the PSNR rule; it is re-initialized
#: from the landmarks with the head placed from the neutral face and pose. Both limits lie well
#: beyond what the real sequences tracked reach (docs/analysis.md, "Camera video", losing and
#: finding the track).
MAX_SHIFT = 0.5
#: Recent frames whose median PSNR is the reference for :data:`LOST_DB`.
RECENT = 10
#: The FAPs the iris model observes (lids 19–22, gaze 23–26): when any is estimated, the eyes
#: are looked at in every frame (:mod:`vtts.fit.iris`).
EYE_FAPS = frozenset(range(19, 27))
#: A video whose face shows its eyes further apart than this (pixels, eye centre to eye centre,
#: at the first face) is estimated at a working size, in both modes: subsampled by the smallest
#: whole factor that brings them within it (Akiyo's are 34 pixels apart at CIF). The landmarks
#: are still found in the frame itself, and the estimates are the same parameters (what the
#: accurate mode gains by it: docs/analysis.md, "Speed").
WORKING_EYES_PX = 64.0
#: A given model whose feature points already fall this close (median, pixels) to the first
#: face's landmarks is left where the camera frames it (a video rendered by vtts itself).
PLACED_PX = 3.0


@dataclass
class Tracked:
    """The outcome of :func:`track`.

    analysis   the :class:`~vtts.analysis.result.Analysis` (one estimate per analyzed frame)
    model      the model tracked (the fitted one with ``model=None``)
    fitted     the paths written for a fitted head (``.wrl``, ``.adt``, ``-face.png``), else []
    first      index of the frame the model was fitted to or placed on
    restarts   indices of the frames re-initialized from landmarks
    held       indices of the frames whose estimate failed even so, or where the landmarks lost
               the face: the last good estimate is held for them (their PSNR is NaN)
    unseen     indices of the frames where the landmarks lost the face (among ``held``)
    scale      the working size's factor: frames were estimated subsampled by it (1: as they are)
    """

    analysis: Analysis
    model: FaceModel
    fitted: list[Path] = field(default_factory=list)
    first: int = 0
    restarts: list[int] = field(default_factory=list)
    held: list[int] = field(default_factory=list)
    unseen: list[int] = field(default_factory=list)
    scale: int = 1


@one_blas_thread()
def track(
    frames: Iterable[np.ndarray],
    *,
    fps: float,
    model: FaceModel | None = None,
    model_path: str | Path | None = None,
    camera: Camera | None = None,
    face: int | None = None,
    step: int = 1,
    unknowns: Sequence[int | str] = DEFAULT_UNKNOWNS,
    progress: Callable[[int], None] | None = None,
    detector=None,
    tracking: bool = False,
    on_estimate: Callable[[FrameEstimate], None] | None = None,
    anchor: int | None = None,
    landmarks: bool = True,
    scale: int | None = None,
    rate: float | None = None,
    **options,
) -> Tracked:
    """Track the face in ``frames`` (each ``(H, W, 3) uint8`` RGB) of a video at ``fps``.

    ``model`` None fits a head on the first frame with a face and writes it to ``model_path``
    (a ``.wrl``; required then). ``camera`` (renderer frame) is for a given model only (default:
    the framing ``vtts render`` uses). ``face``: 1 = the largest face. ``tracking``: the fast
    :class:`~vtts.analysis.tracker.Tracker` (about one rendering a frame) instead of the
    accurate mode, the same class with ``finish`` (each frame ends with the accurate
    estimator's finest level, a rendering after every solve). ``options`` go to the estimator
    (defaults here: ``robust=True``). BLAS runs on one thread meanwhile (:mod:`vtts.threads`).
    ``on_estimate`` is called with each final estimate as soon as it is made, in frame order,
    the copies for the frames before the first face included (a fitted head is written by
    then).

    ``anchor``: with a head to fit, the index of the frame to fit it on (a multiple of
    ``step``; :func:`vtts.analysis.anchor.choose_anchor` picks the most typical one of a video
    file): the frames before it are kept, then tracked from it backwards once it is estimated,
    and the track goes on forwards from it (default: the first frame with a face).

    ``landmarks``: the face mesh's landmarks of every frame are observations of the estimate
    (:mod:`vtts.analysis.landmark_term`), the mesh run on the crop the last frame's landmarks
    give (:meth:`~vtts.fit.landmarks.MediaPipeDetector.follow`); a frame where they lose the
    face holds the last estimate (``Tracked.unseen``). False: the photometric terms alone.

    ``scale``: estimate the frames subsampled by this whole factor (the landmarks are found at
    full size); None: the factor that brings the first face's eyes within
    :data:`WORKING_EYES_PX` pixels.

    ``rate``: analyze the frames a stream coded at ``rate`` Hz shows — the frame nearest each
    time ``j / rate`` (:mod:`vtts.analysis.frame_times`) — instead of every ``step``-th (``step``
    must then be 1); the analysis's rate is then ``rate``."""
    from vtts.fit.landmarks import detect_faces

    if not (math.isfinite(fps) and fps > 0):
        raise AnalysisError(f"fps must be a positive number, got {fps}")
    if step < 1:
        raise AnalysisError(f"step must be at least 1, got {step}")
    check_rate(fps, step, rate)
    if scale is not None and not (isinstance(scale, int) and scale >= 1):
        raise AnalysisError(f"the working scale must be a whole factor of at least 1, got {scale}")
    if model is None and model_path is None:
        raise AnalysisError("fitting a head to the video needs a path to write it to")
    if model is None and camera is not None:
        raise AnalysisError("a fitted head brings the video's camera: give no camera with it")
    if anchor is not None and model is not None:
        raise AnalysisError("a frame to fit the head on (anchor) needs a head to fit: no model")
    if anchor is not None and (anchor < 0 or not analyzed(anchor, fps, step, rate)):
        every = f"a multiple of the step {step}" if rate is None else f"a frame of {rate:g} Hz"
        raise AnalysisError(f"the frame to fit the head on ({anchor}) must be a frame analyzed "
                            f"(0 or more, {every})")  # fmt: skip
    options.setdefault("robust", True)
    estimator: Estimator | None = None
    out: list[FrameEstimate] = []
    waiting: list[tuple[int, float]] = []  # frames before the first face
    before: list[tuple[int, float, np.ndarray]] = []  # frames before the anchor
    empty = Analysis([], (), analysis_fps(fps, step, rate), Camera(1, 1, 0, 0))  # type: ignore
    result = Tracked(empty, model)
    run = _Run(follow=_Follower(detector) if landmarks else None)
    for i, frame in enumerate(frames):
        if not analyzed(i, fps, step, rate):
            continue
        t = i / fps
        if estimator is None and anchor is not None and i < anchor:
            before.append((i, t, frame))
            _progress(progress, i)
            continue
        if estimator is None:
            faces = detect_faces(frame, detector)
            if not faces and anchor is not None:
                raise AnalysisError(f"frame {i}, the frame to fit the head on, shows no face")
            if not faces and model is None:
                waiting.append((i, t))
                _progress(progress, i)
                continue
            chosen = _choose(faces, face, i, anchor is not None) if faces else None
            result.scale = scale or (working_scale(chosen) if chosen is not None else 1)
            estimator = _start(result, frame, chosen, face, model, model_path, camera, unknowns,
                               detector, {"finish": not tracking, **options})  # fmt: skip
            result.first = before[0][0] if before else i
            if run.follow is not None and chosen is not None:
                run.follow.last = chosen
        fe = _follow(estimator, run, frame, i, t, detector, tracking, result)
        done = [_copy(fe, j, tj) for j, tj in waiting] + [fe]
        waiting = []
        if before:
            done = _backwards(estimator, fe, before, detector, tracking, result,
                              run.follow) + done  # fmt: skip
            before = []
        out += done
        if on_estimate is not None:
            for estimate in done:
                on_estimate(estimate)
        _progress(progress, i)
        estimator.between_frames()  # while the next frame is on its way
    if estimator is None and before:
        raise AnalysisError(f"the frame to fit the head on ({anchor}) is past the video's end "
                            f"(its last frame analyzed is {before[-1][0]})")  # fmt: skip
    if estimator is None:
        if not waiting:
            raise AnalysisError("the video has no frames")
        raise AnalysisError(f"no face found in any of the {len(waiting)} frames analyzed")
    result.analysis = Analysis(out, estimator.unknowns, analysis_fps(fps, step, rate),
                               estimator.camera.scaled(1 / result.scale),
                               result.model.name)  # fmt: skip
    return result


@dataclass
class _Follower:
    """The face mesh from frame to frame along one direction of a track: run on the crop the
    last landmarks give (:meth:`~vtts.fit.landmarks.MediaPipeDetector.follow`), the detector
    searching the whole frame only where that finds no face (or with a detector that cannot
    follow). ``seen``: whether a face has been observed on this run."""

    detector: object | None
    last: object | None = None  # the last Face observed
    seen: bool = False
    iris: object | None = None  # the iris model, once the eyes are asked for

    def observe(self, frame: np.ndarray, estimator: Estimator, scale: int = 1):
        """The :class:`~vtts.fit.landmarks.Face` in ``frame`` (the one nearest the tracked
        head where the detector had to search), or None when there is none; in the pixels of
        the working size ``scale`` times smaller."""
        from vtts.fit.landmarks import default_detector, detect_faces

        detector = self.detector if self.detector is not None else default_detector()
        face = None
        if self.last is not None and hasattr(detector, "follow"):
            face = detector.follow(frame, self.last.landmarks)
        if face is None:
            faces = detect_faces(frame, detector)
            if faces:
                small = [scaled_face(f, scale) for f in faces]
                near = _nearest(small, estimator)
                face = faces[next(j for j, f in enumerate(small) if f is near)]
        if face is None:
            return None
        self.last, self.seen = face, True
        return scaled_face(face, scale)

    def eyes(self, frame: np.ndarray, scale: int = 1):
        """The iris model's :class:`~vtts.fit.iris.Eyes` in ``frame`` around the last face
        observed, in the pixels of the working size ``scale`` times smaller."""
        from vtts.fit.iris import IrisModel

        if self.iris is None:
            self.iris = IrisModel()
        return scaled_eyes(self.iris.eyes(frame, self.last.landmarks), scale)


@dataclass
class _Run:
    """What the rules of losing and finding the track keep along one direction of a track:
    the estimator's state after the last good frame, the recent frames' PSNRs, the last
    estimate, and the landmarks followed (None: none used)."""

    kept: tuple | None = None
    recent: list[float] = field(default_factory=list)
    last: FrameEstimate | None = None
    follow: _Follower | None = None


def _follow(estimator: Estimator, run: _Run, frame, i: int, t: float, detector, tracking: bool,
            result: Tracked) -> FrameEstimate:  # fmt: skip
    """Frame ``i``'s estimate, placed again from its landmarks where the track was lost or the
    head ran away, or the last good estimate held (module docstring); ``run`` and ``result``'s
    lists of restarts and held frames are brought up to date. Where the landmarks followed lose
    the face, the last good estimate is held."""
    scale = result.scale
    seen = run.follow.observe(frame, estimator, scale) if run.follow is not None else None
    eyes = None
    if seen is not None and any(u in EYE_FAPS for u in estimator.unknowns):
        eyes = run.follow.eyes(frame, scale)
    if seen is None and run.follow is not None and run.follow.seen and run.kept is not None \
            and run.last is not None:  # fmt: skip
        result.held.append(i)
        result.unseen.append(i)
        fe = _hold(estimator, run.kept, run.last, i, t)
        run.last = fe
        return fe
    try:
        fe = estimator.estimate(shrink(frame, scale), i, t, seen, eyes)
    except VttsError as e:  # the model left the view: start again from the landmarks
        fe, _ = _restart(estimator, frame, i, t, None, detector, kept=run.kept,
                         observe=run.follow is not None, scale=scale)  # fmt: skip
        if fe is not None:
            result.restarts.append(i)
        elif run.kept is None or run.last is None:
            raise AnalysisError(f"frame {i}: {e.message}; no face to restart from") from None
        else:  # hold the last good estimate; a later frame may find the face again
            fe = _hold(estimator, run.kept, run.last, i, t)
            result.held.append(i)
    else:
        away = _run_away(estimator)
        if away or _lost(fe.psnr, run.recent, LOST_REFERENCE_CAP_DB if tracking else math.inf):
            again, tried = _restart(estimator, frame, i, t, None if away else fe, detector,
                                    kept=run.kept if away else None, neutral=away,
                                    observe=run.follow is not None, scale=scale)  # fmt: skip
            if again is not None:
                fe = again
                result.restarts.append(i)
            elif away and run.kept is not None and run.last is not None:
                fe = _hold(estimator, run.kept, run.last, i, t)
                result.held.append(i)
            elif tried:  # placed on its landmarks it does no better: the fall is the frame's
                run.recent = []
    run.kept = estimator.snapshot()
    if math.isfinite(fe.psnr):
        run.recent = [*run.recent[-(RECENT - 1) :], fe.psnr]
    run.last = fe
    return fe


def _backwards(estimator: Estimator, at_anchor: FrameEstimate,
               frames: list[tuple[int, float, np.ndarray]], detector, tracking: bool,
               result: Tracked, follow: _Follower | None) -> list[FrameEstimate]:  # fmt: skip
    """The estimates of ``frames`` ``[(index, time, frame)]`` (those before the anchor, in
    order), tracked from the anchor's estimate ``at_anchor`` backwards (the landmarks followed
    from the anchor's, ``follow``'s), in frame order; the estimator is left as the anchor left
    it."""
    state = estimator.snapshot()
    run = _Run(kept=state, last=at_anchor, follow=None if follow is None else replace(follow))
    out = []
    for i, t, frame in reversed(frames):
        estimator.between_frames()
        out.append(_follow(estimator, run, frame, i, t, detector, tracking, result))
    estimator.restore(state)
    result.restarts.sort()
    result.held.sort()
    return out[::-1]


def _progress(progress: Callable[[int], None] | None, index: int) -> None:
    if progress is not None:
        progress(index)


def _choose(faces: list, face: int | None, index: int, anchored: bool = False):
    """The face to track among ``faces`` (largest first) of frame ``index`` (the first with a
    face, or the one the head is fitted to: ``anchored``)."""
    from vtts.fit.landmarks import choose_face

    which = "one the head is fitted to" if anchored else "first with a face"
    where = f"frame {index}, the {which},"
    return choose_face(faces, face, where, "tracking", AnalysisError, stacklevel=4)


def _start(result: Tracked, frame, chosen, face, model, model_path, camera, unknowns, detector,
           options) -> Tracker:  # fmt: skip
    """The estimator for the first frame with a face: a head fitted to it, or ``model`` placed
    on its landmarks; both at the working size (``result.scale``)."""
    scale = result.scale
    h, w = frame.shape[0] // scale, frame.shape[1] // scale
    if model is None:
        from vtts.fit import fit_photo, with_frame
        from vtts.fit.photo import VIDEO_PARTS

        try:
            head = fit_photo(
                frame, face=face or 1, detector=detector, photo_parts=VIDEO_PARTS, portrait=False
            )
            head = with_frame(head)
        except FitError as e:
            raise AnalysisError(f"cannot fit a head to the first face: {e.message}") from None
        result.fitted = head.write(model_path)
        result.model = head.written_model(result.fitted[0])
        options = {"ignore": FITTED_IGNORED, **options}
        return Tracker(result.model, size=(w, h), model_camera=head.shape.camera.scaled(scale),
                       unknowns=unknowns, **options)  # fmt: skip
    if camera is not None:
        camera = camera.scaled(scale)
    estimator = Tracker(model, size=(w, h), camera=camera, unknowns=unknowns, **options)
    if chosen is None:
        return estimator  # no face seen: the model starts where the camera frames it
    chosen = scaled_face(chosen, scale)
    error = placement_error(estimator, chosen.landmarks)
    if error is None:
        warnings.warn(
            VttsWarning(
                f"{model.name} defines too few MPEG-4 feature points to be placed on the face's "
                "landmarks: it starts where the camera frames it"
            ),
            stacklevel=3,
        )
    elif error > PLACED_PX:
        landmark_pose(estimator, chosen.landmarks)
    return estimator


def working_scale(face) -> int:
    """The working size's factor for a track whose first face is ``face`` (a
    :class:`~vtts.fit.landmarks.Face`): the smallest whole factor that brings its eyes within
    :data:`WORKING_EYES_PX` pixels of each other."""
    xy = np.asarray(face.landmarks, np.float64)[:, :2]
    eyes = float(np.linalg.norm(xy[[33, 133]].mean(0) - xy[[362, 263]].mean(0)))
    return max(1, math.ceil(eyes / WORKING_EYES_PX))


def shrink(frame: np.ndarray, scale: int) -> np.ndarray:
    """``frame`` ``(H, W, 3) uint8`` subsampled by ``scale`` (the mean of each block, rounded;
    edges that do not fill a block dropped): ``(H // scale, W // scale, 3) uint8``."""
    if scale == 1:
        return frame
    return np.round(subsample(frame, scale)).astype(np.uint8)


def scaled_face(face, scale: int):
    """``face`` (a :class:`~vtts.fit.landmarks.Face`) in the pixels of its image subsampled by
    ``scale`` (pixel edges at integers)."""
    if scale == 1:
        return face
    landmarks = np.asarray(face.landmarks, np.float64) / scale
    return replace(face, box=tuple(v / scale for v in face.box), keypoints=face.keypoints / scale,
                   landmarks=landmarks)  # fmt: skip


def scaled_eyes(eyes, scale: int):
    """``eyes`` (the iris model's :class:`~vtts.fit.iris.Eyes`) in the pixels of its image
    subsampled by ``scale``."""
    if scale == 1:
        return eyes
    from vtts.fit.landmarks import Crop

    def one(eye):
        crop = Crop(eye.crop.centre / scale, eye.crop.size / scale, eye.crop.angle)
        return replace(eye, iris=eye.iris / scale, contour=eye.contour / scale, crop=crop)

    return replace(eyes, right=one(eyes.right), left=one(eyes.left))


def _lost(psnr: float, recent: list[float], cap: float = math.inf) -> bool:
    """Whether a frame of face PSNR ``psnr`` (dB) lost the track, given the ``recent`` ones
    (their median, at most ``cap`` dB, is the reference)."""
    if not math.isfinite(psnr):
        return psnr != float("inf")
    if psnr < LOST_FLOOR_DB:
        return True
    reference = min(float(np.median(recent)), cap) if recent else math.inf
    return len(recent) >= 3 and psnr < reference - LOST_DB


def _restart(estimator: Estimator, frame, index: int, time: float, fe: FrameEstimate | None,
             detector, kept: tuple | None = None, neutral: bool = False,
             observe: bool = True,
             scale: int = 1) -> tuple[FrameEstimate | None, bool]:  # fmt: skip
    """Estimate frame ``index`` again from the head placed on its landmarks: the new estimate
    when it matches better than ``fe`` (None: an estimate that failed), else None (the
    estimator is left as ``fe`` left it), and whether a new estimate was made at all (a face
    found, its estimate neither failed nor ran away). ``kept``: the state to place from, when
    the failed estimate left the estimator elsewhere (the last good frame's); ``neutral``: from
    the neutral face and pose (the head ran away; its FAPs too, which may have run away with
    it). An estimate that ran away too is no better. ``observe``: the landmarks are
    observations of the new estimate too. ``scale``: the working size's factor (``frame`` is
    full size)."""
    from vtts.fit.landmarks import detect_faces

    faces = [scaled_face(f, scale) for f in detect_faces(frame, detector)]
    if not faces:
        return None, False
    after = estimator.snapshot()
    if kept is not None:
        estimator.restore(kept)
    if neutral:  # the head ran away: place it from the neutral face and pose
        estimator.params[:] = 0.0
        estimator.translation[:] = 0.0
    near = _nearest(faces, estimator)
    try:
        landmark_pose(estimator, near.landmarks)
        estimator.forget_motion()  # the motion before the loss says nothing about what follows
        again = estimator.estimate(shrink(frame, scale), index, time, near if observe else None)
    except VttsError:
        estimator.restore(after)
        return None, False
    if _run_away(estimator):
        estimator.restore(after)
        return None, False
    if fe is None or again.psnr > fe.psnr:
        return again, True
    estimator.restore(after)
    return None, True


def _hold(estimator: Estimator, kept: tuple, last: FrameEstimate, index: int,
          time: float) -> FrameEstimate:  # fmt: skip
    """Frame ``index`` holds the ``last`` good estimate: the estimator goes back to the state
    ``kept`` after it, with no motion carried on (carried over the frames held, the motion of
    the last two estimates would grow with the gap: :meth:`Estimator._extrapolate`)."""
    estimator.restore(kept)
    estimator.forget_motion()
    return replace(_copy(last, index, time), held=True)


def _run_away(estimator: Estimator) -> bool:
    """Whether the estimated head rotation is beyond :data:`MAX_TURN_AU` on any axis or its
    translation beyond :data:`MAX_SHIFT` of the camera's distance."""
    rotation = estimator.params[[u - 1 for u in HEAD_MOTION if not isinstance(u, str)]]
    shift = float(np.linalg.norm(estimator.translation))
    return bool(np.abs(rotation).max() > MAX_TURN_AU) or shift > MAX_SHIFT * estimator.distance


def _nearest(faces: list, estimator: Estimator):
    """The face whose box centre is nearest the tracked head's image."""
    if len(faces) == 1:
        return faces[0]
    _, ids = estimator.render(1)
    rows, cols = np.nonzero(ids >= 0)
    if rows.size == 0:
        return faces[0]
    centre = np.array([cols.mean(), rows.mean()])
    boxes = np.array([f.box for f in faces], dtype=np.float64)
    mids = np.stack([(boxes[:, 0] + boxes[:, 2]) / 2, (boxes[:, 1] + boxes[:, 3]) / 2], 1)
    return faces[int(np.argmin(np.linalg.norm(mids - centre, axis=1)))]


def _copy(fe: FrameEstimate, index: int, time: float) -> FrameEstimate:
    """``fe`` standing in for frame ``index`` (before the first face, or one whose estimate
    failed): no PSNR of its own."""
    return replace(fe, index=index, time=time, psnr=float("nan"), face_pixels=0, iterations=0,
                   landmark_px=float("nan"))  # fmt: skip
