"""The GPU engine's caustic photon map (the ``photon`` integrator; the estimator is described in
``viewer.reference_common.caustics``): per pass, photons emitted on the CPU
(``caustics.emit_photons``) are traced over the scene's BVH by ``shaders/passes/photon_trace.frag``
(one photon per fragment of a target ``TEX_WIDTH`` texels wide, the photons' origins, directions
and powers read from float textures), which writes each stored photon (position and a valid
flag, direction of travel, power, normal) into four RGBA32F targets; those are read back, put
into ``caustics``' hash grid for the pass's radius, and the grid (its bucket table and the
photons sorted by bucket) goes up as float textures that the path-tracing pass's PHOTONS
variant gathers from (``shaders/pathtrace/photons.glsl``). The numpy parts (emission, the
grid) run on a worker thread (``CausticPhotons.advance``), so a window's frame waits for none.

Pass i (1-based; the image's i-th sample per pixel) uses the photons of the random stream
(seed, ``caustics.PHOTON_STREAM``, i) and gathers with ``caustics.pass_radius(r_1, i)``, so an
image depends on the seed and the number of samples only, as without photons.
"""

from __future__ import annotations

import time

import numpy as np

from viewer.gl.context import release_gl
from viewer.gl.scene_textures import float_texture
from viewer.gl.shaders import build_program, set_uniform
from viewer.geometry.bvh_flat import TEX_WIDTH
from viewer.reference_common import caustics

# the photon pass's own random numbers: a key word apart from the camera samples' (photon_trace.frag)
_PROGRAMS: dict = {}   # (id(ctx), recipe) -> (program, vertex array)
SAMPLERS = ("u_grid_table", "u_gph_pos", "u_gph_dir", "u_gph_pow", "u_gph_nrm")


def release_programs(ctx) -> None:
    """Release the cached photon-pass programs made on ``ctx``."""
    for key in [k for k in _PROGRAMS if k[0] == id(ctx)]:
        prog, vao = _PROGRAMS.pop(key)
        vao.release()
        prog.release()


