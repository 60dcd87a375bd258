"""Everything vtts asks of pyrender beyond its public API, in one place.

vtts draws pyrender's scenes with its own passes (:mod:`vtts.render.forward`,
:mod:`vtts.render.deferred`) on the GL objects pyrender made, and patches pyrender where its
choices cost time or determinism. Each reach into pyrender's internals — a patched module
attribute, a private method or attribute of a pyrender object, the process's offscreen context —
is a function or class here, so that a pyrender upgrade is checked against this module alone:

- the environment Mesa's EGL needs before OpenGL is imported (:func:`load_pyrender`);
- the patches: the scene tree without networkx (:class:`SceneTree`), single-sampled framebuffers
  (:data:`MSAA_SAMPLES`), no interactive Viewer, scenes that iterate their nodes in the order
  they were added (:func:`order_scene`), textures whose mipmaps NumPy makes
  (:func:`pyrender_texture`);
- the one offscreen context (:func:`offscreen`) and the accessors of pyrender's renderer,
  programs, primitives, textures and nodes that the drawing passes use per frame.

Import this module freely: pyrender and OpenGL are loaded by :func:`load_pyrender`, on first use.
"""

from __future__ import annotations

import os
import sys
import types
import weakref
from collections.abc import Iterable, Iterator, MutableSet

import numpy as np

from vtts.deferred import defer_package
from vtts.errors import RenderError

_pyrender = None

#: Multisampling of the main framebuffer (pyrender's own default is 4).
MSAA_SAMPLES = 0

#: The fewest rasterizer threads Mesa's llvmpipe is given (``LP_NUM_THREADS``, unless the
#: environment sets it): its default, one per CPU, leaves the cores idle while the main thread
#: bins the next draw and the deformation thread and ffmpeg take their turn (docs/rendering.md,
#: "Speed", has the timings that chose four).
LLVMPIPE_MIN_THREADS = 4


def llvmpipe_threads() -> int:
    """The rasterizer threads vtts asks llvmpipe for: one per CPU, at least
    :data:`LLVMPIPE_MIN_THREADS`."""
    return max(LLVMPIPE_MIN_THREADS, os.cpu_count() or 1)


def load_pyrender() -> types.ModuleType:
    """pyrender, imported and patched on first use (it opens the GL library)."""
    global _pyrender
    if _pyrender is None:
        # Mesa's software EGL: headless, deterministic. Must be set before OpenGL is imported.
        os.environ.setdefault("PYOPENGL_PLATFORM", "egl")
        # llvmpipe's rasterizer threads (ignored by hardware drivers); a caller's choice stands
        os.environ.setdefault("LP_NUM_THREADS", str(llvmpipe_threads()))
        if os.environ["PYOPENGL_PLATFORM"] in ("egl", "osmesa"):
            # pyrender's interactive Viewer (a pyglet window) cannot run headless, and importing
            # it and pyglet is a large part of pyrender's import time: leave it out.
            sys.modules.setdefault("pyrender.viewer", _headless_viewer_module())
        defer_package("trimesh", lone_submodules=True)  # pyrender: trimesh.transformations
        defer_package("networkx")
        defer_package("freetype")  # pyrender's text rendering, which vtts does not use
        try:
            import pyrender
            import pyrender.renderer as pr_renderer
            import pyrender.scene as pr_scene
        except Exception as e:  # pragma: no cover - depends on the machine
            raise RenderError(f"cannot load pyrender/OpenGL (EGL): {e}") from None
        # pyrender keeps its scene tree in a networkx graph, whose import (every algorithm
        # networkx has) is a noticeable part of a `vtts say`'s start-up; a tree needs none
        pr_scene.nx = SceneTrees
        # pyrender hard-codes 4x multisampling, which makes Mesa's software rasterizer several
        # times slower; vtts renders single-sampled and antialiases stills by supersampling.
        storage = pr_renderer.glRenderbufferStorageMultisample

        def single_sampled(target, samples, *args):
            return storage(target, MSAA_SAMPLES, *args)

        pr_renderer.glRenderbufferStorageMultisample = single_sampled
        _pyrender = pyrender
    return _pyrender


def _headless_viewer_module() -> types.ModuleType:
    """A stand-in for ``pyrender.viewer`` whose Viewer says why there is none."""
    module = types.ModuleType("pyrender.viewer")

    class Viewer:
        def __init__(self, *args, **kwargs) -> None:
            raise RenderError("pyrender's Viewer needs a display; vtts renders offscreen (EGL)")

    module.Viewer = Viewer
    return module


