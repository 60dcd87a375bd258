"""Which triangle each pixel shows: the triangle-index buffer of the analysis.

The estimator needs, for every face pixel of the synthetic image, the triangle the pixel sees
(the barycentric coordinates and depth then follow exactly from the pixel's ray, see
:func:`ray_barycentrics`). pyrender draws the colors; this module draws the same triangles once
more on the same EGL context with a minimal shader whose output is ``gl_PrimitiveID`` — one draw
call per culling mode into an integer framebuffer — so the indices come from the very rasterizer
that drew the colors, with the same projection matrix and depth test.
"""

from __future__ import annotations

import ctypes

import numpy as np

from vtts.errors import RenderError
from vtts.render.camera import Camera

_VERTEX = """#version 330 core
layout(location = 0) in vec3 position;
uniform mat4 PV;
void main() { gl_Position = PV * vec4(position, 1.0); }
"""

_FRAGMENT = """#version 330 core
uniform int first;
layout(location = 0) out uint index;
void main() { index = uint(gl_PrimitiveID + first + 1); }
"""


def projection(camera: Camera, size: tuple[int, int]) -> np.ndarray:
    """The ``(4, 4)`` OpenGL projection of ``camera`` for an image of ``size`` (W, H): pyrender's
    own, so that both passes rasterize alike."""
    from vtts.render.renderer import _pr

    cam = _pr().IntrinsicsCamera(
        camera.fx, camera.fy, camera.cx, camera.cy, znear=camera.znear, zfar=camera.zfar
    )
    return cam.get_projection_matrix(*size)


class TriangleIndexBuffer:
    """Draws triangle indices of a fixed triangle set whose vertices move.

    ``faces`` is ``(m, 3)`` vertex indices into the ``(n, 3)`` positions given to :meth:`draw`;
    ``culled`` ``(m,)`` says which triangles are drawn with back faces culled (VRML ``solid``).
    """

    def __init__(self, faces: np.ndarray, culled: np.ndarray, n_vertices: int) -> None:
        from OpenGL import GL

        from vtts.render.renderer import _offscreen

        self._gl = GL
        self._context = _offscreen()
        self._context._platform.make_current()
        faces = np.asarray(faces, dtype=np.uint32).reshape(-1, 3)
        culled = np.asarray(culled, dtype=bool).reshape(-1)
        if culled.shape[0] != faces.shape[0]:
            raise ValueError("culled must have one flag per triangle")
        # triangles sorted by culling mode; each run is one draw call, ids mapped back after
        order = np.argsort(~culled, kind="stable")
        self.order = order  # drawn triangle k is faces[order[k]]
        self._runs = []
        n_culled = int(culled.sum())
        if n_culled:
            self._runs.append((0, n_culled, True))
        if n_culled < faces.shape[0]:
            self._runs.append((n_culled, faces.shape[0] - n_culled, False))
        self.n_vertices = n_vertices
        self._program = self._link()
        self._loc_pv = GL.glGetUniformLocation(self._program, "PV")
        self._loc_first = GL.glGetUniformLocation(self._program, "first")
        self._vao = GL.glGenVertexArrays(1)
        GL.glBindVertexArray(self._vao)
        self._vbo = GL.glGenBuffers(1)
        GL.glBindBuffer(GL.GL_ARRAY_BUFFER, self._vbo)
        GL.glBufferData(GL.GL_ARRAY_BUFFER, n_vertices * 12, None, GL.GL_DYNAMIC_DRAW)
        GL.glEnableVertexAttribArray(0)
        GL.glVertexAttribPointer(0, 3, GL.GL_FLOAT, GL.GL_FALSE, 12, ctypes.c_void_p(0))
        self._ebo = GL.glGenBuffers(1)
        GL.glBindBuffer(GL.GL_ELEMENT_ARRAY_BUFFER, self._ebo)
        indices = np.ascontiguousarray(faces[order])
        GL.glBufferData(GL.GL_ELEMENT_ARRAY_BUFFER, indices.nbytes, indices, GL.GL_STATIC_DRAW)
        GL.glBindVertexArray(0)
        GL.glBindBuffer(GL.GL_ARRAY_BUFFER, 0)
        self._targets: dict[tuple[int, int], tuple[int, int, int]] = {}

    def _link(self) -> int:
        GL = self._gl
        prog = GL.glCreateProgram()
        for kind, src in ((GL.GL_VERTEX_SHADER, _VERTEX), (GL.GL_FRAGMENT_SHADER, _FRAGMENT)):
            sh = GL.glCreateShader(kind)
            GL.glShaderSource(sh, src)
            GL.glCompileShader(sh)
            if not GL.glGetShaderiv(sh, GL.GL_COMPILE_STATUS):
                raise RenderError(f"triangle-index shader: {GL.glGetShaderInfoLog(sh)!r}")
            GL.glAttachShader(prog, sh)
        GL.glLinkProgram(prog)
        if not GL.glGetProgramiv(prog, GL.GL_LINK_STATUS):
            raise RenderError(f"triangle-index program: {GL.glGetProgramInfoLog(prog)!r}")
        return prog

    def _target(self, size: tuple[int, int]) -> int:
        GL = self._gl
        if size not in self._targets:
            w, h = size
            fb = GL.glGenFramebuffers(1)
            color, depth = GL.glGenRenderbuffers(2)
            GL.glBindRenderbuffer(GL.GL_RENDERBUFFER, color)
            GL.glRenderbufferStorage(GL.GL_RENDERBUFFER, GL.GL_R32UI, w, h)
            GL.glBindRenderbuffer(GL.GL_RENDERBUFFER, depth)
            GL.glRenderbufferStorage(GL.GL_RENDERBUFFER, GL.GL_DEPTH_COMPONENT24, w, h)
            GL.glBindFramebuffer(GL.GL_FRAMEBUFFER, fb)
            GL.glFramebufferRenderbuffer(
                GL.GL_FRAMEBUFFER, GL.GL_COLOR_ATTACHMENT0, GL.GL_RENDERBUFFER, color
            )
            GL.glFramebufferRenderbuffer(
                GL.GL_FRAMEBUFFER, GL.GL_DEPTH_ATTACHMENT, GL.GL_RENDERBUFFER, depth
            )
            if GL.glCheckFramebufferStatus(GL.GL_FRAMEBUFFER) != GL.GL_FRAMEBUFFER_COMPLETE:
                raise RenderError(f"cannot create a {w}x{h} integer framebuffer")
            self._targets[size] = (fb, color, depth)
        return self._targets[size][0]

    def draw(self, positions: np.ndarray, camera: Camera, size: tuple[int, int]) -> np.ndarray:
        """The ``(H, W) int64`` index (into ``faces``) of the triangle each pixel shows, −1 where
        none does, for world ``positions (n, 3)`` seen by ``camera`` in an image of ``size``."""
        GL = self._gl
        self._context._platform.make_current()
        w, h = size
        data = np.ascontiguousarray(positions, dtype=np.float32)
        if data.shape != (self.n_vertices, 3):
            raise ValueError(f"positions must have shape ({self.n_vertices}, 3), got {data.shape}")
        pv = projection(camera, size) @ np.linalg.inv(camera.pose)
        GL.glBindFramebuffer(GL.GL_FRAMEBUFFER, self._target(size))
        GL.glViewport(0, 0, w, h)
        # state first (the clear obeys the write masks other drawing may have left behind)
        GL.glEnable(GL.GL_DEPTH_TEST)
        GL.glDepthMask(GL.GL_TRUE)
        GL.glDepthFunc(GL.GL_LESS)
        GL.glDisable(GL.GL_BLEND)
        GL.glColorMask(GL.GL_TRUE, GL.GL_TRUE, GL.GL_TRUE, GL.GL_TRUE)
        GL.glPolygonMode(GL.GL_FRONT_AND_BACK, GL.GL_FILL)
        GL.glClearBufferuiv(GL.GL_COLOR, 0, np.zeros(4, dtype=np.uint32))
        GL.glClear(GL.GL_DEPTH_BUFFER_BIT)
        GL.glUseProgram(self._program)
        GL.glUniformMatrix4fv(self._loc_pv, 1, GL.GL_TRUE, pv.astype(np.float32))
        GL.glBindVertexArray(self._vao)
        GL.glBindBuffer(GL.GL_ARRAY_BUFFER, self._vbo)
        GL.glBufferSubData(GL.GL_ARRAY_BUFFER, 0, data.nbytes, data)
        for first, count, cull in self._runs:
            if cull:
                GL.glEnable(GL.GL_CULL_FACE)
                GL.glCullFace(GL.GL_BACK)
            else:
                GL.glDisable(GL.GL_CULL_FACE)
            GL.glUniform1i(self._loc_first, first)
            GL.glDrawElements(
                GL.GL_TRIANGLES, 3 * count, GL.GL_UNSIGNED_INT, ctypes.c_void_p(12 * first)
            )
        GL.glBindVertexArray(0)
        GL.glBindBuffer(GL.GL_ARRAY_BUFFER, 0)
        GL.glUseProgram(0)
        GL.glReadBuffer(GL.GL_COLOR_ATTACHMENT0)
        buf = GL.glReadPixels(0, 0, w, h, GL.GL_RED_INTEGER, GL.GL_UNSIGNED_INT)
        GL.glBindFramebuffer(GL.GL_FRAMEBUFFER, 0)
        drawn = np.frombuffer(buf, dtype=np.uint32).reshape(h, w)[::-1].astype(np.int64) - 1
        out = np.full(drawn.shape, -1, dtype=np.int64)
        hit = drawn >= 0
        out[hit] = self.order[drawn[hit]]
        return out


