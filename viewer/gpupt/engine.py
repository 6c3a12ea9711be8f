"""The GPU reference engine: the CPU engine's estimator in GLSL over the scene's BVH textures.

``GpuReferenceRenderer`` has the interface ``viewer.reference_common.estimator.ReferenceEngine``
(``step(spp, cancel=)``, ``mean()``, ``variance()``, ``spp``, ``bad_values``, ``reset(scene)``,
``close()``) plus ``step_for(seconds)``, which renders bands of rows until a time budget is
spent (the window calls it once per frame so the raster stays interactive).

How it runs (OpenGL 4.1 core): the setup is the one the CPU engine renders from (``viewer.reference_common.setup.RenderSetup``: the
same triangles, vertex normals, tangents, camera, lights, environment tables). The triangles
and BVH go to float textures once (``viewer.gl.scene_textures``); the materials are packed
one after another into a float texture in the layout of ``viewer.gl.brdf_glsl.pack_material``
(the generated ``brdf/dispatch.glsl`` reads them through ``mat_f``, here from that texture
instead of the rasterizer's uniform block). Each pass draws ``shaders/passes/pathtrace.frag``:
a whole-image pass over the whole target, a band of rows (``step_for``) only over the band after
the current sums are blitted to the other side; pixels in the band add ``spp_pass`` samples to
the running sums; two RGBA32F targets per ping-pong side hold
(sum of radiance, sample count) and (sum of squares, bad-value count). The random numbers of
sample ``s`` of pixel ``(x, y)`` are a hash of ``(x, y, s, seed)`` (``shaders/common/rng.glsl``),
so an image depends on the seed and the number of samples only, never on how the passes were
cut into bands. Programs are compiled for what the scene uses (its models, environment kind,
number of lights, layered materials with a delta base) and for the estimator's options
(``strategy``, ``mis_heuristic``, ``russian_roulette``, as ``ReferenceRenderer`` takes them:
each a compile-time variant of the pass), and cached by that recipe. ``spectral``: the CPU
engine's hero-wavelength estimator instead of RGB, the compile-time variant ``SPECTRAL``
(``shaders/pathtrace/spectral.glsl``, its data from ``viewer.gpupt.spectral``); None: where a
material is dispersive, as ``ReferenceRenderer`` decides (``viewer.reference_common.select.make_renderer``
passes its ``spectral`` so); the default False keeps RGB. ``integrator``: "path" (the default),
"photon" (path tracing plus a progressive caustic photon map, ``viewer.reference_common.caustics``:
the compile-time variant PHOTONS, its photon map ``viewer.gpupt.photons``; pass i of the map is
sample i of every pixel, so the photon integrator renders one sample per pass) or "auto" (chosen
per scene; ``integrator`` and ``integrator_reason`` say which and why).
"""

from __future__ import annotations

import threading
import time

import numpy as np

from viewer import ViewerError, brdf
from viewer.gl.brdf_glsl import custom_virtual, generate_dispatch, models_used, pack_material, program_defines
from viewer.gl.constants import ENV_MODES, MAX_MATERIALS, STRATEGIES
from viewer.gl.context import release_gl
from viewer.gl.scene_textures import SceneTextures, float_texture
from viewer.gl.shaders import build_program, set_uniform
from viewer.geometry.bvh_flat import TEX_WIDTH, as_texels
from viewer.reference_common.refusals import MEASURED_REFUSAL, measured_tables, needs_spectral, several_measured_tables
from viewer.reference_common.estimator import EstimatorOptions, mean_of, variance_of_mean
from viewer.reference_common.setup import RenderSetup


def dispatch_from_texture(models: tuple[str, ...]) -> str:
    """The generated dispatch for ``models`` reading materials from the texture ``u_mat_tex``
    (every material of the scene at its own offset) instead of the uniform block."""
    return generate_dispatch(models, texture_width=TEX_WIDTH)


def virtual_files(models) -> dict:
    """The virtual files of a program for ``models``: the dispatch from ``u_mat_tex`` and the
    models' own GLSL (.brdf files)."""
    return {"brdf/dispatch.glsl": dispatch_from_texture(models), **custom_virtual(models)}


