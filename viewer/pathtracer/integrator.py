"""Wavefront path tracing in vectorized numpy: one batch of many paths advances one bounce at a
time (camera rays, intersection, environment on a miss, next-event estimation, BSDF sampling,
Russian roulette), shading grouped by material with index arrays so every BRDF is called once
per bounce on the subset of paths that hit it.

Estimator (Veach 1997, ch. 9; pbrt-v4 ``PathIntegrator``):

* Point and directional lights are delta lights: next-event estimation only (no MIS). A light
  adds ``f * I * |cos_i| / r^2`` (point) or ``f * E * |cos_i|`` with ``wi = -direction``
  (directional) where the shadow ray is unoccluded and the rasterizer's test passes:
  ``cos_i`` (shading) > 0 and ``dot(n_g, wi) > 0``; a transmissive surface also takes light
  from behind (both cosines negative), which the rasterizer has no path for.
* The environment is reached by one of three strategies (``RenderSetup.strategy``): ``"mis"``
  (default) samples it (``EnvironmentLight.sample``) and reaches it by BSDF sampling, the two
  combined by multiple importance sampling with the power heuristic (beta = 2) or the balance
  heuristic (``mis_heuristic``); ``"bsdf"`` only by BSDF sampling (weight 1); ``"light"`` only
  by sampling the environment (a BSDF-sampled ray that escapes adds nothing). Each alone is
  unbiased wherever its density covers the integrand (the map's is zero only where the map is
  black). A path whose last bounce was a delta lobe, and a camera ray, take the full
  environment radiance under every strategy (light sampling cannot find a delta direction).
* Delta lobes (``Lobe.DELTA``, viewer/brdf/lobes.py: mirror and smooth dielectric; a layered
  model with a delta base has delta and smooth lobes, and its sampler says which one each
  sample drew, ``Model.sample_lobe``) skip next-event estimation and MIS; a material whose
  lobes are all delta (``Lobe.is_delta``) has no next-event estimation at all.
* ``max_depth`` = number of scattering events: at vertex ``depth <= max_depth`` the path does
  NEE and samples a direction; the ray of the last one is traced only to see whether it
  reaches the environment. ``max_depth = 1`` is direct light only.
* Russian roulette from the fourth scattering event on: survival probability
  ``clamp(max(throughput), 0.05, 0.95)``, survivors divided by it; ``russian_roulette = False``
  traces every path to ``max_depth`` (unbiased either way; roulette trades variance for time).
* Dielectrics: a transmissive material sets the path's medium from the side its new direction
  leaves on: against the triangle's winding normal (entering or reflecting inside) =
  the material's ``sigma_a``, else none; each segment travelled inside is attenuated by
  ``exp(-sigma_a * distance)`` (Bouguer). Objects are assumed closed and not nested.
* ``setup.integrator == "photon"``: ``viewer/pathtracer/photons.py``'s subclasses of these
  integrators leave caustic paths (a smooth vertex, then one or more delta vertices to the light)
  to a caustic photon map, gathered at every vertex with a smooth lobe.

Shading conventions are the rasterizer's (``shaders/passes/forward.frag``): shading normal =
normalized interpolation of the world vertex normals; a ray hitting the back face
(``dot(dir, n_winding) > 0``) flips it (two-sided surfaces; not for transmissive materials,
whose frame must tell inside from outside); the geometric normal is oriented to the shading
normal's side; tangent frame t = normalize(tangent - n (n . tangent)), b = cross(n, t) sign(w).

Robustness: secondary and shadow rays start at ``p + eps n_g`` on the side the ray leaves
(below for transmission), ``eps = 1e-4 (1 + max|p|)``; shadow rays toward a point light stop
``eps`` short of it.

Every model output (f, pdf, weights) that is NaN, infinite or negative is counted in
``bad_values`` and replaced by 0, so the image never holds NaN; a non-zero count is a bug.
"""

from __future__ import annotations

import numpy as np

from viewer import brdf
from viewer.brdf import thin_film
from viewer.brdf.lobes import Lobe, drew_delta
from viewer.reference_common.estimator import RR_MAX, RR_MIN, RR_START_DEPTH, check_options
from viewer.reference_common.setup import MaterialInfo, RenderSetup

DIMS_PER_BOUNCE = 5         # bsdf (2), environment (2), roulette (1)
KEY_SALT = 0x9E3779B97F4A7C15


# ----------------------------------------------------------------------------- setup

