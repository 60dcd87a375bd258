"""Tracking mode: under one rendering a frame, Gauss–Newton on the camera image in between.

The accurate :class:`~vtts.analysis.estimator.Estimator` renders the model after every linear
solve (about twelve renderings a frame over a three-level pyramid) and compares the two images
at fixed pixels. A :class:`Tracker` keeps what one rendering — of a window around the face —
says about the face as **surface samples**: for every second face pixel, the triangle it shows,
the barycentric coordinates of its 3D point, that point in camera space, the point's motion per
unit of each unknown (Equation 9's matrix T, at the rendered estimate) and the model's color
there. The Gauss–Newton iterations move the samples with the parameter change (linearly, as
Equation 9 does), project them into the camera frame and compare the frame *at their
projections* (bilinear samples of the frame and of its gradients) with the model's colors
(forward-additive image alignment, with the efficient second-order gradient: the mean of the
frame's gradient at the projection and the model's at the sample). The samples serve the
following frames until they have moved :data:`RERENDER_PX` pixels since their rendering, where
what is visible may have changed; once a frame's estimate is out, samples that moved
:data:`AHEAD_PX` are rendered again while the next frame is on its way
(:meth:`Tracker.between_frames`), so that most renderings cost a live stream no latency.

Coarse to fine without a pyramid of renderings: the camera frame's window is smoothed with a
wide Gaussian for the first solve and a narrow one for the others (:data:`STAGES`); the model's
colors are smoothed alike from the same rendering.

The first frame of a track (and a frame after the track was placed again) is estimated by the
accurate estimator: it may start far from the truth. A lit face — whose shading, unlike an
unlit head made for the video, changes with every move — is finished by the accurate
estimator's finest level (:data:`POLISH_PX`, :data:`LIT_SHARE`) and a search on the rendered
image of the jaw and the lip corners (:data:`LIT_REFINE_STEPS`), which stall together where the
opening jaw uncovers the teeth. The light model (gain and offset per channel), robust weights,
held unknowns and the eyelid search are the accurate estimator's. See docs/analysis.md,
"Tracking mode".

With ``finish`` a :class:`Tracker` is the **accurate mode** of
:func:`~vtts.analysis.track.track` (camera video): every frame after the first is finished by
the accurate estimator's finest level (a rendering after every solve, as the pyramid ends),
and the stages' solves on the samples stand in for the pyramid's coarse levels — the samples
those of the last frame's final rendering, which the frame's estimate renders anyway (its face
PSNR), so the coarse levels' three or four renderings a frame become none. That holds for a
face drawn unlit, as a head made for the video is: a lit face's frames (a bundled head) are
estimated by the whole pyramid, exactly as the estimator does. On the real
sequences that takes half the time or less of the whole pyramid, and the face PSNR is as good
or better (docs/analysis.md, "The accurate mode on samples").
"""

from __future__ import annotations

import math
import os
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field, replace

import numpy as np
from scipy.ndimage import binary_erosion

from vtts.analysis.estimator import (  # noqa: F401  (LIT_REFINE_STEPS: the tracker's too)
    EDGE,
    HALVED_STOP_PX,
    JUMP_FAR_PX,
    LIT_REFINE_STEPS,
    LIT_SHARE,
    LUMA,
    ROBUST_LIMIT,
    Estimator,
)
from vtts.analysis.landmark_term import unknown_values
from vtts.analysis.result import FrameEstimate
from vtts.analysis.solve import least_squares, smooth
from vtts.analysis.unknowns import EYELIDS
from vtts.errors import VttsError
from vtts.threads import one_blas_thread, result

LUMA32 = LUMA.astype(np.float32)


@dataclass(frozen=True)
class Stage:
    """One stage of a frame's iterations: the Gaussian ``sigma`` (pixels) both images are
    smoothed with, the outlier threshold ``g`` (pixels, Equation 17), at most ``iterations``
    solves, ``limit``, the most (pixels) one solve may move the image of any unknown, and
    ``support``, the fewest samples an unknown's motion must show at (beyond a fifth of its
    largest) to be solved for at this stage (else it is held: an eyelid a pixel or two tall is
    lost in the wide smoothing, and the solve would take it anywhere)."""

    sigma: float
    g: float
    iterations: int
    limit: float = 2.0
    support: int = 4


_SMOOTHING: tuple[int, ThreadPoolExecutor] | None = None


def _smoothing() -> ThreadPoolExecutor:
    """The worker thread that smooths the accurate mode's frames (:meth:`Tracker.estimate`),
    one for the process (made on first use; made again in a forked child, which inherits the
    executor but not its thread)."""
    global _SMOOTHING
    if _SMOOTHING is None or _SMOOTHING[0] != os.getpid():
        pool = ThreadPoolExecutor(max_workers=1, thread_name_prefix="vtts-smooth")
        _SMOOTHING = (os.getpid(), pool)
    return _SMOOTHING[1]


