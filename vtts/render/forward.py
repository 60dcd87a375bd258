"""pyrender's forward pass without its per-primitive overhead.

pyrender draws each primitive by looking up every uniform by name, re-sending the camera and all
lights, re-binding GL state and querying GL limits — a few hundred OpenGL calls through PyOpenGL
per frame, a large part of a frame's Python for a head of a dozen primitives. :class:`ForwardPass`
draws the same scene with the same shader programs, vertex arrays and textures that pyrender put
on the GPU, sets the same uniform values and GL state before every draw and draws in the same
order, so the pixels are the same; it only leaves out what would not change them: a uniform is
sent once per program and frame unless its value changes, locations are looked up once, state is
set when it changes, and only the color buffer is read back (pyrender also reads and converts the
depth buffer).

Nothing is assumed to survive between frames (other code, pyrender included, may draw on the
same context in between): every frame sets all the state it relies on and sends pyrender's
programs their uniforms again. Only programs of vtts's own (see :mod:`vtts.render.deferred`) keep
their uniforms from frame to frame: nobody else uses them.

Scenes this pass does not cover (more lights of a kind than pyrender's shaders hold, wireframe,
specular-glossiness materials) go through pyrender's own ``render``. What it reads of pyrender's
internals goes through :mod:`vtts.render.pyrender_adapter`; import this module only after
:func:`~vtts.render.pyrender_adapter.load_pyrender` has chosen the OpenGL platform.
"""

from __future__ import annotations

import ctypes
import weakref

import numpy as np
from OpenGL import GL

from vtts.render.pyrender_adapter import (
    load_pyrender,
    main_framebuffers,
    make_current,
    node_matrices,
    node_path,
    primitive_program,
    program_id,
    scene_renderer,
    texture_id,
    upload_scene,
    vertex_array,
)


