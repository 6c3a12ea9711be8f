"""The rasterizer: shadow maps, a forward pass into a linear HDR float target with MSAA, and a
tone-mapping pass to the screen or an 8-bit sRGB image. The window and the offscreen path both
call ``Renderer.render``; only the owner of the final framebuffer differs."""

from __future__ import annotations

import json
import math
from typing import NamedTuple

import numpy as np

from viewer.brdf.albedo import TABLE_SIZE, albedo_tables
from viewer.gl.brdf_glsl import uniform_block
from viewer.camera import OrbitCamera, gl_bytes, look_at, orthographic, perspective
from viewer.gl.shaders import ShaderError, compile_sources, default_virtual, program_sources
from viewer.gl.shaders import set_uniform as _set
from viewer.gl.raytrace import KIND_SHADED, chain_kind, dispersive, scene_models
from viewer.gl.raytrace import MAX_SEGMENTS as RT_MAX_SEGMENTS

MAX_LIGHTS = 4  # keep equal to MAX_LIGHTS in shaders/common/shadow.glsl
SHADOW_TILE = 1024
TONEMAPS = {"none": 0, "reinhard": 1, "aces": 2, "filmic": 3}
IBL_MODES = {"off": 0, "split_sum": 1, "fis": 2, "brute_force": 3}
VIEW_MODES = {"shaded": 0, "F": 1, "D": 2, "G": 3, "N.L": 4, "f cos": 5, "shadow": 6,
              # screen-space reflections (viewer/gl/ssr.py; only with [render] ssr = true):
              "ssr hit": 7, "ssr steps": 8, "ssr uv": 9, "ssr only": 10}
SSR_VIEW_BASE = 6  # view mode 7.. = SSR debug output 1..

# (forward, up) of the six cube faces, in the order cube_face() in shadow.glsl returns them
_FACES = [((1, 0, 0), (0, 1, 0)), ((-1, 0, 0), (0, 1, 0)), ((0, 1, 0), (0, 0, 1)),
          ((0, -1, 0), (0, 0, 1)), ((0, 0, 1), (0, 1, 0)), ((0, 0, -1), (0, 1, 0))]


def brdf_spec(params):
    from viewer import brdf

    return brdf.get(params.model).spec


_DFG = None


def _ms_f0(spec_albedo_normal, alpha: float, nov: float) -> np.ndarray:
    """The specular lobe's Fresnel at normal incidence for the multiple-scattering term: its
    albedo there divided by the GGX albedo with F = 1 (A + B of the DFG table), clamped to 1."""
    global _DFG
    from viewer.environment.dfg import dfg_table, lookup_dfg

    if not np.any(np.asarray(spec_albedo_normal, float) > 0):
        return np.zeros(3)  # no specular part (diffuse models): 0 whatever the table says
    if _DFG is None:  # about a second of numpy: made the first time a compensated specular needs it
        _DFG = dfg_table()
    a, b = lookup_dfg(_DFG, nov, max(alpha, 1e-3))
    return np.clip(np.asarray(spec_albedo_normal, float) / max(float(a + b), 1e-6), 0.0, 1.0)


def _absorbing(params) -> bool:
    return brdf_spec(params).transmissive and "sigma_a" in params and bool(np.any(np.asarray(params.sigma_a) > 0))


class _Recipe(NamedTuple):
    """How to build one program from the files under shader_root(), kept so hot reload can
    build it again: stage files, the BRDF models of the generated ``brdf/dispatch.glsl``
    (None: no virtual files) and ``#define``s."""

    vertex: str
    fragment: str
    geometry: str | None = None
    models: tuple[str, ...] | None = ("lambert",)
    defines: tuple[tuple[str, str], ...] = ()

    def sources(self):
        virtual = {} if self.models is None else default_virtual(self.models)
        return program_sources(self.vertex, self.fragment, geometry=self.geometry, virtual=virtual,
                               defines=dict(self.defines) or None)


def _texts(sources) -> tuple:
    return tuple(None if s is None else s.text for s in sources)


def _files(sources) -> set[str]:
    return {f for s in sources if s is not None for f in s.files}


_FIXED = {
    "forward:lambert": _Recipe("passes/forward.vert", "passes/forward.frag", "passes/forward.geom"),
    "shadow": _Recipe("passes/shadow.vert", "passes/shadow.frag"),
    "tonemap": _Recipe("passes/fullscreen.vert", "passes/tonemap.frag"),
}
# programs built on first use
_BACKGROUND = _Recipe("passes/fullscreen.vert", "passes/background.frag")
_THICKNESS = _Recipe("passes/forward.vert", "passes/thickness.frag")
# programs the SSR pass owns (viewer/gl/ssr.py builds them the same way): attribute names
_SSR_PROGRAMS = {
    "ssr:trace": (_Recipe("passes/fullscreen.vert", "passes/ssr.frag"), "prog", "vao"),
    "ssr:background": (_Recipe("passes/fullscreen.vert", "passes/ssr_background.frag"), "bg_prog", "bg_vao"),
    "ssr:hiz": (_Recipe("passes/fullscreen.vert", "passes/ssr_hiz.frag"), "hiz_prog", "hiz_vao"),
}