def texels(a: np.ndarray) -> np.ndarray:
    """(rows, TEX_WIDTH, 4) float32 texels of ``a`` (N, k <= 4), row i at texel (i % TEX_WIDTH,
    i // TEX_WIDTH) (at least one row; the rest zeros)."""
    a = np.asarray(a, np.float32).reshape(a.shape[0], -1)
    rows = max(1, -(-a.shape[0] // TEX_WIDTH))
    out = np.zeros((rows * TEX_WIDTH, 4), np.float32)
    out[: a.shape[0], : a.shape[1]] = a
    return out.reshape(rows, TEX_WIDTH, 4)


def photon_stream(seed: int, i: int) -> np.random.Generator:
    """The emission numbers of pass ``i``: Philox4x64 keyed by the seed, its counter at
    (0, 0, PHOTON_STREAM, i) (a block id no image row uses)."""
    key = np.array([int(seed) & 0xFFFFFFFFFFFFFFFF, 0x9E3779B97F4A7C15], dtype=np.uint64)
    ctr = np.array([0, 0, caustics.PHOTON_STREAM, int(i)], dtype=np.uint64)
    return np.random.Generator(np.random.Philox(key=key, counter=ctr))


class CausticPhotons:
    """The photon map of one setup on ``ctx``. ``recipe``: (models, defines) the photon pass is
    compiled for (the models of the materials with a delta lobe, the material defines);
    ``virtual``: the virtual files of their BRDF dispatch reading materials from ``u_mat_tex``."""

    def __init__(self, ctx, setup, seed: int, recipe, virtual: dict):
        self.ctx, self.setup, self.seed = ctx, setup, int(seed)
        # ``extra["photons_per_pass"]``: a fixed count (tests, benchmarks); else by the image size
        self.n = int(setup.extra.get("photons_per_pass") or caustics.photons_per_pass(setup.width, setup.height))
        _centre, radius = caustics.scene_bounds(setup)
        self.r1 = caustics.initial_radius(radius, self.n)
        # photons of one wavelength each (powers (spectral flux, bin, 0)): caustics.spectral_photons
        self.wavelengths = caustics.spectral_photons(setup)
        self.pass_index = 0          # the pass whose grid is up (0: none)
        self.stored = 0              # photons stored by that pass
        self.emitted = 0
        self.build_seconds = 0.0      # the last build's time
        self.radius = self.r1
        self.table_size = 1
        self._grid_tex: list = []
        self._pool = None            # the worker thread of the stages made ahead (advance)
        self._ahead = None           # [pass, stage "emit" | "grid", its future] under way
        self._dummy = [float_texture(ctx, np.zeros((1, 1, 4), np.float32)) for _ in SAMPLERS]
        key = (id(ctx), recipe)
        entry = _PROGRAMS.get(key)
        if entry is None:
            _models, defines = recipe
            prog = build_program(ctx, "passes/fullscreen.vert", "passes/photon_trace.frag", virtual=virtual,
                                 defines=dict(defines))
            entry = _PROGRAMS[key] = (prog, ctx.vertex_array(prog, []))
        self._prog, self._vao = entry

    @classmethod
    def for_setup(cls, ctx, setup, seed: int, defines, virtual_files) -> "CausticPhotons":
        """The photon map of ``setup``; ``defines``: the path-tracing program's (the material
        ones are kept), ``virtual_files(models)``: a program's virtual files. The photon pass
        samples only materials with a delta lobe, so its dispatch holds their models alone
        (every model of a dispatch is inlined at each call: compile time on software GL)."""
        from viewer.gl.brdf_glsl import models_used

        models = []
        for m in setup.materials:
            if m.lobes.has_delta:
                models.extend(models_used(m.params))
        models = tuple(dict.fromkeys(models))
        defines = tuple((k, v) for k, v in defines if k not in ("PHOTONS", "SPECTRAL"))
        return cls(ctx, setup, seed, (models, defines), virtual_files(models))

    # ------------------------------------------------------------------ one pass's photons
    def emit(self, i: int) -> list[np.ndarray]:
        """Pass ``i``'s new photons as the photon pass's four state arrays (numpy only: any thread)."""
        gen = photon_stream(self.seed, i)
        o, d, p = caustics.emit_photons(self.setup, self.n, gen)
        m = o.shape[0]
        zero = np.zeros((m, 1))
        if self.wavelengths:   # (spectral flux, bin, 0): photon_trace.frag's PHOTON_WAVELENGTHS
            bins = caustics.photon_bins(gen, m)
            p = np.stack([caustics.spectral_flux(p, bins), bins, np.zeros(m)], axis=1)
        return [np.hstack([o, np.arange(m)[:, None]]), np.hstack([d, zero]), np.hstack([p, zero]),
                np.zeros((m, 4))]

    def trace(self, i: int, bind_scene, state=None) -> tuple[np.ndarray, ...]:
        """Emit (or take ``state``, ``emit(i)``'s) and trace pass ``i``'s photons; (positions,
        directions of travel, powers, normals) of the stored ones (float64). ``bind_scene(prog)``
        binds the BVH and material textures and the material uniforms, returning the next free
        texture unit. A photon stored at a material that also has a delta lobe goes on in the
        next round (one stored photon per fragment and round), until none goes on."""
        state = self.emit(i) if state is None else state
        self.emitted = state[0].shape[0]
        found = []
        while state[0].shape[0]:
            out = self._round(i, state, bind_scene)
            keep = out[0][:, 3] > 0.5
            found.append([a[keep, :3] for a in out[:4]])
            on = out[4][:, 3] > 0.5
            state = [a[on] for a in out[4:]]
            # the index travels in the state's w; the first texture carries it again
            state[0] = np.hstack([state[0][:, :3], state[3][:, 3:4]])
        if not found:
            empty = np.zeros((0, 3))
            return empty, empty, empty, empty
        return tuple(np.concatenate([f[k] for f in found]).astype(np.float64) for k in range(4))

    def _round(self, i: int, state, bind_scene) -> list[np.ndarray]:
        """One draw of the photon pass over the photons of ``state`` (four (M, 4) arrays);
        the eight outputs (M, 4) float32."""
        ctx = self.ctx
        m = state[0].shape[0]
        src = [float_texture(ctx, texels(a)) for a in state]
        rows = src[0].size[1]
        dst = [ctx.texture((TEX_WIDTH, rows), 4, dtype="f4") for _ in range(8)]
        fbo = ctx.framebuffer(color_attachments=dst)
        try:
            prog = self._prog
            unit = bind_scene(prog)
            for k, tex in enumerate(src):
                tex.use(location=unit)
                set_uniform(prog, f"u_ph_state{k}", unit)
                unit += 1
            set_uniform(prog, "u_ph_count", int(m))
            set_uniform(prog, "u_ph_width", TEX_WIDTH)
            set_uniform(prog, "u_seed", self.seed & 0xFFFFFFFF)
            set_uniform(prog, "u_pass", int(i) & 0xFFFFFFFF)
            fbo.use()
            fbo.viewport = (0, 0, TEX_WIDTH, rows)
            self._vao.render(vertices=3)
            return [np.frombuffer(t.read(), np.float32).reshape(-1, 4)[:m].copy() for t in dst]
        finally:
            release_gl(fbo, *dst, *src)

    def build(self, i: int, bind_scene) -> None:
        """Trace pass ``i``'s photons and upload their grid for radius r_i, waiting for any
        part made ahead (``build_seconds``: the time it took, emission included)."""
        t0 = time.perf_counter()
        while not self.advance(i, bind_scene, wait=True):
            pass
        self.build_seconds = time.perf_counter() - t0

    # ------------------------------------------------------------------ made ahead, off the GL thread
    # A pass's photon map in three stages, so that a window's frame never waits for numpy: the
    # emission (a worker thread), the photon pass's draws and their read-back (the GL thread: the
    # GPU's work), the hash grid (a worker thread); then its textures go up (the GL thread).
    # ``advance`` moves pass i's map on as far as it can without waiting; the engine's
    # ``step_for`` renders a band only when its pass's map is up, and makes the next pass's up to
    # its upload while this one's bands render.

    def _worker(self):
        if self._pool is None:
            from concurrent.futures import ThreadPoolExecutor

            self._pool = ThreadPoolExecutor(max_workers=1, thread_name_prefix="photon-map")
        return self._pool

    def _grid_arrays(self, i: int, found) -> tuple:
        """(table, sorted photons' arrays as texels, table size, stored) of pass ``i`` (any thread)."""
        grid = caustics.build_grid(*found, caustics.pass_radius(self.r1, i))
        table = np.stack([grid.start, grid.count], axis=1).astype(np.float32)   # exact below 2^24
        arrays = [texels(a) for a in (table, grid.positions, grid.directions, grid.powers, grid.normals)]
        return arrays, grid.table_size, len(grid)

    def advance(self, i: int, bind_scene, wait: bool = False, upload: bool = True) -> bool:
        """Move pass ``i``'s photon map on; True when it is up (``pass_index == i``). Without
        ``wait`` nothing here waits for the worker thread: a stage whose input is not ready
        returns False at once. ``upload=False``: stop before its textures replace the current
        pass's (the next pass's map made while this one's bands render)."""
        if self.pass_index == i:
            return True
        if self._ahead is None or self._ahead[0] != i:
            self._ahead = [i, "emit", self._worker().submit(self.emit, i)]
        _i, stage, fut = self._ahead
        if not wait and not fut.done():
            return False
        if stage == "emit":
            found = self.trace(i, bind_scene, fut.result())           # GL: the photon pass
            self._ahead = [i, "grid", self._worker().submit(self._grid_arrays, i, found)]
            return self.advance(i, bind_scene, wait, upload)
        if not upload:
            return False
        arrays, table_size, stored = fut.result()
        release_gl(*self._grid_tex)
        self._grid_tex = [float_texture(self.ctx, a) for a in arrays]
        self.radius = caustics.pass_radius(self.r1, i)
        self.table_size = table_size
        self.cell = self.radius
        self.stored = stored
        self.pass_index = int(i)
        self._ahead = None
        return True

    def bind(self, prog, unit: int) -> int:
        """Point the path-tracing program's photon samplers and uniforms at the current grid
        (none yet: empty textures, nothing gathered); returns the next free texture unit."""
        for name, tex in zip(SAMPLERS, self._grid_tex or self._dummy):
            tex.use(location=unit)
            set_uniform(prog, name, unit)
            unit += 1
        set_uniform(prog, "u_grid_cell", float(self.radius))
        set_uniform(prog, "u_grid_slots", int(self.table_size))
        set_uniform(prog, "u_ph_r2", float(self.radius) ** 2)
        set_uniform(prog, "u_ph_stored", int(self.stored) if self._grid_tex else 0)
        return unit

    def release(self):
        if self._pool is not None:
            self._pool.shutdown(wait=True, cancel_futures=True)
            self._pool = None
        self._ahead = None
        release_gl(*self._grid_tex, *self._dummy)
        self._grid_tex, self._dummy = [], []