class ForwardPass:
    """Renders pyrender scenes on the context of ``offscreen`` (a ``pyrender.OffscreenRenderer``).

    :meth:`render` returns the color image ``(H, W, 3)`` or, with ``rgba``, ``(H, W, 4) uint8``,
    top row first, as ``offscreen.render(scene)`` would.
    """

    def __init__(self, offscreen) -> None:
        from pyrender.constants import GLTF, MAX_N_LIGHTS, ProgramFlags, RenderFlags, TexFlags

        self._pyrender_module = load_pyrender()
        self._offscreen = offscreen
        self._max_lights = MAX_N_LIGHTS
        self._points_mode = GLTF.POINTS
        self._use_material = ProgramFlags.USE_MATERIAL
        self._flags = RenderFlags.OFFSCREEN
        # pyrender's texture slots in its binding order, with the sampler uniform each feeds
        # (its specular-glossiness name matches no uniform: pyrender skips it silently, so do we)
        self._texture_slots = [
            (TexFlags.NORMAL, "normalTexture", "material.normal_texture"),
            (TexFlags.OCCLUSION, "occlusionTexture", "material.occlusion_texture"),
            (TexFlags.EMISSIVE, "emissiveTexture", "material.emissive_texture"),
            (TexFlags.BASE_COLOR, "baseColorTexture", "material.base_color_texture"),
            (
                TexFlags.METALLIC_ROUGHNESS,
                "metallicRoughnessTexture",
                "material.metallic_roughness_texture",
            ),
            (TexFlags.DIFFUSE, "diffuseTexture", "material.diffuse_texture"),
            (
                TexFlags.SPECULAR_GLOSSINESS,
                "specularGlossinessTexture",
                "material.specular_glossiness_texture",
            ),
        ]
        # primitive -> pyrender ShaderProgram (weak: primitives come and go with their scenes)
        self._programs: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()
        self._locations: dict[tuple[int, str], int] = {}  # (program id, uniform) -> location
        self._frame_uniforms: dict[str, object] = {}  # camera and lights, this frame
        self._frame_sent: set[int] = set()  # programs that have this frame's camera and lights
        self._sent: dict[tuple[int, str], object] = {}  # uniform values sent (see _begin_frame)
        # programs only this pass uses: their uniforms keep their values from frame to frame
        self._private: set[int] = set()
        self._state: dict[object, object] = {}  # GL state set this frame
        # this frame's camera and lights as sent (see _use), and what each of our own programs got
        self._frame_key: tuple = ()
        self._frame_got: dict[int, tuple] = {}
        # node -> (its path to the root, the matrices along it, its world pose): see _pose
        self._poses: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()

    # ---- entry point -------------------------------------------------------------------------

    def supports(self, scene) -> bool:
        """Whether this pass draws ``scene`` as pyrender would (else use pyrender's render)."""
        pr = self._pyrender_module
        if max(light_counts(scene)) > self._max_lights:
            return False
        if scene.main_camera_node is None:
            return False
        for mesh in scene.meshes:
            for p in mesh.primitives:
                if not isinstance(p.material, pr.MetallicRoughnessMaterial) or p.material.wireframe:
                    return False
        return True

    def render(self, scene, width: int, height: int, rgba: bool = False) -> np.ndarray:
        """Draw ``scene`` into a ``width`` × ``height`` image and read it back."""
        if not self.supports(scene):
            return self._pyrender(scene, width, height, rgba)
        r = self._begin_frame(scene, width, height)
        drawn_fb, read_fb, (w, h) = main_framebuffers(r)
        GL.glBindFramebuffer(GL.GL_DRAW_FRAMEBUFFER, drawn_fb)
        GL.glClearColor(*scene.bg_color)
        GL.glClear(GL.GL_COLOR_BUFFER_BIT | GL.GL_DEPTH_BUFFER_BIT)
        self._forward_state()
        for node, pose in self._sorted_mesh_nodes(scene):
            for primitive in node.mesh.primitives:
                self._draw(primitive, pose, r)
        GL.glBindFramebuffer(GL.GL_READ_FRAMEBUFFER, drawn_fb)
        GL.glBindFramebuffer(GL.GL_DRAW_FRAMEBUFFER, read_fb)
        GL.glBlitFramebuffer(0, 0, w, h, 0, 0, w, h, GL.GL_COLOR_BUFFER_BIT, GL.GL_LINEAR)
        self._end_frame()
        return read_color(read_fb, w, h, rgba)

    def _pyrender(self, scene, width: int, height: int, rgba: bool) -> np.ndarray:
        """pyrender's own render (for scenes this pass does not cover)."""
        offscreen = self._offscreen
        offscreen.viewport_width, offscreen.viewport_height = width, height
        flags = self._pyrender_module.RenderFlags
        flags = flags.RGBA if rgba else flags.NONE
        return offscreen.render(scene, flags=flags)[0]

    # ---- one frame ---------------------------------------------------------------------------

    def _begin_frame(self, scene, width: int, height: int):
        """Make the context current, put new meshes and textures on the GPU, forget the last
        frame's state and compute this frame's camera and light uniforms. Returns pyrender's
        renderer."""
        make_current(self._offscreen)
        r = scene_renderer(self._offscreen)
        r.viewport_width, r.viewport_height = width, height
        upload_scene(r, scene, self._flags)
        self._frame_sent.clear()
        # pyrender's own programs may have been used by pyrender in between: forget what they got
        self._sent = {k: v for k, v in self._sent.items() if k[0] in self._private}
        self._state.clear()
        camera = scene.main_camera_node
        cam_pose = self._pose(scene, camera)
        self._cam_pos = cam_pose[:3, 3]
        uniforms = {
            "V": np.linalg.inv(cam_pose),
            "P": camera.camera.get_projection_matrix(width=width, height=height),
            "cam_pos": cam_pose[:3, 3],
            **self._light_uniforms(scene),
        }
        self._frame_uniforms = {name: _gl_value(v) for name, v in uniforms.items()}
        self._frame_key = tuple((n, _fingerprint(v)) for n, v in self._frame_uniforms.items())
        GL.glViewport(0, 0, width, height)
        GL.glDepthRange(0.0, 1.0)
        GL.glPolygonMode(GL.GL_FRONT_AND_BACK, GL.GL_FILL)
        return r

    def _forward_state(self) -> None:
        """The state pyrender's forward pass draws with (per primitive state follows in
        :meth:`_draw`)."""
        GL.glEnable(GL.GL_DEPTH_TEST)
        GL.glDepthMask(GL.GL_TRUE)
        GL.glDepthFunc(GL.GL_LESS)
        GL.glEnable(GL.GL_MULTISAMPLE)
        GL.glEnable(GL.GL_BLEND)
        GL.glActiveTexture(GL.GL_TEXTURE0)
        self._state.clear()
        self._state[GL.GL_ACTIVE_TEXTURE] = 0

    def _end_frame(self) -> None:
        GL.glBindVertexArray(0)
        GL.glUseProgram(0)
        GL.glFlush()

    def _light_uniforms(self, scene) -> dict[str, object]:
        """The lighting uniforms of pyrender's ``_bind_lighting`` (without shadows)."""
        pr = self._pyrender_module
        u: dict[str, object] = {"ambient_light": scene.ambient_light}
        for kind, n in zip(LIGHT_KINDS, light_counts(scene), strict=True):
            u[f"n_{kind}"] = n
        counts = {"point_lights": 0, "spot_lights": 0, "directional_lights": 0}
        for n in scene.light_nodes:
            light = n.light
            pose = self._pose(scene, n)
            position, direction = pose[:3, 3], -pose[:3, 2]
            if isinstance(light, pr.PointLight):
                kind = "point_lights"
            elif isinstance(light, pr.SpotLight):
                kind = "spot_lights"
            else:
                kind = "directional_lights"
            b = f"{kind}[{counts[kind]}]."
            counts[kind] += 1
            if kind == "spot_lights":
                las = 1.0 / max(0.001, np.cos(light.innerConeAngle) - np.cos(light.outerConeAngle))
                u[b + "direction"] = direction
                u[b + "position"] = position
                u[b + "light_angle_scale"] = las
                u[b + "light_angle_offset"] = -np.cos(light.outerConeAngle) * las
            elif kind == "point_lights":
                u[b + "position"] = position
            else:
                u[b + "direction"] = direction
            u[b + "color"] = light.color
            u[b + "intensity"] = light.intensity
        return u

    def _sorted_mesh_nodes(self, scene) -> list[tuple[object, np.ndarray]]:
        """pyrender's drawing order (opaque, then transparent, each farthest first), with each
        node's world pose."""
        solid, transparent = self._mesh_nodes(scene)
        return solid + transparent

    def _mesh_nodes(self, scene) -> tuple[list, list]:
        """The visible opaque and the visible transparent mesh nodes as ``(node, world pose)``,
        each list in pyrender's drawing order (farthest first)."""
        solid, transparent = [], []
        for node in scene.mesh_nodes:
            if not node.mesh.is_visible:
                continue
            pose = self._pose(scene, node)
            (transparent if node.mesh.is_transparent else solid).append((node, pose))
        cam = self._cam_pos

        def key(item):
            return -np.linalg.norm(item[1][:3, 3] - cam)

        solid.sort(key=key)
        transparent.sort(key=key)
        return solid, transparent

    def _pose(self, scene, node) -> np.ndarray:
        """``scene.get_pose(node)``: the same product in the same order, kept from frame to
        frame while the nodes on the way to the root keep their matrices (pyrender makes a new
        array whenever a node's pose is set). Not to be changed by the caller."""
        path = node_path(scene, node)
        if path is None:
            return scene.get_pose(node)  # which finds the path and keeps it
        matrices = node_matrices(path)
        known = self._poses.get(node)
        if (
            known is not None
            and known[0] is path
            and all(a is b for a, b in zip(known[1], matrices, strict=True))
        ):
            return known[2]
        pose = np.eye(4)
        for m in matrices:
            pose = np.dot(m, pose)
        self._poses[node] = (path, matrices, pose)
        return pose

    def _program(self, primitive, r):
        """pyrender's shader program for ``primitive`` (compiled on first use)."""
        program = self._programs.get(primitive)
        if program is None or program_id(program) is None:
            program = primitive_program(r, primitive, self._flags, self._use_material)
            self._programs[primitive] = program
        return program

    def _use(self, pid: int) -> None:
        """Make ``pid`` the current program, with this frame's camera and lights (which one of
        vtts's own programs keeps from an earlier frame when they did not change)."""
        self._set(GL.GL_CURRENT_PROGRAM, pid, GL.glUseProgram)
        if pid not in self._frame_sent:
            if self._frame_got.get(pid) != self._frame_key:
                for name, value in self._frame_uniforms.items():
                    self._uniform(pid, name, value)
                if pid in self._private:
                    self._frame_got[pid] = self._frame_key
            self._frame_sent.add(pid)

    def _draw(self, primitive, pose: np.ndarray, r) -> None:
        """Draw one primitive as pyrender's ``_bind_and_draw_primitive`` does."""
        pid = program_id(self._program(primitive, r))
        self._use(pid)
        self._uniform(pid, "M", pose)
        material = primitive.material
        unit = 0
        for flag, attribute, uniform in self._texture_slots:
            if material.tex_flags & flag:
                texture = getattr(material, attribute)
                self._texture(pid, uniform, unit, texture.tex_type, texture_id(texture))
                unit += 1
        self._uniform(pid, "material.emissive_factor", material.emissiveFactor)
        self._uniform(pid, "material.base_color_factor", material.baseColorFactor)
        self._uniform(pid, "material.metallic_factor", material.metallicFactor)
        self._uniform(pid, "material.roughness_factor", material.roughnessFactor)
        blend = (
            (GL.GL_SRC_ALPHA, GL.GL_ONE_MINUS_SRC_ALPHA)
            if material.alphaMode == "BLEND"
            else (GL.GL_ONE, GL.GL_ZERO)
        )
        self._set(GL.GL_BLEND_SRC, blend, _blend_func)
        self._set(GL.GL_CULL_FACE, not material.doubleSided, cull_back)
        points = primitive.mode == self._points_mode
        self._set(GL.GL_PROGRAM_POINT_SIZE, points and r.point_size, _point_size)
        self._draw_call(primitive)

    def _draw_call(self, primitive) -> None:
        GL.glBindVertexArray(vertex_array(primitive))
        n_instances = 1 if primitive.poses is None else len(primitive.poses)
        if primitive.indices is not None:
            GL.glDrawElementsInstanced(
                primitive.mode,
                primitive.indices.size,
                GL.GL_UNSIGNED_INT,
                ctypes.c_void_p(0),
                n_instances,
            )
        else:
            GL.glDrawArraysInstanced(primitive.mode, 0, len(primitive.positions), n_instances)

    # ---- state and uniforms, each sent only when it changes ------------------------------------

    def _set(self, key, value, apply) -> None:
        if self._state.get(key, _UNSET) != value:
            apply(value)
            self._state[key] = value

    def _texture(self, pid: int, uniform: str, unit: int, target: int, texture: int) -> None:
        """Bind the GL texture ``texture`` to texture unit ``unit`` and point the sampler
        ``uniform`` at it."""
        self._set(GL.GL_ACTIVE_TEXTURE, unit, _active_texture)
        self._set(("texture", unit), (target, texture), _bind_texture)
        self._uniform(pid, uniform, unit)

    def _uniform(self, pid: int, name: str, value) -> None:
        """Set a uniform as pyrender's ``ShaderProgram.set_uniform`` does (same types, same
        conversions; names the shader lacks are skipped), unless it has that value already."""
        value = _gl_value(value)
        key = (pid, name)
        sent = self._sent.get(key, _UNSET)
        fingerprint = _fingerprint(value)
        if sent == fingerprint:
            return
        self._sent[key] = fingerprint
        loc = self._locations.get(key)
        if loc is None:
            loc = self._locations[key] = GL.glGetUniformLocation(pid, name)
        if loc == -1:
            return
        if isinstance(value, np.ndarray):
            if value.ndim == 1:
                _VECTOR[(value.shape[0], value.dtype.kind)](loc, 1, value)
            else:
                _MATRIX[value.shape](loc, 1, GL.GL_TRUE, value)
        elif isinstance(value, float):
            GL.glUniform1f(loc, value)
        elif isinstance(value, int):
            GL.glUniform1i(loc, value)
        # other types: pyrender raises and swallows its own error, leaving the uniform as it was