class GpuMesh:
    """Vertex and index buffers of one MeshData; one vertex array per program."""

    def __init__(self, ctx, mesh):
        data = np.hstack([mesh.positions, mesh.normals, mesh.tangents]).astype("f4")
        self.vbo = ctx.buffer(np.ascontiguousarray(data).tobytes())
        self.ibo = ctx.buffer(np.ascontiguousarray(mesh.indices, dtype="u4").tobytes())
        self.ctx = ctx
        self.vaos = {}

    def vao(self, prog):
        key = id(prog)
        if key not in self.vaos:
            # attributes the compiler dropped (e.g. the tangent when no model uses it) are skipped
            fmt, names = [], []
            for name, comps in (("in_position", 3), ("in_normal", 3), ("in_tangent", 4)):
                try:
                    prog[name]
                    fmt.append(f"{comps}f")
                    names.append(name)
                except KeyError:
                    fmt.append(f"{4 * comps}x")
            content = [(self.vbo, " ".join(fmt), *names)]
            self.vaos[key] = self.ctx.vertex_array(prog, content, index_buffer=self.ibo, index_element_size=4)
        return self.vaos[key]

    def release(self):
        for v in self.vaos.values():
            v.release()
        self.vbo.release()
        self.ibo.release()


class Renderer:
    #: set by hot reload (viewer/gl/hot_reload.py): a program that fails to compile is reported
    #: in ``shader_errors`` instead of raised from ``render`` (objects whose forward program has
    #: no good version yet are left out of the image), and is retried when a shader file changes.
    hot_reload = False

    def __init__(self, ctx):
        self.ctx = ctx
        self.programs = {}
        self._recipes: dict[str, _Recipe] = {}  # how each program in self.programs was built
        self._good: dict[str, tuple] = {}  # the source texts of the program in use, per key
        self._failed: dict[str, tuple] = {}  # key -> (source texts or None, ShaderError)
        self._render_error: ShaderError | None = None
        self.last_reloaded: list[str] = []
        self._fullscreen_vaos: dict[int, object] = {}  # id(program) -> its attribute-less vertex array
        self._meshes: dict[int, tuple[object, GpuMesh]] = {}
        self.build_programs()
        self._targets = None
        self._target_key = None
        self._ldr = None
        self._shadow = None
        self._shadow_key = None
        self._shadow_mats = np.zeros((MAX_LIGHTS * 6, 4, 4))
        self._shadow_texel = np.zeros(MAX_LIGHTS)
        self._albedo_cache: dict[str, tuple] = {}
        self.gpu_albedo = True  # albedo tables with the GLSL samplers (False: the numpy builder)
        self._albedo_gpu = None
        self.albedo_gpu_error: ShaderError | None = None
        self._ms_cache: dict[str, np.ndarray] = {}
        self._thick = None
        self._ibl = None
        self._ssr = None
        self._rt = None
        self._measured = None

    # ---------------------------------------------------------------- programs
    def build_programs(self):
        """(Re)compile the fixed passes. Raises ShaderError; on failure the old programs stay.

        The forward pass is compiled per set of material models (``forward_program``), on
        first use, and cached: a slider move is a uniform upload, a model switch compiles at
        most once. ``reload_shaders`` rebuilds every program from the files."""
        new = {}
        try:
            for key, recipe in _FIXED.items():
                new[key] = self._compile(key, recipe)
        except ShaderError:
            for p, _ in new.values():
                p.release()
            raise
        for key, (prog, text) in new.items():
            self._recipes[key] = _FIXED[key]
            self._install(key, prog, text)

    def _sources(self, key: str, recipe: _Recipe):
        """``recipe``'s preprocessed sources, read from disk now; a failure (unreadable file)
        is remembered (``shader_errors``) and raised."""
        try:
            return recipe.sources()
        except ShaderError as e:
            e.program = key
            self._failed[key] = (None, e)
            raise

    def _link(self, key: str, sources, text: tuple):
        """Compile ``sources`` (whose texts are ``text``); a failure is remembered and raised."""
        try:
            prog = compile_sources(self.ctx, *sources)
        except ShaderError as e:
            e.program = key
            self._failed[key] = (text, e)
            raise
        self._failed.pop(key, None)
        return prog

    def _compile(self, key: str, recipe: _Recipe):
        """(program, its source texts); a failure is remembered (``shader_errors``) and raised."""
        sources = self._sources(key, recipe)
        text = _texts(sources)
        return self._link(key, sources, text), text

    def _fullscreen_vao(self, prog):
        """The attribute-less vertex array of a fullscreen program, made on first use."""
        vao = self._fullscreen_vaos.get(id(prog))
        if vao is None:
            vao = self._fullscreen_vaos[id(prog)] = self.ctx.vertex_array(prog, [])
        return vao

    def _drop_program(self, prog):
        """Release a program and every vertex array made for it (all are keyed by its id)."""
        vaos = [self._fullscreen_vaos.pop(id(prog), None)] + [gm.vaos.pop(id(prog), None)
                                                               for _, gm in self._meshes.values()]
        for v in vaos:
            if v is not None:
                v.release()
        prog.release()

    def _install(self, key: str, prog, text: tuple):
        """Put ``prog`` (built from sources ``text``) in use under ``key``; the program it
        replaces is released only now."""
        old = self.programs.get(key)
        self.programs[key] = prog
        self._good[key] = text
        if old is not None and old is not prog:
            self._drop_program(old)

    def _program(self, key: str, recipe: _Recipe):
        """The cached program ``key``, built from ``recipe`` on first use. In hot-reload mode a
        build that failed is not tried again until a shader file changes (``reload_shaders``)."""
        prog = self.programs.get(key)
        if prog is not None:
            return prog
        self._recipes[key] = recipe
        failed = self._failed.get(key)
        if failed is not None and self.hot_reload:
            raise failed[1]
        prog, text = self._compile(key, recipe)
        self._install(key, prog, text)
        return prog

    # ---------------------------------------------------------------- hot reload
    @property
    def shader_errors(self) -> list[ShaderError]:
        """The programs that do not compile from the current files (each error once; a program
        that failed keeps rendering with its last good version). Empty when all compile."""
        out, seen = [], set()
        errs = [e for _, e in self._failed.values()]
        if self._render_error is not None:
            errs.append(self._render_error)
        for e in errs:
            k = (e.file, e.line, e.detail)
            if k not in seen:
                seen.add(k)
                out.append(e)
        return out

    def _reload_slots(self):
        """(key, recipe, install) of every program that can be rebuilt, the SSR and IBL passes'
        included (their installers swap the program, its vertex array and stale results)."""
        slots = [(k, r, lambda p, t, k=k: self._install(k, p, t)) for k, r in list(self._recipes.items())]
        if self._ssr is not None:
            for key, (recipe, attr, vao_attr) in _SSR_PROGRAMS.items():
                slots.append((key, recipe, lambda p, t, a=attr, va=vao_attr: self._install_ssr(p, a, va)))
        if self._ibl is not None:
            for name in list(self._ibl._programs):
                recipe = _Recipe("passes/fullscreen.vert", f"passes/{name}.frag", models=None)
                slots.append(("ibl:" + name, recipe, lambda p, t, n=name: self._install_ibl(p, n)))
        return slots

    def _install_ssr(self, prog, attr: str, vao_attr: str):
        ssr = self._ssr
        old, old_vao = getattr(ssr, attr), getattr(ssr, vao_attr)
        setattr(ssr, attr, prog)
        setattr(ssr, vao_attr, self.ctx.vertex_array(prog, []))
        old_vao.release()
        old.release()

    def _install_ibl(self, prog, name: str):
        """Swap an IBL program and drop what it computed, so the next render recomputes it."""
        ibl = self._ibl
        old, old_vao = ibl._programs.get(name), ibl._vaos.get(name)
        ibl._programs[name] = prog
        ibl._vaos[name] = self.ctx.vertex_array(prog, [])
        if old_vao is not None:
            old_vao.release()
        if old is not None:
            old.release()
        # the disk cache is keyed by the map and the settings, not by shader sources: bypass it
        # (and never store results of an edited shader) for the rest of this session
        ibl.use_cache = False
        if name == "ibl_dfg" and ibl.dfg_tex is not None:
            ibl.dfg_tex.release()
            ibl.dfg_tex = None
        if name in ("ibl_downsample", "ibl_prefilter", "ibl_dfg"):
            ibl._key = None
            ibl._last_ident = None
        if name == "ibl_cubemap":
            ibl._cube_key = None

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
        if changed is None or any(c.startswith(("brdf/", "common/")) for c in changed):
            # the albedo tables come from the GLSL samplers: rebuild them from the new files
            if self._albedo_gpu is not None:
                self._albedo_gpu.release()
                self._albedo_gpu = None
            self._albedo_cache.clear()
            self.albedo_gpu_error = None
        self.last_reloaded = []
        self._render_error = None  # the next render tries again
        for key, recipe, install in self._reload_slots():
            failed = self._failed.get(key)
            good = self._good.get(key)
            try:
                sources = self._sources(key, recipe)
            except ShaderError:
                continue
            text = _texts(sources)
            if failed is not None and failed[0] == text:
                continue  # the same sources as the failed attempt: the same error
            if text == good:
                self._failed.pop(key, None)  # back to the sources of the program in use
                continue
            if failed is None and good is None and changed is not None and not (_files(sources) & changed):
                continue
            try:
                prog = self._link(key, sources, text)
            except ShaderError:
                continue
            self._good[key] = text
            install(prog, text)
            self.last_reloaded.append(key)
        return self.shader_errors

    # Per-sample shading (GLSL 'sample' inputs) is off: on Mesa llvmpipe 22.3 it gave wrong shadow
    # visibility on fully covered pixels near silhouettes (measured against the reference). For
    # an exact box filter use render_arrays(..., supersample=k) instead.
    sample_shading = False

    def forward_program(self, params, sample_shading: bool | None = None, ssr: bool = False,
                        ibl_sampled: bool = False, env_light: bool = True, env_constant: bool = False,
                        raytrace: tuple[str, ...] | None = None, dispersion: bool = False,
                        thin_film: bool | None = None):
        """The forward program for a material (its model, and a nested base model if any).
        ``ibl_sampled`` compiles in the per-pixel environment sampling of the fis and
        brute_force modes (left out otherwise: software GL pays for untaken loops).
        ``raytrace``: the models of every material in the scene, for a mirror or smooth glass
        whose specular chain is traced (viewer/gl/raytrace.py); ``dispersion`` traces each
        colour channel's chain apart. ``thin_film``: compile the film's wavelength loop (None: where
        this material has a film)."""
        from viewer.gl.brdf_glsl import models_used, uses_thin_film

        per_sample = self.sample_shading if sample_shading is None else sample_shading
        used = models_used(params)
        if raytrace is not None:
            used = tuple(dict.fromkeys(used + tuple(raytrace)))
        key = ("forward:" + "+".join(used) + (":sample" if per_sample else "") + (":ssr" if ssr else "")
               + (":iblsampled" if ibl_sampled else "") + (":env" if env_light else "")
               + (":const" if env_constant else "") + (":rt" if raytrace is not None else "")
               + (":disp" if dispersion else ""))
        if thin_film is None:
            thin_film = uses_thin_film(params)
        if thin_film:
            key += ":film"
        prog = self.programs.get(key)  # the per-frame path: no recipe built when cached
        if prog is not None:
            return prog
        defines = {}
        if per_sample:
            defines["SAMPLE_SHADING"] = "1"
        if ssr:
            defines["SSR"] = "1"
        if ibl_sampled:
            defines["IBL_SAMPLED"] = "1"
        if env_light:
            defines["ENV_LIGHT"] = "1"
        if env_constant:
            defines["ENV_CONSTANT"] = "1"
        if "measured" in used:  # the measured model's table texture (shaders/brdf/measured.glsl)
            defines["MEASURED_TEXTURE"] = "1"
        if raytrace is not None:
            defines["RAYTRACE"] = "1"
            defines["MAT_TEXTURE"] = "1"
            if dispersion:
                defines["RT_DISPERSION"] = "1"
        if thin_film:
            defines["THIN_FILM"] = "1"
        return self._program(key, _Recipe("passes/forward.vert", "passes/forward.frag", "passes/forward.geom",
                                          models=tuple(used), defines=tuple(defines.items())))

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

    def forget_meshes(self, keep=()):
        """Release GPU buffers of meshes not in ``keep`` (called when a scene is replaced)."""
        keep_ids = {id(m) for m in keep}
        for key in list(self._meshes):
            if key not in keep_ids:
                self._meshes.pop(key)[1].release()

    def _ensure_targets(self, w, h, samples):
        samples = samples if samples > 1 else 0
        samples = min(samples, self.ctx.max_samples)
        key = (w, h, samples)
        if self._target_key == key:
            return self._targets
        self._release_targets()
        ctx = self.ctx
        resolved = ctx.texture((w, h), 4, dtype="f4")
        resolved.filter = (ctx.NEAREST, ctx.NEAREST)
        resolved_fbo = ctx.framebuffer(color_attachments=[resolved])
        if samples:
            ms_color = ctx.renderbuffer((w, h), 4, samples=samples, dtype="f4")
            ms_depth = ctx.depth_renderbuffer((w, h), samples=samples)
            ms_fbo = ctx.framebuffer(color_attachments=[ms_color], depth_attachment=ms_depth)
            extra = [ms_color, ms_depth]
        else:
            depth = ctx.depth_renderbuffer((w, h))
            ms_fbo = ctx.framebuffer(color_attachments=[resolved], depth_attachment=depth)
            extra = [depth]
        self._targets = {"resolved": resolved, "resolved_fbo": resolved_fbo, "draw_fbo": ms_fbo,
                         "extra": extra, "samples": samples}
        self._target_key = key
        return self._targets

    def _release_targets(self):
        if self._targets:
            t = self._targets
            if t["draw_fbo"] is not t["resolved_fbo"]:
                t["draw_fbo"].release()
            t["resolved_fbo"].release()
            t["resolved"].release()
            for r in t["extra"]:
                r.release()
        self._targets = None
        self._target_key = None

    # ---------------------------------------------------------------- shadows
    def _shadow_lights(self, scene):
        return scene.lights[:MAX_LIGHTS]

    def _update_shadows(self, scene):
        lights = self._shadow_lights(scene)
        key = (tuple((l.type, tuple(np.round(l.position, 9)), tuple(np.round(l.direction, 9))) for l in lights),
               tuple((id(o.mesh_data), o.model_matrix().tobytes()) for o in scene.objects))
        if key == self._shadow_key and self._shadow is not None:
            return
        rows = max(1, len(lights))
        S = SHADOW_TILE
        ctx = self.ctx
        if self._shadow is None or self._shadow["rows"] != rows:
            if self._shadow is not None:
                self._shadow["fbo"].release()
                self._shadow["tex"].release()
            tex = ctx.depth_texture((6 * S, rows * S))
            tex.compare_func = "<="
            tex.filter = (ctx.LINEAR, ctx.LINEAR)
            tex.repeat_x = False
            tex.repeat_y = False
            self._shadow = {"tex": tex, "fbo": ctx.framebuffer(depth_attachment=tex), "rows": rows}
        lo, hi = scene.bounds()
        center = 0.5 * (lo + hi)
        radius = max(0.5 * float(np.linalg.norm(hi - lo)), 1e-3)
        mats = np.zeros((MAX_LIGHTS * 6, 4, 4))
        for i, light in enumerate(lights):
            if light.type == "point":
                p = np.asarray(light.position, float)
                far = float(np.linalg.norm(p - center)) + radius * 1.1
                near = max(far * 1e-3, 1e-3)
                # a little wider than 90 degrees: 3 texels of margin per side for the PCF kernel
                fov = 2.0 * math.degrees(math.atan(S / (S - 6.0)))
                proj = perspective(fov, 1.0, near, far)
                for f, (fwd, up) in enumerate(_FACES):
                    mats[i * 6 + f] = proj @ look_at(p, p + np.array(fwd, float), up)
            else:
                d = np.asarray(light.direction, float)
                d = d / np.linalg.norm(d)
                up = (0, 1, 0) if abs(d[1]) < 0.99 else (0, 0, 1)
                eye = center - d * 2.0 * radius
                mats[i * 6] = orthographic(radius, radius, radius * 0.9, radius * 3.1) @ look_at(eye, center, up)
                self._shadow_texel[i] = 2.0 * radius / S
        fbo = self._shadow["fbo"]
        fbo.use()
        fbo.clear(depth=1.0)
        prog = self.programs["shadow"]
        ctx.enable(ctx.DEPTH_TEST)
        ctx.disable(ctx.CULL_FACE)
        ctx.polygon_offset = (1.5, 2.0)  # slope-scaled depth bias in the shadow pass
        for i, light in enumerate(lights):
            faces = range(6) if light.type == "point" else range(1)
            for f in faces:
                fbo.viewport = (f * S, i * S, S, S)
                for obj in scene.objects:
                    _set(prog, "u_mvp", gl_bytes(mats[i * 6 + f] @ obj.model_matrix()))
                    self._gpu_mesh(obj.mesh_data).vao(prog).render()
        ctx.polygon_offset = (0.0, 0.0)
        self._shadow_mats = mats
        self._shadow_key = key

    def albedo_tables(self, params) -> tuple[np.ndarray, np.ndarray, np.ndarray, float, np.ndarray]:
        """A material's environment-lighting data, cached by its parameter values: float32
        (32, 3) tables of the reflected albedo, the transmitted albedo and the reflected albedo
        of the specular part alone (the model's ``ibl_split`` hook; none for diffuse models),
        that part's lobe width alpha, and its normal-incidence Fresnel for the multiple-scattering
        compensation (``ms_f0``; computed on first use, since only scenes with
        ``ms_compensation`` need it and it needs the DFG table)."""
        tables = self._base_albedo_tables(params)
        return tables + (self.ms_f0(params),)

    def ms_f0(self, params) -> np.ndarray:
        """The normal-incidence Fresnel of a material's specular part for the multiple-scattering
        compensation (see ``_ms_f0``), cached with the albedo tables."""
        key = json.dumps(params.to_plain(), sort_keys=True)
        f0 = self._ms_cache.get(key)
        if f0 is None:
            _, _, spec, alpha = self._base_albedo_tables(params)
            f0 = _ms_f0(spec[-1], alpha, (TABLE_SIZE - 0.5) / TABLE_SIZE)
            if len(self._ms_cache) > 256:
                self._ms_cache.clear()
            self._ms_cache[key] = f0
        return f0

    def _base_albedo_tables(self, params) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
        key = json.dumps(params.to_plain(), sort_keys=True)
        tables = self._albedo_cache.get(key)
        if tables is None:
            from viewer import brdf

            model = brdf.get(params.model)
            r, t = self._albedo_pair(model, params)
            split = getattr(model.module, "ibl_split", None)
            if split is None:
                spec, alpha = np.zeros_like(r), 1.0
            else:
                spec_params, alpha = split(params)
                spec = r if spec_params is params else self._albedo_pair(model, spec_params)[0]
            spec = np.minimum(spec, r)
            tables = (r.astype("f4"), t.astype("f4"), spec.astype("f4"), float(alpha))
            if len(self._albedo_cache) > 256:
                self._albedo_cache.clear()
            self._albedo_cache[key] = tables
        return tables

    def _albedo_pair(self, model, params):
        """(reflected, transmitted) albedo tables: on the GPU with the GLSL samplers
        (viewer/gl/albedo_gpu.py, the same estimator and points as the numpy builder), or with
        numpy where ``gpu_albedo`` is off or the sampling program fails to compile."""
        if self.gpu_albedo:
            try:
                if self._albedo_gpu is None:
                    from viewer.gl.albedo_gpu import GPUAlbedoTables

                    self._albedo_gpu = GPUAlbedoTables(self.ctx)
                return self._albedo_gpu.tables(params)
            except ShaderError as e:  # e.g. a family file being edited: numpy still knows the model
                self.albedo_gpu_error = e
        return albedo_tables(model, params)

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
               height: int | None = None, view_mode: int = 0, msaa: int | None = None, frame_index: int = 0):
        """Render the scene into the linear HDR target; returns the resolved float texture.

        Raises ShaderError when a program it needs does not compile, except in hot-reload mode
        (``hot_reload``): there the error goes to ``shader_errors``, an object whose forward
        program never compiled is left out, and a pass that cannot be built gives back the
        colour target as it is (normally the previous frame)."""
        if not self.hot_reload:
            return self._render(scene, camera, width, height, view_mode, msaa, frame_index)
        try:
            hdr = self._render(scene, camera, width, height, view_mode, msaa, frame_index)
        except ShaderError as e:
            self._render_error = e
            w = int(width or scene.camera.width)
            h = int(height or scene.camera.height)
            return self._ensure_targets(w, h, scene.render.msaa if msaa is None else msaa)["resolved"]
        self._render_error = None
        return hdr

    def _render(self, scene, camera, width, height, view_mode, msaa, frame_index):
        ctx = self.ctx
        w = int(width or scene.camera.width)
        h = int(height or scene.camera.height)
        cam = camera or OrbitCamera.from_scene(scene)
        ssr_on = bool(scene.render.ssr)
        targets = self._ensure_targets(w, h, scene.render.msaa if msaa is None else msaa)
        if ssr_on:  # the same sample count, with the SSR pass's three attachments
            targets = self.ssr().targets(w, h, targets["samples"])
        ssr_debug = view_mode - SSR_VIEW_BASE if view_mode > SSR_VIEW_BASE else 0
        if ssr_debug:
            view_mode = 0  # the forward pass shades; the SSR pass shows its debug output
        lights = self._shadow_lights(scene)
        shadows = bool(scene.render.shadows) and len(lights) > 0
        if shadows:
            self._update_shadows(scene)

        env = scene.environment
        env_rad = np.zeros(3) if env.constant is None else np.asarray(env.constant, float) * env.intensity
        env_map = env.radiance_map() if env.map is not None else None
        thickness = None
        absorbers = [o for o in scene.objects if _absorbing(scene.materials[o.material])
                     and not (scene.render.raytrace and chain_kind(scene.materials[o.material]) != KIND_SHADED)]
        if absorbers and scene.render.ibl != "off" and (env_map is not None or np.any(env_rad > 0)):
            thickness = self._thickness_pass(absorbers, cam, w, h)
        ibl = self.ibl()
        ibl.set_environment(env_map, constant=None if env_map is not None else env_rad)
        if ssr_on or (scene.render.ibl != "off" and (env_map is not None or bool(np.any(env_rad > 0)))):
            for obj in scene.objects:  # before the forward pass: a GPU table build binds its own targets
                self.albedo_tables(scene.materials[obj.material])
        fbo = targets["draw_fbo"]
        fbo.use()
        fbo.viewport = (0, 0, w, h)
        fbo.clear(*[float(x) for x in env_rad], 1.0, depth=1.0)
        if ssr_on:
            self._ssr.background(ibl, cam, w, h, env_map is not None, env_rad, env.rotation_deg)
        elif env_map is not None:  # draw the environment behind the scene
            bg = self._program("background", _BACKGROUND)
            ctx.disable(ctx.DEPTH_TEST)
            _set(bg, "u_inv_view_proj", gl_bytes(np.linalg.inv(cam.projection(w / h) @ cam.view())))
            _set(bg, "u_camera_pos", tuple(float(x) for x in cam.position))
            ibl.bind(bg, env.rotation_deg)
            self._fullscreen_vao(bg).render(vertices=3)
        ctx.enable(ctx.DEPTH_TEST)
        ctx.disable(ctx.CULL_FACE)
        view_proj = cam.projection(w / h) @ cam.view()
        types = np.zeros(MAX_LIGHTS, "i4")
        pos = np.zeros((MAX_LIGHTS, 3), "f4")
        val = np.zeros((MAX_LIGHTS, 3), "f4")
        for i, l in enumerate(lights):
            types[i] = 0 if l.type == "point" else 1
            pos[i] = l.position if l.type == "point" else l.direction
            val[i] = l.intensity if l.type == "point" else l.irradiance
        env_on = scene.render.ibl != "off" and (env_map is not None or bool(np.any(env_rad > 0)))
        frame_uniforms = {
            "u_view_proj": gl_bytes(view_proj),
            "u_camera_pos": tuple(float(x) for x in cam.position),
            "u_num_lights": len(lights),
            "u_light_type": types.tobytes(),
            "u_light_pos": pos.tobytes(),
            "u_light_value": val.tobytes(),
            "u_env_on": int(env_on),
            "u_env_constant": tuple(float(x) for x in env_rad),
            "u_ibl_mode": IBL_MODES.get(scene.render.ibl, 1),
            "u_frame_index": int(frame_index),
            "u_ms_on": int(bool(getattr(scene.render, "ms_compensation", False))),
            "u_view_mode": int(view_mode),
            "u_shadows_on": int(shadows),
        }
        if ssr_on:
            frame_uniforms["u_view"] = gl_bytes(cam.view())
        if shadows:
            self._shadow["tex"].use(location=0)
            frame_uniforms.update({
                "u_shadow_atlas": 0,
                "u_shadow_mat": b"".join(gl_bytes(m) for m in self._shadow_mats),
                "u_shadow_atlas_tiles": (6.0, float(self._shadow["rows"])),
                "u_shadow_tile_size": float(SHADOW_TILE),
                "u_shadow_texel_world": self._shadow_texel.astype("f4").tobytes(),
            })
        rt = None
        if scene.render.raytrace and any(chain_kind(scene.materials[o.material]) != KIND_SHADED
                                         for o in scene.objects):
            rt = self.raytrace_state()
            rt.update(scene, self.albedo_tables)
            rt_models, rt_disp = scene_models(scene), dispersive(scene)
            from viewer.gl.brdf_glsl import uses_thin_film

            rt_film = any(uses_thin_film(scene.materials[o.material]) for o in scene.objects)
        ready = set()
        for obj in scene.objects:
            params = scene.materials[obj.material]
            traced = rt is not None and chain_kind(params) != KIND_SHADED
            try:
                prog = self.forward_program(params, sample_shading=self.sample_shading and targets["samples"] > 1,
                                            ssr=ssr_on,
                                            ibl_sampled=env_on and scene.render.ibl in ("fis", "brute_force"),
                                            env_light=env_on, env_constant=env_map is None,
                                            raytrace=rt_models if traced else None,
                                            dispersion=traced and rt_disp,
                                            thin_film=True if traced and rt_film else None)
            except ShaderError:
                if not self.hot_reload:
                    raise
                continue  # never compiled (see shader_errors): leave the object out, draw the rest
            if id(prog) not in ready:
                for k, v in frame_uniforms.items():
                    _set(prog, k, v)
                # always: unbound samplers default to unit 0, where the shadow atlas (a different
                # sampler type) is, and that makes the draw call invalid
                ibl.bind(prog, env.rotation_deg)
                ready.add(id(prog))
            if traced:  # every frame: the shadow atlas and IBL share no units with these
                rt.bind(prog, first_unit=8)
                row = rt.rows[obj.material]
                _set(prog, "u_rt_row", row)
                _set(prog, "u_mat_base", row * 256)
                _set(prog, "u_rt_depth", int(scene.render.raytrace_depth))
                _set(prog, "u_rt_max_segments", RT_MAX_SEGMENTS)
            m = obj.model_matrix()
            _set(prog, "u_model", gl_bytes(m))
            _set(prog, "u_normal_matrix", gl_bytes(np.linalg.inv(m[:3, :3]).T))
            idx, block = uniform_block(params)
            _set(prog, "u_model_id", idx)
            _set(prog, "u_mat", block.tobytes())
            if "u_measured" in prog:
                self._measured_textures().bind(prog, params)
            if env_on or ssr_on:
                refl, trans, spec, alpha = self._base_albedo_tables(params)
                _set(prog, "u_albedo", refl.tobytes())
                _set(prog, "u_albedo_t", trans.tobytes())
                _set(prog, "u_albedo_s", spec.tobytes())
                _set(prog, "u_ibl_alpha", alpha)
                _set(prog, "u_ibl_delta", int(brdf_spec(params).delta and alpha == 0.0))
                # compensation for the whole scene, or for a material whose reference has the
                # multiple-scattering random walk (the raster's approximation of the same light)
                ms_on = bool(frame_uniforms["u_ms_on"]) or bool(params.get("multiple_scattering", False))
                _set(prog, "u_ms_on", int(ms_on))
                if ms_on:  # the shader reads u_ms_f0 only then
                    _set(prog, "u_ms_f0", tuple(float(x) for x in self.ms_f0(params)))
                absorbing = "sigma_a" in params and brdf_spec(params).transmissive
                _set(prog, "u_transmit_on", int(bool(np.any(trans > 0))))
                _set(prog, "u_sigma_a", tuple(float(x) for x in (params.sigma_a if absorbing else np.zeros(3))))
                _set(prog, "u_ior", float(params.get("ior", 1.0)))
                if thickness is not None:
                    thickness.use(location=1)
                    _set(prog, "u_thickness", 1)
            self._gpu_mesh(obj.mesh_data).vao(prog).render()
        if ssr_on:
            return self._ssr.resolve_and_trace(ibl, cam, w, h, env_on, env.rotation_deg, ssr_debug, frame_index)
        if targets["draw_fbo"] is not targets["resolved_fbo"]:
            ctx.copy_framebuffer(targets["resolved_fbo"], targets["draw_fbo"])
        return targets["resolved"]

    def _thickness_pass(self, objects, cam, w, h):
        """Distance from the camera to the nearest back face of absorbing transmissive objects,
        per pixel (R32F). The forward pass takes back - front as the path length inside, the
        rasterizer's approximation of Bouguer absorption (the reference path tracer follows
        the refracted path exactly)."""
        ctx = self.ctx
        key = (w, h)
        if self._thick is None or self._thick[0] != key:
            if self._thick is not None:
                for r in self._thick[1:]:
                    r.release()
            tex = ctx.texture((w, h), 1, dtype="f4")
            tex.filter = (ctx.NEAREST, ctx.NEAREST)
            depth = ctx.depth_renderbuffer((w, h))
            self._thick = (key, tex, depth, ctx.framebuffer(color_attachments=[tex], depth_attachment=depth))
        _, tex, _, fbo = self._thick
        prog = self._program("thickness", _THICKNESS)
        fbo.use()
        fbo.viewport = (0, 0, w, h)
        fbo.clear(0.0, 0.0, 0.0, 0.0, depth=1.0)
        ctx.enable(ctx.DEPTH_TEST | ctx.CULL_FACE)
        ctx.cull_face = "front"  # keep back faces: the far side of each object
        _set(prog, "u_view_proj", gl_bytes(cam.projection(w / h) @ cam.view()))
        _set(prog, "u_camera_pos", tuple(float(x) for x in cam.position))
        for obj in objects:
            m = obj.model_matrix()
            _set(prog, "u_model", gl_bytes(m))
            _set(prog, "u_normal_matrix", gl_bytes(np.linalg.inv(m[:3, :3]).T))
            self._gpu_mesh(obj.mesh_data).vao(prog).render()
        ctx.cull_face = "back"
        ctx.disable(ctx.CULL_FACE)
        return tex

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
        hdr.use(location=0)
        _set(prog, "u_hdr", 0)
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
                self._ldr[1].release()
                self._ldr[0].release()
            tex = self.ctx.texture((w, h), 4, dtype="f1")
            self._ldr = (tex, self.ctx.framebuffer(color_attachments=[tex]))
        self.tonemap_to(self._ldr[1], hdr, exposure, tonemap, viewport=(0, 0, w, h))
        a = np.frombuffer(self._ldr[0].read(), dtype=np.uint8).reshape(h, w, 4)
        return np.ascontiguousarray(a[::-1, :, :3])

    def render_arrays(self, scene, camera=None, width=None, height=None, view_mode=0, supersample: int = 1,
                      frames: int = 1):
        """(linear float32, sRGB uint8) images, (H, W, 3), row 0 = top.

        ``supersample`` k > 1 renders k x k shading points per pixel on a regular grid (no MSAA)
        and averages them: the box filter of docs/conventions.md up to 1/k^2 of the error of
        shading at the pixel centre (what MSAA does), at k^2 times the cost."""
        if supersample <= 1 and frames <= 1:
            hdr = self.render(scene, camera, width, height, view_mode)
            return (self.read_linear(hdr),
                    self.read_srgb(hdr, scene.render.exposure, scene.render.tonemap))
        if supersample <= 1:  # progressive: the mean of ``frames`` frames with new sample sets
            from viewer.colour import to_srgb8

            acc = None
            for f in range(frames):
                img = self.read_linear(self.render(scene, camera, width, height, view_mode, frame_index=f))
                acc = img.astype(np.float64) if acc is None else acc + img
            linear = (acc / frames).astype(np.float32)
            return linear, to_srgb8(linear, scene.render.exposure, scene.render.tonemap)
        from viewer.colour import to_srgb8

        k = int(supersample)
        w = int(width or scene.camera.width)
        h = int(height or scene.camera.height)
        hdr = self.render(scene, camera, w * k, h * k, view_mode, msaa=0)
        big = self.read_linear(hdr)
        linear = big.reshape(h, k, w, k, 3).mean(axis=(1, 3), dtype=np.float64).astype(np.float32)
        return linear, to_srgb8(linear, scene.render.exposure, scene.render.tonemap)

    def release(self):
        self._release_targets()
        for _, gm in self._meshes.values():
            gm.release()
        self._meshes.clear()
        if self._shadow:
            self._shadow["fbo"].release()
            self._shadow["tex"].release()
        if self._ldr:
            self._ldr[1].release()
            self._ldr[0].release()
        if self._thick:
            for r in self._thick[1:]:
                r.release()
        if self._ibl is not None:
            self._ibl.release()
        if self._ssr is not None:
            self._ssr.release()
        if self._albedo_gpu is not None:
            self._albedo_gpu.release()
            self._albedo_gpu = None
        if self._rt is not None:
            self._rt.release()
        if self._measured is not None:
            self._measured.release()
        for v in self._fullscreen_vaos.values():
            v.release()
        self._fullscreen_vaos.clear()
        for p in self.programs.values():
            p.release()
        self.programs.clear()
