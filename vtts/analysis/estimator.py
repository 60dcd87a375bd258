"""Estimating FAPs from video by analysis by synthesis (Eisert & Girod 1998).

For every camera frame I(n) the model is rendered with the current estimate, and the parameter
change that carries the synthetic image onto the camera frame is solved for in the least-squares
sense over all face pixels. Each pixel gives, per color channel, the optical-flow constraint
(Equation 10) with the image motion written as a linear function of the parameter changes
(Equations 14–15, 16): the pixel's 3D point moves by ``T · ΔFAP`` (Equation 9), where T combines
the model's per-vertex motion (:mod:`vtts.analysis.geometry`) with the pixel's barycentric
coordinates in the triangle it shows (:func:`vtts.mesh.ray_barycentrics`), and the depth comes
from the model. Because the estimate is always made between the camera frame and the model
rendered with the current parameters — never between two camera frames — errors do not
accumulate.

A three-level pyramid (88×72, 176×144, 352×288 for CIF: moving-average subsampling, then a
Gaussian filter on both images) handles large motion; pixels whose displacement estimate
(Equation 17) exceeds the level's threshold G (5 → 0.5 pixels) are dropped as outliers; after
each solve the model is rendered again with the new parameters.

Beyond the paper, the camera frame is modelled as ``gain · synthetic + offset`` per color channel,
with gain and offset estimated along with the FAPs, so that a change of light does not read as
motion. And the eyelids (:data:`~vtts.analysis.unknowns.EYELIDS`), whose thin edges change the
rendered image in whole pixels where the optical-flow model expects a smooth change, are refined
at the end on the rendered image itself: a search over integer FAP values for the best match
around the eye.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable, Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass, replace

import numpy as np
from scipy.ndimage import binary_erosion
from scipy.sparse import csr_matrix

from vtts.analysis.geometry import HeadGeometry
from vtts.analysis.landmark_pose import MIN_POINTS
from vtts.analysis.landmark_term import (
    LANDMARK_WEIGHT,
    LandmarkPoints,
    LandmarkSystem,
    Projection,
    crop_side,
    landmark_points,
    observed,
    project_points,
    unknown_values,
)
from vtts.analysis.result import TRANSLATION, Analysis, FrameEstimate
from vtts.analysis.solve import (
    SMOOTH_REACH,
    gradients_at,
    least_squares,
    normal_equations,
    smooth,
    subsample,
)
from vtts.analysis.unknowns import (  # noqa: F401
    DEFAULT_UNKNOWNS,
    ESTIMABLE,
    EYELIDS,
    HEAD_MOTION,
    HEAD_ROTATION,
    JAW_AND_CORNERS,
    TABLE1_FAPS,
)
from vtts.errors import VttsError
from vtts.face import N_PARAMS, FaceModel
from vtts.mesh import ray_barycentrics
from vtts.render.camera import Camera
from vtts.render.renderer import FaceRenderer
from vtts.threads import one_blas_thread

#: The landmark term is linearized at each frame's start, and again when the estimate moved its
#: points further than this (pixels) since. Carried on from frame to frame while the head's
#: motion moved them less than 4 pixels (the FAPs' motion is linear within their tables'
#: intervals), the linearization cost Carphone 0.8 dB and 1.4 % of geometry (docs/analysis.md).
RELINEARIZE_PX = 2.0
#: Gauss–Newton steps on the landmarks alone that start a frame
#: (:meth:`Estimator._jump_to_landmarks`), …
JUMP_STEPS = 3
#: … each change damped by this share of its own curvature (Levenberg's), …
JUMP_DAMPING = 0.1
#: … the last one when it moved the points by less than this (pixels); a turn of the head by
#: this much (AU) costs the jump as much as every landmark a pixel off.
JUMP_STOP_PX = 0.5
JUMP_TURN_AU = 3000.0
#: A frame whose estimate starts further than this (pixels, the median landmark) from its
#: landmarks — a head moving fast, analyzed every second frame (the accurate mode's
#: ``--step 2``) — may take up to the estimator's ``far_jump_steps`` instead of
#: :data:`JUMP_STEPS`: three steps left lp_d12's fastest frames 2–2.5 pixels off, which the
#: photometric solves, at 2 pixels a solve, did not make up (docs/analysis.md, "Measuring on
#: people").
JUMP_FAR_PX = 8.0

#: Where asked for (``halved_stop`` of :meth:`Estimator._descend`: the accurate mode's finest
#: level, :class:`~vtts.analysis.tracker.Tracker`), with robust matching, a step that made the
#: match worse is halved (:data:`STALL_GAIN`) only while the halved step still moves the image
#: of some unknown by at least this many pixels (of the level); below that the step is taken
#: back whole and the level ends, without the rendering that would judge so small a change (the
#: camera's noise and what the model cannot show decide it more than the step does).
HALVED_STOP_PX = 0.5

#: Pixels next to the model's outline left out of the estimation.
EDGE = 2

#: Residuals beyond this many gray levels count as this many in the match energy (robust).
TRUNCATE = 10.0

#: Residuals (gray levels of luminance) beyond which a pixel has no say in a robust solve.
ROBUST_LIMIT = 30.0

#: Rec. 601 luminance weights (Equation 18 is on luminance).
LUMA = np.array([0.299, 0.587, 0.114])

#: Steps (FAP units) of the search that refines FAPs on the rendered image, largest first, and
#: how many times in a row each may be taken (so the search stays within ±60 units).
REFINE_STEPS = (8, 4, 2, 1)
REFINE_MOVES = 4

#: The eyelid search on the first frame, which starts from neutral: steps from 128 units, so
#: that it reaches ±1020 units (an eyelid anywhere from wide open to closed), and how many times
#: at most the first frame's search and pyramid are restarted (:meth:`Estimator.estimate`).
FIRST_REFINE_STEPS = (128, 64, 32, 16, 8, 4, 2, 1)
FIRST_RESTARTS = 3

#: The search steps for the FAPs an estimator finds by the search alone (``searched``): with
#: no linear solve to bring them near, each frame's search reaches ±252 units.
SEARCHED_STEPS = (32, 16, 8, 4, 2, 1)

#: The eyelids' steps in the search after the solves (when they are solved, not ``searched``):
#: from 32 units, each taken at most :data:`REFINE_MOVES` times in a row, so that the search
#: reaches ±252 units a frame. The pyramid holds the lids at its coarse levels and its finest
#: level can open a lid that is closing fast (seed 5 of
#: :func:`~vtts.analysis.synthetic.random_truth`: 57 → 216 → 423 units in two analyzed frames,
#: the solves took it to −29), where :data:`REFINE_STEPS` (±60 units) stop on the match's
#: plateau.
LID_STEPS = SEARCHED_STEPS

#: A frame shows "a lit face" when at least this share of its face pixels lie on lit surfaces
#: (a bundled head, the synthetic Table 1; a head made for the video is drawn unlit but for
#: its mouth): its shading changes with every move.
LIT_SHARE = 0.5

#: The steps (FAP units, largest first) by which the search after the solves takes the FAPs it
#: refines on a lit face only (``lit_refine``: the jaw and the lip corners), at most
#: :data:`REFINE_MOVES` times each: within ±12 units of where the solves left them.
LIT_REFINE_STEPS = (2, 1)

#: How many times at most the search of the ``searched`` FAPs and the finest level's solves
#: take turns on one frame.
SEARCH_ROUNDS = 3

#: A level's solves stop when no unknown moved its image by more than this many pixels (of that
#: level) in the last one.
TOLERANCE = 0.003

#: With robust matching (camera video), a level ends when it has settled — when its last
#: step lowered the match's energy (the truncated mean squared luminance difference) by less
#: than this share: what is left is the camera's noise and what the model cannot show, and
#: more solves (a rendering each) move the estimate about without bettering the match.
SETTLED_GAIN: float | None = 0.005

#: A step that made the match worse is halved, at most three times, before the next solve;
#: with robust matching, when the step before it gained less than this share, the step is
#: taken back whole and the level ends there instead.
STALL_GAIN: float | None = 0.01

#: Pixels around the image of what a refined FAP moves that its match is measured over.
REFINE_MARGIN = 4

#: The solves' renderings and a frame's final rendering draw a window of the frame around the
#: face (:meth:`Estimator._render_near_face`): the last face's box with this many pixels (of the
#: full size) more on each side than :data:`RENDER_MARGIN`, so that a face that moved this far
#: since is still inside, …
RENDER_SLACK = 16
#: … and a rendering whose face comes closer than this (pixels) to a side of the window that is
#: not the frame's is made again of the whole frame: the smoothing, the gradients and the
#: tracker's samples read that far around the face.
RENDER_MARGIN = 24


@dataclass
class Level:
    """One level of the pyramid: subsampling ``factor``, outlier threshold ``g`` (pixels of
    that level), linear solves ``iterations`` (each followed by a new rendering), ``limit``, the
    most (pixels of that level) one solve may move the image of any unknown, and ``support``,
    the fewest pixels an unknown must move to be estimated at that level (an eyelid covers a
    handful of pixels at 88×72 and is held until a finer level resolves it)."""

    factor: int
    g: float
    iterations: int
    limit: float = 2.0
    support: int = 0


#: The paper's pyramid: 88×72 → 352×288 for CIF, G from 5 to 0.5.
PYRAMID = (
    Level(4, 5.0, 2, support=40),
    Level(2, 1.6, 2, support=4),
    Level(1, 0.5, 8),
)


class Estimator:
    """Tracks one model through a sequence of frames of ``size`` (W, H).

    ``camera`` is the camera of the video (default: the framing ``vtts render`` uses for this
    model and size) in the renderer's world; ``model_camera`` the same in the model's own
    coordinates (as :func:`vtts.fit.fit_photo` and :func:`~vtts.analysis.init.initial_camera`
    give it). ``unknowns`` are FAP numbers and ``"tx"``, ``"ty"``, ``"tz"``.
    ``illumination`` estimates a gain and offset per color channel. ``sigma`` is the Gaussian
    filter (pixels of each level) applied to both images before the gradients. A level's solves
    stop when the last one moved no unknown's image by more than ``tolerance`` pixels of that
    level. ``refine``: the FAPs that, when they are unknowns, are refined after the pyramid by
    a search over integer values on the rendered image (:meth:`_refine`). ``predict``: the
    unknowns that start each frame where their motion between the last two estimates leads
    (:meth:`_extrapolate`; default the head's rotation and translation). ``robust``: Tukey's
    biweight on each pixel's luminance residual (a pixel beyond :data:`ROBUST_LIMIT` gray levels
    has no say), for camera video where parts of the image are not the model's. ``ignore``:
    DEF names of IndexedFaceSets drawn but left out of the match (a fitted head's hair, ears and
    neck, whose texture the photo did not give); their pixels are not in the face area either.
    ``searched``: FAPs among the unknowns (and, for the search, among ``refine``'s) that every
    linear solve holds, so that they are found by the search on the rendered image alone, after
    the pyramid, with the head's pose and the other FAPs held where the solves left them (a
    second stage on the eye region's pixels: the eyelids then cannot trade against the head's
    pitch in the solves; each frame's search reaches ±252 units, :data:`SEARCHED_STEPS`).
    ``lit_refine``: FAPs that, when they are unknowns, the search on the rendered image takes
    as well on a frame that shows a lit face (:data:`LIT_SHARE`; default the jaw and the
    lip-corner raisers, :data:`~vtts.analysis.unknowns.JAW_AND_CORNERS`, which stall together
    where the opening jaw uncovers the teeth), by :data:`LIT_REFINE_STEPS`.
    ``bounds``: FAP -> (lowest, highest) value the search on the rendered image may take it to
    (e.g. an eyelid of a head made from a video frame opened no further than that frame shows
    it: its eyeball is textured only where the frame showed it).
    ``landmark_weight``: the weight of a frame's face-mesh landmarks, when :meth:`estimate` is
    given them, beside the photometric terms of every solve (:mod:`vtts.analysis.landmark_term`;
    0 leaves them out).
    ``far_jump_steps``: the most steps of the jump onto a frame's landmarks when the frame
    starts further than :data:`JUMP_FAR_PX` from them (default :data:`JUMP_STEPS`, as any
    other frame; the accurate mode of :func:`~vtts.analysis.track.track` takes more).
    """

    def __init__(
        self,
        model: FaceModel,
        *,
        size: tuple[int, int] = (352, 288),
        camera: Camera | None = None,
        model_camera: Camera | None = None,
        unknowns: Sequence[int | str] = DEFAULT_UNKNOWNS,
        pyramid: Sequence[Level] = PYRAMID,
        illumination: bool = True,
        sigma: float = 0.6,
        tolerance: float = TOLERANCE,
        refine: Iterable[int] = EYELIDS,
        predict: Iterable[int | str] = HEAD_MOTION,
        robust: bool = False,
        ignore: Iterable[str] = (),
        searched: Iterable[int] = (),
        bounds: dict[int, tuple[float, float]] | None = None,
        lit_refine: Iterable[int] = JAW_AND_CORNERS,
        landmark_weight: float = LANDMARK_WEIGHT,
        far_jump_steps: int = JUMP_STEPS,
    ) -> None:
        self.unknowns = _check_unknowns(unknowns)
        alone = set(searched)
        wanted = set(refine) | alone
        self.refined = tuple(u for u in self.unknowns if u in wanted)
        self.searched = tuple(u for u in self.unknowns if u in alone)
        # columns of the linear solves held for the searched FAPs
        self._searched_columns = np.array([u in alone for u in self.unknowns])
        self.bounds = dict(bounds or {})
        #: FAP -> the steps the search after the solves (:meth:`_settle`) takes it by, where
        #: they are not :data:`REFINE_STEPS`: the eyelids that are solved, :data:`LID_STEPS`
        self.search_steps: dict[int, tuple[int, ...]] = {
            fap: LID_STEPS for fap in self.refined if fap in EYELIDS and fap not in alone
        }
        # on a lit face the search takes these as well, by small steps: the solves leave them
        # a few units off, and a wider search lets a window's match pull one to make up for
        # another FAP's last unit
        lit_wanted = set(self.refined) | set(lit_refine)
        self._lit_refined = tuple(u for u in self.unknowns if u in lit_wanted)
        self.search_steps.update(
            dict.fromkeys(set(self._lit_refined) - set(self.refined), LIT_REFINE_STEPS)
        )
        # the triangle indices (h, w) of the last solve's rendering, for _lit_frame
        self._last_faces = np.empty((0, 0), dtype=np.int64)
        self.model = model
        self.size = (int(size[0]), int(size[1]))
        self.pyramid = tuple(pyramid)
        self.illumination = illumination
        self.sigma = sigma
        self.tolerance = tolerance
        self.robust = robust
        carried = set(predict)
        self.predicted = tuple(u for u in self.unknowns if u in carried)
        # (frame index, parameters, translation) of the last two estimates
        self._history: list[tuple[int, np.ndarray, np.ndarray]] = []
        w, h = self.size
        # one renderer for every view (pyramid levels, refinement windows): the GL context holds
        # one scene at a time, and changing scenes uploads every mesh and texture again
        if camera is not None and model_camera is not None:
            raise VttsError("give the camera in the renderer's frame or the model's, not both")
        self._renderer = FaceRenderer(model, size=self.size, camera=camera)
        if model_camera is not None:  # the renderer centres the model: carry the camera along
            placed = self._renderer.model_matrix(0) @ model_camera.pose
            self._renderer.set_view(replace(model_camera, pose=placed), self.size, 1)
        self.camera = self._renderer.camera
        # pyramid factor -> (camera, image size) of that level
        self._levels: dict[int, tuple[Camera, tuple[int, int]]] = {1: (self.camera, self.size)}
        for lv in self.pyramid:
            f = lv.factor
            if f in self._levels:
                continue
            lsize = (w // f, h // f)
            if min(lsize) < 16:
                raise VttsError(f"a {w}x{h} video is too small for a pyramid level of 1/{f}")
            self._levels[f] = (self.camera.scaled(f), lsize)
        self._root = self._renderer.scene.get_pose(self._renderer.instances[0].root)
        #: the camera's distance from the model's origin at the start (world units)
        self.distance = float(np.linalg.norm(self.camera.pose[:3, 3] - self._root[:3, 3]))
        self.geometry = HeadGeometry(model, self.unknowns, self._root)
        self._faces = _face_numbers(self._renderer, self.geometry)
        self.ignored = frozenset(ignore)
        for node, first, count in self._renderer.triangle_sets:
            if node.name in self.ignored:  # drawn (they hide what is behind them), not matched
                self._faces[first : first + count] = -1
        # the same with a last entry −1 for the renderer's −1 (no triangle): one lookup a pixel
        self._faces_or_none = np.append(self._faces, np.array([-1], self._faces.dtype))
        #: the window ``(x0, y0, width, height)`` of the frame that the next rendering near the
        #: face draws (:meth:`_render_near_face`; None: the whole frame), its corner a multiple
        #: of every pyramid factor
        self._render_box: tuple[int, int, int, int] | None = None
        self._align = math.lcm(*(lv.factor for lv in self.pyramid))
        self._last_step: _Step | None = None
        self._stalled = False  # the level being solved ended on a step taken back
        #: the full-size level's last two renderings, each as ``(params, translation, what
        #: :meth:`_render_window` gave)``: a level that ends on a step taken back ends at the
        #: one before the last
        self._rendered: list[tuple[np.ndarray, np.ndarray, tuple]] = []
        #: the triangle indices of the last frame's final rendering (full size), or None
        self._shown: np.ndarray | None = None
        self._fewest = 4 * len(self.unknowns)  # face pixels a level needs for a solve
        self.params = np.zeros(N_PARAMS)
        self.translation = np.zeros(3)
        self.gain = np.ones(3)
        self.offset = np.zeros(3)
        self.landmark_weight = float(landmark_weight)
        #: the most steps of the jump onto the landmarks (:meth:`_jump_to_landmarks`) for a frame
        #: that starts further than :data:`JUMP_FAR_PX` from them
        self.far_jump_steps = int(far_jump_steps)
        self._landmark_points: LandmarkPoints | None = None
        #: the frame's landmarks ``(468, 2)`` pixels and their crop's side, while it is estimated
        self._observed: tuple[np.ndarray, float] | None = None
        #: the frame's landmark term, linearized where it was last asked for
        self._landmarks: LandmarkSystem | None = None
        self._eyes = None  # the frame's iris model eyes, while it is estimated
        self._eye_points = None  # the model's pupils and lid points, once asked for
        self._projection: Projection | None = None  # where they lie, linearized

    # ---- rendering -----------------------------------------------------------------------------

    def render(self, factor: int = 1) -> tuple[np.ndarray, np.ndarray]:
        """The model at the current estimate at pyramid ``factor``: the image ``(h, w, 3)
        float32`` (0–255, before gain and offset) and the index into ``geometry.faces`` of the
        triangle each pixel shows ``(h, w)`` (−1: none).

        Both come from one rendering at full size: the image is subsampled exactly as the camera
        frame is (a moving average over the same full-size pixels), and each pixel of a smaller
        level takes the triangle of the full-size pixel at its centre."""
        image, faces, _ = self._render_window(factor, whole=True)
        return image, faces

    def surface(self, shrink: int = 0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Where the model lies in the full-size image at the current estimate: the pixels it
        covers ``(N, 2)`` int (row, column), less ``shrink`` pixels along every outline of the
        covered area, the index into ``geometry.faces`` of the triangle each shows ``(N,)`` and
        the barycentric coordinates of the point its ray meets there ``(N, 3)``."""
        _, numbers = self._synthesize(self.camera, self.size, triangles=True)
        faces = self._face_indices(numbers)
        covered = faces >= 0
        if shrink:
            covered = binary_erosion(covered, iterations=shrink)
        rows, cols = np.nonzero(covered)
        tri = faces[rows, cols]
        positions = self.geometry.positions(self.params, self.translation)
        pix = np.c_[cols + 0.5, rows + 0.5]
        lam, _ = ray_barycentrics(pix, self.camera, positions[self.geometry.faces[tri]])
        return np.c_[rows, cols], tri, lam

    def _render_window(
        self, factor: int, whole: bool = False
    ) -> tuple[np.ndarray, np.ndarray, tuple[int, int]]:
        """What :meth:`render` gives at pyramid ``factor``, cut to the window around the face
        that a solve reads: ``(image, faces, (top, left))``, the window's image ``(h, w, 3)``
        and triangle indices ``(h, w)`` and where its top-left pixel lies in the level's image.

        The window holds every face pixel with :func:`_window_margin` pixels of the level
        around it (the smoothing's reach and the gradients'), so that the subsampling, the
        smoothing, the erosion of the outline and the gradients give the same numbers over the
        face as on the whole image, for a fraction of the pixels (the face is a sixth of a CIF
        head-and-shoulders frame). With ``whole``, or without face pixels, the whole level.

        But for ``whole``, what is rendered is a window of the frame around the face
        (:meth:`_render_near_face`), which holds that window and the smoothing's margin."""
        if whole:
            image, numbers = self._synthesize(self.camera, self.size, triangles=True)
            top = left = 0
        else:
            image, numbers, (top, left) = self._render_near_face()
        # the level's pixels the rendered window holds: level pixel (i, j) is the full-size
        # pixel at its centre, (i f + f // 2, j f + f // 2); the window starts at a multiple of f
        w, h = self._levels[factor][1]
        ly, lx = top // factor, left // factor
        c = factor // 2
        faces = self._face_indices(numbers[c::factor, c::factor][: h - ly, : w - lx])
        wh, ww = faces.shape
        box = (0, wh), (0, ww)
        inner = _bounds(faces >= 0)
        if inner is not None and not whole:
            m = _window_margin(self.sigma)
            (i0, i1), (j0, j1) = inner
            box = (max(0, i0 - m), min(wh, i1 + m)), (max(0, j0 - m), min(ww, j1 + m))
        (y0, y1), (x0, x1) = box
        window = image[y0 * factor : y1 * factor, x0 * factor : x1 * factor]
        return subsample(window, factor), faces[y0:y1, x0:x1], (ly + y0, lx + x0)

    def _render_near_face(self) -> tuple[np.ndarray, np.ndarray, tuple[int, int]]:
        """The model at the current estimate, rendered in the window of the frame around the
        face (:attr:`_render_box`): the window's image ``(h, w, 3) uint8``, the renderer's
        triangle numbers ``(h, w)`` and where its top-left pixel lies in the frame ``(top,
        left)``. A window whose face comes within :data:`RENDER_MARGIN` pixels of a side that
        is not the frame's, or that shows no face, is rendered again as the whole frame (so are
        the first frame's); the next window is the face's box with :data:`RENDER_SLACK` pixels
        more on each side. The pixels are the whole frame's rendering's (up to a gray level at
        a few textured ones: :meth:`~vtts.render.renderer.FaceRenderer.set_view`)."""
        w, h = self.size
        box = self._render_box
        image = numbers = None
        inner = None
        if box is not None:
            x0, y0, ww, wh = box
            cam = replace(self.camera, cx=self.camera.cx - x0, cy=self.camera.cy - y0)
            image, numbers = self._synthesize(cam, (ww, wh), triangles=True)
            inner = _bounds(self._face_indices(numbers) >= 0)
            if inner is None or not _clear(inner, box, self.size, RENDER_MARGIN):
                image = None
        if image is None:
            x0, y0 = 0, 0
            image, numbers = self._synthesize(self.camera, self.size, triangles=True)
            inner = _bounds(self._face_indices(numbers) >= 0)
        self._render_box = None if inner is None else _window_of(
            inner, (x0, y0), self.size, RENDER_MARGIN + RENDER_SLACK, self._align, box)  # fmt: skip
        return image, numbers, (y0, x0)

    def _at_level(self, full: np.ndarray, factor: int) -> np.ndarray:
        """A full-size per-pixel array ``(H, W)`` (triangle numbers or indices) at pyramid
        ``factor``: each level pixel takes the value at its centre."""
        if factor == 1:
            return full
        w, h = self._levels[factor][1]
        c = factor // 2
        return full[c::factor, c::factor][:h, :w]

    def _face_indices(self, numbers: np.ndarray) -> np.ndarray:
        """The renderer's triangle ``numbers`` ``(h, w)`` as indices into ``geometry.faces``
        (−1: none, or a part left out of the match)."""
        return self._faces_or_none[numbers]  # numbers ≥ −1

    def _synthesize(self, camera: Camera, size: tuple[int, int], triangles: bool = False):
        """The model at the current estimate through ``camera`` at ``size``: the image ``(h, w,
        3) uint8`` and, with ``triangles``, the renderer's triangle numbers ``(h, w)``."""
        renderer = self._renderer
        renderer.set_view(camera, size, 1)
        root = self._root.copy()
        root[:3, 3] += self.translation  # the estimated head translation
        renderer.scene.set_pose(renderer.instances[0].root, root)
        pose = self.geometry.pose(self.params)
        return renderer.render(self.params, poses=[pose], triangles=triangles)

    def snapshot(self) -> tuple:
        """The estimate as it stands (parameters, translation, light, recent motion), for
        :meth:`restore`."""
        return (self.params.copy(), self.translation.copy(), self.gain.copy(),
                self.offset.copy(), list(self._history))  # fmt: skip

    def restore(self, snapshot: tuple) -> None:
        """Go back to a :meth:`snapshot`."""
        params, translation, gain, offset, history = snapshot
        self.params, self.translation = params.copy(), translation.copy()
        self.gain, self.offset, self._history = gain.copy(), offset.copy(), list(history)

    def forget_motion(self) -> None:
        """Start the next frame as a first one: no motion carried on from earlier estimates,
        and the first frame's wider search (after a track was lost and placed again)."""
        self._history = []

    def reconstruct(self) -> np.ndarray:
        """The synthetic frame ``(H, W, 3) uint8`` at full size with gain and offset applied."""
        image, _ = self.render(1)
        return np.clip(np.round(image * self.gain + self.offset), 0, 255).astype(np.uint8)

    # ---- estimation ----------------------------------------------------------------------------

    @one_blas_thread()
    def estimate(self, frame: np.ndarray, index: int = 0, time: float = 0.0,
                 landmarks=None, eyes=None) -> FrameEstimate:  # fmt: skip
        """Update the estimate to the camera ``frame`` ``(H, W, 3) uint8`` and return it (with
        one BLAS thread: :mod:`vtts.threads`). ``landmarks``: the face mesh's
        :class:`~vtts.fit.landmarks.Face` in this frame, observed in every solve (None: the
        photometric terms alone, as the paper); ``eyes``: the iris model's
        :class:`~vtts.fit.iris.Eyes` there (:meth:`observe`)."""
        frame = np.asarray(frame)
        w, h = self.size
        if frame.shape != (h, w, 3):
            raise VttsError(f"frame {index} is {frame.shape}, expected ({h}, {w}, 3)")
        self.observe(landmarks, eyes)
        full = frame.astype(np.float32)
        if self.predicted:
            self._extrapolate(index)
        self._jump_to_landmarks()
        pyramid: dict[int, np.ndarray] = {}
        for lv in self.pyramid:
            if lv.factor not in pyramid:
                pyramid[lv.factor] = smooth(subsample(full, lv.factor), self.sigma)
        solves, converged = self._descend(pyramid)
        if self.searched and self._history:
            # the second stage: the searched FAPs, with everything else held where the solves
            # left it; while they move far, what the solves matched against the wrong lids (the
            # head's pitch) is solved again at the finest level, the lids held
            for _ in range(SEARCH_ROUNDS):
                if self._refine(full, SEARCHED_STEPS) <= REFINE_STEPS[-1]:
                    break
                solves += self._descend(pyramid, self.pyramid[-1:])[0]
        if not self._history:
            # the first frame starts from neutral, which may be far from the truth (an eyelid
            # half closed, the head turned): its eyelids are searched over their whole range and
            # the pyramid restarted from the coarsest level until it settles. A restart that
            # matches the frame worse is taken back (with a change of light the solves can
            # wander about without settling; another pass then lands elsewhere, no closer)
            best = self._mismatch(full)
            for _ in range(FIRST_RESTARTS):
                state = self._state()
                moved = self._refine(full, FIRST_REFINE_STEPS)
                if converged and moved <= REFINE_STEPS[0]:
                    break  # what is left is the ordinary search's
                more, converged = self._descend(pyramid)
                solves += more
                mismatch = self._mismatch(full)
                if mismatch >= best:
                    self._set_state(state)
                    break
                best = mismatch
            self._search_from_neutral(full)
        return self._final_estimate(full, index, time, solves, self._lit_frame())

    def observe(self, landmarks, eyes=None) -> None:
        """Take ``landmarks`` (a :class:`~vtts.fit.landmarks.Face`, or None) as the observations
        of the frame about to be estimated (:meth:`estimate` does), with the iris model's
        ``eyes`` (:class:`~vtts.fit.iris.Eyes`) where given: pupils and lids."""
        self._landmarks = None
        self._projection = None
        self._observed = None
        self._eyes = eyes
        if landmarks is None or self.landmark_weight <= 0:
            return
        if eyes is not None and self._eye_points is None:
            from vtts.analysis.eyes import eye_points

            self._eye_points = eye_points(self)
        if self._landmark_points is None:
            self._landmark_points = landmark_points(self.geometry,
                                                    self.model.tables.feature_points)  # fmt: skip
        if len(self._landmark_points) >= MIN_POINTS:
            points = np.asarray(landmarks.landmarks, np.float64)[:, :2]
            self._observed = (points, crop_side(landmarks))

    def landmark_term(self) -> LandmarkSystem | None:
        """The frame's landmark term, linearized where the frame's estimate starts and again
        when the estimate moved its points further than :data:`RELINEARIZE_PX` (the term moves
        them linearly until then); None without landmarks."""
        if self._observed is None:
            return None
        values = unknown_values(self)
        points = self._landmark_points
        assert points is not None
        eyes = self._eye_points if self._eyes is not None else None
        projection = self._projection
        if (projection is None or projection.eyes != (eyes is not None)
                or projection.moved(values) > RELINEARIZE_PX):  # fmt: skip
            projection = self._projection = project_points(self, points, values, eyes)
            self._landmarks = None
        if self._landmarks is not None:
            return self._landmarks
        term = observed(projection, points, *self._observed, self._eyes, eyes)
        term.weight = self.landmark_weight
        self._landmarks = term
        return term

    def _jump_to_landmarks(self) -> None:
        """Move the estimate onto the frame's landmarks before the photometric solves: a few
        damped Gauss–Newton steps on the landmark term alone (:data:`JUMP_STEPS`, each change
        damped by :data:`JUMP_DAMPING` of its own curvature; :attr:`far_jump_steps` where the
        frame starts further than :data:`JUMP_FAR_PX` from its landmarks). The photometric
        solves move each unknown's pixels by a few pixels a solve at most; a head that moved
        further between two frames would otherwise be followed over several frames, or lost."""
        k = len(self.unknowns)
        turns = np.array([u in HEAD_ROTATION for u in self.unknowns])
        start = unknown_values(self)
        steps = JUMP_STEPS
        step = 0
        while step < steps:
            term = self.landmark_term()
            if term is None:
                return
            values = unknown_values(self)
            if step == 0 and self.far_jump_steps > steps and term.error(values) > JUMP_FAR_PX:
                steps = self.far_jump_steps  # a head that moved far since the last estimate
            step += 1
            ata, atb = term.normal_equations(values, held=self._searched_columns)
            ata[np.diag_indices(k)] *= 1.0 + JUMP_DAMPING
            # the head's turns held near where the frame started: the face's points lie nearly
            # in a plane, and a turn and a shift move them much alike
            prior = term.total_weight() / JUMP_TURN_AU**2
            ata[turns, turns] += prior
            atb[turns] -= prior * (values - start)[turns]
            delta = least_squares(ata, atb)
            self._apply(np.concatenate([delta, np.zeros(6)]))
            if term.shift(delta[:k]) < JUMP_STOP_PX:
                return

    def landmark_error(self) -> float:
        """The median distance (pixels) between the frame's landmarks and where the current
        estimate puts their points; NaN without landmarks."""
        term = self.landmark_term()
        return math.nan if term is None else term.error(term.values0)

    def _final_estimate(self, full: np.ndarray, index: int, time: float, solves: int,
                        lit: bool) -> FrameEstimate:  # fmt: skip
        """Frame ``index``'s estimate once the solves (``solves`` of them) are done: the integer
        FAPs and the search (:meth:`_settle`; the jaw and lip corners too when ``lit``), and the
        face PSNR of one full-size rendering (:meth:`_final_rendering`) against the camera frame
        ``full`` ``(H, W, 3) float32``."""
        with self._refining(lit):
            params, (image, ids, (top, left)) = self._settle(full, index, self._final_rendering)
        h, w = ids.shape
        self._shown = np.full(full.shape[:2], -1, dtype=ids.dtype)
        self._shown[top : top + h, left : left + w] = ids
        synth = np.clip(np.round(image * self.gain + self.offset), 0, 255)
        mask = ids >= 0
        seen = full[top : top + h, left : left + w]
        return self._estimate_of(params, index, time, face_psnr(seen, synth, mask),
                                 int(mask.sum()), solves)  # fmt: skip

    def _final_rendering(self) -> tuple[np.ndarray, np.ndarray, tuple[int, int]]:
        """The full-size rendering a frame's estimate ends with, at the integer FAPs the
        estimate gives, of the window around the face (:meth:`_render_window` at factor 1):
        its image ``(h, w, 3) float32``, triangle indices ``(h, w)`` and top-left pixel ``(top,
        left)`` in the frame; every face pixel lies inside."""
        return self._render_window(1)

    def _lit_frame(self) -> bool:
        """Whether the frame being estimated shows a lit face (:data:`LIT_SHARE`), by the face
        pixels of the last solve's rendering."""
        shown = self._last_faces[self._last_faces >= 0]
        return shown.size > 0 and float(self.geometry.lit[shown].mean()) >= LIT_SHARE

    @contextmanager
    def _refining(self, lit: bool) -> Iterator[None]:
        """Within it, the search after the solves takes the FAPs of ``lit_refine`` as well when
        ``lit``."""
        refined = self.refined
        if lit:
            self.refined = self._lit_refined
        try:
            yield
        finally:
            self.refined = refined

    def _search_from_neutral(self, frame: np.ndarray) -> None:
        """The first frame's last look at the FAPs :attr:`refined` (the eyelids): searched once
        more over their whole range from neutral, against the camera ``frame`` ``(H, W, 3)
        float32``, and kept there if the face matches better.

        A search made while the head's pose is still far off can close a lid past its range,
        where it folds under the other lid; the solves that then find the pose carry it along,
        and a search from there meets no better match on its way back (seed 26 of
        :func:`~vtts.analysis.synthetic.random_truth`: the left lid 1,093 units too far
        closed, 32 dB)."""
        if not self.refined:
            return
        state, before = self._state(), self._mismatch(frame)
        for fap in self.refined:
            self.params[fap - 1] = 0.0
        self._refine(frame, FIRST_REFINE_STEPS)
        if self._mismatch(frame) >= before:
            self._set_state(state)

    def _settle(self, frame: np.ndarray, index: int, then: Callable[[], object] | None = None):
        """The estimate as a FAP stream carries it — integer FAPs — with the FAPs :attr:`refined`
        searched on the rendered image (against the camera ``frame`` ``(H, W, 3)``) from there
        (but the eyelids on a frame whose eyes the iris model observed);
        ``then`` is called at those parameters. Returns the integer parameters ``(N_PARAMS,)``
        and what ``then`` returned; the estimator keeps its unrounded values (the searched FAPs
        as the search left them), and frame ``index`` joins the motion history."""
        params = self.params.copy()
        for u in self.unknowns:
            if not isinstance(u, str):
                params[u - 1] = np.round(params[u - 1]) + 0.0  # no negative zeros
        kept, self.params = self.params, params
        refined = self.refined
        if self._observed is not None and self._eyes is not None:
            # the iris model observed the lids: they are not searched on the image
            self.refined = tuple(f for f in refined if f not in EYELIDS)
        try:
            self._refine(frame)
            result = then() if then is not None else None
        finally:
            for fap in self.refined:
                kept[fap - 1] = self.params[fap - 1]
            self.refined = refined
            params, self.params = self.params, kept
        self._history = [*self._history[-1:], (index, self.params.copy(), self.translation.copy())]
        return params, result

    def _estimate_of(self, params: np.ndarray, index: int, time: float, psnr: float,
                     pixels: int, solves: int) -> FrameEstimate:  # fmt: skip
        """Frame ``index``'s :class:`FrameEstimate`: ``params`` as :meth:`_settle` gave them,
        with the current translation and light, its face ``psnr`` over ``pixels`` face pixels,
        after ``solves`` linear solves."""
        return FrameEstimate(
            index=index,
            time=time,
            params=params,
            translation=self.translation.copy(),
            gain=self.gain.copy(),
            offset=self.offset.copy(),
            psnr=psnr,
            face_pixels=pixels,
            iterations=solves,
            landmark_px=self.landmark_error(),
        )

    def between_frames(self) -> None:
        """Work for the next frame that can be done before it arrives, once this frame's
        estimate is out (nothing here; :class:`~vtts.analysis.tracker.Tracker` renders)."""

    def _mismatch(self, frame: np.ndarray) -> float:
        """Mean squared luminance difference over the face area between the camera ``frame``
        ``(H, W, 3) float32`` and the model at the current estimate (one full-size rendering)."""
        image, ids = self.render(1)
        diff = (frame - (image * self.gain + self.offset)) @ LUMA
        face = ids >= 0
        return float(np.mean(diff[face] ** 2)) if face.any() else math.inf

    def _state(self) -> tuple[np.ndarray, ...]:
        """The current estimate: parameters, translation, gain and offset (copies)."""
        return tuple(a.copy() for a in (self.params, self.translation, self.gain, self.offset))

    def _set_state(self, state: tuple[np.ndarray, ...]) -> None:
        for target, value in zip(
            (self.params, self.translation, self.gain, self.offset), state, strict=True
        ):
            target[:] = value

    def _descend(
        self,
        pyramid: dict[int, np.ndarray],
        levels: Sequence[Level] | None = None,
        tolerance: float | None = None,
        halved_stop: float | None = None,
    ) -> tuple[int, bool]:
        """One pass down the pyramid (or ``levels`` of it), coarse to fine, with the camera
        frame smoothed at each level's factor in ``pyramid``; returns the linear solves made and
        whether the finest level's last one moved no unknown by ``tolerance`` (pixels of the
        level; default :attr:`tolerance`) or more. ``halved_stop``: with robust matching, no
        halved step that moves the image less than this (pixels of the level) is rendered
        (:data:`HALVED_STOP_PX`; None: every halving is)."""
        tolerance = self.tolerance if tolerance is None else tolerance
        solves, step = 0, math.inf
        for lv in self.pyramid if levels is None else levels:
            self._last_step = None  # energies of different levels do not compare
            self._stalled = False
            if lv.factor > 1 and self._history and self._too_small(self._shown, lv.factor):
                # as at the last frame's estimate: not rendered, the finer levels solve
                solves, step = solves + 1, 0.0
                continue
            for _ in range(lv.iterations):
                step = self._solve(pyramid[lv.factor], lv, halved_stop)
                solves += 1
                if step < tolerance or self._stalled:
                    break
        return solves, step < tolerance

    def _extrapolate(self, index: int) -> None:
        """Start frame ``index`` with the unknowns :attr:`predicted` carried on at the speed
        (per frame) they had between the last two estimates: the pyramid then has less way to
        go."""
        if len(self._history) < 2:
            return
        (i0, p0, t0), (i1, p1, t1) = self._history
        if not (i0 < i1 < index or i0 > i1 > index):  # forwards, or backwards from an anchor
            return
        ratio = (index - i1) / (i1 - i0)
        for u in self.predicted:
            if isinstance(u, str):
                axis = TRANSLATION.index(u)
                self.translation[axis] += ratio * (t1[axis] - t0[axis])
            else:
                self.params[u - 1] += ratio * (p1[u - 1] - p0[u - 1])

    def _solve(
        self, camera_image: np.ndarray, lv: Level, halved_stop: float | None = None
    ) -> float:
        """One Gauss–Newton step at one level; returns how far (pixels of that level) the step
        moved the image of the unknown that moved most. ``halved_stop``: as :meth:`_descend`'s."""
        cam = self._levels[lv.factor][0]
        image, ids, (top, left) = self._render_window(lv.factor)
        self._last_faces = ids
        if lv.factor == 1:
            self._rendered = [*self._rendered[-1:], (self.params.copy(), self.translation.copy(),
                                                     (image, ids, (top, left)))]  # fmt: skip
        camera_image = camera_image[top : top + ids.shape[0], left : left + ids.shape[1]]
        raw = smooth(image, self.sigma)
        gain, offset = self.gain.astype(np.float32), self.offset.astype(np.float32)
        # pixels within the model's outline: at the outline the synthetic background (which a
        # camera never shows) and antialiasing would read as motion
        rows, cols = np.nonzero(_inside(ids))
        if rows.size < self._fewest and lv.factor > 1:
            return 0.0  # too small a face for this level (QCIF at 1/4): the finer levels solve
        if rows.size < self._fewest:
            raise VttsError(
                f"the model covers only {rows.size} pixels at 1/{lv.factor} size: it is out of "
                "view (check --camera and the first frame)"
            )
        s_p = raw[rows, cols]
        r_p = camera_image[rows, cols] - (s_p * gain + offset)  # (n, 3)
        # a step that made the match worse is taken back by half (at most three times in a row)
        # before the next linear solve: the linear model can be wrong where shading or
        # occlusion, not texture motion, dominates what an unknown does to the image
        energy = float(np.mean(np.minimum((r_p @ LUMA) ** 2, TRUNCATE**2)))
        term = self.landmark_term()
        if term is not None:  # the landmarks' cost, per pixel of the level as the match's
            energy += term.cost(term.values0, lv.factor) / rows.size
        last = self._last_step
        improved = math.inf if last is None else (last.energy - energy) / max(last.energy, 1e-12)
        if self.robust and last is not None and self._settled(improved, last):
            self._last_step, self._stalled = None, True
            return 0.0
        if last is not None and energy > last.energy and last.halvings < 3:
            if self.robust and halved_stop is not None and last.reach / 2 < halved_stop:
                self._apply(-last.delta)  # back where the match was best
                self._last_step, self._stalled = None, True
                return 0.0
            half = last.delta / 2
            self._apply(-half)
            self._last_step = replace(last, delta=half, halvings=last.halvings + 1,
                                      reach=last.reach / 2)  # fmt: skip
            return last.reach / 2
        # gradients of the camera frame and of gain · synthetic + offset
        gy_p, gx_p = gradients_at(camera_image, raw, rows, cols, gain)
        # Equation 17 on luminance: drop pixels whose displacement estimate exceeds G
        ry, gxy, gyy = r_p @ LUMA, gx_p @ LUMA, gy_p @ LUMA
        d = np.abs(ry) / np.sqrt(gxy * gxy + gyy * gyy + 1e-6)
        keep = d <= lv.g
        rows, cols = rows[keep], cols[keep]
        gx_p, gy_p, r_p, s_p = gx_p[keep], gy_p[keep], r_p[keep], s_p[keep]
        tri = ids[rows, cols]
        pix = np.stack([cols + (left + 0.5), rows + (top + 0.5)], axis=1)  # pixels of the level
        _, _, du, dv = self._image_motion(pix, tri, cam)
        k = du.shape[1]
        # an unknown whose motion covers too few pixels at this level is held
        speed = np.hypot(du, dv)
        support = (speed > 0.2 * speed.max(axis=0, initial=0.0)).sum(axis=0)
        held = (support < lv.support) | self._searched_columns
        du[:, held] = 0.0
        dv[:, held] = 0.0
        weights = None
        if self.robust:
            # Tukey's biweight on the luminance residual: pixels the model cannot explain
            # (background at the outline, teeth in an open mouth, a hand) pull less and less,
            # and not at all beyond ROBUST_LIMIT gray levels
            u = np.minimum(np.abs(ry[keep]) / ROBUST_LIMIT, 1.0)
            weights = (1.0 - u * u) ** 2
        ata, atb = normal_equations(
            du, dv, gx_p, gy_p, r_p, s_p if self.illumination else None, weights
        )
        if term is not None:
            # every unknown the landmarks see, the photometric terms' too-small ones included
            lm_ata, lm_atb = term.normal_equations(term.values0, lv.factor,
                                                   held=self._searched_columns)  # fmt: skip
            ata[:k, :k] += lm_ata
            atb[:k] += lm_atb
        delta = least_squares(ata, atb)
        # the linearization holds for small motion: no unknown may move any of its pixels
        # further than the level's step limit in one solve
        reach = speed.max(axis=0, initial=0.0) * np.abs(delta[:k])  # held columns: delta 0
        delta[:k] *= np.minimum(1.0, lv.limit / np.maximum(reach, 1e-12))
        moved = float(np.minimum(reach, lv.limit).max(initial=0.0))
        self._apply(delta)
        self._last_step = _Step(energy, delta, 0, moved, improved)
        return moved

    def _too_small(self, faces: np.ndarray | None, factor: int) -> bool:
        """Whether the face the full-size triangle indices ``faces`` ``(H, W)`` show (the last
        frame's final rendering, :attr:`_shown`) covers too few pixels for a solve at pyramid
        ``factor``, counted as :meth:`_solve` counts them at that level: fewer than four per
        unknown. A frame after the first skips such a level without rendering it (Carphone's
        QCIF face at 1/4 is on the edge)."""
        if faces is None:
            return False
        return int(_inside(self._at_level(faces, factor)).sum()) < self._fewest

    def _settled(self, improved: float, last: _Step) -> bool:
        """Whether a level ends at a rendering that shows the ``last`` step lowered the match
        by the share ``improved`` (negative: made it worse) (:data:`SETTLED_GAIN`,
        :data:`STALL_GAIN`); a step that made the match worse after one that gained little is
        taken back here."""
        if improved >= 0:
            return SETTLED_GAIN is not None and improved < SETTLED_GAIN
        if STALL_GAIN is None or last.halvings or last.gain >= STALL_GAIN:
            return False
        self._apply(-last.delta)  # back where the match was best
        return True

    def _image_motion(self, pix: np.ndarray, tri: np.ndarray, cam: Camera):
        """What the unknowns do at the pixel centres ``pix`` ``(N, 2)`` (pixels of ``cam``'s
        image) showing the triangles ``tri`` ``(N,)`` (indices into ``geometry.faces``), at the
        current estimate: each pixel's surface point in camera coordinates ``(N, 3)``, its 3D
        motion per unit of each unknown in camera axes ``(N, 3, K)`` (Equation 9: the vertices'
        motion combined by the barycentric coordinates), and the image motion it makes, ``du``
        and ``dv`` ``(N, K)`` pixels per unit (Equations 14–15) — all ``float32``: the image
        terms carry no more than single precision."""
        positions = self.geometry.positions(self.params, self.translation)
        verts = self.geometry.faces[tri]  # (N, 3)
        lam, point = ray_barycentrics(pix, cam, positions[verts])
        uniq, inverse = _used_vertices(verts, len(positions))
        jac = self.geometry.jacobian(self.params, self.translation, uniq)  # (U, 3, K) world
        jac = np.linalg.inv(cam.pose)[:3, :3] @ jac  # camera axes (U, 3, K)
        jac = jac.astype(np.float32)
        # each pixel's three vertices weighted by its barycentric coordinates: a sparse (N, U)
        # matrix times the vertices' motion (U, 3 K), without gathering (N, 3, 3, K)
        (n, u), k = (len(verts), len(uniq)), jac.shape[-1]  # no pixel: n = u = 0
        weights = csr_matrix((lam.astype(np.float32).ravel(), inverse.ravel(),
                              np.arange(0, 3 * n + 1, 3)), shape=(n, u))  # fmt: skip
        motion = np.asarray(weights @ jac.reshape(u, 3 * k)).reshape(n, 3, k)
        point = point.astype(np.float32)
        depth = -point[:, 2:3]  # distance along the view axis, > 0
        x_rel = (pix[:, 0:1] - cam.cx).astype(np.float32)
        y_rel = (cam.cy - pix[:, 1:2]).astype(np.float32)
        du = (np.float32(cam.fx) * motion[:, 0] + x_rel * motion[:, 2]) / depth
        dv = -(np.float32(cam.fy) * motion[:, 1] + y_rel * motion[:, 2]) / depth
        return point, motion, du, dv

    def _refine(self, frame: np.ndarray, steps: Sequence[int] = REFINE_STEPS) -> float:
        """Refine the (integer) values of the FAPs :attr:`refined` on the rendered image: a
        pattern search with ``steps`` (:data:`REFINE_STEPS`), each taken (up or down, at most
        :data:`REFINE_MOVES` times in a row) while it improves the luminance match (sum of
        squared differences after gain and offset) with the camera ``frame`` ``(H, W, 3)
        float32`` over the pixels where the FAP's motion shows (:meth:`_window`).

        The Gauss–Newton steps converge slowly on the eyelids and can stop tens of units off:
        the rendered edge of an eyelid moves in whole pixels, which the optical-flow model
        (smooth image, sub-pixel motion) does not describe. The rendered image does.

        FAPs whose windows do not overlap (the left and the right eyelid) are searched side by
        side: each rendering tries a move of each of them, and each keeps its own move by the
        match in its own window, exactly as if it were searched alone.

        A FAP with steps of its own in :attr:`search_steps` takes those instead of the
        ordinary ``steps`` (:data:`REFINE_STEPS`), and is searched beside FAPs with the same
        steps only.

        Returns how far (units) the FAP that moved most was moved."""
        own = {fap: self.search_steps.get(fap, steps) if steps == REFINE_STEPS else steps
               for fap in self.refined}  # fmt: skip
        windows = {
            fap: self._window(fap, max(100.0, REFINE_MOVES * sum(own[fap]))) for fap in self.refined
        }
        groups: list[list[int]] = []
        for fap, win in windows.items():
            if win is None:
                continue
            for group in groups:
                if own[group[0]] == own[fap] and not any(
                    _overlap(win, windows[other]) for other in group
                ):
                    group.append(fap)
                    break
            else:
                groups.append([fap])
        before = self.params.copy()
        for group in groups:
            self._search(frame, {fap: windows[fap] for fap in group}, own[group[0]])
        return float(np.abs(self.params - before).max(initial=0.0))

    def _search(
        self, frame: np.ndarray, windows: dict[int, tuple[slice, slice]], steps: Sequence[int]
    ) -> None:
        """The pattern search of :meth:`_refine` for FAPs whose ``windows`` do not overlap, all
        in one rendering of the box around them."""
        boxes = list(windows.values())
        ys, xs = (
            slice(min(b[i].start for b in boxes), max(b[i].stop for b in boxes)) for i in (0, 1)
        )
        c = self.camera
        view = (
            replace(c, cx=c.cx - xs.start, cy=c.cy - ys.start),
            (xs.stop - xs.start, ys.stop - ys.start),
        )
        luma = (frame[ys, xs] @ LUMA).astype(np.float32)
        # each FAP's own window within the box
        local = {
            fap: (
                slice(wy.start - ys.start, wy.stop - ys.start),
                slice(wx.start - xs.start, wx.stop - xs.start),
            )
            for fap, (wy, wx) in windows.items()
        }

        def mismatch() -> dict[int, float]:
            synth = (self._synthesize(*view).astype(np.float32) * self.gain + self.offset) @ LUMA
            synth -= luma
            return {fap: float(np.sum(synth[win] ** 2)) for fap, win in local.items()}

        best = mismatch()
        for step in steps:
            # FAP -> moves left at this step (0: neither way improves any more)
            left = dict.fromkeys(windows, REFINE_MOVES)
            direction = dict.fromkeys(windows, 0)  # 0: try up, then down
            while any(left.values()):
                trying = {f: step if direction[f] >= 0 else -step for f in windows if left[f]}
                for fap, change in list(trying.items()):
                    lo, hi = self.bounds.get(fap, (-math.inf, math.inf))
                    value = self.params[fap - 1] + change
                    if (value < lo and change < 0) or (value > hi and change > 0):
                        del trying[fap]  # further out of bounds: as if it did not improve
                        if direction[fap] == 0:
                            direction[fap] = -1
                        else:
                            left[fap] = 0
                if not trying:
                    continue
                for fap, change in trying.items():
                    self.params[fap - 1] += change
                value = mismatch()
                for fap, change in trying.items():
                    if value[fap] < best[fap]:
                        best[fap] = value[fap]
                        left[fap] -= 1
                        direction[fap] = 1 if change > 0 else -1  # keep going this way
                        continue
                    self.params[fap - 1] -= change
                    if direction[fap] == 0:
                        direction[fap] = -1  # up did not help: try down next
                    else:
                        left[fap] = 0  # the last way taken (or both) no longer improves

    def _window(self, fap: int, reach: float = 100.0) -> tuple[slice, slice] | None:
        """The rows and columns of the full-size image where ``fap``'s motion shows: the box
        around the vertices it moves (at the current estimate, opened and closed by ``reach``
        units), widened by :data:`REFINE_MARGIN`. None when it moves nothing in view."""
        probe = self.params.copy()
        probe[fap - 1] -= reach
        lo = self.geometry.positions(probe, self.translation)
        probe[fap - 1] += 2 * reach
        hi = self.geometry.positions(probe, self.translation)
        moved = np.any(np.abs(hi - lo) > 0, axis=1)
        if not moved.any():
            return None
        w, h = self.size
        xy = self.camera.project(np.concatenate([lo[moved], hi[moved]]))
        x0, y0 = np.floor(xy.min(axis=0)).astype(int) - REFINE_MARGIN
        x1, y1 = np.ceil(xy.max(axis=0)).astype(int) + REFINE_MARGIN
        x0, y0, x1, y1 = max(x0, 0), max(y0, 0), min(x1, w), min(y1, h)
        if x1 <= x0 or y1 <= y0:
            return None
        # whole blocks of 16 pixels: never smaller than the renderer's smallest image
        cols = _blocks(x0, x1, w)
        rows = _blocks(y0, y1, h)
        return slice(*rows), slice(*cols)

    def _apply(self, delta: np.ndarray) -> None:
        """Add a change of the unknowns (then gains and offsets, if estimated)."""
        k = len(self.unknowns)
        for j, u in enumerate(self.unknowns):
            if isinstance(u, str):
                self.translation[TRANSLATION.index(u)] += delta[j]
            else:
                self.params[u - 1] += delta[j]
        if self.illumination:
            self.gain += delta[k : k + 3]
            self.offset += delta[k + 3 : k + 6]


@dataclass
class _Step:
    """The last change made at a level: the match before it (``energy``), the change, how
    often it has been halved, how far (pixels) it moved the image of the unknown that moved
    most, and the share by which the step before it lowered the match (``gain``; infinite for
    a level's first)."""

    energy: float
    delta: np.ndarray
    halvings: int
    reach: float
    gain: float = math.inf


def analyze(
    frames: Iterable[np.ndarray],
    model: FaceModel,
    *,
    fps: float,
    step: int = 1,
    camera: Camera | None = None,
    unknowns: Sequence[int | str] = DEFAULT_UNKNOWNS,
    progress: Callable[[int], None] | None = None,
    **options,
) -> Analysis:
    """Estimate the parameters of every ``step``-th frame of ``frames`` (each ``(H, W, 3)
    uint8`` RGB, all the same size) of a video at ``fps`` frames per second. ``options`` go to
    :class:`Estimator`. ``progress`` is called with the frame index after each estimate."""
    if not (math.isfinite(fps) and fps > 0):
        raise VttsError(f"fps must be a positive number, got {fps}")
    if step < 1:
        raise VttsError(f"step must be at least 1, got {step}")
    estimator: Estimator | None = None
    out: list[FrameEstimate] = []
    for i, frame in enumerate(frames):
        if i % step:
            continue
        if estimator is None:
            h, w = frame.shape[:2]
            estimator = Estimator(model, size=(w, h), camera=camera, unknowns=unknowns, **options)
        out.append(estimator.estimate(frame, i, i / fps))
        if progress is not None:
            progress(i)
    if estimator is None:
        raise VttsError("the video has no frames")
    return Analysis(out, estimator.unknowns, fps / step, estimator.camera, model.name)


def face_psnr(frame: np.ndarray, synthetic: np.ndarray, mask: np.ndarray) -> float:
    """Luminance PSNR (dB) of two ``(H, W, 3)`` images (0–255) over the ``(H, W)`` ``mask``;
    ``inf`` when they agree there exactly."""
    if not mask.any():
        return float("nan")
    diff = (np.asarray(frame, np.float64) - np.asarray(synthetic, np.float64)) @ LUMA
    mse = float(np.mean(diff[mask] ** 2))
    return float("inf") if mse == 0 else 10 * math.log10(255.0**2 / mse)


# ---- helpers -----------------------------------------------------------------------------------


def _check_unknowns(unknowns: Sequence[int | str]) -> tuple[int | str, ...]:
    out: list[int | str] = []
    for u in unknowns:
        if isinstance(u, str):
            if u not in TRANSLATION:
                raise VttsError(f"unknown {u!r}: the non-FAP unknowns are tx, ty and tz")
        elif not (isinstance(u, int | np.integer) and int(u) in ESTIMABLE):
            raise VttsError(
                f"FAP {u!r} cannot be estimated: FAPs {ESTIMABLE[0]}–{ESTIMABLE[-1]} can"
            )
        else:
            u = int(u)
        if u in out:
            raise VttsError(f"{u} is listed twice among the unknowns")
        out.append(u)
    if not out:
        raise VttsError("nothing to estimate: the list of unknowns is empty")
    return tuple(out)


def _face_numbers(renderer: FaceRenderer, geometry: HeadGeometry) -> np.ndarray:
    """Renderer triangle number -> index into ``geometry.faces`` (−1: not in the geometry):
    both triangulate the same IndexedFaceSets, each listing them in its own order."""
    firsts: dict[int, list[int]] = {}
    total = 0
    for node, first, count in renderer.triangle_sets:
        firsts.setdefault(id(node), []).append(first)
        total = max(total, first + count)
    out = np.full(total, -1, dtype=np.int64)
    for s in geometry.shapes:
        queue = firsts.get(id(s.node))
        if not queue:
            raise VttsError(f"{geometry.model.name}: the renderer does not draw every face set")
        first = queue.pop(0)
        start = s.first_face
        out[first : first + len(s.mesh.faces)] = np.arange(start, start + len(s.mesh.faces))
    return out


def _used_vertices(verts: np.ndarray, n_vertices: int) -> tuple[np.ndarray, np.ndarray]:
    """``np.unique(verts, return_inverse=True)`` for vertex indices ``verts`` (any shape) below
    ``n_vertices``: the vertices used, ascending ``(U,)``, and where each entry of ``verts``
    lies among them (``verts``' shape) — by marking, not sorting."""
    used = np.zeros(n_vertices, dtype=bool)
    used[verts] = True
    rank = np.cumsum(used) - 1
    return np.flatnonzero(used), rank[verts]


def _overlap(a: tuple[slice, slice], b: tuple[slice, slice]) -> bool:
    """Whether two (rows, columns) windows share a pixel."""
    return all(p.start < q.stop and q.start < p.stop for p, q in zip(a, b, strict=True))


def _blocks(lo: int, hi: int, n: int, block: int = 16) -> tuple[int, int]:
    """``[lo, hi)`` widened to a multiple of ``block`` (at most ``n``) that stays within
    ``[0, n)``."""
    size = min(n, -(-(hi - lo) // block) * block)
    start = min(max(0, lo - (size - (hi - lo)) // 2), n - size)
    return start, start + size


def _inside(ids: np.ndarray) -> np.ndarray:
    """The pixels ``(h, w) bool`` of the face indices ``ids`` ``(h, w)`` that a solve reads:
    within the model's outline by :data:`EDGE` pixels."""
    return binary_erosion(ids >= 0, iterations=EDGE)


def _bounds(mask: np.ndarray) -> tuple[tuple[int, int], tuple[int, int]] | None:
    """The rows ``[top, bottom)`` and columns ``[left, right)`` that hold every True pixel of
    ``mask`` ``(H, W)``; None when it has none."""
    rows, cols = np.flatnonzero(mask.any(axis=1)), np.flatnonzero(mask.any(axis=0))
    if rows.size == 0:
        return None
    return (int(rows[0]), int(rows[-1]) + 1), (int(cols[0]), int(cols[-1]) + 1)


def _clear(inner: tuple[tuple[int, int], tuple[int, int]], box: tuple[int, int, int, int],
           size: tuple[int, int], margin: int) -> bool:  # fmt: skip
    """Whether the rows and columns ``inner`` (:func:`_bounds`, in the pixels of the window
    ``box`` ``(x0, y0, width, height)`` of a frame of ``size`` (W, H)) keep ``margin`` pixels
    from every side of the window that is not a side of the frame."""
    (i0, i1), (j0, j1) = inner
    x0, y0, ww, wh = box
    w, h = size
    return ((y0 == 0 or i0 >= margin) and (y0 + wh == h or i1 <= wh - margin)
            and (x0 == 0 or j0 >= margin) and (x0 + ww == w or j1 <= ww - margin))  # fmt: skip


def _window_of(inner: tuple[tuple[int, int], tuple[int, int]], at: tuple[int, int],
               size: tuple[int, int], margin: int, align: int,
               last: tuple[int, int, int, int] | None) -> tuple[int, int, int, int]:  # fmt: skip
    """The window ``(x0, y0, width, height)`` of a frame of ``size`` (W, H) that holds the
    rows and columns ``inner`` (:func:`_bounds`, of an image whose top-left pixel is the
    frame's ``at`` (x, y)) with ``margin`` pixels on each side: of the ``last`` window's size
    where that fits with at most 64 pixels to spare (the renderer's targets are then not made
    anew), else of the size rounded up to 32 pixels, and widened at the top and the left to a
    corner that is a multiple of ``align``."""
    (i0, i1), (j0, j1) = inner
    lo = (at[0] + j0 - margin, at[1] + i0 - margin)
    need = (j1 - j0 + 2 * margin, i1 - i0 + 2 * margin)
    out = []
    for axis in (0, 1):
        n = size[axis]
        have = last[2 + axis] if last is not None else 0
        side = have if need[axis] <= have <= need[axis] + 64 else -(-need[axis] // 32) * 32
        side = min(side, n)
        start = min(max(0, lo[axis] - (side - need[axis]) // 2), n - side)
        end = start + side
        start -= start % align
        out.append((start, end - start))
    (x0, ww), (y0, wh) = out
    return x0, y0, ww, wh


def _window_margin(sigma: float) -> int:
    """Pixels (of a level) around the face that a solve's numbers depend on: the Gaussian
    filter's radius (:func:`~vtts.analysis.solve.smooth`, scipy's ``int(truncate · σ + 0.5)``),
    one more for the central differences of the gradients, and one to spare."""
    return int(SMOOTH_REACH * sigma + 0.5) + 2