def _smoothed(frame: np.ndarray, sigma: float) -> tuple[np.ndarray, np.ndarray]:
    """The camera ``frame`` ``(H, W, 3) uint8`` as ``float32`` and that smoothed by
    :func:`~vtts.analysis.solve.smooth` with ``sigma`` (pixels)."""
    full = frame.astype(np.float32)
    return full, smooth(full, sigma)


#: Wide smoothing first (motion of a few pixels), then the accurate estimator's own.
STAGES = (Stage(2.0, 5.0, 1, support=40), Stage(0.8, 2.0, 3))

#: Samples that moved this far (pixels) since the rendering may show another surface: render.
#: Within one frame's solves, the k-th rendering waits for k times this (the latency of a frame
#: of fast motion; the rendering between frames catches up, :meth:`Tracker.between_frames`).
#: Chosen for the latency: a frame that renders within its solves pays for the rendering and
#: its samples, and farther apart fewer frames do, at no cost in decoded PSNR (the figures:
#: docs/analysis.md, "Tracking mode", step 3).
RERENDER_PX = 6.0

#: … on a lit face, whose frames end with the accurate estimator's finest level anyway (no
#: latency to save), this, the setting its synthetic figures were measured with: its samples'
#: colors, the rendering's, go stale with the shading.
LIT_RERENDER_PX = 3.0

#: After the stages, when the samples have moved more than this (pixels) since their
#: rendering and lie on a lit face, the frame is finished by the accurate estimator's finest
#: level (a rendering after every solve, :meth:`Estimator._descend`): the samples' colors
#: are the rendering's, and a lit face's shading changes with every move.
POLISH_PX = 0.02

#: In the accurate mode (``finish``) the finest level's solves end after a step that moved no
#: unknown's image by this many pixels: the step is kept without the rendering that would judge
#: it (the frame's final rendering shows it), as small a change as the camera's noise moves the
#: match by.
FINISH_TOLERANCE_PX = 0.1

#: Between two frames, samples that moved this far (pixels) are rendered anew
#: (:meth:`Tracker.between_frames`), …
AHEAD_PX = 1.5
#: … and this far after a frame observed on its landmarks in the tracking mode: its jump and
#: landmark rows hold the estimate where the samples' linear motion drifts (1.5 pixels there gave
#: the same figures on the development clips at 0.6–0.8 times the speed: docs/analysis.md,
#: "Measuring on people").
AHEAD_LANDMARKS_PX = 3.0

#: With ``finish`` (the accurate mode, every second frame of a file), a frame that starts far
#: from its landmarks jumps onto them in up to this many steps (the estimator's
#: ``far_jump_steps``, :data:`~vtts.analysis.estimator.JUMP_FAR_PX`). The tracking mode keeps
#: :data:`~vtts.analysis.estimator.JUMP_STEPS`: on lp_d12, analyzed every frame, more steps cost
#: 0.2 dB (docs/analysis.md, "Measuring on people").
FAR_JUMP_STEPS = 8

#: Pixels of the camera frame kept around the face's box (motion within a frame is smaller).
MARGIN = 16

#: The face's pixels used as samples: every ``SAMPLE_STEP``-th row and column.
SAMPLE_STEP = 2


@dataclass
class _Samples:
    """What one rendering says about the face at the rendered estimate (N samples, K
    unknowns), all in the pixels of the rendered window ``box`` (rows, cols slices of the
    frame): pixel ``rows``, ``cols`` ``(N,)``; ``point`` the 3D point in camera space ``(N, 3)``;
    ``motion`` its motion per unit of each unknown in camera axes ``(N, 3, K)``; ``du``, ``dv``
    ``(N, K)`` the image motion (pixels per unit) it gives at the rendered estimate; ``raw`` the
    rendered window ``(h, w, 3)`` float32; ``at`` the unknowns' values ``(K,)`` at the
    rendering; ``lit`` the share of the samples on lit surfaces; ``pixels`` the face pixels
    of the rendering (the samples are all of them or a grid of them); ``models`` the model's
    colors smoothed for each stage, by sigma.

    The samples serve the frames that follow as long as they have not moved
    :attr:`Tracker.rerender` pixels: the model's colors move with its surface (a head made
    for the video is drawn unlit), and the motion per unit is exact within the tables'
    intervals and linear in the rotations."""

    rows: np.ndarray
    cols: np.ndarray
    point: np.ndarray
    motion: np.ndarray
    du: np.ndarray
    dv: np.ndarray
    raw: np.ndarray
    box: tuple[slice, slice]
    at: np.ndarray
    lit: float
    pixels: int
    models: dict = field(default_factory=dict)

    def model(self, sigma: float) -> _Model:
        """The model's colors and gradients at the samples, smoothed with ``sigma``."""
        if sigma not in self.models:
            self.models[sigma] = _Model(self, sigma)
        return self.models[sigma]