# ---- the scene tree without networkx -----------------------------------------------------------


class SceneTree:
    """What pyrender's ``Scene`` asks of its ``networkx.DiGraph``: a tree whose edges go from each
    node to its parent (``"world"`` at the top)."""

    def __init__(self) -> None:
        self._parent: dict = {}  # node -> its parent, or None
        self._children: dict = {}  # node -> the nodes whose parent it is

    def add_node(self, node) -> None:
        if node not in self._parent:
            self._parent[node] = None
            self._children[node] = set()

    def add_edge(self, node, parent) -> None:
        self.add_node(node)
        self.add_node(parent)
        old = self._parent[node]
        if old is not None:
            self._children[old].discard(node)
        self._parent[node] = parent
        self._children[parent].add(node)

    def neighbors(self, node) -> Iterator:
        """The node's parent (a DiGraph's successors), if it has one."""
        parent = self._parent[node]
        return iter(() if parent is None else (parent,))

    def remove_node(self, node) -> None:
        """Remove ``node`` and its edges, as networkx does (its children lose their parent)."""
        parent = self._parent.pop(node)
        if parent is not None:
            self._children[parent].discard(node)
        for child in self._children.pop(node):
            self._parent[child] = None


class SceneTrees:
    """Stands in for ``networkx`` in ``pyrender.scene`` (see :func:`load_pyrender`)."""

    DiGraph = SceneTree

    @staticmethod
    def shortest_path(graph, source, target) -> list:
        """The path from ``source`` up to ``target`` (in a tree, the only one); ``graph`` a
        :class:`SceneTree` or a DiGraph made before pyrender's networkx was replaced."""
        path = [source]
        while path[-1] != target:
            up = next(iter(graph.neighbors(path[-1])), None)
            if up is None:
                raise ValueError(f"no path from {source!r} to {target!r} in the scene")
            path.append(up)
        return path


# ---- drawing order -----------------------------------------------------------------------------


class _InsertionOrdered(MutableSet):
    """A set that iterates in the order its members were added (a dict's keys)."""

    def __init__(self, items: Iterable = ()) -> None:
        self._items = dict.fromkeys(items)

    def __contains__(self, item) -> bool:
        return item in self._items

    def __iter__(self) -> Iterator:
        return iter(self._items)

    def __len__(self) -> int:
        return len(self._items)

    def add(self, item) -> None:
        self._items[item] = None

    def discard(self, item) -> None:
        self._items.pop(item, None)


#: The node sets of a pyrender ``Scene`` whose order reaches the pixels: the drawing order of
#: meshes the same distance from the camera (pyrender sorts them by their origin's distance,
#: and a head's meshes share one), and the order of the lights, whose contributions the shader
#: sums in that order.
ORDERED_SCENE_SETS = ("_mesh_nodes", "_point_light_nodes", "_spot_light_nodes",
                      "_directional_light_nodes")  # fmt: skip


def order_scene(scene) -> None:
    """Make ``scene`` draw in the order its nodes were added. pyrender keeps them in sets,
    which iterate in the order of the nodes' memory addresses: two renderers of the same model
    drew a head's meshes in different orders, so pixels where two meshes meet at the same
    depth came out of one mesh or the other, and the analysis of a video went another way
    from there from one run to the next. pyrender's own ``render`` iterates the same sets, so
    its pixels stay ours."""
    for name in ORDERED_SCENE_SETS:
        setattr(scene, name, _InsertionOrdered(getattr(scene, name)))


# ---- the offscreen context ---------------------------------------------------------------------

_OFFSCREEN = None


def offscreen():
    """The process's one offscreen OpenGL context (a ``pyrender.OffscreenRenderer``). pyrender's
    EGL platform terminates the EGL display when a context is deleted, which breaks every other
    context of the process, so vtts keeps one and changes its viewport per scene."""
    global _OFFSCREEN
    if _OFFSCREEN is None:
        pr = load_pyrender()
        try:
            _OFFSCREEN = pr.OffscreenRenderer(64, 64)
        except Exception as e:  # pragma: no cover - depends on the machine
            raise RenderError(f"cannot create an offscreen OpenGL context (EGL): {e}") from None
    return _OFFSCREEN