def reference_model(m: "MaterialInfo", compiled: bool = False):
    """The model the reference evaluates a material with: its registry model, or for a layered
    material with ``reference = "random_walk"`` (and a non-delta base) the stochastic layered
    random walk (viewer/brdf/layered_walk.py). ``compiled``: its compiled stand-in where there
    is one (``viewer.pathtracer.compiled.compiled_model``: the same values and random numbers)."""
    if brdf.is_file(m.params):  # a .brdf file: its numpy twin (never its GLSL: no GL here)
        return brdf.get(m.model_name).of(m.params).numpy_model()
    model = brdf.get(m.model_name).reference_model(m.params)
    if compiled:
        from viewer.pathtracer.compiled import compiled_model  # numba: only where paths are traced

        return compiled_model(m.params, model) or model
    return model


def make_kernel(triangles, kind: str = "embree"):
    if kind == "numba":
        from viewer.pathtracer.kernel_numba import NumbaKernel

        return NumbaKernel(triangles)
    from viewer.pathtracer.kernel_embree import EmbreeKernel

    return EmbreeKernel(triangles)


def philox_key(seed: int) -> tuple[int, int]:
    """The Philox key of the streams of ``seed`` (``philox``)."""
    return int(seed) & 0xFFFFFFFFFFFFFFFF, KEY_SALT


def philox(seed: int, block: int, sample: int) -> np.random.Generator:
    """The counter-based stream of (seed, block of pixels, sample index): Philox4x64 keyed by
    the seed, its counter starting at (0, 0, block, sample); draws advance the lowest word only,
    so streams never overlap (Salmon et al. 2011, 'Parallel random numbers: as easy as 1, 2, 3')."""
    key = np.array([int(seed) & 0xFFFFFFFFFFFFFFFF, KEY_SALT], dtype=np.uint64)
    ctr = np.array([0, 0, int(block) & 0xFFFFFFFFFFFFFFFF, int(sample) & 0xFFFFFFFFFFFFFFFF], dtype=np.uint64)
    return np.random.Generator(np.random.Philox(key=key, counter=ctr))


def _power(a, b):
    """Power heuristic weight of strategy a against b (Veach 1997, eq. 9.13, beta = 2)."""
    a2, b2 = a * a, b * b
    s = a2 + b2
    return np.where(s > 0, a2 / np.where(s > 0, s, 1.0), 0.0)


def _balance(a, b):
    """Balance heuristic weight of strategy a against b (Veach 1997, eq. 9.10)."""
    s = a + b
    return np.where(s > 0, a / np.where(s > 0, s, 1.0), 0.0)


HEURISTICS = {"power": _power, "balance": _balance}


def _dot(a, b):
    return np.einsum("ij,ij->i", a, b)


class BounceDraws:
    """``draw()`` for ``Integrator.trace``: each call returns the next bounce's numbers
    (N, DIMS_PER_BOUNCE) of every stream ``gens`` (``counts`` paths each), in stream order;
    ``calls`` counts them."""

    def __init__(self, gens, counts):
        self.gens, self.counts = gens, list(counts)
        self.calls = 0

    def __call__(self):
        self.calls += 1
        out = np.empty((sum(self.counts), DIMS_PER_BOUNCE))
        off = 0
        for g, n in zip(self.gens, self.counts):   # each stream's numbers straight into its rows
            g.random(out=out[off:off + n])
            off += n
        return out


def fused_bounce(it):
    """The whole bounce compiled (``viewer.pathtracer.fused``) for integrator ``it`` where every
    step has a compiled stand-in, else None: the RGB integrator's own steps only (subclasses
    override them), its materials' compiled models, no film over height."""
    if type(it) is not Integrator or it._object_y or not it.COMPILED_MODELS:
        return None
    from viewer.pathtracer.fused import plan  # numba: only where paths are traced

    return plan(it)


def fused_render(it, blocks, samples, seed: int):
    """``Integrator.render_blocks``' radiance of its wavefront by the fused bounce of ``it``
    (``fused.FusedBounce.render``: the camera rays and every number computed in the loop)."""
    counts = [(r1 - r0) * it.s.width for r0, r1, _ in blocks for _ in samples]
    it.sample_of_path = np.repeat(np.array([si for _ in blocks for si in samples], np.int64), counts)
    return it.fused.render(it, PathState(sum(counts), it.CHANNELS), blocks, samples, philox_key(seed))


# ----------------------------------------------------------------------------- integrator