class Tracker(Estimator):
    """An :class:`~vtts.analysis.estimator.Estimator` that tracks with about one rendering per
    frame (see the module's docstring). Takes the same arguments, plus ``stages``
    (:data:`STAGES`), ``rerender`` (:data:`RERENDER_PX`), ``polish`` (:data:`POLISH_PX`),
    ``sample_step`` (:data:`SAMPLE_STEP`); ``lit_refine`` is the estimator's, applied on a
    frame whose samples lie on a lit face (:data:`~vtts.analysis.estimator.LIT_SHARE`).
    ``finish``: every frame ends with the estimator's finest level and its final rendering
    gives the next frame's samples; a lit face's frames are estimated by the whole pyramid (the
    accurate mode; the module's docstring)."""

    def __init__(self, *args, stages=STAGES, rerender: float = RERENDER_PX,
                 polish: float = POLISH_PX, sample_step: int = SAMPLE_STEP,
                 finish: bool = False, **kwargs) -> None:  # fmt: skip
        if finish:
            kwargs.setdefault("far_jump_steps", FAR_JUMP_STEPS)
        super().__init__(*args, **kwargs)
        self.finish = bool(finish)
        # the eyelids by REFINE_STEPS: the first stage's wide smoothing follows a closing lid,
        # which the accurate pyramid holds at its coarse levels (LID_STEPS)
        for fap in EYELIDS:
            self.search_steps.pop(fap, None)
        self.stages = tuple(stages)
        self.rerender = float(rerender)
        self.polish = float(polish)
        # on an unlit face the eyelids (the FAPs the search on the rendered image refines) are
        # held in the solves on the samples and left to the search: a lid's edge a pixel or
        # two tall is what linearized samples describe worst (solved there, the lids run off and
        # lose the track: docs/analysis.md, "Tracking mode"). A lit face's are solved, as its
        # frames end with
        # the accurate estimator's finest level
        self._refined_columns = np.array([u in self.refined for u in self.unknowns])
        self.sample_step = int(sample_step)
        #: renderings of the last frame estimated (the samples' and the polish's; not the
        #: search's windows on the rendered image)
        self.renderings = 0
        # the window (x0, y0, width, height) of the frame rendered and matched: the face's box
        # with a margin; None for the whole frame
        self._box: tuple[int, int, int, int] | None = None
        self._samples: _Samples | None = None  # the last rendering's, while they serve
        # the accurate mode's frame ends: its final rendering may be the finest level's last
        self._reuse = False
        # whether the last frame's solves had to render (its head outran the samples)
        self._outrun = False
        # the last samples projected, the unknowns' values they were projected at, and where
        # they lie then (:meth:`_project`)
        self._projected: tuple[_Samples, bytes, tuple[np.ndarray, np.ndarray]] | None = None

    def forget_motion(self) -> None:
        super().forget_motion()
        self._box = None
        self._samples = None

    @one_blas_thread()
    def estimate(self, frame: np.ndarray, index: int = 0, time: float = 0.0,
                 landmarks=None, eyes=None) -> FrameEstimate:  # fmt: skip
        """Update the estimate to the camera ``frame`` ``(H, W, 3) uint8`` and return it;
        ``landmarks`` and ``eyes`` as :meth:`Estimator.estimate`'s."""
        self._outrun = False
        if not self._history or (self.finish and super()._lit_frame()):
            # a first frame: the accurate start; with ``finish``, a frame of a lit face (by the
            # last frame's last solve): the whole pyramid, as the estimator — its shading changes
            # with every move, and the samples' colors are those of the last rendering
            if not self._history:
                self.forget_motion()
            self.renderings = 0
            return super().estimate(frame, index, time, landmarks, eyes)
        frame = np.asarray(frame)
        w, h = self.size
        if frame.shape != (h, w, 3):
            raise VttsError(f"frame {index} is {frame.shape}, expected ({h}, {w}, 3)")
        # the accurate mode's finest level reads the whole frame smoothed: a Gaussian filter of
        # the frame that does not depend on the estimate (about a tenth of a 512² frame's time),
        # made in a worker thread while this thread runs the stages (SciPy's filters release
        # the GIL)
        smoothed = _smoothing().submit(_smoothed, frame, self.sigma) if self.finish else None
        self.observe(landmarks, eyes)
        if self.predicted:
            self._start_near_landmarks(index)
        self._jump_to_landmarks()
        self.renderings = 0
        samples, solves = self._stages(frame)
        self._outrun = self.renderings > 0
        if self.finish:
            # the accurate mode: the finest level of the pyramid, a rendering after every solve,
            # from where the samples left the estimate; the frame's final rendering gives the
            # next frame's samples (:meth:`_final_rendering`)
            full, smoothed_full = result(smoothed)
            self._rendered = []
            more, _ = self._descend({1: smoothed_full}, self.pyramid[-1:],
                                    max(self.tolerance, FINISH_TOLERANCE_PX),
                                    HALVED_STOP_PX)  # fmt: skip
            self.renderings += more
            self._reuse = True
            try:
                return self._final_estimate(full, index, time, solves + more, self._lit_frame())
            finally:
                self._reuse = False
        lit = samples.lit >= LIT_SHARE
        if lit and self._shift(samples) > self.polish:
            # a lit face: the accurate estimator's finest level, a rendering after every solve
            pyramid = {1: smooth(frame.astype(np.float32), self.sigma)}
            more, _ = self._descend(pyramid, self.pyramid[-1:])
            solves += more
            self.renderings += more
            samples = self._sample(self.sample_step)
        self._samples = samples
        with self._refining(lit):  # the jaw and the lip corners searched too (``lit_refine``)
            return self._finish(frame, samples, index, time, solves)

    def _start_near_landmarks(self, index: int) -> None:
        """Start frame ``index`` where the head's motion carries it on
        (:meth:`~vtts.analysis.estimator.Estimator._extrapolate`); with :attr:`finish` and the
        frame's landmarks observed, where the last estimate left it instead when the carried-on
        start lies further than :data:`~vtts.analysis.estimator.JUMP_FAR_PX` from the landmarks
        and standing still lies nearer them: a jerky head moving fast, analyzed every second
        frame, overshoots (lp_d12: 15 working pixels off its landmarks, the median frame)."""
        if not (self.finish and self._observed is not None):
            self._extrapolate(index)
            return
        still = self._state()
        self._extrapolate(index)
        carried = self._state()
        far = self.landmark_term().error(unknown_values(self))
        if far > JUMP_FAR_PX:
            self._set_state(still)
            if self.landmark_term().error(unknown_values(self)) >= far:
                self._set_state(carried)

    def _stages(self, frame: np.ndarray) -> tuple[_Samples, int]:
        """The :attr:`stages`' solves on the samples against the camera ``frame`` ``(H, W, 3)
        uint8``, rendering new samples where they moved too far; returns the samples last used
        (also :attr:`_samples`) and the solves made. In the tracking mode a frame with
        landmarks observed starts at the last stage: its jump onto them does the coarse stage's
        work (on the development clips the same figures, 1.2–1.7 times the speed; in the
        accurate mode it cost Carphone and lp_d12 0.1–0.3 % of geometry, docs/analysis.md)."""
        samples = self._samples
        images: dict[float, np.ndarray] = {}  # the frame's window smoothed, by sigma
        solves = 0
        # a frame observed on its landmarks has jumped onto them (the coarse stage's work)
        quick = self._observed is not None and not self.finish
        stages = self.stages[-1:] if quick else self.stages
        for stage in stages:
            for _ in range(stage.iterations):
                # the k-th rendering within a frame waits for k times the shift of the first
                # (a frame's latency), but comes: far beyond it the samples would drift away
                stale = samples is None or (
                    self._shift(samples) > self._rerender(samples) * (1 + self.renderings)
                )
                if stale:
                    new = self._sample(self.sample_step)  # what is visible may have changed
                    if samples is None or new.box != samples.box:
                        images.clear()  # the frame's window for them
                    samples = new
                moved = self._iterate(samples, self._frame(frame, samples, stage, images), stage)
                solves += 1
                if moved < self.tolerance:
                    break
        self._samples = samples
        return samples, solves

    def _lit_frame(self) -> bool:
        """The first frame's accurate estimate searches no more than the eyelids (the tracking
        mode's synthetic figures were measured so); the other frames decide on their samples
        (:meth:`estimate`). With :attr:`finish` the accurate estimator's rule."""
        return self.finish and super()._lit_frame()

    def between_frames(self) -> None:
        """Render now, after the estimate went out and before the next frame arrives, when the
        samples have moved :data:`AHEAD_PX` (:data:`AHEAD_LANDMARKS_PX` after a frame observed
        on its landmarks) since their rendering: the next frame would likely need it, and a
        live stream has the time between two frames to spare. Not after a frame observed on its
        landmarks whose solves had to render (the head moved further since the last frame than
        the samples serve, as a head moving fast does): its next frame would likely outrun these
        samples too, and renders after its jump onto its landmarks anyway."""
        quick = self._observed is not None and not self.finish
        ahead = AHEAD_LANDMARKS_PX if quick else AHEAD_PX
        if quick and self._outrun:
            # the head moved further between the last two frames than the samples serve, and
            # the frame rendered within its solves, after its jump onto the landmarks: samples
            # rendered now would likely be outrun again (docs/analysis.md, "Speed")
            return
        if self._samples is not None and self._shift(self._samples) > ahead:
            try:
                self._samples = self._sample(self.sample_step)
            except VttsError:  # out of view: the next frame's estimate finds out and recovers
                self._samples = None

    def _final_rendering(self) -> tuple[np.ndarray, np.ndarray, tuple[int, int]]:
        """The frame's final rendering; with :attr:`finish`, its face also gives the samples for
        the next frame (none where it shows too little of the face: the next frame renders; none
        on a lit face, whose next frame takes the whole pyramid)."""
        shown = self._rendered_at_estimate() if self._reuse else None
        if shown is None:
            image, ids, (top, left) = super()._final_rendering()
            self.renderings += self._reuse
        else:
            image, ids, (top, left) = shown
        if self.finish:
            self._samples = None
            rows, cols = np.nonzero(ids >= 0)
            if rows.size and not super()._lit_frame():
                x0, y0, ww, wh = _window_around(rows + top, cols + left, self._box_size(),
                                                self.size)  # fmt: skip
                # the samples' window in the rendered one's pixels: what lies beyond it is far
                # from the face (:data:`~vtts.analysis.estimator.RENDER_MARGIN`), and no sample
                # reads it
                h, w = ids.shape
                window = np.zeros((wh, ww, 3), image.dtype)
                faces = np.full((wh, ww), -1, ids.dtype)
                ys = slice(max(y0, top), min(y0 + wh, top + h))
                xs = slice(max(x0, left), min(x0 + ww, left + w))
                inside = (slice(ys.start - y0, ys.stop - y0), slice(xs.start - x0, xs.stop - x0))
                there = (
                    slice(ys.start - top, ys.stop - top),
                    slice(xs.start - left, xs.stop - left),
                )
                window[inside] = image[there]
                faces[inside] = ids[there]
                try:
                    self._samples = self._take(window, faces, x0, y0, self.sample_step)
                except VttsError:
                    pass
        return image, ids, (top, left)

    def _rendered_at_estimate(self) -> tuple | None:
        """One of the finest level's last two renderings (:attr:`_rendered`) made at the
        estimate the frame ends with, up to the rounding of the unknown FAPs to the integers the
        stream carries (half a unit at most: hundredths of a pixel), or None. The level's
        solves end at a rendering (the last step settled) or at the one before it (the last step
        taken back), and the frame's final rendering would draw the same face again."""
        for params, translation, shown in reversed(self._rendered):
            rounded = params.copy()
            for u in self.unknowns:
                if not isinstance(u, str):
                    rounded[u - 1] = np.round(rounded[u - 1]) + 0.0
            # a step taken back leaves the translation where it was but for the last bits
            same_place = np.allclose(translation, self.translation, rtol=0.0, atol=1e-9)
            if same_place and np.array_equal(rounded, self.params):
                return shown
        return None

    # ---- samples -------------------------------------------------------------------------------

    def _sample(self, step: int = 1) -> _Samples:
        """Render the model at the current estimate (the window around the face) and take its
        face pixels as samples: those of every ``step``-th row and column."""
        w, h = self.size
        x0, y0, ww, wh = self._box or (0, 0, w, h)
        while True:
            cam = replace(self.camera, cx=self.camera.cx - x0, cy=self.camera.cy - y0)
            image, numbers = self._synthesize(cam, (ww, wh), triangles=True)
            self.renderings += 1
            ids = self._face_indices(numbers)
            covered = ids >= 0
            whole = (ww, wh) == (w, h)
            edge = covered[[0, -1]].any() or covered[:, [0, -1]].any()
            if whole or (covered.sum() >= 4 * len(self.unknowns) and not edge):
                break
            # the face reaches the window's edge, or left it: render the whole frame
            x0, y0, ww, wh = 0, 0, w, h
        return self._take(image, ids, x0, y0, step)

    def _box_size(self) -> tuple[int, int]:
        """The size (W, H) of the window the next rendering of samples would draw."""
        return self._box[2:] if self._box is not None else self.size

    def _take(self, image: np.ndarray, ids: np.ndarray, x0: int, y0: int, step: int) -> _Samples:
        """The samples of a rendering of the window whose top-left pixel is ``(x0, y0)`` in the
        frame: its ``image`` ``(h, w, 3)`` and the triangle index each pixel shows ``ids``
        ``(h, w)`` (−1: none); the face's pixels less :data:`EDGE` along its outline, those of
        every ``step``-th row and column of the frame. Also sets the window of the next
        rendering of samples."""
        wh, ww = ids.shape
        inside = binary_erosion(ids >= 0, iterations=EDGE)
        pixels = int(inside.sum())
        if step > 1:
            grid = np.zeros_like(inside)
            grid[y0 % step :: step, x0 % step :: step] = True  # the frame's grid
            inside &= grid
        rows, cols = np.nonzero(inside)
        if rows.size < 4 * len(self.unknowns):
            raise VttsError(
                f"the model covers only {rows.size} pixels: it is out of view (check --camera "
                "and the first frame)"
            )
        self._box = _window_around(rows + y0, cols + x0, (ww, wh), self.size)
        cam = replace(self.camera, cx=self.camera.cx - x0, cy=self.camera.cy - y0)
        tri = ids[rows, cols]
        pix = np.stack([cols + 0.5, rows + 0.5], axis=1)
        point, motion, du, dv = self._image_motion(pix, tri, cam)
        held = self._searched_columns
        du[:, held] = 0.0
        dv[:, held] = 0.0
        box = (slice(y0, y0 + wh), slice(x0, x0 + ww))
        lit = float(self.geometry.lit[tri].mean())
        return _Samples(rows, cols, point, motion, du, dv, image.astype(np.float32), box,
                        self._values(), lit, pixels)  # fmt: skip

    # ---- one Gauss–Newton step -----------------------------------------------------------------

    @staticmethod
    def _frame(frame: np.ndarray, s: _Samples, stage: Stage, images: dict) -> np.ndarray:
        """The camera ``frame``'s window of the samples ``s`` smoothed for ``stage``, with its
        gradients (:func:`_with_gradients`), kept in ``images`` by sigma."""
        if stage.sigma not in images:
            window = frame[s.box].astype(np.float32)
            images[stage.sigma] = _with_gradients(smooth(window, stage.sigma))
        return images[stage.sigma]

    def _iterate(self, s: _Samples, images: np.ndarray, stage: Stage) -> float:
        """One solve against the camera frame's window ``images`` (:func:`_with_gradients`,
        smoothed for ``stage``); returns how far (pixels) it moved the image of the unknown
        that moved most."""
        model = s.model(stage.sigma)
        u, v = self._project(s)
        at = _bilinear(images, u - 0.5, v - 0.5)  # (N, 9)
        gain, offset = self.gain.astype(np.float32), self.offset.astype(np.float32)
        r = at[:, 0:3] - (model.color * gain + offset)
        gx = 0.5 * (at[:, 3:6] + model.gx * gain)
        gy = 0.5 * (at[:, 6:9] + model.gy * gain)
        ry, gxy, gyy = r @ LUMA32, gx @ LUMA32, gy @ LUMA32
        # Equation 17: pixels whose displacement estimate exceeds G have no say
        weights = (np.abs(ry) <= stage.g * np.sqrt(gxy * gxy + gyy * gyy + 1e-6)).astype(np.float32)
        if weights.sum() < 4 * len(self.unknowns):
            return 0.0
        if self.robust:
            q = np.minimum(np.abs(ry) / np.float32(ROBUST_LIMIT), np.float32(1.0))
            weights *= (1.0 - q * q) ** 2
        du, dv = s.du, s.dv
        held = model.support < stage.support
        if s.lit < LIT_SHARE:
            held = held | self._refined_columns
        if held.any():
            du, dv = du.copy(), dv.copy()
            du[:, held] = 0.0
            dv[:, held] = 0.0
        ata, atb = _system(du, dv, gx, gy, r, model.color if self.illumination else None,
                           weights)  # fmt: skip
        term = self.landmark_term()
        if term is not None:  # a sample for every step² of the window's pixels
            k = du.shape[1]
            lm_ata, lm_atb = term.normal_equations(term.values0, density=self.sample_step**-2,
                                                   held=self._searched_columns)  # fmt: skip
            ata[:k, :k] += lm_ata
            atb[:k] += lm_atb
        delta = least_squares(ata, atb)
        k = s.du.shape[1]
        reach = model.speed * np.abs(delta[:k])
        delta[:k] *= np.minimum(1.0, stage.limit / np.maximum(reach, 1e-12))
        self._apply(delta)
        return float(np.minimum(reach, stage.limit).max(initial=0.0))

    def _rerender(self, s: _Samples) -> float:
        """How far (pixels) samples ``s`` may move before the first rendering within a frame:
        :attr:`rerender`, at most :data:`LIT_RERENDER_PX` on a lit face."""
        return min(self.rerender, LIT_RERENDER_PX) if s.lit >= LIT_SHARE else self.rerender

    def _values(self) -> np.ndarray:
        """The unknowns' current values ``(K,)`` (FAP units, ES units of the translation)."""
        return unknown_values(self)

    def _shift(self, s: _Samples) -> float:
        """How far (pixels) the samples have moved since their rendering: the largest."""
        u, v = self._project(s)
        return float(np.sqrt(np.max((u - s.cols - 0.5) ** 2 + (v - s.rows - 0.5) ** 2)))

    def _project(self, s: _Samples) -> tuple[np.ndarray, np.ndarray]:
        """Where the samples lie in their window at the current estimate (moved linearly by the
        unknowns' change since the rendering): X and Y ``(N,)`` (pixel centres at +0.5)."""
        values = self._values()
        kept = self._projected
        if kept is not None and kept[0] is s and kept[1] == values.tobytes():
            return kept[2]  # the stages' check of the shift, then the solve: the same estimate
        cam = self.camera
        y0, x0 = s.box[0].start, s.box[1].start
        since = (values - s.at).astype(np.float32)
        p = s.point + s.motion @ since  # (N, 3)
        depth = -p[:, 2]
        u = (cam.cx - x0) + np.float32(cam.fx) * p[:, 0] / depth
        v = (cam.cy - y0) - np.float32(cam.fy) * p[:, 1] / depth
        self._projected = (s, values.tobytes(), (u, v))
        return u, v

    def _psnr(self, frame: np.ndarray, s: _Samples) -> float:
        """The face PSNR (dB, luminance) at the samples: the camera ``frame`` at their
        projections against the model's unsmoothed colors with the light model applied."""
        u, v = self._project(s)
        seen = _bilinear(frame[s.box].astype(np.float32), u - 0.5, v - 0.5)
        synth = np.clip(np.round(s.raw[s.rows, s.cols] * self.gain + self.offset), 0, 255)
        diff = (seen - synth) @ LUMA
        mse = float(np.mean(diff * diff))
        return float("inf") if mse == 0 else 10 * math.log10(255.0**2 / mse)

    # ---- the frame's estimate ------------------------------------------------------------------

    def _finish(self, frame: np.ndarray, s: _Samples, index: int, time: float,
                solves: int) -> FrameEstimate:  # fmt: skip
        """Integer FAPs, the eyelid search, and the estimate with the face PSNR measured at the
        samples (the frame at their projections against the model's unsmoothed colors)."""
        params, _ = self._settle(frame, index)
        return self._estimate_of(params, index, time, self._psnr(frame, s), s.pixels, solves)


