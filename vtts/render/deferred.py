"""Deferred shading of pyrender scenes: pyrender's pixels for half of the rasterizer's work.

Mesa's software rasterizer runs the fragment shader on 4×4 pixel blocks, the whole block for
every triangle that touches it. A head of about as many triangles as the pixels it covers
therefore runs pyrender's physically based shader (two lights, five ``pow`` per fragment) on
many times more fragments than there are pixels (docs/rendering.md, "Speed", has the numbers),
and that was most of a frame's time.

:class:`DeferredPass` draws the opaque geometry once with a cheap shader that only stores what
pyrender's ``mesh.frag`` would read for the fragment — position, normal, texture sample,
per-vertex color and which material — in float textures (the G-buffer), with pyrender's own
vertex shader, drawing order and depth test (an unlit material's pixels, which pyrender's
lighting never sees, without position and normal). A second pass then runs pyrender's own fragment
shader code (its ``mesh.frag``, with its inputs turned into globals loaded from the G-buffer) once
per covered pixel. Same inputs, same code: the same pixels (``tests/render`` compares the two
pixel for pixel). Transparent primitives are drawn afterwards as pyrender draws them, over the
resolved colors and the G-buffer's depth.

Scenes outside what the G-buffer holds (materials with textures other than a base color, point
primitives, more than :attr:`DeferredPass.MAX_MATERIALS` opaque materials) are drawn by the
:class:`~vtts.render.forward.ForwardPass`.
"""

from __future__ import annotations

import os
import weakref
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from OpenGL import GL
from OpenGL.GL import shaders

from vtts.errors import RenderError
from vtts.render.forward import LIGHT_KINDS, ForwardPass, cull_back, light_counts, read_color
from vtts.render.pyrender_adapter import (
    compiled_program,
    make_current,
    program_id,
    scene_renderer,
    shader_dir,
    shader_source,
    texture_id,
)
from vtts.render.scene import SPECULAR, UNLIT

SHADER_DIR = Path(__file__).resolve().parent / "shaders"

#: The G-buffer's targets, in attachment order, as the resolve shader samples them (floats; the
#: texture sample in 8 bits on llvmpipe: :func:`_filters_in_8_bits`; the material's index and
#: whether it is textured in 8 bits); the last one (per-vertex colors) is drawn only for scenes
#: that have such colors. Position and normal are stored for lit materials only
#: (:func:`_lit_targets`).
G_TARGETS = ("g_position", "g_normal", "g_texel", "g_material", "g_color")

#: The targets that only a lit material's pixels need (the resolve pass reads them for those).
LIT_TARGETS = (0, 1)

#: The G-buffer's sides are whole multiples of this many pixels (:meth:`DeferredPass._targets_for`).
TARGET_STEP = 64

#: The G-buffer's attachment for triangle numbers (drawn only when asked for).
TRIANGLE_ATTACHMENT = len(G_TARGETS)

#: pyrender's mesh.frag, from its inputs to plain globals (each must occur exactly once).
_RESOLVE_EDITS = (
    ("in vec3 frag_position;", "vec3 frag_position;"),
    ("in vec3 frag_normal;", "vec3 frag_normal;"),
    ("in vec4 color_multiplier;", "vec4 color_multiplier;"),
    ("uniform Material material;", "Material material;\nfloat specular_scale = 1.0;"),
    # the dielectric highlight scaled per material (SPECULAR: none for ``specularColor 0 0 0``)
    (
        "vec3 f0 = mix(dialectric_spec, base_color.rgb, metallic);",
        "vec3 f0 = mix(dialectric_spec * specular_scale, base_color.rgb, metallic);",
    ),
    ("void main()", "void pyrender_main()"),
)