def pack_materials(materials) -> tuple[np.ndarray, np.ndarray]:
    """(info (2 * MAX_MATERIALS, 4) float32 for ``u_mat_info``, floats (F,) for ``u_mat_tex``)
    for a list of ``viewer.reference_common.setup.MaterialInfo``."""
    if len(materials) > MAX_MATERIALS:
        raise ViewerError(f"the GPU engine holds {MAX_MATERIALS} materials; the scene has {len(materials)}")
    info = np.zeros((2 * MAX_MATERIALS, 4), np.float32)
    data: list[np.ndarray] = []
    offset = 0
    for i, m in enumerate(materials):
        model, arr = pack_material(m.params, offset, limit=None)
        info[2 * i] = (model, offset, int(m.lobes), 1.0 if m.transmissive else 0.0)
        info[2 * i + 1, :3] = m.sigma_a
        data.append(arr)
        offset += arr.size
    return info, (np.concatenate(data) if data else np.zeros(4, np.float32)).astype(np.float32)


_PROGRAMS: dict = {}   # (id(ctx), recipe) -> (program, vertex array)


def release_programs(ctx) -> None:
    """Release the cached path-tracing and photon programs made on ``ctx`` (before releasing it)."""
    from viewer.gpupt import photons

    for key in [k for k in _PROGRAMS if k[0] == id(ctx)]:
        prog, vao = _PROGRAMS.pop(key)
        vao.release()
        prog.release()
    photons.release_programs(ctx)