class _Model:
    """The model's colors ``(N, 3)`` and their gradients at the samples, from the rendering
    smoothed with ``sigma``."""

    def __init__(self, s: _Samples, sigma: float) -> None:
        smoothed = smooth(s.raw, sigma)
        self.color = smoothed[s.rows, s.cols]
        self.gx, self.gy = _gradients_at(smoothed, s.rows, s.cols)
        other = next(iter(s.models.values()), None)  # the same samples' motion, another sigma
        if other is not None:
            self.speed, self.support = other.speed, other.support
            return
        #: the most (pixels) a unit of each unknown moves any sample ``(K,)``
        speed = np.hypot(s.du, s.dv)
        self.speed = speed.max(axis=0, initial=0.0)
        #: how many samples each unknown moves by more than a fifth of its most ``(K,)``
        self.support = (speed > 0.2 * self.speed).sum(axis=0)


def _gradients_at(image: np.ndarray, rows: np.ndarray, cols: np.ndarray):
    """The central differences ``(d/dX, d/dY)``, each ``(N, C)``, of ``image`` ``(H, W, C)``
    at the pixels ``rows``, ``cols`` ``(N,)``: one-sided at the border, the same numbers as
    :func:`_with_gradients` (``np.gradient``) there, without differencing the whole image."""
    h, w = image.shape[:2]
    up, down = np.maximum(rows - 1, 0), np.minimum(rows + 1, h - 1)
    left, right = np.maximum(cols - 1, 0), np.minimum(cols + 1, w - 1)
    # np.gradient divides by 2 inside and by 1 at the border: exact, as these products are
    sy = (1.0 / (down - up)).astype(image.dtype)[:, None]
    sx = (1.0 / (right - left)).astype(image.dtype)[:, None]
    return (image[rows, right] - image[rows, left]) * sx, (image[down, cols] - image[up, cols]) * sy