#: pyrender's kinds of light, as its uniforms name them (``n_directional_lights``, …), in the
#: order of :func:`light_counts`.
LIGHT_KINDS = ("directional_lights", "point_lights", "spot_lights")


def light_counts(scene) -> tuple[int, int, int]:
    """The numbers of directional, point and spot lights of ``scene`` (:data:`LIGHT_KINDS`)."""
    return (
        len(scene.directional_light_nodes),
        len(scene.point_light_nodes),
        len(scene.spot_light_nodes),
    )


def read_color(framebuffer: int, width: int, height: int, rgba: bool) -> np.ndarray:
    """The color buffer of ``framebuffer``, top row first, ``(H, W, 3 or 4) uint8``."""
    GL.glBindFramebuffer(GL.GL_READ_FRAMEBUFFER, framebuffer)
    channels, fmt = (4, GL.GL_RGBA) if rgba else (3, GL.GL_RGB)
    buf = GL.glReadPixels(0, 0, width, height, fmt, GL.GL_UNSIGNED_BYTE)
    return np.flip(np.frombuffer(buf, dtype=np.uint8).reshape(height, width, channels), axis=0)


def _gl_value(value):
    """A uniform value as pyrender sends it: arrays as float32 (int32 when integer), Python
    scalars as they are."""
    if isinstance(value, np.ndarray):
        want = np.int32 if value.dtype.kind in "iu" else np.float32
        return value if value.dtype == want else value.astype(want)
    return value


