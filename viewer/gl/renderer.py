"""The rasterizer: shadow maps, a forward pass into a linear HDR float target with MSAA, and a
tone-mapping pass to the screen or an 8-bit sRGB image. The window and the offscreen path both
call ``Renderer.render``; only the owner of the final framebuffer differs.

A frame is a sequence of named steps (``_render``): the frame's targets and switches, the shadow
pass (viewer/gl/shadow.py), the environment (IBL, the thickness of absorbers: viewer/gl/targets.py,
the materials' albedo tables: viewer/gl/material_tables.py), the background, the per-frame uniforms, the
traced chains' scene data (viewer/gl/raytrace.py), one draw per object with its forward-program
variant (viewer/gl/programs.py), and the SSR pass or the MSAA resolve. Programs are kept and hot
reloaded by a ``ProgramCache``."""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from viewer import brdf
from viewer.brdf import thin_film
from viewer.scene.camera import OrbitCamera, gl_bytes
from viewer.gl import texture_units
from viewer.gl.brdf_glsl import uniform_block
from viewer.gl.constants import IBL_MODES, LIGHT_TYPES, MAT_FLOATS, MAX_LIGHTS, SSR_VIEW_BASE, TONEMAPS, VIEW_MODES
from viewer.gl.context import release_gl
from viewer.gl.material_tables import MaterialTables
from viewer.gl.programs import FORWARD_STAGES, ProgramCache, Recipe, forward_variant
from viewer.gl.shaders import ShaderError
from viewer.gl.shaders import set_uniform as _set
from viewer.gl.raytrace import chain_traces, dispersive
from viewer.gl.raytrace import MAX_SEGMENTS as RT_MAX_SEGMENTS
from viewer.gl.shadow import SHADOW_TILE, ShadowMaps, shadow_lights
from viewer.gl.targets import HdrTarget, ThicknessPass

GL_SRC1_COLOR = 0x88F9  # dual-source blending (core since OpenGL 3.3); moderngl names no constant

__all__ = ["Renderer", "GpuMesh", "MAX_LIGHTS", "SHADOW_TILE", "TONEMAPS", "IBL_MODES", "VIEW_MODES",
           "SSR_VIEW_BASE"]


def brdf_spec(params):
    from viewer import brdf

    return brdf.get(params.model).spec


def thin_shell(params) -> bool:
    """A dielectric of ior 1 (air on both sides, e.g. a soap film's bubble): light crosses it
    without bending, so the rasterizer blends what lies behind it through its transmittance
    instead of looking the refracted ray up in the environment."""
    return brdf_spec(params).transmissive and float(params.get("ior", 1.5)) == 1.0


def _absorbing(params) -> bool:
    return brdf_spec(params).transmissive and "sigma_a" in params and bool(np.any(np.asarray(params.sigma_a) > 0))


_FIXED = {
    "forward:lambert": Recipe(*FORWARD_STAGES),
    "shadow": Recipe("passes/shadow.vert", "passes/shadow.frag"),
    "tonemap": Recipe("passes/fullscreen.vert", "passes/tonemap.frag"),
}
# programs built on first use
_BACKGROUND = Recipe("passes/fullscreen.vert", "passes/background.frag")
_THICKNESS = Recipe("passes/forward.vert", "passes/thickness.frag")
_TRACED_MASK = Recipe("passes/forward.vert", "passes/traced_mask.frag")


def group_by(items, key) -> list[list]:
    """``items`` in groups of equal ``key(item)``, the groups in order of first appearance."""
    groups: dict = {}
    for it in items:
        groups.setdefault(key(it), []).append(it)
    return list(groups.values())


INSTANCE_FLOATS = 25   # per instance: the model matrix (16) and the normal matrix (9), column-major


def instance_data(objects) -> np.ndarray:
    """(N, 25) float32 per-instance attributes of ``objects`` for ``in_model`` and
    ``in_normal_matrix`` (shaders/passes/forward.vert): ``SceneObject.model_matrix`` for all of
    them at once, T(translate) R_y S(scale), and its inverse transpose R_y S^-1 (R_y is
    orthonormal), both column-major as GLSL reads them."""
    n = len(objects)
    out = np.empty((n, INSTANCE_FLOATS), np.float32)
    if n == 0:
        return out
    t = np.array([o.translate for o in objects], np.float64).reshape(n, 3)
    sc = np.array([np.broadcast_to(np.asarray(o.scale, np.float64), (3,)) for o in objects])
    ang = [math.radians(o.rotate_y_deg) for o in objects]
    c = np.array([math.cos(a) for a in ang])
    sn = np.array([math.sin(a) for a in ang])
    rot = np.zeros((n, 3, 3))
    rot[:, 0, 0], rot[:, 0, 2], rot[:, 1, 1], rot[:, 2, 0], rot[:, 2, 2] = c, sn, 1.0, -sn, c
    m = np.zeros((n, 4, 4))
    m[:, :3, :3] = rot * sc[:, None, :]
    m[:, :3, 3] = t
    m[:, 3, 3] = 1.0
    nrm = rot / sc[:, None, :]
    out[:, :16] = m.transpose(0, 2, 1).reshape(n, 16)      # column-major
    out[:, 16:] = nrm.transpose(0, 2, 1).reshape(n, 9)
    return out