class _Group:
    """The hits of one material at one bounce: indices ``sel`` into the bounce's hits, the
    material, and its shading frames (n, tx, ty), geometric normals ``ng`` and local ``wo``."""

    def __init__(self, sel, info: MaterialInfo, model, wo_l, n, tx, ty, ng, mi=None, act=None):
        self.sel, self.info, self.model, self.prm = sel, info, model, info.params
        self.mi = mi              # the material's index
        self.act = act            # the paths (indices into the trace's N) of the hits
        self.k = sel.size
        self.transmissive = info.transmissive  # shades both sides
        self.wo = wo_l[sel]
        self.n, self.tx, self.ty, self.ng = n[sel], tx[sel], ty[sel], ng[sel]

    def local(self, w):
        """World directions (r k, 3) (r stacked sets of k) in the group's shading frames."""
        k = self.k
        r = w.shape[0] // k
        if r == 1:
            return np.stack([_dot(w, self.tx), _dot(w, self.ty), _dot(w, self.n)], axis=1)
        w3 = w.reshape(r, k, 3)
        return np.stack([np.einsum("rij,ij->ri", w3, self.tx), np.einsum("rij,ij->ri", w3, self.ty),
                         np.einsum("rij,ij->ri", w3, self.n)], axis=-1).reshape(-1, 3)

    def world(self, wl):
        return wl[:, :1] * self.tx + wl[:, 1:2] * self.ty + wl[:, 2:3] * self.n

    def valid(self, wl, ww):
        """The rasterizer's light test: shading and geometric cosine on the same side (both
        positive for a reflection-only surface)."""
        g = _dot(self.ng, ww)
        if self.transmissive:
            return wl[:, 2] * g > 0
        return (wl[:, 2] > 0) & (g > 0)


class _Shadows:
    """Shadow rays collected over the materials of one bounce, traced together."""

    def __init__(self):
        self.idx, self.o, self.d, self.tmax, self.c = [], [], [], [], []

    def add(self, idx, o, d, tmax, c):
        self.idx.append(idx)
        self.o.append(o)
        self.d.append(d)
        self.tmax.append(tmax)
        self.c.append(c)


class PathState:
    """The state of the N paths of one trace: radiance ``L`` and throughput ``T`` per channel
    (RGB, or the spectral integrator's four wavelengths), the medium each is in (``sigma``),
    and what the last bounce's sample needs for MIS at the environment."""

    def __init__(self, n: int, channels: int):
        self.L = np.zeros((n, channels))
        self.T = np.ones((n, channels))
        self.sigma = np.zeros((n, 3))
        self.prev_pdf = np.zeros(n)
        self.prev_lpdf = np.zeros(n)
        self.prev_delta = np.ones(n, dtype=bool)   # camera rays count as "delta": full environment


class _Hits:
    """The surface points of one bounce's hits in the rasterizer's shading conventions (see the
    module docstring): points ``p``, winding normals ``ng_raw``, oriented shading normals ``n``
    with their frames (``tx``, ``ty``), geometric normals ``ng`` on the side of ``n``, local
    ``wo_l``, ray offsets ``eps``, material indices ``mat`` and whether they transmit."""

    def __init__(self, integrator, d, prim, bu, bv):
        from viewer.pathtracer.compiled import hit_shading  # numba: only where paths are traced

        self.prim = prim
        h = hit_shading(integrator.geom, integrator.trans_table, d, prim, bu, bv)  # compiled
        self.p, self.ng_raw, self.n, self.ng = h["p"], h["ng_raw"], h["n"], h["ng"]
        self.tx, self.ty, self.wo_l, self.eps = h["tx"], h["ty"], h["wo_l"], h["eps"]
        self.mat, self.trans = h["mat"], h["trans"]

    def groups(self):
        """Index arrays of the hits per material, in material order."""
        order = np.argsort(self.mat, kind="stable")
        bounds = np.flatnonzero(np.diff(self.mat[order])) + 1
        return [sel for sel in np.split(order, bounds) if sel.size]

    def offset(self, sel, w):
        """Ray origins at hits ``sel`` leaving along ``w``: ``p + eps n_g`` on the side w leaves."""
        ng = self.ng[sel]
        side = np.where(_dot(ng, w) < 0, -1.0, 1.0)
        return self.p[sel] + (self.eps[sel] * side)[:, None] * ng


class _Bounce:
    """What the material groups of one bounce decide for its M paths: the new direction, the
    sample's weight per channel, its pdf and light sampling's pdf there (MIS), whether it came
    from a delta lobe, and whether it left the path to its hero wavelength (spectral only)."""

    def __init__(self, m: int, channels: int):
        self.dir = np.zeros((m, 3))
        self.w = np.zeros((m, channels))
        self.pdf = np.zeros(m)
        self.lpdf = np.zeros(m)
        self.delta = np.zeros(m, dtype=bool)
        self.hero_only = np.zeros(m, dtype=bool)