class GpuReferenceRenderer:
    """Progressive GPU reference of ``scene`` (``camera`` as for ``ReferenceRenderer``).
    ``ctx``: a moderngl context (default: a new headless EGL one, owned and released here).
    ``strategy``, ``mis_heuristic``, ``russian_roulette``, ``integrator``: the estimator's options,
    as for ``ReferenceRenderer`` (spectral or not).
    ``spectral``: trace wavelengths (True), RGB (False, the default) or, None, wavelengths where
    a material is dispersive (``ReferenceRenderer``'s default)."""

    engine = "gpu"
    is_spectral = False  # set per setup: wavelengths (the SPECTRAL variant) or RGB

    def __init__(self, scene, camera=None, width=None, height=None, max_depth=8, seed=0,
                 env_image=None, ctx=None, spp_pass: int = 1, strategy: str = "mis",
                 mis_heuristic: str = "power", russian_roulette: bool = True, spectral: bool | None = False,
                 integrator: str = "path"):
        if int(max_depth) < 1:
            raise ValueError("max_depth must be >= 1")
        _refuse_measured(scene)
        self._measured_params = next(iter(measured_tables(scene).values()), None)
        self.options = EstimatorOptions(strategy, mis_heuristic, russian_roulette, integrator)
        self.spectral = spectral    # trace wavelengths; None: where a material is dispersive
        self.max_depth, self.env_image, self.seed = int(max_depth), env_image, int(seed)
        self._own_ctx = ctx is None
        if ctx is None:
            from viewer.gl.context import create_offscreen_context

            ctx = create_offscreen_context()
        self.ctx = ctx
        self.spp_pass = max(1, int(spp_pass))
        self._scene_tex = None
        self._measured = None               # MeasuredTextures: the scene's one measured table
        self._textures: list = []
        self._targets: list = []
        self.photons = None                 # the photon map (viewer.gpupt.photons.CausticPhotons) under photon
        self.rows_per_pass = None           # adapted by step_for
        self._set_setup(self._make_setup(scene, camera, width, height))

    # ------------------------------------------------------------------ setup
    def _make_setup(self, scene, camera, width, height) -> RenderSetup:
        setup = RenderSetup.from_scene(scene, camera, width, height, self.max_depth, self.env_image,
                                       **self.options.as_kwargs())
        setup.extra["spectral"] = needs_spectral(scene, self.spectral)   # as the CPU engine (the cache key reads it)
        return setup

    def reset(self, scene, camera=None, width=None, height=None, *, strategy=None, mis_heuristic=None,
              russian_roulette=None, integrator=None):
        """Start over on a changed scene, camera or size (the programs stay cached); the
        estimator's options change where given (None: as before)."""
        _refuse_measured(scene)
        self._measured_params = next(iter(measured_tables(scene).values()), None)
        self.options = self.options.updated(strategy, mis_heuristic, russian_roulette, integrator)
        self._set_setup(self._make_setup(scene, camera, width, height))

    def _release_scene(self):
        release_gl(*self._textures, *self._targets)
        self._textures, self._targets = [], []
        if self.photons is not None:
            self.photons.release()
            self.photons = None
        if self._scene_tex is not None:
            self._scene_tex.release()
            self._scene_tex = None

    def _set_setup(self, setup: RenderSetup):
        self._release_scene()
        self.setup = setup
        # "path" or "photon" (an "auto" option resolved for this scene) and why
        self.integrator, self.integrator_reason = setup.integrator, setup.integrator_reason
        self.width, self.height = setup.width, setup.height
        self.spp = 0
        self.bad_values = 0
        self.samples_done = 0
        self._band_row = 0                  # next row of the band being filled by step_for
        ctx = self.ctx
        self._scene_tex = SceneTextures(ctx, setup.geometry)
        info, floats = pack_materials(setup.materials)
        self._mat_info = info
        self.is_spectral = bool(setup.extra.get("spectral", False))
        if self.is_spectral:   # the materials' parameter sets per wavelength after the RGB ones
            from viewer.gpupt.spectral import pack_spectral_materials, spectral_table

            self._mat_spec, more = pack_spectral_materials(setup.materials, len(floats), MAX_MATERIALS)
            floats = np.concatenate([floats, more])
            self._spec_tex = float_texture(ctx, spectral_table())
            self._textures.append(self._spec_tex)
        self._mat_tex = float_texture(ctx, as_texels(np.concatenate([floats, np.zeros((-len(floats)) % 4,
                                                                                          np.float32)])))
        self._textures.append(self._mat_tex)
        env = setup.env
        self.env_mode = ENV_MODES["black" if env.is_black else ("map" if env.is_map else "constant")]
        self._env_tex, self._env_size, self._to_map = environment_textures(ctx, env, self.env_mode)
        self._textures.extend(self._env_tex)
        self._targets = []
        for _ in range(2):
            a = ctx.texture((self.width, self.height), 4, dtype="f4")
            b = ctx.texture((self.width, self.height), 4, dtype="f4")
            a.write(np.zeros((self.height, self.width, 4), np.float32).tobytes())
            b.write(np.zeros((self.height, self.width, 4), np.float32).tobytes())
            self._targets += [a, b]
        self._fbos = [ctx.framebuffer(color_attachments=self._targets[0:2]),
                      ctx.framebuffer(color_attachments=self._targets[2:4])]
        self._textures.extend(self._fbos)
        # the sums at the last whole-image sample (state() while a band of rows is half done)
        self._snap = [ctx.texture((self.width, self.height), 4, dtype="f4") for _ in range(2)]
        self._targets.extend(self._snap)
        self._single = [ctx.framebuffer(color_attachments=[t]) for t in self._targets]
        self._textures.extend(self._single)
        self._snap_spp = 0
        self._cur = 0                       # side holding the current sums
        self._prog = self._program()
        if self.uses_photons:
            from viewer.gpupt.photons import CausticPhotons

            self.photons = CausticPhotons.for_setup(ctx, setup, self.seed, self.recipe()[1], virtual_files)

    def recipe(self):
        """What the pass's program is compiled for: (the models used, sorted (define, value)
        pairs). Renderers with the same recipe share one program."""
        s = self.setup
        models = []
        for m in s.materials:
            models.extend(models_used(m.params))
        models = tuple(dict.fromkeys(models)) or ("lambert",)
        defines = {"ENV_MODE": str(self.env_mode), "N_LIGHTS": str(len(s.lights))}
        defines.update(program_defines([m.params for m in s.materials]))
        if s.strategy != "mis" and self.env_mode != ENV_MODES["black"]:   # strategies differ only in reaching the environment
            defines["STRATEGY"] = str(STRATEGIES[s.strategy])
        if s.strategy == "mis" and s.mis_heuristic == "balance" and self.env_mode != ENV_MODES["black"]:   # the heuristic matters only to MIS
            defines["BALANCE_HEURISTIC"] = "1"
        if not s.russian_roulette:
            defines["NO_ROULETTE"] = "1"
        if (s.strategy != "mis" or self.env_mode == ENV_MODES["black"]) and any(
                brdf.is_file(m.params) and brdf.model_of(m.params).of(m.params).bfile.has_sampler for m in s.materials):
            # a .brdf file's own sampler (isFunc) draws its directions where no MIS weight needs
            # the pdf of a direction it did not draw (which sampleBRDF does not give)
            defines["FILE_SAMPLERS"] = "1"
        if self.is_spectral:
            defines["SPECTRAL"] = "1"
        if self.uses_photons:
            defines["PHOTONS"] = "1"
            from viewer.reference_common.caustics import spectral_photons

            if spectral_photons(s):   # photons of one wavelength each (a dispersive delta surface)
                defines["PHOTON_WAVELENGTHS"] = "1"
        return models, tuple(sorted(defines.items()))

    @property
    def uses_photons(self) -> bool:
        """The photon integrator on a scene with a delta lobe (without one no path is a caustic
        path and the photon integrator is the path tracer: the plain program renders it)."""
        return self.setup.integrator == "photon" and any(m.lobes.has_delta for m in self.setup.materials)

    def _program(self):
        """The pass's program for this scene's recipe, shared by every renderer on the same
        context (compiling takes 0.2-6 s on llvmpipe; a material change of the same models
        reuses it)."""
        key = (id(self.ctx), self.recipe())
        entry = _PROGRAMS.get(key)
        if entry is None:
            models, defines = key[1]
            prog = build_program(self.ctx, "passes/fullscreen.vert", "passes/pathtrace.frag",
                                 virtual=virtual_files(models), defines=dict(defines))
            entry = _PROGRAMS[key] = (prog, self.ctx.vertex_array(prog, []))
        self._vao = entry[1]
        return entry[0]

    def _bind_materials(self, prog) -> int:
        """Bind the BVH, material textures and uniforms (both passes); the next free unit."""
        unit = self._scene_tex.bind(prog, 0)
        self._mat_tex.use(location=unit)
        set_uniform(prog, "u_mat_tex", unit)
        unit += 1
        set_uniform(prog, "u_mat_info", self._mat_info.tobytes())
        if self.is_spectral and "u_spec_tab" in prog:   # (the photon pass with wavelengths reads them too)
            self._spec_tex.use(location=unit)
            set_uniform(prog, "u_spec_tab", unit)
            unit += 1
            set_uniform(prog, "u_mat_spec", self._mat_spec.tobytes())
        if self._measured_params is not None and "u_measured" in prog:
            if self._measured is None:
                from viewer.gl.measured_tex import MeasuredTextures

                self._measured = MeasuredTextures(self.ctx)
            self._measured.bind(prog, self._measured_params, unit)
            unit += 1
        return unit

    def _bind(self):
        prog, s = self._prog, self.setup
        unit = self._bind_materials(prog)
        for name, tex in zip(("u_env_map", "u_env_row_cdf", "u_env_col_cdf"), self._env_tex):
            tex.use(location=unit)
            set_uniform(prog, name, unit)
            unit += 1
        src = self._targets[2 * self._cur: 2 * self._cur + 2]
        for name, tex in zip(("u_prev_sum", "u_prev_sq"), src):
            tex.use(location=unit)
            set_uniform(prog, name, unit)
            unit += 1
        if self.photons is not None:
            unit = self.photons.bind(prog, unit)
        set_uniform(prog, "u_seed", self.seed & 0xFFFFFFFF)
        set_uniform(prog, "u_max_depth", s.max_depth)
        set_uniform(prog, "u_size", (self.width, self.height))
        set_uniform(prog, "u_cam_pos", tuple(map(float, s.cam_pos)))
        set_uniform(prog, "u_cam_forward", tuple(map(float, s.cam_forward)))
        set_uniform(prog, "u_cam_right", tuple(map(float, s.cam_right)))
        set_uniform(prog, "u_cam_up", tuple(map(float, s.cam_up)))
        set_uniform(prog, "u_tan_half_y", float(s.tan_half_y))
        env = s.env
        set_uniform(prog, "u_env_constant", tuple(map(float, env.constant)))
        set_uniform(prog, "u_env_size", self._env_size)
        # GLSL reads a mat3 column by column: the transpose's rows are the matrix's columns
        set_uniform(prog, "u_env_to_map", np.ascontiguousarray(np.asarray(self._to_map).T, np.float32).tobytes())
        if s.lights:
            a = np.zeros((len(s.lights), 4), np.float32)
            v = np.zeros((len(s.lights), 3), np.float32)
            for j, (kind, x, val) in enumerate(s.lights):
                a[j, :3] = x
                a[j, 3] = 0.0 if kind == "point" else 1.0
                v[j] = val
            set_uniform(prog, "u_light_a", a.tobytes())
            set_uniform(prog, "u_light_v", v.tobytes())

    def _build_photons(self):
        """The photon map of the next sample (pass spp + 1), once whatever the bands."""
        if self.photons is not None and self.photons.pass_index != self.spp + 1:
            self.photons.build(self.spp + 1, self._bind_materials)

    def _pass(self, row0: int, row1: int, spp: int):
        """One draw: rows [row0, row1) gain ``spp`` samples each (one under photons: a pass)."""
        if self.photons is not None and spp > 0:
            if spp != 1:
                raise ValueError("the photon integrator renders one sample per pass")
            self._build_photons()
        self._bind()
        set_uniform(self._prog, "u_row0", int(row0))
        set_uniform(self._prog, "u_row1", int(row1))
        set_uniform(self._prog, "u_spp_pass", int(spp))
        dst = self._fbos[1 - self._cur]
        if row0 <= 0 and row1 >= self.height:
            dst.use()
            dst.viewport = (0, 0, self.width, self.height)
        else:
            # a band: the other side gets the current sums by a blit (a copy), then only the
            # band's fragments run (on software GL the shader over every other pixel cost as
            # much as 30 rows of samples)
            for k in range(2):
                self.ctx.copy_framebuffer(self._single[2 * (1 - self._cur) + k], self._single[2 * self._cur + k])
            dst.use()
            r0, r1 = max(0, int(row0)), min(self.height, int(row1))
            dst.viewport = (0, r0, self.width, max(0, r1 - r0))
        self._vao.render(vertices=3)
        self._cur = 1 - self._cur

    # ------------------------------------------------------------------ work
    def step(self, spp: int = 1, cancel: threading.Event | None = None, progress=None) -> bool:
        """Add ``spp`` samples per pixel to every pixel. Returns False when ``cancel`` is set
        before the pass completes (the samples already added stay: the image remains a valid
        estimate whose ``spp`` counts only completed whole-image samples)."""
        spp = int(spp)
        done = 0
        while done < spp:
            if cancel is not None and cancel.is_set():
                return False
            k = min(1 if self.photons is not None else self.spp_pass, spp - done)
            self._pass(0, self.height, k)
            self.ctx.finish()
            done += k
            self.spp += k
            self.samples_done += k * self.width * self.height
            if progress:
                progress(done / spp)
        return True

    def step_for(self, seconds: float) -> int:
        """Render bands of rows (one sample each) for about ``seconds``; returns the camera samples
        added. ``spp`` counts the samples every pixel has; ``rows_per_pass`` adapts so that one
        draw takes about a quarter of the budget, starting from about 1,000 pixels (a first draw
        of unknown cost must not hold a slow or busy machine's frame for seconds; the doubling
        reaches the budget within a frame or two)."""
        t0 = time.perf_counter()
        added = 0
        if self.rows_per_pass is None:
            self.rows_per_pass = max(1, min(self.height, 1024 // max(self.width, 1)))
        while True:
            r0 = self._band_row
            r1 = min(self.height, r0 + self.rows_per_pass)
            # a new pass's photon map, made ahead on a worker thread (viewer.gpupt.photons): a
            # band waits for none of it; until it is up this call renders nothing more
            if self.photons is not None and not self.photons.advance(self.spp + 1, self._bind_materials):
                break
            t_pass = time.perf_counter()
            self._pass(r0, r1, 1)
            self.ctx.finish()
            dt = time.perf_counter() - t_pass
            added += (r1 - r0) * self.width
            self.samples_done += (r1 - r0) * self.width
            self._band_row = 0 if r1 >= self.height else r1
            if r1 >= self.height:
                self.spp += 1
                self._snapshot()
            elif self.photons is not None:   # the next pass's map, up to its upload
                self.photons.advance(self.spp + 2, self._bind_materials, upload=False)
            # aim for a draw of a quarter of the budget
            want = max(1e-3, 0.25 * seconds)
            scale = want / max(dt, 1e-5)
            self.rows_per_pass = int(max(1, min(self.height, round(self.rows_per_pass * min(2.0, max(0.5, scale))))))
            if time.perf_counter() - t0 + dt > seconds:
                break
        return added

    def warm_up(self):
        """Compile and run one tiny pass now, so the first ``step`` measures rendering only."""
        self._pass(0, 0, 0)
        self.ctx.finish()

    # ------------------------------------------------------------------ results
    def _read(self):
        a, b = self._targets[2 * self._cur: 2 * self._cur + 2]
        s = np.frombuffer(a.read(), np.float32).reshape(self.height, self.width, 4).astype(np.float64)
        q = np.frombuffer(b.read(), np.float32).reshape(self.height, self.width, 4).astype(np.float64)
        return s, q

    def sums(self):
        """(sum (H, W, 3), sum of squares (H, W, 3), count (H, W)) as accumulated (float64 copies)."""
        s, q = self._read()
        self.bad_values = int(q[:, :, 3].sum())
        return s[:, :, :3], q[:, :, :3], s[:, :, 3]

    def _snapshot(self):
        """Copy the current sums to the snapshot textures (GPU-side blits)."""
        for k in range(2):
            self.ctx.copy_framebuffer(self._single[4 + k], self._single[2 * self._cur + k])
        self._snap_spp = self.spp

    def state(self):
        """(sum, sum of squares, spp) of the whole-image samples so far (float64). While
        ``step_for`` is half-way through a sample, the sums as they were at the last whole one."""
        if self._band_row == 0:
            s, q, n = self.sums()
            return s, q, self.spp
        if self._snap_spp == 0:
            return None
        a, b = self._snap
        s = np.frombuffer(a.read(), np.float32).reshape(self.height, self.width, 4).astype(np.float64)
        q = np.frombuffer(b.read(), np.float32).reshape(self.height, self.width, 4).astype(np.float64)
        return s[:, :, :3], q[:, :, :3], self._snap_spp

    def resume(self, total, total2, spp: int):
        """Continue from stored sums of ``spp`` samples per pixel (the reference cache)."""
        total = np.asarray(total, np.float32)
        if total.shape != (self.height, self.width, 3):
            raise ValueError(f"resume: sums of shape {total.shape}, the image is {(self.height, self.width, 3)}")
        a = np.concatenate([total, np.full((self.height, self.width, 1), float(spp), np.float32)], axis=2)
        b = np.concatenate([np.asarray(total2, np.float32), np.zeros((self.height, self.width, 1), np.float32)],
                           axis=2)
        src = self._targets[2 * self._cur: 2 * self._cur + 2]
        src[0].write(np.ascontiguousarray(a).tobytes())
        src[1].write(np.ascontiguousarray(b).tobytes())
        self.spp = int(spp)
        self._band_row = 0
        self._snapshot()

    def mean(self) -> np.ndarray:
        """(H, W, 3) float32 running mean, row 0 = top (pixels with no sample yet: 0)."""
        s, _, n = self.sums()
        return mean_of(s, n[:, :, None])

    def variance(self) -> np.ndarray:
        """(H, W, 3) variance of the mean per pixel (``estimator.variance_of_mean``)."""
        s, q, n = self.sums()
        return variance_of_mean(s, q, n[:, :, None])

    def close(self):
        if self.ctx is None:
            return
        self._release_scene()
        if self._measured is not None:
            self._measured.release()
            self._measured = None
        if self._own_ctx:
            release_programs(self.ctx)
            self.ctx.release()
        self.ctx = None

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


def environment_textures(ctx, env, mode: int):
    """(textures, (w, h), to_map) of an environment map (its image with each texel's pdf in w, the
    row and column CDFs; nearest filtering) for ``ENV_MODES["map"]``, else ([], (1, 1), I)."""
    if mode != ENV_MODES["map"]:
        return [], (1, 1), np.eye(3)
    import moderngl

    texel_p, row_cdf, col_cdf, to_map = env.distribution()
    h, w, _ = env.image.shape
    img = np.concatenate([env.image, (texel_p * (w * h))[:, :, None]], axis=2).astype(np.float32)
    tex = [ctx.texture((w, h), 4, np.ascontiguousarray(img).tobytes(), dtype="f4"),
           ctx.texture((h + 1, 1), 1, row_cdf.astype(np.float32).tobytes(), dtype="f4"),
           ctx.texture((w + 1, h), 1, np.ascontiguousarray(col_cdf, np.float32).tobytes(), dtype="f4")]
    for t in tex:
        t.filter = (moderngl.NEAREST, moderngl.NEAREST)
    return tex, (w, h), to_map


def _refuse_measured(scene):
    if several_measured_tables(scene):
        raise ViewerError(MEASURED_REFUSAL)