def _fingerprint(value) -> tuple:
    """What tells two uniform values (as :func:`_gl_value` makes them) apart."""
    if isinstance(value, np.ndarray):
        return (value.dtype.char, value.shape, value.tobytes())
    return (type(value), value)


_UNSET = object()

_VECTOR = {
    (1, "f"): GL.glUniform1fv,
    (2, "f"): GL.glUniform2fv,
    (3, "f"): GL.glUniform3fv,
    (4, "f"): GL.glUniform4fv,
    (1, "i"): GL.glUniform1iv,
    (2, "i"): GL.glUniform2iv,
    (3, "i"): GL.glUniform3iv,
    (4, "i"): GL.glUniform4iv,
}
_MATRIX = {
    (2, 2): GL.glUniformMatrix2fv,
    (3, 3): GL.glUniformMatrix3fv,
    (4, 4): GL.glUniformMatrix4fv,
}


def _active_texture(unit: int) -> None:
    GL.glActiveTexture(GL.GL_TEXTURE0 + unit)


def _bind_texture(target_and_id: tuple[int, int]) -> None:
    GL.glBindTexture(*target_and_id)


def _blend_func(factors: tuple[int, int]) -> None:
    GL.glBlendFunc(*factors)


def cull_back(cull: bool) -> None:
    """Cull back faces (``cull``), as pyrender does for a material that is not double-sided, or
    draw both sides."""
    if cull:
        GL.glEnable(GL.GL_CULL_FACE)
        GL.glCullFace(GL.GL_BACK)
    else:
        GL.glDisable(GL.GL_CULL_FACE)


def _point_size(size) -> None:
    if size:
        GL.glEnable(GL.GL_PROGRAM_POINT_SIZE)
        GL.glPointSize(size)
    else:
        GL.glDisable(GL.GL_PROGRAM_POINT_SIZE)