class GpuMesh:
    """Vertex and index buffers of one MeshData, shared by every object that uses it, and its
    per-instance buffer: each draw renders all the instances written by ``draw`` at once (one
    draw per mesh and material instead of one per object). One vertex array per program."""

    def __init__(self, ctx, mesh):
        data = np.hstack([mesh.positions, mesh.normals, mesh.tangents]).astype("f4")
        self.vbo = ctx.buffer(np.ascontiguousarray(data).tobytes())
        self.ibo = ctx.buffer(np.ascontiguousarray(mesh.indices, dtype="u4").tobytes())
        self.inst = ctx.buffer(reserve=4 * INSTANCE_FLOATS, dynamic=True)
        self.ctx = ctx
        self.vaos = {}

    def vao(self, prog):
        key = id(prog)
        if key not in self.vaos:
            # attributes the compiler dropped (e.g. the tangent when no model uses it) are skipped
            content = []
            for buf, attrs, per in ((self.vbo, (("in_position", "3f", 12), ("in_normal", "3f", 12),
                                                ("in_tangent", "4f", 16)), ""),
                                    (self.inst, (("in_model", "16f", 64), ("in_normal_matrix", "9f", 36)), "/i")):
                fmt, names = [], []
                for name, f, size in attrs:
                    if name in prog:
                        fmt.append(f)
                        names.append(name)
                    else:
                        fmt.append(f"{size}x")
                if names:
                    content.append((buf, " ".join(fmt) + per, *names))
            self.vaos[key] = self.ctx.vertex_array(prog, content, index_buffer=self.ibo, index_element_size=4)
        return self.vaos[key]

    def draw(self, prog, instances: np.ndarray):
        """Render the mesh once per row of ``instances`` ((N, 25) float32, ``instance_data``)."""
        data = np.ascontiguousarray(instances, np.float32).tobytes()
        if not data:
            return
        self.inst.orphan(len(data))   # fresh storage: a draw still reading the old rows is not waited for
        self.inst.write(data)
        self.vao(prog).render(instances=len(instances))

    def release(self):
        for v in self.vaos.values():
            v.release()
        self.vbo.release()
        self.ibo.release()
        self.inst.release()


class _Frame(NamedTuple):
    """What one frame renders with: size, camera, targets and the switches the steps share."""

    w: int
    h: int
    cam: OrbitCamera
    targets: dict
    view_mode: int      # the forward pass's (0 when the SSR pass shows a debug view)
    ssr_on: bool
    ssr_debug: int      # the SSR pass's output (0: the composite)
    lights: list
    shadows: bool
    env_rad: np.ndarray  # the constant environment's radiance (intensity applied)
    env_map: object      # the radiance map, or None
    env_on: bool         # the environment lights the scene (IBL not off, not black)
    raytrace: bool       # traced chains on (the scene's ``raytrace`` unless the call overrides it)
    region: tuple | None  # (x, y, w, h) scissor of the background and forward draws, else None


def frame_switches(scene, raytrace: bool | None = None) -> tuple[bool, bool, bool, bool]:
    """(SSR on, the environment lights the scene, it is a constant one, traced chains drawn) of
    a frame of ``scene`` (``raytrace`` overrides the scene's), as ``Renderer.render`` decides
    them, without loading a map."""
    env = scene.environment
    constant = env.map is None
    lit = constant and env.constant is not None and bool(np.any(np.asarray(env.constant, float) * env.intensity > 0))
    env_on = scene.render.ibl != "off" and (not constant or lit)
    rt_on = bool(scene.render.raytrace) if raytrace is None else bool(raytrace)
    # as _raytrace_setup: the call's switch on, and the scene's (``traces``)
    traced = rt_on and bool(scene.render.raytrace) and any(
        chain_traces(scene.materials[o.material]) for o in scene.objects)
    return bool(scene.render.ssr), env_on, constant, traced


def forward_args(scene, params, ssr_on: bool, env_on: bool, env_constant: bool, traced_frame: bool) -> dict:
    """The ``Renderer.forward_program`` arguments of the program that draws ``params`` in a frame
    of ``scene`` with these switches (``traced_frame``: the frame traces specular chains)."""
    traced = traced_frame and chain_traces(params)
    shell = not traced and thin_shell(params)
    # a file BRDF's lobe is unknown: no split sum can be pre-integrated for it, so its
    # environment light is importance sampled (fis, or brute force when asked for)
    custom_fis = brdf.is_file(params) and env_on and scene.render.ibl == "split_sum"
    ibl_sampled = env_on and scene.render.ibl in ("fis", "brute_force")
    return {"ssr": ssr_on and not shell, "ibl_sampled": ibl_sampled or custom_fis, "env_light": env_on,
            "env_constant": env_constant, "traced": list(scene.materials.values()) if traced else None,
            "dispersion": traced and dispersive(scene), "shell": shell}