@dataclass
class _Targets:
    """The framebuffers of one image size: the G-buffer and the color image, sharing a depth
    buffer."""

    size: tuple[int, int]
    gbuffer: int
    color_fb: int
    textures: list[int]
    renderbuffers: list[int]

    def delete(self) -> None:
        GL.glDeleteFramebuffers(2, [self.gbuffer, self.color_fb])
        GL.glDeleteTextures(self.textures)
        GL.glDeleteRenderbuffers(len(self.renderbuffers), self.renderbuffers)


class DeferredPass(ForwardPass):
    """Renders pyrender scenes with deferred shading (see the module's notes); same interface
    as :class:`~vtts.render.forward.ForwardPass`."""

    #: Opaque materials the resolve shader's tables hold (at most 32: the G-buffer's material
    #: target holds the index plus 32 for a textured material in 8 bits).
    MAX_MATERIALS = 32

    def __init__(self, offscreen) -> None:
        super().__init__(offscreen)
        from pyrender.constants import GLTF, TexFlags

        self._triangle_modes = {GLTF.TRIANGLES, GLTF.TRIANGLE_STRIP, GLTF.TRIANGLE_FAN}
        self._base_color_only = TexFlags.BASE_COLOR
        # (pyrender's defines, (vertex colors?, triangle numbers?)) -> G-buffer program;
        # primitive -> the same
        self._gbuffer_programs: dict[tuple[frozenset, bool], object] = {}
        self._gbuffer_of: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()
        # (vertex colors?, light counts) -> the resolve programs (lit, unlit only), each with an
        # empty vertex array, or None if they cannot be made
        self._resolve: dict[tuple[bool, tuple[int, int, int]], tuple | None] = {}
        self._targets: _Targets | None = None

    def deferrable(self, scene) -> bool:
        """Whether the G-buffer holds everything pyrender's shader reads for ``scene``'s opaque
        primitives."""
        materials = set()
        for mesh in scene.meshes:
            if mesh.is_transparent:
                continue
            for p in mesh.primitives:
                if p.mode not in self._triangle_modes:
                    return False
                if p.material.tex_flags & ~self._base_color_only:
                    return False
                materials.add(p.material)
        return len(materials) <= self.MAX_MATERIALS

    def draws_unlit(self, scene) -> bool:
        """Whether :meth:`render` draws ``scene`` through the G-buffer, where an opaque unlit
        material (:data:`~vtts.render.scene.UNLIT`) shows its colours whatever its normals;
        where it falls back to pyrender's forward shading such materials are lit like the rest
        and need their normals."""
        if not (self.supports(scene) and self.deferrable(scene)):
            return False
        make_current(self._offscreen)
        opaque = [(n, None) for n in scene.mesh_nodes if not n.mesh.is_transparent]
        colors = self._vertex_colors(opaque)
        lights = light_counts(scene)
        return self._resolve_program(scene_renderer(self._offscreen), colors, lights) is not None

    @staticmethod
    def _vertex_colors(opaque) -> bool:
        """Whether any of the ``(node, pose)`` has per-vertex colors (the G-buffer then keeps
        them too)."""
        return any(p.color_0 is not None for n, _ in opaque for p in n.mesh.primitives)

    def render(self, scene, width: int, height: int, rgba: bool = False, triangles=None):
        """Draw ``scene`` as :meth:`ForwardPass.render` does.

        ``triangles``: ``{primitive: number of its first triangle}`` for the opaque triangle
        primitives to number. Then also returns, after the image, the number of the triangle
        each pixel shows ``(H, W) int64`` (a primitive's first triangle plus the triangle's
        index in its ``indices``; −1: background, an unnumbered primitive)."""
        if not (self.supports(scene) and self.deferrable(scene)):
            if triangles is not None:
                raise RenderError("triangle numbers need a scene the G-buffer holds")
            return super().render(scene, width, height, rgba)
        r = self._begin_frame(scene, width, height)
        opaque, transparent = self._mesh_nodes(scene)
        colors = self._vertex_colors(opaque)
        resolve = self._resolve_program(r, colors, light_counts(scene))
        if resolve is None:
            if triangles is not None:
                raise RenderError("triangle numbers need pyrender's shader as vtts knows it")
            return super().render(scene, width, height, rgba)
        targets = self._targets_for(width, height)
        # the targets may be larger than the image (:meth:`_targets_for`): clear and draw only
        # its corner, the viewport (drawing is clipped to the viewport already; clears are not)
        GL.glScissor(0, 0, width, height)
        GL.glEnable(GL.GL_SCISSOR_TEST)
        try:
            self._draw_scene(scene, r, targets, resolve, opaque, transparent, colors, triangles)
        finally:
            GL.glDisable(GL.GL_SCISSOR_TEST)
            GL.glDisable(GL.GL_STENCIL_TEST)
        self._end_frame()
        image = read_color(targets.color_fb, width, height, rgba)
        if triangles is None:
            return image
        return image, _read_triangles(targets.gbuffer, width, height)

    # ---- G-buffer pass -----------------------------------------------------------------------

    def _draw_scene(
        self, scene, r, targets: _Targets, resolve, opaque, transparent, colors: bool, triangles
    ) -> None:
        """The G-buffer pass, the resolve pass and the transparent primitives of :meth:`render`."""
        GL.glBindFramebuffer(GL.GL_DRAW_FRAMEBUFFER, targets.gbuffer)
        buffers = [GL.GL_COLOR_ATTACHMENT0 + i for i in range(len(G_TARGETS))]
        if not colors:
            buffers[-1] = GL.GL_NONE
        if triangles is not None:
            buffers.append(GL.GL_COLOR_ATTACHMENT0 + TRIANGLE_ATTACHMENT)
        while buffers[-1] == GL.GL_NONE:
            buffers.pop()
        GL.glDrawBuffers(len(buffers), buffers)
        GL.glEnable(GL.GL_DEPTH_TEST)
        GL.glDepthMask(GL.GL_TRUE)
        GL.glDepthFunc(GL.GL_LESS)
        GL.glDisable(GL.GL_BLEND)
        GL.glClearDepth(1.0)  # the far plane, where the resolve pass's triangle lies
        GL.glClearStencil(0)
        GL.glStencilMask(0xFF)
        GL.glClear(GL.GL_DEPTH_BUFFER_BIT | GL.GL_STENCIL_BUFFER_BIT)
        # the stencil marks the pixels a lit material shows (:func:`_lit_targets`)
        GL.glEnable(GL.GL_STENCIL_TEST)
        GL.glStencilOp(GL.GL_KEEP, GL.GL_KEEP, GL.GL_REPLACE)
        if triangles is not None:
            GL.glColorMask(GL.GL_TRUE, GL.GL_TRUE, GL.GL_TRUE, GL.GL_TRUE)
            GL.glClearBufferfv(GL.GL_COLOR, TRIANGLE_ATTACHMENT, np.zeros(4, np.float32))
        materials: dict[object, int] = {}
        for node, pose in opaque:
            for primitive in node.mesh.primitives:
                self._draw_gbuffer(primitive, pose, r, materials, colors, triangles)
        self._set(LIT_TARGETS, True, _lit_targets)  # the resolve pass writes attachment 0
        GL.glDisable(GL.GL_STENCIL_TEST)

        GL.glBindFramebuffer(GL.GL_DRAW_FRAMEBUFFER, targets.color_fb)
        GL.glClearColor(*scene.bg_color)
        GL.glClear(GL.GL_COLOR_BUFFER_BIT)
        GL.glEnable(GL.GL_STENCIL_TEST)
        GL.glStencilOp(GL.GL_KEEP, GL.GL_KEEP, GL.GL_KEEP)
        lit = [not _unlit(m) for m in materials]
        if not all(lit):  # the unlit materials' pixels, without pyrender's lighting code
            GL.glStencilFunc(GL.GL_EQUAL, 0, 0xFF)
            self._draw_resolve(resolve[1], targets, list(materials), colors)
        if any(lit):
            GL.glStencilFunc(GL.GL_EQUAL, 1, 0xFF)
            self._draw_resolve(resolve[0], targets, list(materials), colors)
        GL.glDisable(GL.GL_STENCIL_TEST)

        if transparent:
            self._forward_state()
            for node, pose in transparent:
                for primitive in node.mesh.primitives:
                    self._draw(primitive, pose, r)

    def _draw_gbuffer(
        self, primitive, pose: np.ndarray, r, materials: dict, colors: bool, triangles=None
    ) -> None:
        """Store what pyrender's shader would read for ``primitive``'s fragments (and, with
        ``triangles``, the numbers of its triangles)."""
        pid = program_id(self._gbuffer_program(primitive, r, colors, triangles is not None))
        self._use(pid)
        self._uniform(pid, "M", pose)
        material = primitive.material
        index = materials.setdefault(material, len(materials))
        self._uniform(pid, "material_index", float(index))
        if triangles is not None:
            first = triangles.get(primitive)
            # stored plus one (0: none); floats hold integers exactly up to 2**24
            self._uniform(pid, "first_triangle", -1.0 if first is None else float(first + 1))
        texture = material.baseColorTexture
        if texture is not None:
            self._texture(pid, "base_color_texture", 0, texture.tex_type, texture_id(texture))
            cutoff = material.alphaCutoff if material.alphaMode == "MASK" else 0.0
            self._uniform(pid, "alpha_cutoff", float(cutoff))
        self._set(GL.GL_CULL_FACE, not material.doubleSided, cull_back)
        self._set(LIT_TARGETS, not _unlit(material), _lit_targets)
        self._draw_call(primitive)

    def _gbuffer_program(self, primitive, r, colors: bool, triangles: bool = False):
        """pyrender's mesh.vert with the G-buffer shader, under the defines pyrender uses for
        ``primitive`` (so that the vertex stage is exactly pyrender's); ``colors``: with the
        per-vertex color target; ``triangles``: with the triangle-number target. An unlit
        material's program computes no position or normal (``VTTS_UNLIT``)."""
        unlit = _unlit(primitive.material)
        variant = (colors, triangles, unlit)
        known = self._gbuffer_of.get(primitive)
        if known is not None and known[0] == variant and program_id(known[1]) is not None:
            return known[1]
        defines = dict(self._program(primitive, r).defines)
        key = (frozenset(defines.items()), variant)
        program = self._gbuffer_programs.get(key)
        if program is None or program_id(program) is None:
            if colors:
                defines["VERTEX_COLORS"] = 1
            if triangles:
                defines["TRIANGLE_NUMBERS"] = 1
            if unlit:
                defines["VTTS_UNLIT"] = 1
            program = compiled_program(
                os.path.join(shader_dir(r), "mesh.vert"), str(SHADER_DIR / "gbuffer.frag"), defines
            )
            self._gbuffer_programs[key] = program
            self._private.add(program_id(program))
        self._gbuffer_of[primitive] = (variant, program)
        return program

    # ---- resolve pass ------------------------------------------------------------------------

    def _draw_resolve(
        self, resolve: tuple[int, int], targets: _Targets, materials: list, colors: bool
    ) -> None:
        """Shade every pixel the G-buffer covers and the stencil test lets through, once, with
        pyrender's lighting (``resolve`` the lit program) or as unlit materials show."""
        pid, vertex_array = resolve
        GL.glDepthFunc(GL.GL_GREATER)  # the far-plane triangle passes where geometry was drawn
        GL.glDepthMask(GL.GL_FALSE)
        self._set(GL.GL_CULL_FACE, False, cull_back)
        self._use(pid)
        n_targets = len(G_TARGETS) if colors else len(G_TARGETS) - 1
        for unit in range(n_targets):
            self._texture(pid, G_TARGETS[unit], unit, GL.GL_TEXTURE_2D, targets.textures[unit])
        self._uniform_array(pid, "base_color_factors", [m.baseColorFactor for m in materials])
        self._uniform_array(
            pid,
            "emissive_metallic_factors",
            [[*m.emissiveFactor, m.metallicFactor] for m in materials],
        )
        self._uniform_array(pid, "roughness_factors", [m.roughnessFactor for m in materials])
        self._uniform_array(pid, "unlit", [float(getattr(m, UNLIT, False)) for m in materials])
        self._uniform_array(
            pid, "specular_scales", [float(getattr(m, SPECULAR, 1.0)) for m in materials]
        )
        GL.glBindVertexArray(vertex_array)
        GL.glDrawArrays(GL.GL_TRIANGLES, 0, 3)
        GL.glDepthFunc(GL.GL_LESS)  # the depth state pyrender draws with, for whoever draws next
        GL.glDepthMask(GL.GL_TRUE)

    def _resolve_program(
        self, r, colors: bool, lights: tuple[int, int, int]
    ) -> tuple[tuple[int, int], tuple[int, int]] | None:
        """The resolve programs, each ``(program, empty vertex array)``: pyrender's mesh.frag
        (as pyrender would compile it for an untextured metallic-roughness material with
        normals, and with vertex colors if ``colors``) with its inputs loaded from the G-buffer,
        made for ``lights`` (the scene's directional, point and spot lights:
        :func:`light_counts`), and the same without pyrender's lighting code, for the unlit
        materials' pixels (``VTTS_UNLIT_ONLY``: llvmpipe runs both sides of a branch, so the
        lighting cost every pixel its time). None when this pyrender's shader does not read as
        expected.

        The light counts, uniforms in pyrender's shader, are constants here: its light loops
        then have fixed bounds that the compiler unrolls, and the loops for kinds the scene
        lacks vanish. Same arithmetic, less of a frame's rasterizer time (llvmpipe runs a loop
        with a uniform bound as a masked loop over every lane; docs/rendering.md has the
        figure)."""
        key = (colors, lights)
        if key in self._resolve:
            return self._resolve[key]
        n_lights = self._max_lights
        defines = {
            "USE_METALLIC_MATERIAL": 1,
            "NORMAL_LOC": 1,
            "MAX_DIRECTIONAL_LIGHTS": n_lights,
            "MAX_SPOT_LIGHTS": n_lights,
            "MAX_POINT_LIGHTS": n_lights,
        }
        if colors:
            defines["COLOR_0_LOC"] = 2
        source = shader_source(os.path.join(shader_dir(r), "mesh.frag"), defines)
        edits = _RESOLVE_EDITS + tuple(
            (f"uniform int n_{kind};", f"const int n_{kind} = {n};")
            for kind, n in zip(LIGHT_KINDS, lights, strict=True)
        )
        for old, new in edits:
            if source.count(old) != 1:
                self._resolve[key] = None
                return None
            source = source.replace(old, new)
        main = (SHADER_DIR / "resolve_main.frag").read_text(encoding="utf-8")
        main = main.replace("MAX_MATERIALS", str(self.MAX_MATERIALS))
        source += ("\n#define VERTEX_COLORS 1\n" if colors else "\n") + main
        vertex = (SHADER_DIR / "resolve.vert").read_text(encoding="utf-8")
        vertex_array = GL.glGenVertexArrays(1)
        GL.glBindVertexArray(vertex_array)  # core profile: validation needs a vertex array
        programs = []
        for unlit_only in (False, True):
            head, rest = source.split("\n", 1)  # after the #version line
            defined = f"{head}\n#define VTTS_UNLIT_ONLY 1\n{rest}" if unlit_only else source
            pid = int(
                shaders.compileProgram(
                    shaders.compileShader(vertex, GL.GL_VERTEX_SHADER),
                    shaders.compileShader(defined, GL.GL_FRAGMENT_SHADER),
                )
            )
            self._private.add(pid)
            programs.append((pid, vertex_array))
        GL.glBindVertexArray(0)
        self._resolve[key] = (programs[0], programs[1])
        return self._resolve[key]

    def _uniform_array(self, pid: int, name: str, values: list) -> None:
        """Set the first ``len(values)`` elements of the float (vec) array uniform ``name``."""
        if not values:
            return
        array = np.asarray(values, dtype=np.float32)
        fingerprint = (array.shape, array.tobytes())
        key = (pid, name)
        if self._sent.get(key) == fingerprint:
            return
        self._sent[key] = fingerprint
        loc = self._locations.get(key)
        if loc is None:
            loc = self._locations[key] = GL.glGetUniformLocation(pid, f"{name}[0]")
        if loc == -1:
            return
        width = 1 if array.ndim == 1 else array.shape[1]
        setter = {1: GL.glUniform1fv, 3: GL.glUniform3fv, 4: GL.glUniform4fv}[width]
        setter(loc, array.shape[0], array)

    # ---- framebuffers ------------------------------------------------------------------------

    def _targets_for(self, width: int, height: int) -> _Targets:
        """G-buffer and color framebuffers that hold a ``width`` × ``height`` image in their
        lower left corner (the viewport): the last ones while they are large enough, else new
        ones of the larger of each side, rounded up to :data:`TARGET_STEP` pixels. The analysis
        renders windows around the face whose size changes from one rendering to the next;
        making (and first touching) new targets for each was a noticeable part of its frame.
        The pixels are the same in any size of target (``texelFetch`` at the fragment's own
        pixel; clears under the scissor)."""
        if self._targets is not None:
            have_w, have_h = self._targets.size
            if have_w >= width and have_h >= height:
                return self._targets
            width, height = max(width, have_w), max(height, have_h)
            self._targets.delete()
        width, height = (-(-n // TARGET_STEP) * TARGET_STEP for n in (width, height))
        textures = [int(t) for t in np.atleast_1d(GL.glGenTextures(len(G_TARGETS) + 1))]
        for i, t in enumerate(textures):
            fmt, channels = GL.GL_RGBA32F, GL.GL_RGBA
            if i == TRIANGLE_ATTACHMENT:
                fmt, channels = GL.GL_R32F, GL.GL_RED
            elif G_TARGETS[i] == "g_texel" and _filters_in_8_bits():
                fmt = GL.GL_RGBA8  # the texture's samples are 8-bit already: same values
            elif G_TARGETS[i] == "g_material":
                fmt, channels = GL.GL_R8, GL.GL_RED  # (index + 32 if textured) / 255: exact
            GL.glBindTexture(GL.GL_TEXTURE_2D, t)
            GL.glTexImage2D(GL.GL_TEXTURE_2D, 0, fmt, width, height, 0, channels, GL.GL_FLOAT, None)
            GL.glTexParameteri(GL.GL_TEXTURE_2D, GL.GL_TEXTURE_MIN_FILTER, GL.GL_NEAREST)
            GL.glTexParameteri(GL.GL_TEXTURE_2D, GL.GL_TEXTURE_MAG_FILTER, GL.GL_NEAREST)
        GL.glBindTexture(GL.GL_TEXTURE_2D, 0)
        color, depth = (int(b) for b in GL.glGenRenderbuffers(2))
        for rb, fmt in ((color, GL.GL_RGBA8), (depth, GL.GL_DEPTH24_STENCIL8)):
            GL.glBindRenderbuffer(GL.GL_RENDERBUFFER, rb)
            GL.glRenderbufferStorage(GL.GL_RENDERBUFFER, fmt, width, height)
        GL.glBindRenderbuffer(GL.GL_RENDERBUFFER, 0)
        gbuffer, color_fb = (int(f) for f in GL.glGenFramebuffers(2))
        GL.glBindFramebuffer(GL.GL_FRAMEBUFFER, gbuffer)
        for i, t in enumerate(textures):
            GL.glFramebufferTexture2D(
                GL.GL_FRAMEBUFFER, GL.GL_COLOR_ATTACHMENT0 + i, GL.GL_TEXTURE_2D, t, 0
            )
        GL.glFramebufferRenderbuffer(
            GL.GL_FRAMEBUFFER, GL.GL_DEPTH_STENCIL_ATTACHMENT, GL.GL_RENDERBUFFER, depth
        )
        _check_complete("G-buffer", width, height)
        GL.glBindFramebuffer(GL.GL_FRAMEBUFFER, color_fb)
        GL.glFramebufferRenderbuffer(
            GL.GL_FRAMEBUFFER, GL.GL_COLOR_ATTACHMENT0, GL.GL_RENDERBUFFER, color
        )
        GL.glFramebufferRenderbuffer(
            GL.GL_FRAMEBUFFER, GL.GL_DEPTH_STENCIL_ATTACHMENT, GL.GL_RENDERBUFFER, depth
        )
        _check_complete("color", width, height)
        GL.glBindFramebuffer(GL.GL_FRAMEBUFFER, 0)
        # the state cache may hold a binding of a deleted texture name that GL reuses
        self._state.clear()
        self._targets = _Targets((width, height), gbuffer, color_fb, textures, [color, depth])
        return self._targets


def _unlit(material) -> bool:
    """Whether the resolve pass shows ``material``'s pixels unlit
    (:data:`~vtts.render.scene.UNLIT`), without their position and normal."""
    return bool(getattr(material, UNLIT, False))


def _lit_targets(on: bool) -> None:
    """Store the G-buffer's position and normal (:data:`LIT_TARGETS`) of what is drawn next
    (``on``), or leave them as they are: an unlit material's pixels do not need them, and
    writing the two float targets was a fifth of the G-buffer pass's rasterizer time. The
    stencil marks what is drawn next as lit (1) or unlit (0), so that the resolve pass runs
    pyrender's lighting on the lit pixels only."""
    for index in LIT_TARGETS:
        GL.glColorMaski(index, on, on, on, on)
    GL.glStencilFunc(GL.GL_ALWAYS, int(on), 0xFF)


def _filters_in_8_bits() -> bool:
    """Whether the current context is Mesa's llvmpipe, which filters 8-bit textures in 8-bit
    arithmetic: every sample of the (8-bit) textures vtts draws is then a multiple of 1/255,
    which an ``RGBA8`` G-buffer target keeps exactly, for a third of the bytes the rasterizer's
    threads write and read (docs/rendering.md, "Speed"; ``tests/render`` compares the textured
    pixels with pyrender's). Other drivers filter in floats: their samples stay in a float
    target."""
    renderer = GL.glGetString(GL.GL_RENDERER) or b""
    return b"llvmpipe" in renderer


def _read_triangles(gbuffer: int, width: int, height: int) -> np.ndarray:
    """The triangle numbers of the G-buffer ``(H, W) int64``, top row first (−1: none)."""
    GL.glBindFramebuffer(GL.GL_READ_FRAMEBUFFER, gbuffer)
    GL.glReadBuffer(GL.GL_COLOR_ATTACHMENT0 + TRIANGLE_ATTACHMENT)
    buf = GL.glReadPixels(0, 0, width, height, GL.GL_RED, GL.GL_FLOAT)
    GL.glReadBuffer(GL.GL_COLOR_ATTACHMENT0)
    GL.glBindFramebuffer(GL.GL_READ_FRAMEBUFFER, 0)
    stored = np.frombuffer(buf, dtype=np.float32).reshape(height, width)[::-1]
    return stored.astype(np.int64) - 1


def _check_complete(what: str, width: int, height: int) -> None:
    if GL.glCheckFramebufferStatus(GL.GL_FRAMEBUFFER) != GL.GL_FRAMEBUFFER_COMPLETE:
        raise RenderError(f"cannot create a {width}x{height} {what} framebuffer")
