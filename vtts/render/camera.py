"""The pinhole camera of Eisert & Girod (their Equation 3) and automatic framing of heads.

Equation 3 maps a point (x, y, z) in camera coordinates to pixel coordinates

    X = X0 − fx · x / z,    Y = Y0 − fy · y / z

with the camera looking along +z, y up and x to the left, X to the right and Y down the image.
That is the standard pinhole model with intrinsics (fx, fy, cx = X0, cy = Y0) measured in pixels
from the top-left corner, which is how pyrender's IntrinsicsCamera takes them.

A VRML97 ``Viewpoint`` is such a camera too (:meth:`Camera.from_viewpoint`, and the inverse
:func:`viewpoint_fields`): placed at ``position``, turned by ``orientation`` from the default view
along −z with +y up, with ``fieldOfView`` the angle spanned by the smaller of the image's width and
height and the principal point in the middle of the image.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np

from vtts.errors import RenderError
from vtts.vrml import Node, Scene, rotation_matrix

#: VRML97's default Viewpoint ``fieldOfView`` (radians, π/4).
DEFAULT_FIELD_OF_VIEW = 0.785398


#: The largest focal length or principal-point offset a camera takes, in pixels (a focal length
#: of a million pixels is a 0.03° field of view on a 512-pixel image).
MAX_PIXELS = 1e6


@dataclass
class Camera:
    """Pinhole intrinsics (pixels) and the camera's pose in the world.

    ``pose`` is the ``(4, 4)`` camera-to-world matrix in the OpenGL convention (the camera looks
    along its −z axis, y up). ``znear``/``zfar`` bound the depth range (model units).
    ``placed`` is False for a camera given by its intrinsics alone (``--camera fx,fy,X0,Y0``):
    the renderer then puts it in front of the heads, far enough for them to fill its view.
    """

    fx: float
    fy: float
    cx: float
    cy: float
    pose: np.ndarray = field(default_factory=lambda: np.eye(4))
    znear: float = 0.01
    zfar: float = 100.0
    placed: bool = True

    def scaled(self, factor: float) -> Camera:
        """The camera of this one's image subsampled by ``factor`` (pixel edges at integers;
        below 1: enlarged)."""
        return replace(self, fx=self.fx / factor, fy=self.fy / factor, cx=self.cx / factor,
                       cy=self.cy / factor)  # fmt: skip

    def __post_init__(self) -> None:
        for name in ("fx", "fy"):
            v = getattr(self, name)
            if not (math.isfinite(v) and 0 < v <= MAX_PIXELS):
                raise RenderError(
                    f"camera {name} must be a positive number of pixels up to {MAX_PIXELS:g}, "
                    f"got {v}"
                )
        for name in ("cx", "cy"):
            v = getattr(self, name)
            if not (math.isfinite(v) and abs(v) <= MAX_PIXELS):
                raise RenderError(
                    f"camera {name} must be a number of pixels within ±{MAX_PIXELS:g}, got {v}"
                )
        self.pose = np.asarray(self.pose, dtype=np.float64).reshape(4, 4)

    @classmethod
    def eisert_girod(cls, fx: float, fy: float, x0: float, y0: float, **kw) -> Camera:
        """The camera of Eisert–Girod Equation 3 (``X0``, ``Y0`` in pixels from the top left)."""
        return cls(fx, fy, x0, y0, **kw)

    @classmethod
    def parse(cls, text: str) -> Camera:
        """``"fx,fy,X0,Y0"`` as given on the command line (``--camera 400,400,176,144``)."""
        parts = text.replace(" ", "").split(",")
        try:
            values = [float(p) for p in parts]
        except ValueError:
            values = []
        if len(values) != 4:
            raise RenderError(f"--camera takes four numbers fx,fy,X0,Y0, got {text!r}")
        return cls.eisert_girod(*values, placed=False)

    @classmethod
    def from_viewpoint(
        cls,
        node: Node,
        size: tuple[int, int],
        world_matrix: np.ndarray | None = None,
        *,
        znear: float = 0.01,
        zfar: float = 100.0,
    ) -> Camera:
        """The camera of a VRML97 ``Viewpoint`` node for images of ``size`` (W, H) pixels.

        ``world_matrix`` ``(4, 4)`` is the transform of the Viewpoint's coordinate system (the
        Transforms above it, e.g. from :func:`find_viewpoint`; default identity). Its scale
        moves the position, as it moves everything, but does not scale the camera (a pinhole
        has none). The focal length is ``f = (min(W, H) / 2) / tan(fieldOfView / 2)`` pixels
        for both axes (VRML97: the field of view spans the smaller side of the image) and the
        principal point ``(W / 2, H / 2)``. ``znear``/``zfar`` bound the depth range (world
        units)."""
        node = node.expand()
        if node.type.name != "Viewpoint":
            raise RenderError(f"a camera comes from a Viewpoint node, got a {node.type.name}")
        w, h = (int(v) for v in size)
        fov = float(node["fieldOfView"])
        if not (math.isfinite(fov) and 0 < fov < math.pi):
            label = f"Viewpoint {node.name}" if node.name else "a Viewpoint's"
            raise RenderError(f"{label} fieldOfView must lie between 0 and π radians, got {fov}")
        f = (min(w, h) / 2) / math.tan(fov / 2)
        local = np.eye(4)
        local[:3, :3] = rotation_matrix(node["orientation"])
        local[:3, 3] = node["position"]
        if world_matrix is not None:
            local = np.asarray(world_matrix, dtype=np.float64).reshape(4, 4) @ local
        return cls(f, f, w / 2, h / 2, _rigid(local), znear=znear, zfar=zfar)

    def project(self, points: np.ndarray) -> np.ndarray:
        """Pixel coordinates ``(n, 2)`` (X right, Y down) of world points ``(n, 3)``."""
        p = np.c_[np.asarray(points, float), np.ones(len(points))] @ np.linalg.inv(self.pose).T
        x, y, z = p[:, 0], p[:, 1], p[:, 2]
        return np.stack([self.cx + self.fx * x / -z, self.cy - self.fy * y / -z], axis=1)


def look_at(eye: np.ndarray, target: np.ndarray, up=(0.0, 1.0, 0.0)) -> np.ndarray:
    """``(4, 4)`` camera-to-world pose of a camera at ``eye`` looking at ``target``."""
    eye, target, up = (np.asarray(v, dtype=np.float64) for v in (eye, target, up))
    back = eye - target
    back /= np.linalg.norm(back)
    right = np.cross(up, back)
    right /= np.linalg.norm(right)
    true_up = np.cross(back, right)
    m = np.eye(4)
    m[:3, 0], m[:3, 1], m[:3, 2], m[:3, 3] = right, true_up, back, eye
    return m


def frame_bounds(
    lo: np.ndarray,
    hi: np.ndarray,
    size: tuple[int, int],
    *,
    fill: float = 0.8,
    fovy_deg: float = 25,
    intrinsics: Camera | None = None,
) -> Camera:
    """A camera on +z looking at the box ``lo``–``hi`` (world units) so that it fills ``fill`` of
    the image's height or width, whichever is tighter: with a vertical field of view of
    ``fovy_deg`` and the principal point in the middle, or with the focal lengths and principal
    point of ``intrinsics``."""
    w, h = size
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    centre = (lo + hi) / 2
    extent = np.maximum(hi - lo, 1e-6)
    if intrinsics is None:
        f = (h / 2) / math.tan(math.radians(fovy_deg) / 2)
        fx, fy, cx, cy = f, f, w / 2, h / 2
    else:
        fx, fy, cx, cy = intrinsics.fx, intrinsics.fy, intrinsics.cx, intrinsics.cy
    dist_h = (extent[1] / 2) / (fill * (h / 2) / fy)
    dist_w = (extent[0] / 2) / (fill * (w / 2) / fx)
    dist = max(dist_h, dist_w) + extent[2] / 2
    eye = centre + np.array([0.0, 0.0, dist])
    return Camera(fx, fy, cx, cy, look_at(eye, centre), znear=dist / 50, zfar=dist * 10)


def _rigid(matrix: np.ndarray) -> np.ndarray:
    """The rotation and translation of an affine ``(4, 4)`` matrix, without its scale (the
    nearest rotation to its linear part, by polar decomposition)."""
    m = np.asarray(matrix, dtype=np.float64).reshape(4, 4)
    u, _, vt = np.linalg.svd(m[:3, :3])
    r = u @ vt
    if np.linalg.det(r) < 0:  # a mirroring transform: keep a right-handed camera
        r = u @ np.diag([1.0, 1.0, -1.0]) @ vt
    out = np.eye(4)
    out[:3, :3], out[:3, 3] = r, m[:3, 3]
    return out


def viewpoints(scene: Scene) -> list[tuple[Node, np.ndarray]]:
    """Every ``Viewpoint`` the scene graph reaches, in file order, with the ``(4, 4)`` transform
    of its coordinate system (the Transforms above it)."""
    return [(n, m) for n, m, _ in scene.traverse() if n.type.name == "Viewpoint"]


def find_viewpoint(scene: Scene, name: str) -> tuple[Node, np.ndarray]:
    """The ``Viewpoint`` DEFed as ``name`` and the ``(4, 4)`` world transform of its coordinate
    system (its first instance when it is USEd several times). A RenderError lists the named
    Viewpoints the scene has when none is called ``name``."""
    found = viewpoints(scene)
    for node, matrix in found:
        if node.name == name:
            return node, matrix
    names = list(dict.fromkeys(n.name for n, _ in found if n.name))
    where = f" of {scene.path.name}" if scene.path is not None else ""
    if names:
        have = f"its Viewpoints are {', '.join(names)}"
    elif found:
        have = f"its {len(found)} Viewpoint{'s' if len(found) > 1 else ''} have no DEF name"
    else:
        have = "it has no Viewpoint"
    raise RenderError(f"no Viewpoint named {name!r} in the scene{where}: {have}")


def viewpoint_fields(camera: Camera, size: tuple[int, int]) -> dict[str, object]:
    """The VRML97 ``Viewpoint`` fields that :meth:`Camera.from_viewpoint` turns back into
    ``camera`` for images of ``size`` (W, H) pixels: ``{"position": (3,) float64,
    "orientation": (4,) float64 axis-angle (radians), "fieldOfView": float (radians)}``.

    A Viewpoint has one focal length and its principal point in the middle of the image, so
    ``camera`` must have ``fx == fy`` and ``(cx, cy) == (W / 2, H / 2)`` (relative tolerance
    1e-9); its ``pose`` is camera-to-world in the OpenGL convention, as :class:`Camera` keeps it.
    """
    from scipy.spatial.transform import Rotation

    w, h = (int(v) for v in size)
    if not math.isclose(camera.fx, camera.fy, rel_tol=1e-9):
        raise RenderError(
            f"a Viewpoint has one focal length: the camera's fx {camera.fx} and fy "
            f"{camera.fy} differ"
        )
    if not (
        math.isclose(camera.cx, w / 2, rel_tol=1e-9)
        and math.isclose(camera.cy, h / 2, rel_tol=1e-9)
    ):
        raise RenderError(
            f"a Viewpoint looks through the middle of the image: the camera's principal point "
            f"({camera.cx}, {camera.cy}) is not ({w / 2}, {h / 2}) of a {w}x{h} image"
        )
    fov = 2 * math.atan((min(w, h) / 2) / camera.fx)
    pose = _rigid(camera.pose)
    rotvec = Rotation.from_matrix(pose[:3, :3]).as_rotvec()
    angle = float(np.linalg.norm(rotvec))
    axis = rotvec / angle if angle > 0 else np.array([0.0, 0.0, 1.0])
    return {
        "position": pose[:3, 3].copy(),
        "orientation": np.array([*axis, angle]),
        "fieldOfView": fov,
    }


#: The largest scene extent (model units) vtts frames; beyond it depth precision and the
#: camera's placement break down (coordinates of 1e308 overflow).
MAX_EXTENT = 1e9


def row_layout(
    bounds: list[tuple[np.ndarray, np.ndarray]], names: list[str], error: type = RenderError
) -> tuple[list[np.ndarray], list[tuple[np.ndarray, np.ndarray]], np.ndarray, np.ndarray]:
    """Place heads with bounding boxes ``bounds`` (``(lo, hi)``, each ``(3,)``, in their own
    coordinates) side by side along x, centred, 15 % of the widest head apart, as
    :class:`~vtts.render.FaceRenderer` draws them. A head with nothing visible (infinite bounds)
    takes a unit box. Returns each head's ``(4, 4)`` placing matrix, the bounds used, and the
    ``(3,)`` bounds of them all placed. A head spanning more than :data:`MAX_EXTENT` (or not
    finite) raises ``error`` naming it (``names``)."""
    fixed = []
    for (lo, hi), name in zip(bounds, names, strict=True):
        if np.isinf(lo).all() and np.isinf(hi).all():
            # nothing visible (an empty scene, a scale of 0, a Switch choosing nothing): a unit
            # box frames an empty picture
            lo, hi = np.full(3, -0.5), np.full(3, 0.5)
        extent = hi - lo
        if not (np.isfinite(extent).all() and extent.max() <= MAX_EXTENT):
            raise error(
                f"{name}: the scene spans {extent.max():.3g} units, more than the "
                f"{MAX_EXTENT:g} a picture can frame (coordinates too large?)"
            )
        fixed.append((lo, hi))
    widths = [max(hi[0] - lo[0], 1e-6) for lo, hi in fixed]
    gap = 0.15 * max(widths)
    x = -(sum(widths) + gap * (len(widths) - 1)) / 2
    all_lo, all_hi = np.full(3, np.inf), np.full(3, -np.inf)
    matrices = []
    for (lo, hi), width in zip(fixed, widths, strict=True):
        shift = np.array([x - lo[0], -(lo[1] + hi[1]) / 2, -(lo[2] + hi[2]) / 2])
        m = np.eye(4)
        m[:3, 3] = shift
        matrices.append(m)
        all_lo, all_hi = np.minimum(all_lo, lo + shift), np.maximum(all_hi, hi + shift)
        x += width + gap
    return matrices, fixed, all_lo, all_hi