def ray_barycentrics(
    pixels: np.ndarray, camera: Camera, triangles: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Where the rays of ``pixels`` meet their triangles.

    ``pixels`` ``(N, 2)`` are (X, Y) image coordinates (pixel centres at ``col + 0.5``,
    ``row + 0.5``); ``triangles`` ``(N, 3, 3)`` the world positions of each pixel's triangle.
    Returns the barycentric coordinates ``(N, 3)`` (perspective-correct: the 3D point is
    ``Σ λ_m v_m``) and the camera-space points ``(N, 3)`` (OpenGL camera: looking along −z).
    """
    inv = np.linalg.inv(camera.pose)
    v = triangles @ inv[:3, :3].T + inv[:3, 3]  # camera space (N, 3, 3)
    d = np.stack(
        [
            (pixels[:, 0] - camera.cx) / camera.fx,
            -(pixels[:, 1] - camera.cy) / camera.fy,
            -np.ones(len(pixels)),
        ],
        axis=1,
    )
    # Möller–Trumbore with the ray from the camera centre (the origin)
    e1 = v[:, 1] - v[:, 0]
    e2 = v[:, 2] - v[:, 0]
    pv = np.cross(d, e2)
    det = np.einsum("ij,ij->i", e1, pv)
    det = np.where(np.abs(det) < 1e-300, 1e-300, det)
    tv = -v[:, 0]
    b1 = np.einsum("ij,ij->i", tv, pv) / det
    qv = np.cross(tv, e1)
    b2 = np.einsum("ij,ij->i", d, qv) / det
    t = np.einsum("ij,ij->i", e2, qv) / det
    lam = np.stack([1 - b1 - b2, b1, b2], axis=1)
    return lam, d * t[:, None]