class Renderer:
    # No per-sample shading (GLSL 'sample' inputs): on Mesa llvmpipe 22.3 it gave wrong shadow
    # visibility on fully covered pixels near silhouettes (measured against the reference). For
    # an exact box filter use render_arrays(..., supersample=k) instead.

    def __init__(self, ctx):
        self.ctx = ctx
        self._meshes: dict[int, tuple[object, GpuMesh]] = {}
        self._programs = ProgramCache(ctx, vao_tables=lambda: [gm.vaos for _, gm in self._meshes.values()])
        self._render_error: ShaderError | None = None
        self.build_programs()
        self._hdr = HdrTarget(ctx)
        self._ldr = None
        self._shadows = ShadowMaps(ctx)
        self.tables = MaterialTables(ctx)
        self._thick = ThicknessPass(ctx)
        self._ssr_back = ThicknessPass(ctx)  # the nearest back face of every object, for SSR hits
        self._ibl = None
        self._ssr = None
        self._rt = None
        self._measured = None
        self._frame_targets = None  # the last frame's colour targets (resolved_framebuffer)
        self._mask_target = None    # (size, texture, depth, framebuffer) of traced_mask

    # ---------------------------------------------------------------- programs
    @property
    def programs(self) -> dict:
        """The programs built so far, by key (``forward:<models>:<variant>``, ``shadow``, ...)."""
        return self._programs.programs

    #: set by hot reload (viewer/gl/hot_reload.py): a program that fails to compile is reported
    #: in ``shader_errors`` instead of raised from ``render`` (objects whose forward program has
    #: no good version yet are left out of the image), and is retried when a shader file changes.
    @property
    def hot_reload(self) -> bool:
        return self._programs.hot_reload

    @hot_reload.setter
    def hot_reload(self, on: bool):
        self._programs.hot_reload = bool(on)

    @property
    def last_reloaded(self) -> list[str]:
        """The keys of the programs the last ``reload_shaders`` replaced."""
        return self._programs.last_reloaded

    def build_programs(self):
        """(Re)compile the fixed passes. Raises ShaderError; on failure the old programs stay.

        The forward pass is compiled per set of material models (``forward_program``), on
        first use, and cached: a slider move is a uniform upload, a model switch compiles at
        most once. ``reload_shaders`` rebuilds every program from the files."""
        self._programs.build_all(_FIXED)

    def _fullscreen_vao(self, prog):
        return self._programs.fullscreen_vao(prog)

    @property
    def shader_errors(self) -> list[ShaderError]:
        """The programs that do not compile from the current files (each error once; a program
        that failed keeps rendering with its last good version). Empty when all compile."""
        return self._programs.errors([] if self._render_error is None else [self._render_error])

    def file_brdfs(self) -> set[str]:
        """The paths of the ``.brdf`` files of the programs in use (hot reload watches them)."""
        return self._programs.file_brdfs()

    def reload_shaders(self, changed=None) -> list[ShaderError]:
        """Rebuild programs from the shader files as they are now and return ``shader_errors``.

        ``changed``: paths relative to shader_root() that changed (as ShaderWatcher reports
        them), or None for all. A program is compiled again only if its preprocessed sources
        differ from those of the program in use (or, for the SSR and IBL passes' programs, if
        it includes a changed file), or if it failed before and its sources changed since.
        A program that compiles replaces the old one, which is released only then; one that
        fails keeps the old one in use. Never raises ShaderError. ``last_reloaded`` lists the
        keys of the programs replaced."""
        changed = None if changed is None else {str(c).replace("\\", "/") for c in changed}
        if changed is None or any(c.startswith(("brdf/", "common/")) or c.endswith(".brdf") for c in changed):
            self.tables.shaders_changed()  # the albedo tables come from the GLSL samplers
        self._render_error = None  # the next render tries again
        self._programs.reload(changed, passes={"ssr": self._ssr, "ibl": self._ibl})
        return self.shader_errors

    def forward_program(self, params, ssr: bool = False,
                        ibl_sampled: bool = False, env_light: bool = True, env_constant: bool = False,
                        traced=None, dispersion: bool = False, shell: bool = False):
        """The forward program for a material (its model, and a nested base model if any); the
        variants are ``programs.forward_variant``'s (``traced``: the scene's materials, for a
        mirror or smooth glass whose specular chain is traced; ``shell``: a thin shell's)."""
        key, models, defines = forward_variant(params, ssr=ssr, ibl_sampled=ibl_sampled,
                                               env_light=env_light, env_constant=env_constant, traced=traced,
                                               dispersion=dispersion, shell=shell)
        prog = self.programs.get(key)  # the per-frame path: no recipe built when cached
        if prog is not None:
            return prog
        return self._programs.get(key, Recipe(*FORWARD_STAGES, models=tuple(models),
                                              defines=tuple(defines.items())))

    def forward_keys(self, scene, raytrace: bool | None = None) -> dict[str, str]:
        """material name -> the key of the forward program a frame of ``scene`` draws its
        objects with (``programs`` holds it once built): what a preset or model change must
        compile before the frame can show it."""
        sw = frame_switches(scene, raytrace)
        out = {}
        for name in dict.fromkeys(o.material for o in scene.objects):
            params = scene.materials[name]
            out[name] = forward_variant(params, **forward_args(scene, params, *sw))[0]
        return out

    # ---------------------------------------------------------------- resources
    def _gpu_mesh(self, mesh) -> GpuMesh:
        key = id(mesh)
        hit = self._meshes.get(key)
        if hit is None or hit[0] is not mesh:
            if hit is not None:
                hit[1].release()
            hit = (mesh, GpuMesh(self.ctx, mesh))
            self._meshes[key] = hit
        return hit[1]

    def draw_objects(self, objects, prog):
        """Draw ``objects`` with ``prog``: one instanced draw per mesh they use, in order of
        first appearance (the shadow and thickness passes)."""
        for group in group_by(objects, lambda o: id(o.mesh_data)):
            self._gpu_mesh(group[0].mesh_data).draw(prog, instance_data(group))

    def forget_meshes(self, keep=()):
        """Release GPU buffers of meshes not in ``keep`` (called when a scene is replaced)."""
        keep_ids = {id(m) for m in keep}
        for key in list(self._meshes):
            if key not in keep_ids:
                self._meshes.pop(key)[1].release()

    def _ensure_targets(self, w, h, samples):
        return self._hdr.ensure(w, h, samples)

    # ---------------------------------------------------------------- material tables
    @property
    def gpu_albedo(self) -> bool:
        """Albedo tables with the GLSL samplers (False: the numpy builder)."""
        return self.tables.gpu

    @gpu_albedo.setter
    def gpu_albedo(self, on: bool):
        self.tables.gpu = bool(on)

    @property
    def albedo_gpu_error(self) -> ShaderError | None:
        """Why the GPU albedo builder last failed (the tables then came from numpy), or None."""
        return self.tables.gpu_error

    def albedo_tables(self, params) -> tuple[np.ndarray, np.ndarray, np.ndarray, float, np.ndarray]:
        """A material's environment-lighting data, cached by its parameter values (see
        ``MaterialTables.albedo_tables``)."""
        return self.tables.albedo_tables(params)

    def ms_f0(self, params) -> np.ndarray:
        """The normal-incidence Fresnel of a material's specular part (``MaterialTables.ms_f0``)."""
        return self.tables.ms_f0(params)

    # ---------------------------------------------------------------- passes
    def ibl(self):
        """The image-based lighting state (prefiltered environment), created on first use."""
        if self._ibl is None:
            from viewer.gl.ibl import IBL

            self._ibl = IBL(self.ctx)
        return self._ibl

    def _measured_textures(self):
        """The 3D textures of measured BRDF tables (viewer/gl/measured_tex.py), made on first use."""
        if self._measured is None:
            from viewer.gl.measured_tex import MeasuredTextures

            self._measured = MeasuredTextures(self.ctx)
        return self._measured

    def raytrace_state(self):
        """The scene's BVH and material textures for traced chains (viewer/gl/raytrace.py)."""
        if self._rt is None:
            from viewer.gl.raytrace import RayTrace

            self._rt = RayTrace(self.ctx)
        return self._rt

    def ssr(self):
        """The screen-space reflection pass (viewer/gl/ssr.py), created on first use."""
        if self._ssr is None:
            from viewer.gl.ssr import SSR

            self._ssr = SSR(self.ctx)
        return self._ssr

    def render(self, scene, camera: OrbitCamera | None = None, width: int | None = None,
               height: int | None = None, view_mode: int = 0, msaa: int | None = None, frame_index: int = 0,
               raytrace: bool | None = None, region: tuple | None = None):
        """Render the scene into the linear HDR target; returns the resolved float texture.

        ``raytrace``: False draws mirrors and smooth glass with the untraced approximation even
        when the scene says ``raytrace = true`` (the window's preview frames), None follows the
        scene. ``region`` = (x, y, w, h) in pixels from the bottom left: only those pixels are
        drawn (a scissor on the background and forward draws; shadow maps and the other passes
        are whole), each exactly as in a whole frame (the window's progressive trace,
        ``viewer.gl.raytrace.ProgressiveTrace``); the rest of the target is left undefined.

        Raises ShaderError when a program it needs does not compile, except in hot-reload mode
        (``hot_reload``): there the error goes to ``shader_errors``, an object whose forward
        program never compiled is left out, and a pass that cannot be built gives back the
        colour target as it is (normally the previous frame)."""
        self._programs.keep_files(scene.materials.values())  # a file the scene let go: no stale error
        if not self.hot_reload:
            return self._render(scene, camera, width, height, view_mode, msaa, frame_index, raytrace, region)
        try:
            hdr = self._render(scene, camera, width, height, view_mode, msaa, frame_index, raytrace, region)
        except ShaderError as e:
            self._render_error = e
            w = int(width or scene.camera.width)
            h = int(height or scene.camera.height)
            return self._ensure_targets(w, h, scene.render.msaa if msaa is None else msaa).resolved
        self._render_error = None
        return hdr

    def _render(self, scene, camera, width, height, view_mode, msaa, frame_index, raytrace=None, region=None):
        f = self._begin_frame(scene, camera, width, height, view_mode, msaa, raytrace, region)
        if f.shadows:
            self._shadows.update(scene, self.programs["shadow"], self.draw_objects)
        thickness = self._environment(scene, f)
        if f.region is not None:  # applied by every use() of the frame's colour target
            f.targets.draw_fbo.scissor = f.region
        try:
            self._draw_background(scene, f)
            uniforms = self._frame_uniforms(scene, f, frame_index)
            rt = self._raytrace_setup(scene, f)
            self._draw_objects(scene, f, uniforms, rt, thickness)
        finally:
            if f.region is not None:
                f.targets.draw_fbo.scissor = None
                f.targets.draw_fbo.use()
        return self._finish(scene, f, frame_index)

    def resolved_framebuffer(self, hdr):
        """The framebuffer of ``hdr``, a texture ``render`` returned (to read or copy from)."""
        t = self._frame_targets
        if t is None or t.resolved is not hdr:
            raise ValueError("not the resolved target of this renderer's last frame (an SSR frame has its own)")
        return t.resolved_fbo

    def traces(self, scene) -> bool:
        """Whether a render of ``scene`` traces specular chains (``raytrace`` on and a mirror or
        smooth glass in the scene)."""
        return bool(scene.render.raytrace) and any(chain_traces(scene.materials[o.material])
                                                   for o in scene.objects)

    def traced_mask(self, scene, camera: OrbitCamera | None = None, width: int | None = None,
                    height: int | None = None, raytrace: bool | None = None) -> np.ndarray:
        """(H, W) bool in the texture's row order (row 0 = bottom): the pixels whose front-most
        surface at the pixel centre is an object drawn with a traced chain, i.e. the pixels where
        a traced frame without MSAA differs from an untraced one (every other object keeps its
        program). The objects are drawn as the forward pass draws them (same vertex stage, order
        and depth test), so the coverage is the forward pass's without MSAA."""
        ctx = self.ctx
        w = int(width or scene.camera.width)
        h = int(height or scene.camera.height)
        on = bool(scene.render.raytrace) if raytrace is None else bool(raytrace)
        if not (on and self.traces(scene)):
            return np.zeros((h, w), bool)
        if self._mask_target is None or self._mask_target[0] != (w, h):
            self._release_mask()
            tex = ctx.texture((w, h), 1, dtype="f1")
            depth = ctx.depth_renderbuffer((w, h))
            self._mask_target = ((w, h), tex, depth, ctx.framebuffer(color_attachments=[tex], depth_attachment=depth))
        _, tex, _, fbo = self._mask_target
        cam = camera or OrbitCamera.from_scene(scene)
        prog = self._programs.get("traced_mask", _TRACED_MASK)
        fbo.use()
        fbo.viewport = (0, 0, w, h)
        fbo.clear(0.0, 0.0, 0.0, 0.0, depth=1.0)
        ctx.enable(ctx.DEPTH_TEST)
        ctx.disable(ctx.CULL_FACE)
        _set(prog, "u_view_proj", gl_bytes(cam.projection(w / h) @ cam.view()))
        for obj in scene.objects:  # one draw each, in the forward pass's order (u_traced per object)
            _set(prog, "u_traced", float(chain_traces(scene.materials[obj.material])))
            self._gpu_mesh(obj.mesh_data).draw(prog, instance_data([obj]))
        return np.frombuffer(tex.read(alignment=1), np.uint8).reshape(h, w) > 127

    def _release_mask(self):
        if self._mask_target is not None:
            release_gl(*self._mask_target[1:])
            self._mask_target = None

    def _begin_frame(self, scene, camera, width, height, view_mode, msaa, raytrace=None, region=None) -> _Frame:
        """The frame's size, camera, colour targets (the SSR pass's with SSR) and switches."""
        w = int(width or scene.camera.width)
        h = int(height or scene.camera.height)
        ssr_on = bool(scene.render.ssr)
        targets = self._ensure_targets(w, h, scene.render.msaa if msaa is None else msaa)
        if ssr_on:  # the same sample count, with the SSR pass's three attachments
            targets = self.ssr().targets(w, h, targets.samples)
        ssr_debug = view_mode - SSR_VIEW_BASE if view_mode > SSR_VIEW_BASE else 0
        if ssr_debug:
            view_mode = 0  # the forward pass shades; the SSR pass shows its debug output
        lights = scene.lights[:MAX_LIGHTS]   # all of them (the validator refuses more); 4 shadowed
        env = scene.environment
        env_rad = np.zeros(3) if env.constant is None else np.asarray(env.constant, float) * env.intensity
        env_map = env.radiance_map() if env.map is not None else None
        env_on = frame_switches(scene, raytrace)[1]
        self._frame_targets = targets
        rt_on = bool(scene.render.raytrace) if raytrace is None else bool(raytrace)
        if region is not None:
            x, y, rw, rh = (int(v) for v in region)
            x0, y0 = max(0, x), max(0, y)
            region = (x0, y0, max(0, min(w, x + rw) - x0), max(0, min(h, y + rh) - y0))
        return _Frame(w, h, camera or OrbitCamera.from_scene(scene), targets, view_mode, ssr_on, ssr_debug,
                      lights, bool(scene.render.shadows) and len(shadow_lights(scene)) > 0, env_rad, env_map, env_on, rt_on, region)

    def _environment(self, scene, f: _Frame):
        """The thickness of absorbing objects (or None), the IBL textures of the environment, and
        the albedo tables of every material the environment lights (before the forward pass: a
        GPU table build binds its own targets)."""
        thickness = None
        absorbers = [o for o in scene.objects if _absorbing(scene.materials[o.material])
                     and not (f.raytrace and chain_traces(scene.materials[o.material]))]
        if absorbers and f.env_on:
            thickness = self._thick.render(absorbers, f.cam, f.w, f.h, self._programs.get("thickness", _THICKNESS),
                                           self.draw_objects)
        self.ibl().set_environment(f.env_map, constant=None if f.env_map is not None else f.env_rad)
        ms_scene = bool(getattr(scene.render, "ms_compensation", False))
        for name in dict.fromkeys(o.material for o in scene.objects):   # each material once
            params = scene.materials[name]
            if f.ssr_on or f.env_on:
                self.albedo_tables(params)
            if ms_scene or bool(params.get("multiple_scattering", False)):
                self.tables.ms_terms(params)  # point and directional lights use them too
        return thickness

    def _draw_background(self, scene, f: _Frame):
        """Clear the colour target to the constant environment and draw the map behind the scene."""
        ctx = self.ctx
        fbo = f.targets.draw_fbo
        fbo.use()
        fbo.viewport = (0, 0, f.w, f.h)
        fbo.clear(*[float(x) for x in f.env_rad], 1.0, depth=1.0)
        env = scene.environment
        if f.ssr_on:
            self._ssr.background(self._ibl, f.cam, f.w, f.h, f.env_map is not None, f.env_rad, env.rotation_deg)
        elif f.env_map is not None:  # draw the environment behind the scene
            bg = self._programs.get("background", _BACKGROUND)
            ctx.disable(ctx.DEPTH_TEST)
            _set(bg, "u_inv_view_proj", gl_bytes(np.linalg.inv(f.cam.projection(f.w / f.h) @ f.cam.view())))
            _set(bg, "u_camera_pos", tuple(float(x) for x in f.cam.position))
            self._ibl.bind(bg, env.rotation_deg)
            self._fullscreen_vao(bg).render(vertices=3)
        ctx.enable(ctx.DEPTH_TEST)
        ctx.disable(ctx.CULL_FACE)

    def _frame_uniforms(self, scene, f: _Frame, frame_index: int) -> dict:
        """The uniforms every forward program of the frame gets (camera, lights, environment,
        view mode, the shadow atlas, bound to its unit here)."""
        types = np.zeros(MAX_LIGHTS, "i4")
        pos = np.zeros((MAX_LIGHTS, 3), "f4")
        val = np.zeros((MAX_LIGHTS, 3), "f4")
        for i, l in enumerate(f.lights):
            types[i] = LIGHT_TYPES[l.type]
            pos[i] = l.position if l.type == "point" else l.direction
            val[i] = l.intensity if l.type == "point" else l.irradiance
        uniforms = {
            "u_view_proj": gl_bytes(f.cam.projection(f.w / f.h) @ f.cam.view()),
            "u_camera_pos": tuple(float(x) for x in f.cam.position),
            "u_num_lights": len(f.lights),
            "u_light_type": types.tobytes(),
            "u_light_pos": pos.tobytes(),
            "u_light_value": val.tobytes(),
            "u_env_on": int(f.env_on),
            "u_env_constant": tuple(float(x) for x in f.env_rad),
            "u_ibl_mode": IBL_MODES.get(scene.render.ibl, 1),
            "u_frame_index": int(frame_index),
            "u_ms_on": int(bool(getattr(scene.render, "ms_compensation", False))),
            "u_view_mode": int(f.view_mode),
            "u_shadows_on": int(f.shadows),
        }
        if f.ssr_on:
            uniforms["u_view"] = gl_bytes(f.cam.view())
        if f.shadows:
            uniforms.update(self._shadows.bind(unit=texture_units.SHADOW_ATLAS))
        return uniforms

    def _raytrace_setup(self, scene, f: _Frame):
        """(RayTrace state, the scene's materials, dispersion) when a traced chain starts at a
        mirror or smooth glass of the scene, else None."""
        if not (f.raytrace and self.traces(scene)):
            return None
        rt = self.raytrace_state()
        rt.update(scene, self.albedo_tables)
        return rt, list(scene.materials.values()), dispersive(scene)

    def _draw_objects(self, scene, f: _Frame, uniforms: dict, rt, thickness):
        """One instanced draw per mesh and material (per object where a thin film varies over
        the object's height) with the forward-program variant of its material; the frame's
        uniforms are set once per program."""
        ready = set()

        own = {name: thin_film.varies(p) for name, p in scene.materials.items()}   # u_film_y: the object's own

        def group_key(i_obj):
            i, obj = i_obj
            return (obj.material, id(obj.mesh_data), i if own[obj.material] else -1)

        shells = []  # untraced thin shells: drawn after everything opaque, back to front
        for group in group_by(list(enumerate(scene.objects)), group_key):
            obj = group[0][1]
            params = scene.materials[obj.material]
            traced = rt is not None and chain_traces(params)
            if not traced and thin_shell(params):
                shells += [o for _, o in group]
                continue
            args = forward_args(scene, params, f.ssr_on, f.env_on, f.env_map is None, rt is not None)
            # sampled in split_sum mode: a file BRDF's environment light (forward_args)
            custom_fis = args["ibl_sampled"] and scene.render.ibl == "split_sum"
            try:
                prog = self.forward_program(params, **args)
            except ShaderError:
                if not self.hot_reload:
                    raise
                continue  # never compiled (see shader_errors): leave the objects out, draw the rest
            if id(prog) not in ready:
                for k, v in uniforms.items():
                    _set(prog, k, v)
                # always: unbound samplers default to unit 0, where the shadow atlas (a different
                # sampler type) is, and that makes the draw call invalid
                self._ibl.bind(prog, scene.environment.rotation_deg)
                if custom_fis:
                    _set(prog, "u_ibl_mode", IBL_MODES["fis"])
                ready.add(id(prog))
            if traced:  # every frame: the shadow atlas and IBL share no units with these
                rt[0].bind(prog, first_unit=texture_units.TRACED)
                row = rt[0].rows[obj.material]
                _set(prog, "u_rt_row", row)
                _set(prog, "u_mat_base", row * MAT_FLOATS)
                _set(prog, "u_rt_depth", int(scene.render.raytrace_depth))
                _set(prog, "u_rt_max_segments", RT_MAX_SEGMENTS)
            self._material_uniforms(prog, obj, params, uniforms, thickness, env=f.env_on or f.ssr_on)
            if args["ibl_sampled"]:
                self._sampled_env_uniforms(prog, params, scene)
            self._gpu_mesh(obj.mesh_data).draw(prog, instance_data([o for _, o in group]))
        if shells:
            self._draw_shells(scene, f, uniforms, thickness, shells)

    def _material_uniforms(self, prog, obj, params, uniforms: dict, thickness, env: bool):
        idx, block = uniform_block(params)
        _set(prog, "u_model_id", idx)
        # the object's world y range: a film over height (thickness_top_nm); (0, 0) a uniform one
        _set(prog, "u_film_y", obj.y_range() if thin_film.varies(params) else (0.0, 0.0))
        _set(prog, "u_mat", block.tobytes())
        if "u_measured" in prog:
            self._measured_textures().bind(prog, params)
        self._ms_uniforms(prog, params, bool(uniforms["u_ms_on"]))
        if env:
            self._environment_uniforms(prog, params, thickness)

    def _sampled_env_uniforms(self, prog, params, scene):
        """A file material samples its environment light with its own sampler, its lookups
        filtered for all the samples of the frames a still view averages, and in split-sum mode
        lights its constant part with the irradiance (``viewer.gl.file_env``); the built-in
        models sample with the proxy lobe."""
        from viewer.gl.file_env import FRAME_SAMPLES, constant_part, settle_frames

        own = brdf.is_file(params)
        _set(prog, "u_ibl_own", int(own))
        floor = constant_part(params) if own and scene.render.ibl == "split_sum" else np.zeros(3)
        _set(prog, "u_env_floor", tuple(float(x) for x in floor))
        _set(prog, "u_fis_samples", FRAME_SAMPLES * (settle_frames(scene) if own else 1))

    def _draw_shells(self, scene, f: _Frame, uniforms: dict, thickness, shells):
        """Thin shells over the opaque frame, farthest first, each in two draws (its far faces,
        then its near ones) with dual-source blending: destination x transmittance + reflected
        radiance, i.e. each face lets its transmitted fraction of what lies behind it through
        and adds what it reflects (forward.frag, THIN_SHELL). No depth writes: what a shell
        covers stays the depth and, with SSR, the geometry of what lies behind it."""
        ctx = self.ctx
        fbo = f.targets.shell_fbo
        own_scissor = f.region is not None and fbo is not f.targets.draw_fbo
        if own_scissor:
            fbo.scissor = f.region
        fbo.use()
        eye = np.asarray(f.cam.position, float)
        shells = sorted(shells, key=lambda o: -float(np.linalg.norm(np.asarray(o.translate, float) - eye)))
        ctx.enable(ctx.BLEND | ctx.CULL_FACE | ctx.DEPTH_TEST)
        ctx.blend_func = (ctx.ONE, GL_SRC1_COLOR)
        fbo.depth_mask = False
        try:
            for obj in shells:
                params = scene.materials[obj.material]
                try:
                    prog = self.forward_program(params, **forward_args(scene, params, f.ssr_on, f.env_on,
                                                                       f.env_map is None, False))
                except ShaderError:
                    if not self.hot_reload:
                        raise
                    continue
                for k, v in uniforms.items():
                    _set(prog, k, v)
                self._ibl.bind(prog, scene.environment.rotation_deg)
                # always: the transmittance comes from the material's albedo tables
                self._material_uniforms(prog, obj, params, uniforms, thickness, env=True)
                mesh = self._gpu_mesh(obj.mesh_data)
                for side in ("front", "back"):  # culled: far faces first, then near ones
                    ctx.cull_face = side
                    mesh.draw(prog, instance_data([obj]))
        finally:
            fbo.depth_mask = True
            ctx.cull_face = "back"
            ctx.disable(ctx.BLEND | ctx.CULL_FACE)
            ctx.blend_func = ctx.DEFAULT_BLENDING
            if own_scissor:
                fbo.scissor = None
            f.targets.draw_fbo.use()

    def _ms_uniforms(self, prog, params, ms_scene: bool):
        """The multiple-scattering compensation of a material (environment light: Fdez-Aguera;
        point and directional lights: Kulla-Conty; viewer/brdf/ms_compensation.py): for the whole scene, or
        for a material whose reference has the multiple-scattering random walk (the raster's
        approximation of the same light)."""
        from viewer.brdf import ms_compensation
        ms_on = ms_scene or bool(params.get("multiple_scattering", False))
        _set(prog, "u_ms_on", int(ms_on))
        if ms_on:  # the shader reads u_ms_f0, u_ms_ess and u_ms_eavg only then
            ms_ess, ms_f0 = self.tables.ms_terms(params)
            _set(prog, "u_ms_f0", tuple(float(x) for x in ms_f0))
            _set(prog, "u_ms_ess", ms_ess.tobytes())
            _set(prog, "u_ms_eavg", ms_compensation.e_avg(ms_ess))

    def _environment_uniforms(self, prog, params, thickness):
        """A material's environment-lighting uniforms: its albedo tables, lobe width,
        transmission and absorption."""
        refl, trans, spec, alpha = self.tables.tables(params)
        _set(prog, "u_albedo", refl.tobytes())
        _set(prog, "u_albedo_t", trans.tobytes())
        _set(prog, "u_albedo_s", spec.tobytes())
        _set(prog, "u_ibl_alpha", alpha)
        _set(prog, "u_ibl_delta", int(brdf_spec(params).delta and alpha == 0.0))
        absorbing = "sigma_a" in params and brdf_spec(params).transmissive
        _set(prog, "u_transmit_on", int(bool(np.any(trans > 0))))
        _set(prog, "u_sigma_a", tuple(float(x) for x in (params.sigma_a if absorbing else np.zeros(3))))
        _set(prog, "u_ior", float(params.get("ior", 1.0)))
        if thickness is not None:
            thickness.use(location=texture_units.THICKNESS)
        # always: left at unit 0 it would share the shadow atlas's unit (another sampler type)
        _set(prog, "u_thickness", texture_units.THICKNESS)

    def _finish(self, scene, f: _Frame, frame_index: int):
        """The SSR pass (which resolves and traces), or the MSAA resolve; the linear HDR texture."""
        if f.ssr_on:
            # what lies behind each visible surface: the distance to the nearest back face (0 where
            # none, e.g. a one-sided floor), so a reflected ray passing behind a closed object's
            # front within the object hits it and one passing behind the object does not
            back = self._ssr_back.render(scene.objects, f.cam, f.w, f.h,
                                         self._programs.get("thickness", _THICKNESS), self.draw_objects)
            return self._ssr.resolve_and_trace(self._ibl, f.cam, f.w, f.h, f.env_on, scene.environment.rotation_deg,
                                               f.ssr_debug, frame_index, back=back)
        t = f.targets
        if t.draw_fbo is not t.resolved_fbo:
            if f.region is not None:  # a blit honours the scissor: resolve the region alone
                t.resolved_fbo.scissor = f.region
                t.resolved_fbo.use()
            try:
                self.ctx.copy_framebuffer(t.resolved_fbo, t.draw_fbo)
            finally:
                if f.region is not None:
                    t.resolved_fbo.scissor = None
                    t.resolved_fbo.use()
        return t.resolved

    def tonemap_to(self, fbo, hdr, exposure: float = 0.0, tonemap: str = "none", viewport=None):
        """Exposure, tone mapping and sRGB encoding of ``hdr`` into ``fbo`` (e.g. ctx.screen)."""
        ctx = self.ctx
        fbo.use()
        if viewport is not None:
            fbo.viewport = viewport
        ctx.disable(ctx.DEPTH_TEST)
        prog = self.programs["tonemap"]
        # linear filtering when a preview resolution is stretched over the viewport
        hdr.filter = (ctx.LINEAR, ctx.LINEAR)
        hdr.use(location=texture_units.SOURCE)
        _set(prog, "u_hdr", texture_units.SOURCE)
        _set(prog, "u_exposure", float(exposure))
        _set(prog, "u_tonemap", TONEMAPS.get(tonemap, 0))
        self._fullscreen_vao(prog).render(vertices=3)

    # ---------------------------------------------------------------- readback
    def read_linear(self, hdr) -> np.ndarray:
        """(H, W, 3) float32 radiance, row 0 = top (docs/conventions.md)."""
        w, h = hdr.size
        a = np.frombuffer(hdr.read(), dtype="f4").reshape(h, w, 4)  # exact texels, no filtering
        return np.ascontiguousarray(a[::-1, :, :3])

    def read_srgb(self, hdr, exposure=0.0, tonemap="none") -> np.ndarray:
        """(H, W, 3) uint8 sRGB after exposure and tone mapping, row 0 = top."""
        w, h = hdr.size
        if self._ldr is None or self._ldr[0].size != (w, h):
            if self._ldr is not None:
                release_gl(self._ldr[1], self._ldr[0])
            tex = self.ctx.texture((w, h), 4, dtype="f1")
            self._ldr = (tex, self.ctx.framebuffer(color_attachments=[tex]))
        self.tonemap_to(self._ldr[1], hdr, exposure, tonemap, viewport=(0, 0, w, h))
        a = np.frombuffer(self._ldr[0].read(), dtype=np.uint8).reshape(h, w, 4)
        return np.ascontiguousarray(a[::-1, :, :3])

    def render_arrays(self, scene, camera=None, width=None, height=None, view_mode=0, supersample: int = 1,
                      frames: int | None = None):
        """(linear float32, sRGB uint8) images, (H, W, 3), row 0 = top.

        ``supersample`` k > 1 renders k x k shading points per pixel on a regular grid (no MSAA)
        and averages them: the box filter of docs/conventions.md up to 1/k^2 of the error of
        shading at the pixel centre (what MSAA does), at k^2 times the cost. ``frames``: the mean
        of that many frames with new sample sets; None: the frames a still window view averages
        before it rests (``viewer.gl.file_env.settle_frames``: a file material's sampled
        environment light settles over 64, every other scene is one frame)."""
        if frames is None:
            from viewer.gl.file_env import settle_frames

            frames = settle_frames(scene) if view_mode == 0 else 1
        if supersample <= 1 and frames <= 1:
            hdr = self.render(scene, camera, width, height, view_mode)
            return (self.read_linear(hdr),
                    self.read_srgb(hdr, scene.render.exposure, scene.render.tonemap))
        from viewer.image.colour import to_srgb8

        k = max(int(supersample), 1)
        w = int(width or scene.camera.width)
        h = int(height or scene.camera.height)
        acc = None
        for f in range(max(int(frames), 1)):  # progressive: frames with new sample sets
            if k == 1:
                img = self.read_linear(self.render(scene, camera, width, height, view_mode, frame_index=f))
            else:
                big = self.read_linear(self.render(scene, camera, w * k, h * k, view_mode, msaa=0, frame_index=f))
                img = big.reshape(h, k, w, k, 3).mean(axis=(1, 3), dtype=np.float64)
            acc = img.astype(np.float64) if acc is None else acc + img
        linear = (acc / max(int(frames), 1)).astype(np.float32)
        return linear, to_srgb8(linear, scene.render.exposure, scene.render.tonemap)

    def release(self):
        self._hdr.release()
        for _, gm in self._meshes.values():
            gm.release()
        self._meshes.clear()
        self._shadows.release()
        if self._ldr:
            release_gl(self._ldr[1], self._ldr[0])
        self._release_mask()
        for part in (self._thick, self._ssr_back, self._ibl, self._ssr, self.tables, self._rt, self._measured):
            if part is not None:
                part.release()
        self._programs.release()