def _with_gradients(image: np.ndarray) -> np.ndarray:
    """``(H, W, 3)`` float32 and its central differences along X and Y (one-sided at the
    border, as ``np.gradient``): ``(H, W, 9)`` = image, d/dX, d/dY."""
    gy, gx = np.gradient(image, axis=(0, 1))
    return np.concatenate([image, gx, gy], axis=2).astype(np.float32, copy=False)


def _bilinear(image: np.ndarray, x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """``image`` ``(H, W, C)`` at the ``(N,)`` positions ``x``, ``y`` (index coordinates: pixel
    ``(r, c)`` at ``x = c``, ``y = r``), bilinearly; positions outside are clamped to the
    border. Returns ``(N, C)``."""
    h, w = image.shape[:2]
    x = np.clip(x, 0.0, w - 1.0)
    y = np.clip(y, 0.0, h - 1.0)
    x0 = np.minimum(x.astype(np.int64), w - 2)
    y0 = np.minimum(y.astype(np.int64), h - 2)
    fx = (x - x0).astype(np.float32)[:, None]
    fy = (y - y0).astype(np.float32)[:, None]
    flat = image.reshape(h * w, -1)
    i = y0 * w + x0
    top = flat[i] * (1 - fx) + flat[i + 1] * fx
    bottom = flat[i + w] * (1 - fx) + flat[i + w + 1] * fx
    return top * (1 - fy) + bottom * fy


def _window_around(rows: np.ndarray, cols: np.ndarray, size: tuple[int, int],
                   frame: tuple[int, int]) -> tuple[int, int, int, int]:  # fmt: skip
    """The window ``(x0, y0, width, height)`` of the frame (``frame`` (W, H)) to render next:
    the box of the face pixels ``rows``, ``cols`` (frame coordinates) with :data:`MARGIN` on
    each side, centred on it: of the last window's ``size`` (W, H) when the box fits in it
    with at most 64 pixels to spare, else of the box's size rounded up to 32 pixels (so that
    the renderer's targets are rarely made anew)."""
    fw, fh = frame
    need_w = int(cols.max() - cols.min()) + 1 + 2 * MARGIN
    need_h = int(rows.max() - rows.min()) + 1 + 2 * MARGIN
    ww, wh = size
    if not need_w <= ww <= need_w + 64:
        ww = -(-need_w // 32) * 32
    if not need_h <= wh <= need_h + 64:
        wh = -(-need_h // 32) * 32
    ww, wh = min(ww, fw), min(wh, fh)
    cx, cy = (
        (int(cols.max()) + int(cols.min()) + 1) // 2,
        (int(rows.max()) + int(rows.min()) + 1) // 2,
    )
    x0 = min(max(cx - ww // 2, 0), fw - ww)
    y0 = min(max(cy - wh // 2, 0), fh - wh)
    return x0, y0, ww, wh


def _system(
    du: np.ndarray,
    dv: np.ndarray,
    gx: np.ndarray,
    gy: np.ndarray,
    r: np.ndarray,
    color: np.ndarray | None,
    weights: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """The normal equations ``(AᵀWA, AᵀWb)`` (float64) of the per-sample, per-channel equations
    ``−(gx_c·du + gy_c·dv)·Δ + color_c·Δgain_c + Δoffset_c = r_c`` — the system of
    :func:`vtts.analysis.solve.normal_equations`, in single precision: a sample's three
    channel rows reduce to the 2×2 matrix of its gradients summed over the channels, so the
    products are (N × K)ᵀ(N × K) ones. ``du``, ``dv`` ``(N, K)``; ``gx``, ``gy``, ``r``,
    ``color`` ``(N, 3)``; ``weights`` ``(N,)``."""
    k = du.shape[1]
    m = k + (6 if color is not None else 0)
    wgx, wgy = gx * weights[:, None], gy * weights[:, None]
    gxx, gxy, gyy = (wgx * gx).sum(1), (wgx * gy).sum(1), (wgy * gy).sum(1)
    ata = np.zeros((m, m))
    atb = np.zeros(m)
    ata[:k, :k] = du.T @ (du * gxx[:, None] + dv * gxy[:, None]) + dv.T @ (
        du * gxy[:, None] + dv * gyy[:, None]
    )
    atb[:k] = -(du.T @ (wgx * r).sum(1) + dv.T @ (wgy * r).sum(1))
    if color is not None:
        # the gains' and offsets' columns: gradient times color (gain) or one (offset)
        ex = np.concatenate([wgx * color, wgx], axis=1)  # (N, 6)
        ey = np.concatenate([wgy * color, wgy], axis=1)
        ata[:k, k:] = -(du.T @ ex + dv.T @ ey)
        ata[k:, :k] = ata[:k, k:].T
        wc, wr = color * weights[:, None], r * weights[:, None]
        for c in range(3):
            g, o = k + c, k + 3 + c
            ata[g, g] = wc[:, c] @ color[:, c]
            ata[g, o] = ata[o, g] = wc[:, c].sum()
            ata[o, o] = weights.sum()
            atb[g] = wc[:, c] @ r[:, c]
            atb[o] = wr[:, c].sum()
    return ata, atb