class Integrator:
    """The RGB path tracer. The steps of a bounce are methods; the spectral integrator
    (``spectral.SpectralIntegrator``) runs the same steps on four wavelengths by overriding the
    hooks marked *channel hook* (how an RGB quantity becomes the path's channels, how a
    material is evaluated, sampled and its pdf taken)."""

    CHANNELS = 3
    COMPILED_MODELS = True   # RGB: a material's model may be its compiled stand-in (same values)
    sample_of_path = None    # the sample index of each path of the wavefront being traced (_block_streams)

    def __init__(self, setup: RenderSetup):
        check_options(setup.strategy, setup.mis_heuristic)
        self.s = setup
        self.geom = setup.geometry
        self.kernel = make_kernel(self.geom.triangles, setup.kernel)
        self.models = [reference_model(m, self.COMPILED_MODELS) for m in setup.materials]
        self._film_cache: dict = {}
        self._object_y = {mi: np.asarray(setup.extra.get("object_y", np.zeros((1, 2))))
                          for mi, m in enumerate(setup.materials) if thin_film.varies(m.params)}
        self.trans_table = np.array([m.transmissive for m in setup.materials] or [False], dtype=bool)
        self.sigma_table = np.array([m.sigma_a for m in setup.materials] or [np.zeros(3)])
        self.bad_values = 0
        self._set_options(setup.strategy, setup.mis_heuristic, setup.russian_roulette)
        self.fused = fused_bounce(self)   # the whole bounce compiled, where every step has a stand-in

    def _set_options(self, strategy: str, mis_heuristic: str, russian_roulette: bool):
        self.strategy = strategy
        self.mis_heuristic, self.heuristic = mis_heuristic, HEURISTICS[mis_heuristic]
        self.russian_roulette = bool(russian_roulette)
        self.env_on = not self.s.env.is_black
        # which strategies reach the environment (point / directional lights: always NEE)
        self.env_by_light = self.env_on and strategy in ("mis", "light")
        self.env_by_bsdf = self.env_on and strategy in ("mis", "bsdf")

    # -- helpers
    FILM_STEP_NM = 0.25   # a film over height: hits grouped by thickness in these steps

    def _film_groups(self, mi, sel, p, prim):
        """[(hits, params or None)]: the material's hits as one group, or, for a thin film whose
        thickness varies with height (viewer/brdf/thin_film.py), grouped by the local thickness
        d(y) of each hit (in FILM_STEP_NM steps, the bin's centre) with the material at that
        thickness."""
        prm = self.s.materials[mi].params
        if not thin_film.varies(prm):
            return [(sel, None)]
        ranges = self._object_y.get(mi)
        obj = self.geom.object_index[prim[sel]]
        y0, y1 = ranges[obj, 0], ranges[obj, 1]
        t = np.where(y1 > y0, (p[sel, 1] - y0) / np.where(y1 > y0, y1 - y0, 1.0), 0.0)
        d = thin_film.thickness_at(thin_film.film_of(prm), t)
        q = np.round(d / self.FILM_STEP_NM).astype(np.int64)
        out = []
        for v in np.unique(q):
            key = (mi, int(v))
            if key not in self._film_cache:
                self._film_cache[key] = thin_film.local(prm, v * self.FILM_STEP_NM)
            out.append((sel[q == v], self._film_cache[key]))
        return out

    def _clean(self, a, allow_negative=False):
        """Count and zero NaN / Inf (and negative) entries of a model output."""
        bad = ~np.isfinite(a)
        if not allow_negative:
            bad |= a < 0
        nb = int(np.count_nonzero(bad))
        if nb:
            self.bad_values += nb
            a = np.where(bad, 0.0, a)
        return a

    def camera_rays(self, rows: np.ndarray, cols: np.ndarray, jitter: np.ndarray):
        s = self.s
        x = (2.0 * (cols + jitter[:, 0]) / s.width - 1.0) * s.tan_half_y * (s.width / s.height)
        y = (1.0 - 2.0 * (rows + jitter[:, 1]) / s.height) * s.tan_half_y
        d = s.cam_forward + x[:, None] * s.cam_right + y[:, None] * s.cam_up
        d /= np.linalg.norm(d, axis=1, keepdims=True)
        o = np.broadcast_to(s.cam_pos, d.shape).copy()
        return o, d

    # -- one block of pixels, several samples
    def _block_streams(self, blocks, samples, seed: int):
        """The random streams of the samples of blocks ``(row0, row1, block_id)`` (block by
        block, sample by sample), the paths of each stream (the block's pixels) and the camera
        jitter (the first two numbers of every stream), with the pixels' rows and columns, in
        that order. Sets ``sample_of_path``: the sample index of each of these paths."""
        W = self.s.width
        gens, counts, rows, cols, jit, sample_of = [], [], [], [], [], []
        for row0, row1, block_id in blocks:
            npix = (row1 - row0) * W
            pix = np.arange(npix)
            for si in samples:
                g = philox(seed, block_id, si)
                gens.append(g)
                counts.append(npix)
                rows.append(row0 + pix // W)
                cols.append(pix % W)
                jit.append(g.random((npix, 2)))
                sample_of.append(np.full(npix, si, dtype=np.int64))
        self.sample_of_path = np.concatenate(sample_of)
        return gens, counts, np.concatenate(rows), np.concatenate(cols), np.concatenate(jit)

    @staticmethod
    def _bounce_draws(gens, npix):
        """``draw()`` for ``trace``: the next bounce's numbers of every stream, in stream order
        (``npix``: the paths of every stream, or one count per stream)."""
        counts = [npix] * len(gens) if np.ndim(npix) == 0 else list(npix)
        return BounceDraws(gens, counts)

    def render_block(self, row0: int, row1: int, samples, seed: int, block_id: int):
        """Render rows [row0, row1) with the given sample indices. Returns (sum, sum of squares)
        of the per-sample radiance, each (row1 - row0, width, 3) float64."""
        return self.render_blocks([(row0, row1, block_id)], samples, seed)[0]

    def render_blocks(self, blocks, samples, seed: int):
        """``render_block`` of several blocks ``(row0, row1, block_id)`` in one wavefront (wider
        batches: less of numpy's cost per call per path). Every path draws from its own block's
        and sample's stream as ``render_block`` does, so each block's sums are the same."""
        samples = list(samples)
        if self.fused is not None:   # the camera rays and every number compiled too (fused.py)
            L = self._final(fused_render(self, blocks, samples, seed))
        else:
            gens, counts, rows, cols, jit = self._block_streams(blocks, samples, seed)
            L = self.trace(*self.camera_rays(rows, cols, jit), self._bounce_draws(gens, counts))
        out, off = [], 0
        for r0, r1, _ in blocks:
            n = len(samples) * (r1 - r0) * self.s.width
            Lb = L[off:off + n].reshape(len(samples), r1 - r0, self.s.width, 3)
            off += n
            out.append((Lb.sum(axis=0), (Lb * Lb).sum(axis=0)))
        return out

    def warm(self):
        """Trace one ray onto each material's first triangle (or render a row, below), the result
        thrown away: the compiled kernels (``viewer.pathtracer.compiled``, ``fused``) a render of
        this scene calls are loaded from numba's cache (or compiled) now, not in the first chunk."""
        geom = self.geom
        mats = geom.material_index
        idx = np.array([np.flatnonzero(mats == m)[0] for m in np.unique(mats)], dtype=np.int64)
        if idx.size == 0:
            return
        c = geom.triangles[idx].mean(axis=1)
        n = geom.geo_normals[idx]
        o = c + n * (1e-2 * (1.0 + np.abs(c).max(axis=1)))[:, None]
        rng = np.random.default_rng(0)
        draw = lambda: rng.random((idx.size, DIMS_PER_BOUNCE))  # noqa: E731
        if self.CHANNELS == 3 and self.fused is None:
            self.trace(o, -n, draw)
        else:  # (spectral paths carry wavelengths; the fused bounce renders with its own kernels)
            mid = self.s.height // 2
            self.render_block(mid, mid + 1, [0], 0, 0)

    def trace(self, o, d, draw):
        """Radiance (N, 3) along the rays (o, d); ``draw()`` returns the random numbers
        (N, DIMS_PER_BOUNCE) of the next bounce for all N paths."""
        return self.trace_paths(PathState(o.shape[0], self.CHANNELS), o, d, draw)

    # -- channel hooks (RGB here; the spectral integrator overrides them)
    def spectrum(self, rgb, paths: PathState, idx):
        """An RGB quantity (3,) or (k, 3) in the channels of paths ``idx``."""
        return rgb

    def emission_share(self, g: "_Group", paths: PathState):
        """A factor on next-event contributions of group ``g`` (None: 1)."""
        return None

    def eval_directions(self, g: "_Group", paths: PathState, dirs_w):
        """[(local direction, f in the paths' channels)] for each world direction set in
        ``dirs_w`` (each (k, 3)) at the hits of ``g``: one model call for all of them."""
        k = g.k
        dw = np.concatenate(dirs_w)
        dl = g.local(dw)
        f = self._clean(g.model.eval(g.prm, dl, np.tile(g.wo, (len(dirs_w), 1))))
        return [(dl[j * k:(j + 1) * k], f[j * k:(j + 1) * k]) for j in range(len(dirs_w))]

    def material_pdf(self, g: "_Group", paths: PathState, wi_l):
        """The pdf of ``g``'s sampling for local directions ``wi_l``."""
        return self._clean(g.model.pdf(g.prm, wi_l, g.wo))

    def sample_material(self, g: "_Group", paths: PathState, rnd_g):
        """``g``'s sample: (local wi, weight in the paths' channels (cleaned), raw pdf,
        hero-only flags or None, the lobe each sample drew)."""
        wi_l, wgt, pdf_s, lobe = g.model.sample_lobe(g.prm, g.wo, rnd_g)
        return wi_l, self._clean(np.asarray(wgt, dtype=np.float64)), pdf_s, None, lobe

    def throughput(self, paths: PathState, act, T_before, new: _Bounce):
        """The paths' throughput after the bounce."""
        return T_before * new.w

    # -- the steps of one bounce
    def _bsdf_hits_environment(self, paths: PathState, idx, d):
        """BSDF sampling's part: radiance of the environment reached by rays ``d`` of paths
        ``idx``, weighted against light sampling (MIS), fully (BSDF sampling only) or not at all
        (light sampling only: the environment was reached by NEE). A camera ray or a delta
        lobe's discrete sample, which light sampling cannot find, always takes it fully."""
        Le = self.spectrum(self.s.env.eval(d), paths, idx)
        prev_delta = paths.prev_delta
        if self.strategy == "mis":
            w = np.where(prev_delta[idx], 1.0, self.heuristic(paths.prev_pdf[idx], paths.prev_lpdf[idx]))
        elif self.strategy == "bsdf":
            w = np.ones(idx.size)
        else:
            w = np.where(prev_delta[idx], 1.0, 0.0)
        paths.L[idx] += paths.T[idx] * Le * w[:, None]

    def _absorb(self, paths: PathState, act, t):
        """Bouguer attenuation exp(-sigma_a t) of the segment just travelled inside a medium."""
        sig = paths.sigma[act]
        inside = np.any(sig > 0, axis=1)
        if np.any(inside):
            ia = act[inside]
            paths.T[ia] *= self.spectrum(np.exp(-sig[inside] * t[inside, None]), paths, ia)

    def _delta_lights(self, hits: _Hits, paths: PathState, act):
        """Per point / directional light: directions to it (M, 3), its arriving radiance term
        (intensity / r^2 or irradiance, in the paths' channels) and the shadow ray's length."""
        p, eps = hits.p, hits.eps
        M = p.shape[0]
        dirs, vals, tmax = [], [], []
        for kind, a, val in self.s.lights:
            e = self.spectrum(val, paths, act)
            if kind == "point":
                dv = a - p
                r2 = np.maximum(_dot(dv, dv), 1e-300)
                r = np.sqrt(r2)
                dirs.append(dv / r[:, None])
                vals.append(e / r2[:, None])
                tmax.append(r - eps)
            else:
                dirs.append(np.broadcast_to(-a, (M, 3)))
                vals.append(np.broadcast_to(e, (M, self.CHANNELS)))
                tmax.append(np.full(M, np.inf))
        return dirs, vals, tmax

    def _light_sample_environment(self, rnd, n, trans):
        """Light sampling's directions toward the environment: (wi, radiance, pdf) per hit."""
        if self.s.env.is_map:
            e_dir, e_val, e_pdf = self.s.env.sample(rnd[:, 2:4], n, trans)
        else:
            from viewer.pathtracer.compiled import constant_env_sample  # numba: where paths are traced

            e_dir, e_val, e_pdf = constant_env_sample(self.s.env, rnd[:, 2:4], n, trans)
        return e_dir, e_val, self._clean(e_pdf)

    def _next_event(self, g: "_Group", paths: PathState, Tg, hits: _Hits, lights, env_sample,
                    shadows: "_Shadows"):
        """Next-event estimation at the hits of group ``g``: every delta light, and the
        environment sample when light sampling is on (weighted against BSDF sampling under MIS).
        Adds one shadow ray per candidate with a non-zero contribution."""
        sel, k = g.sel, g.k
        light_dirs, light_vals, light_tmax = lights
        dirs_w = [ld[sel] for ld in light_dirs]
        if env_sample is not None:
            dirs_w.append(env_sample[0][sel])
        share = self.emission_share(g, paths)
        from viewer.pathtracer.compiled import nee_candidates  # numba: only where paths are traced

        for j, (ww, (wl, fj)) in enumerate(zip(dirs_w, self.eval_directions(g, paths, dirs_w))):
            if j < len(light_dirs):
                fac, extra_ok = light_vals[j][sel], None
                tmax = light_tmax[j][sel]
            else:
                pe = env_sample[2][sel]
                extra_ok = pe > 0
                if self.strategy == "mis":
                    pb = self.material_pdf(g, paths, wl)
                    wmis = self.heuristic(pe, pb) / np.where(pe > 0, pe, 1.0)
                else:
                    wmis = 1.0 / np.where(pe > 0, pe, 1.0)
                fac = self.spectrum(env_sample[1][sel], paths, g.act) * wmis[:, None]
                tmax = np.full(k, np.inf)
            # the light test, the contribution T f |cos| (share) fac, the shadow ray's origin
            ok, c, o = nee_candidates(wl, ww, g.ng, sel, hits.p, hits.eps, Tg, fj, fac, share, extra_ok,
                                      g.transmissive)
            if np.any(ok):
                shadows.add(g.act[ok], o[ok], ww[ok], tmax[ok], c[ok])

    def _sample_bsdf(self, g: "_Group", paths: PathState, rnd_g):
        """BSDF sampling at the hits of group ``g``: (world direction, weight f cos / pdf with
        failed samples 0, pdf, discrete flag: the sample drew a delta lobe (``Lobe.DELTA``),
        hero-only flags or None)."""
        wi_l, wgt, pdf_s, hero_only, lobe = self.sample_material(g, paths, rnd_g)
        pdf_s = self._clean(np.asarray(pdf_s, dtype=np.float64))
        bad_dir = ~np.all(np.isfinite(wi_l), axis=1)
        if np.any(bad_dir):
            self.bad_values += int(np.count_nonzero(bad_dir))
            wi_l = np.where(bad_dir[:, None], np.array([0.0, 0.0, 1.0]), wi_l)
            wgt = np.where(bad_dir[:, None], 0.0, wgt)
        disc = drew_delta(lobe)  # the model says which lobe it drew (sample_lobe)
        wi_w = g.world(wi_l)
        ok = g.valid(wi_l, wi_w) & (pdf_s > 0) & np.any(wgt > 0, axis=1)
        return wi_w, np.where(ok[:, None], wgt, 0.0), pdf_s, disc, hero_only

    def _scatter(self, g: "_Group", paths: PathState, hits: _Hits, rnd_g, new: _Bounce):
        """Sample group ``g``'s next directions into ``new``; a transmissive material sets the
        medium the new direction enters."""
        sel = g.sel
        wi_w, wgt, pdf_s, disc, hero_only = self._sample_bsdf(g, paths, rnd_g)
        new.dir[sel] = wi_w
        new.w[sel] = wgt
        new.pdf[sel] = pdf_s
        new.delta[sel] = disc
        if hero_only is not None:
            new.hero_only[sel] = hero_only
        if self.env_by_light and self.env_by_bsdf:  # MIS: light sampling's density there
            new.lpdf[sel] = np.where(disc, 0.0, self.s.env.pdf(wi_w, g.n, np.full(g.k, g.transmissive)))
        if g.transmissive:
            inside_next = _dot(hits.ng_raw[sel], wi_w) < 0
            paths.sigma[g.act] = np.where(inside_next[:, None], g.info.sigma_a, 0.0)

    def _bounce(self, paths: PathState, act, hits: _Hits, rnd) -> _Bounce:
        """One bounce at the hits of paths ``act``: per material, next-event estimation (shadow
        rays traced together at the end) and a BSDF sample."""
        s = self.s
        T_before = paths.T[act]
        lights = self._delta_lights(hits, paths, act)
        env_sample = self._light_sample_environment(rnd, hits.n, hits.trans) if self.env_by_light else None
        new = _Bounce(act.size, self.CHANNELS)
        shadows = _Shadows()
        for sel in hits.groups():
            mi = int(hits.mat[sel[0]])
            for sel, prm in self._film_groups(mi, sel, hits.p, hits.prim):
                g = _Group(sel, s.materials[mi], self.models[mi], hits.wo_l, hits.n, hits.tx, hits.ty,
                           hits.ng, mi=mi, act=act[sel])
                if prm is not None:  # a film over height: the material at this hit's thickness
                    g.prm = prm
                if not g.info.lobes.is_delta and (s.lights or env_sample is not None):
                    self._next_event(g, paths, T_before[sel], hits, lights, env_sample, shadows)
                self._scatter(g, paths, hits, rnd[sel, 0:2], new)
        self._trace_shadows(paths.L, shadows)
        return new

    def _trace_shadows(self, L, shadows: "_Shadows"):
        """Trace every collected shadow ray at once; unoccluded ones add their contribution."""
        if not shadows.idx:
            return
        idx = np.concatenate(shadows.idx)
        blocked = self.kernel.occluded(np.concatenate(shadows.o), np.concatenate(shadows.d), 0.0,
                                       np.concatenate(shadows.tmax))
        c = np.concatenate(shadows.c)
        free = ~blocked
        np.add.at(L, idx[free], c[free])

    def _roulette(self, T_after, alive, u, depth):
        """Russian roulette from ``RR_START_DEPTH`` on (when enabled): survival probability
        clamp(max throughput), survivors divided by it."""
        if self.russian_roulette and depth >= RR_START_DEPTH:
            q = np.clip(T_after.max(axis=1), RR_MIN, RR_MAX)
            survive = u < q
            T_after = T_after / q[:, None]
            alive &= survive
        return T_after, alive

    def _continue(self, paths: PathState, act, hits: _Hits, new: _Bounce, u_rr, depth):
        """The paths' new throughput, MIS memory and rays; returns (o, d, act) of the survivors."""
        T_after = self.throughput(paths, act, paths.T[act], new)
        alive = np.any(T_after > 0, axis=1)
        T_after, alive = self._roulette(T_after, alive, u_rr, depth)
        paths.T[act] = T_after
        paths.prev_pdf[act] = new.pdf
        paths.prev_lpdf[act] = new.lpdf
        paths.prev_delta[act] = new.delta
        side = np.where(_dot(hits.ng, new.dir) < 0, -1.0, 1.0)
        o = (hits.p + (hits.eps * side)[:, None] * hits.ng)[alive]
        return o, new.dir[alive], act[alive]

    def _final(self, L):
        """Count and zero NaN / Inf / negative radiance (never expected; see bad_values)."""
        bad = ~np.isfinite(L) | (L < 0)
        if np.any(bad):
            self.bad_values += int(np.count_nonzero(bad))
            L = np.where(bad, 0.0, L)
        return L

    def trace_paths(self, paths: PathState, o, d, draw):
        """Follow the rays (o, d) of ``paths`` to ``max_depth`` scattering events; returns the
        paths' radiance in their channels."""
        if self.fused is not None:   # the same steps, compiled into one loop per bounce (fused.py)
            return self._final(self.fused.trace(self, paths, o, d, draw))
        s = self.s
        act = np.arange(o.shape[0])
        for depth in range(1, s.max_depth + 2):
            if act.size == 0:
                break
            rnd_all = draw() if depth <= s.max_depth else None
            t, prim, bu, bv = self.kernel.intersect(o, d, 0.0, np.inf)
            miss = prim < 0
            # a camera ray or delta bounce reaches the environment even with BSDF sampling off
            if self.env_on and np.any(miss):
                self._bsdf_hits_environment(paths, act[miss], d[miss])
            if depth > s.max_depth:
                break
            hit = ~miss
            act, d, t, prim, bu, bv = act[hit], d[hit], t[hit], prim[hit], bu[hit], bv[hit]
            if act.size == 0:
                break
            self._absorb(paths, act, t)
            rnd = rnd_all[act]
            hits = _Hits(self, d, prim, bu, bv)
            new = self._bounce(paths, act, hits, rnd)
            o, d, act = self._continue(paths, act, hits, new, rnd[:, 4], depth)
        return self._final(paths.L)


# ----------------------------------------------------------------------------- for the photon tracer

def surface_hits(it: Integrator, d, prim, bu, bv) -> _Hits:
    """The surface points of rays ``d`` that hit ``prim`` at (bu, bv), in ``it``'s shading conventions."""
    return _Hits(it, d, prim, bu, bv)


def material_groups(it: Integrator, hits: _Hits, act):
    """The hits of paths ``act`` per material (and film thickness), as ``Integrator._bounce`` groups them."""
    for sel in hits.groups():
        mi = int(hits.mat[sel[0]])
        for sub, prm in it._film_groups(mi, sel, hits.p, hits.prim):
            g = _Group(sub, it.s.materials[mi], it.models[mi], hits.wo_l, hits.n, hits.tx, hits.ty,
                       hits.ng, mi=mi, act=act[sub])
            if prm is not None:
                g.prm = prm
            yield g