def make_current(context) -> None:
    """Make the GL context of ``context`` (an ``OffscreenRenderer``) the thread's current one."""
    context._platform.make_current()


def scene_renderer(context):
    """The ``pyrender.Renderer`` behind ``context`` (an ``OffscreenRenderer``): the GL objects
    it made for scenes, its shader programs and its framebuffers."""
    return context._renderer


def upload_scene(renderer, scene, flags) -> None:
    """Put ``scene``'s new meshes and textures on the GPU (and take removed ones off), as
    pyrender does before it draws."""
    renderer._update_context(scene, flags)


def main_framebuffers(renderer) -> tuple[int, int, tuple[int, int]]:
    """pyrender's main framebuffers for its current viewport, made when it changed: ``(the one
    drawn into, the one read back, (width, height))``."""
    renderer._configure_main_framebuffer()
    return renderer._main_fb_ms, renderer._main_fb, renderer._main_fb_dims


def shader_dir(renderer) -> str:
    """The folder of pyrender's shader sources (``mesh.vert``, ``mesh.frag``, …)."""
    return renderer._program_cache.shader_dir


# ---- shader programs ---------------------------------------------------------------------------


def primitive_program(renderer, primitive, flags, program_flags):
    """pyrender's ``ShaderProgram`` for ``primitive`` (compiled on first use)."""
    return renderer._get_primitive_program(primitive, flags, program_flags)


def program_id(program) -> int | None:
    """The GL name of a pyrender ``ShaderProgram``, None when it is not compiled (any more)."""
    return program._program_id


def compiled_program(vertex_path: str, fragment_path: str, defines: dict):
    """A pyrender ``ShaderProgram`` of these source files under ``defines``, compiled on the
    current context (pyrender's ``#include`` and ``#define`` handling)."""
    from pyrender.shader_program import ShaderProgram

    program = ShaderProgram(vertex_path, fragment_path, defines=defines)
    program._add_to_context()
    return program


def shader_source(path: str, defines: dict) -> str:
    """The source of pyrender's shader file ``path`` as pyrender would compile it under
    ``defines``."""
    from pyrender.shader_program import ShaderProgram

    return ShaderProgram(None, path, defines=defines)._load(path)


# ---- primitives, textures, nodes ---------------------------------------------------------------


def vertex_array(primitive) -> int:
    """The GL vertex array pyrender made for ``primitive``."""
    return primitive._vaid


def on_gpu(primitive) -> bool:
    """Whether pyrender has put ``primitive`` on the GPU (its buffers are then fixed)."""
    return primitive._in_context()


def rewrite_vertex_buffer(primitive, vertex_data: np.ndarray | None) -> bool:
    """Overwrite the vertex buffer of a primitive that is already on the GPU with
    ``vertex_data`` (``(n, 6 + k) float32``, laid out as pyrender lays it out).

    pyrender uploads a primitive once (one interleaved buffer: positions, normals, texture
    coordinates, colors) and offers no public way to change it; replacing the node re-creates
    every GL object. When the primitive is bound, its buffer is rewritten with
    ``glBufferSubData`` instead. Returns whether it was; when not (not on the GPU yet, another
    pyrender layout, no ``vertex_data``) the caller replaces the node."""
    buffers = getattr(primitive, "_buffers", None)
    if getattr(primitive, "_vaid", None) is None or not buffers or vertex_data is None:
        return False
    from OpenGL.GL import GL_ARRAY_BUFFER, glBindBuffer, glBufferSubData

    glBindBuffer(GL_ARRAY_BUFFER, buffers[0])
    glBufferSubData(GL_ARRAY_BUFFER, 0, vertex_data.nbytes, vertex_data)
    glBindBuffer(GL_ARRAY_BUFFER, 0)
    return True


def gpu_buffers(primitive) -> object:
    """What stays the same object while ``primitive`` keeps the GL buffers it has on the GPU:
    pyrender's list of them, which it replaces when it takes the primitive off the GPU (a
    primitive put on again has new buffers, filled from its own arrays)."""
    return getattr(primitive, "_buffers", None)


def texture_id(texture) -> int:
    """The GL name of a pyrender ``Texture`` on the GPU."""
    return texture._texid


def node_path(scene, node) -> list | None:
    """The nodes from ``node`` up to the root that ``scene.get_pose`` found and keeps (``None``
    until it has been asked once)."""
    return getattr(scene, "_path_cache", {}).get(node)


def node_matrices(path: list) -> list[np.ndarray]:
    """The local matrices of the nodes of ``path`` but its last (the root), as pyrender keeps
    them: the same array objects until a node's pose is set."""
    matrices = []
    for n in path[:-1]:
        if n._matrix is None:
            _ = n.matrix  # pyrender computes it from the node's pose and keeps it
        matrices.append(n._matrix)
    return matrices


_TEXTURE_CLASS = None
#: The mipmap chains of read-only texture images (the decoded image files renderers share,
#: :func:`vtts.render.scene.load_image`), by the image's id while it lives.
_MIPMAPS: dict[int, tuple[weakref.ref, list[np.ndarray]]] = {}


def _mips(source: np.ndarray, mip_levels) -> list[np.ndarray]:
    """The mipmap chain of ``source (h, w, 4) uint8`` flipped upside down (GL's row order),
    made once per read-only image: another renderer of the same head uploads the same levels."""
    if source.flags.writeable:
        return mip_levels(np.flip(source, axis=0))
    key = id(source)
    kept = _MIPMAPS.get(key)
    if kept is not None and kept[0]() is source:
        return kept[1]
    levels = mip_levels(np.flip(source, axis=0))
    _MIPMAPS[key] = (weakref.ref(source, lambda _, key=key: _MIPMAPS.pop(key, None)), levels)
    return levels


def pyrender_texture(rgba: np.ndarray):
    """A pyrender texture of an ``(h, w, 4) uint8`` image, top row first, whose mipmaps vtts
    makes (:mod:`vtts.render.mipmaps`)."""
    # pyrender (like glTF) puts t = 0 at the bottom of such images, which is VRML's convention
    # too (a test checks the orientation)
    return _texture_class()(source=np.ascontiguousarray(rgba), source_channels="RGBA")


def _texture_class():
    """pyrender's ``Texture`` with its mipmaps computed by NumPy (:func:`mip_levels`) instead
    of ``glGenerateMipmap``; otherwise set up on the GPU as pyrender sets it up."""
    global _TEXTURE_CLASS
    if _TEXTURE_CLASS is not None:
        return _TEXTURE_CLASS
    pr = load_pyrender()
    from OpenGL import GL

    from vtts.render.mipmaps import mip_levels, power_of_two

    class MipmappedTexture(pr.Texture):
        def _add_to_context(self) -> None:
            source = self.source
            if (
                source is None
                or source.dtype != np.uint8
                or source.ndim != 3
                or source.shape[2] != 4
                or not power_of_two(source.shape[:2])
                or self.sampler.minFilter is not None
            ):
                super()._add_to_context()
                return
            if self._texid is not None:
                raise ValueError("Texture already loaded into OpenGL context")
            self._texid = GL.glGenTextures(1)
            GL.glBindTexture(self.tex_type, self._texid)
            GL.glPixelStorei(GL.GL_UNPACK_ALIGNMENT, 1)
            for k, level in enumerate(_mips(source, mip_levels)):
                h, w = level.shape[:2]
                GL.glTexImage2D(
                    self.tex_type, k, GL.GL_RGBA, w, h, 0, GL.GL_RGBA, GL.GL_UNSIGNED_BYTE,
                    np.ascontiguousarray(level),
                )  # fmt: skip
            GL.glPixelStorei(GL.GL_UNPACK_ALIGNMENT, 4)
            mag = self.sampler.magFilter if self.sampler.magFilter is not None else GL.GL_LINEAR
            GL.glTexParameteri(self.tex_type, GL.GL_TEXTURE_MAG_FILTER, mag)
            GL.glTexParameteri(self.tex_type, GL.GL_TEXTURE_MIN_FILTER, GL.GL_LINEAR_MIPMAP_LINEAR)
            GL.glTexParameteri(self.tex_type, GL.GL_TEXTURE_WRAP_S, self.sampler.wrapS)
            GL.glTexParameteri(self.tex_type, GL.GL_TEXTURE_WRAP_T, self.sampler.wrapT)
            border = 255 * np.ones(4).astype(np.uint8)
            GL.glTexParameterfv(self.tex_type, GL.GL_TEXTURE_BORDER_COLOR, border)
            GL.glBindTexture(self.tex_type, 0)

    _TEXTURE_CLASS = MipmappedTexture
    return _TEXTURE_CLASS
