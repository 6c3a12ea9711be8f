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
* The environment is sampled (``EnvironmentLight.sample``) and reached by BSDF sampling; the
  two strategies are combined with the power heuristic (beta = 2). A path whose last bounce
  was a delta lobe, and a camera ray, take the full environment radiance.
* Delta lobes (``spec.delta`` models, i.e. mirror and smooth dielectric; a layered model with a
  delta base is "mixed": a sample is discrete when ``sample``'s pdf differs from ``pdf`` at the
  sampled pair) skip next-event estimation and MIS.
* ``max_depth`` = number of scattering events: at vertex ``depth <= max_depth`` the path does
  NEE and samples a direction; the ray of the last one is traced only to see whether it
  reaches the environment. ``max_depth = 1`` is direct light only.
* Russian roulette from the fourth scattering event on: survival probability
  ``clamp(max(throughput), 0.05, 0.95)``, survivors divided by it.
* Dielectrics: a transmissive material sets the path's medium from the side its new direction
  leaves on: against the triangle's winding normal (entering or reflecting inside) =
  the material's ``sigma_a``, else none; each segment travelled inside is attenuated by
  ``exp(-sigma_a * distance)`` (Bouguer). Objects are assumed closed and not nested.

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

import math
from dataclasses import dataclass, field

import numpy as np

from viewer import brdf
from viewer.pathtracer.envmap import EnvironmentLight
from viewer.pathtracer.geometry import SceneGeometry, build_geometry, hit_points, interpolate_shading, shading_frame

RR_START_DEPTH = 4          # Russian roulette from the 4th scattering event on ("after 3 bounces")
RR_MIN, RR_MAX = 0.05, 0.95
EPS_REL = 1e-4
DIMS_PER_BOUNCE = 5         # bsdf (2), environment (2), roulette (1)
KEY_SALT = 0x9E3779B97F4A7C15


# ----------------------------------------------------------------------------- setup

@dataclass
class MaterialInfo:
    name: str
    model_name: str
    params: object
    kind: str                 # "smooth" (no delta lobe), "delta" (only delta lobes), "mixed"
    transmissive: bool
    sigma_a: np.ndarray       # (3,) absorption inside (transmissive), else zeros


def _is_pure_delta(p) -> bool:
    spec = brdf.get(p.model).spec
    if not spec.delta:
        return False
    if spec.name == "dielectric":
        return float(p.get("alpha", 0.0)) <= 0.0
    return True


def material_info(name: str, p) -> MaterialInfo:
    spec = brdf.get(p.model).spec
    if _is_pure_delta(p):
        kind = "delta"
    elif spec.delta:
        kind = "smooth"  # a rough dielectric: continuous lobes only
    elif any(prm.kind == "material" and _is_pure_delta(p[prm.name]) for prm in spec.params):
        kind = "mixed"
    else:
        kind = "smooth"
    sigma = np.zeros(3)
    if spec.transmissive and "sigma_a" in p:
        sigma = np.asarray(p["sigma_a"], dtype=np.float64).reshape(3).copy()
    return MaterialInfo(name, p.model, p, kind, bool(spec.transmissive), sigma)


@dataclass
class RenderSetup:
    """Everything a worker needs (picklable): geometry, materials, lights, environment, camera."""

    geometry: SceneGeometry
    materials: list
    lights: list              # [("point", position, intensity) | ("directional", direction, irradiance)]
    env: EnvironmentLight
    cam_pos: np.ndarray
    cam_forward: np.ndarray
    cam_right: np.ndarray
    cam_up: np.ndarray
    tan_half_y: float
    width: int
    height: int
    max_depth: int = 8
    kernel: str = "embree"
    extra: dict = field(default_factory=dict)

    @classmethod
    def from_scene(cls, scene, camera=None, width=None, height=None, max_depth: int = 8,
                   env_image=None, kernel: str = "embree") -> "RenderSetup":
        if camera is None:
            from viewer.camera import OrbitCamera

            camera = OrbitCamera.from_scene(scene)
        width = int(width or scene.camera.width)
        height = int(height or scene.camera.height)
        pos = np.asarray(camera.position, dtype=np.float64)
        target = np.asarray(camera.target, dtype=np.float64)
        up = np.asarray(getattr(camera, "up", (0.0, 1.0, 0.0)), dtype=np.float64)
        fwd = target - pos
        fwd /= np.linalg.norm(fwd)
        right = np.cross(fwd, up)
        if np.linalg.norm(right) < 1e-12:  # looking along up: any perpendicular (as look_at would fail)
            right = np.cross(fwd, [1.0, 0.0, 0.0] if abs(fwd[0]) < 0.9 else [0.0, 0.0, 1.0])
        right /= np.linalg.norm(right)
        cam_up = np.cross(right, fwd)
        geom = build_geometry(scene)
        mats = [material_info(n, scene.materials[n]) for n in geom.material_names]
        lights = []
        for light in scene.lights:
            if light.type == "point":
                lights.append(("point", np.asarray(light.position, float), np.asarray(light.intensity, float)))
            else:
                d = np.asarray(light.direction, float)
                lights.append(("directional", d / np.linalg.norm(d), np.asarray(light.irradiance, float)))
        env = EnvironmentLight.from_scene(scene, env_image)
        return cls(geom, mats, lights, env, pos, fwd, right, cam_up,
                   math.tan(math.radians(float(camera.fov_y)) / 2.0), width, height, int(max_depth), kernel)


def make_kernel(triangles, kind: str = "embree"):
    if kind == "numba":
        from viewer.pathtracer.kernel_numba import NumbaKernel

        return NumbaKernel(triangles)
    from viewer.pathtracer.kernel_embree import EmbreeKernel

    return EmbreeKernel(triangles)


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


def _dot(a, b):
    return np.einsum("ij,ij->i", a, b)


# ----------------------------------------------------------------------------- integrator

class Integrator:
    def __init__(self, setup: RenderSetup):
        self.s = setup
        self.geom = setup.geometry
        self.kernel = make_kernel(self.geom.triangles, setup.kernel)
        self.models = [brdf.get(m.model_name) for m in setup.materials]
        self.trans_table = np.array([m.transmissive for m in setup.materials] or [False], dtype=bool)
        self.sigma_table = np.array([m.sigma_a for m in setup.materials] or [np.zeros(3)])
        self.bad_values = 0

    # -- helpers
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
    def render_block(self, row0: int, row1: int, samples, seed: int, block_id: int):
        """Render rows [row0, row1) with the given sample indices. Returns (sum, sum of squares)
        of the per-sample radiance, each (row1 - row0, width, 3) float64."""
        s = self.s
        W = s.width
        npix = (row1 - row0) * W
        samples = list(samples)
        ns = len(samples)
        gens = [philox(seed, block_id, si) for si in samples]
        pix = np.arange(npix)
        rows = row0 + pix // W
        cols = pix % W
        jit = np.concatenate([g.random((npix, 2)) for g in gens])
        o, d = self.camera_rays(np.tile(rows, ns), np.tile(cols, ns), jit)
        L = self.trace(o, d, lambda: np.concatenate([g.random((npix, DIMS_PER_BOUNCE)) for g in gens]))
        L = L.reshape(ns, row1 - row0, W, 3)
        return L.sum(axis=0), (L * L).sum(axis=0)

    def trace(self, o, d, draw):
        """Radiance (N, 3) along the rays (o, d); ``draw()`` returns the random numbers
        (N, DIMS_PER_BOUNCE) of the next bounce for all N paths."""
        s = self.s
        geom = self.geom
        env = s.env
        env_on = not env.is_black
        N = o.shape[0]
        L = np.zeros((N, 3))
        T = np.ones((N, 3))
        sigma = np.zeros((N, 3))
        prev_pdf = np.zeros(N)
        prev_lpdf = np.zeros(N)
        prev_delta = np.ones(N, dtype=bool)   # camera rays count as "delta": full environment
        act = np.arange(N)
        lights = s.lights
        for depth in range(1, s.max_depth + 2):
            if act.size == 0:
                break
            rnd_all = draw() if depth <= s.max_depth else None
            t, prim, bu, bv = self.kernel.intersect(o, d, 0.0, np.inf)
            miss = prim < 0
            if env_on and np.any(miss):
                idx = act[miss]
                Le = env.eval(d[miss])
                w = np.where(prev_delta[idx], 1.0, _power(prev_pdf[idx], prev_lpdf[idx]))
                L[idx] += T[idx] * Le * w[:, None]
            if depth > s.max_depth:
                break
            hit = ~miss
            act, o, d, t, prim, bu, bv = act[hit], o[hit], d[hit], t[hit], prim[hit], bu[hit], bv[hit]
            if act.size == 0:
                break
            # Bouguer attenuation of the segment just travelled inside a medium
            sig = sigma[act]
            inside = np.any(sig > 0, axis=1)
            if np.any(inside):
                ia = act[inside]
                T[ia] *= np.exp(-sig[inside] * t[inside, None])
            rnd = rnd_all[act]
            p = hit_points(geom, prim, bu, bv)
            ng_raw = geom.geo_normals[prim]
            n, tan = interpolate_shading(geom, prim, bu, bv)
            mat = geom.material_index[prim]
            trans = self.trans_table[mat]
            flip = (_dot(d, ng_raw) > 0) & ~trans
            n = np.where(flip[:, None], -n, n)
            ng = ng_raw * np.where(_dot(ng_raw, n) < 0, -1.0, 1.0)[:, None]
            tx, ty = shading_frame(n, tan)
            wo = -d
            wo_l = np.stack([_dot(wo, tx), _dot(wo, ty), _dot(wo, n)], axis=1)
            eps = EPS_REL * (1.0 + np.abs(p).max(axis=1))
            M = act.size
            Ta = T[act]

            # light directions for every hit (delta lights), and the environment sample
            light_dirs, light_vals, light_tmax = [], [], []
            for kind, a, val in lights:
                if kind == "point":
                    dv = a - p
                    r2 = np.maximum(_dot(dv, dv), 1e-300)
                    r = np.sqrt(r2)
                    light_dirs.append(dv / r[:, None])
                    light_vals.append(val[None, :] / r2[:, None])
                    light_tmax.append(r - eps)
                else:
                    light_dirs.append(np.broadcast_to(-a, (M, 3)))
                    light_vals.append(np.broadcast_to(val, (M, 3)))
                    light_tmax.append(np.full(M, np.inf))
            if env_on:
                e_dir, e_val, e_pdf = env.sample(rnd[:, 2:4], n, trans)
                e_pdf = self._clean(e_pdf)
            new_dir = np.zeros((M, 3))
            new_w = np.zeros((M, 3))
            new_pdf = np.zeros(M)
            new_lpdf = np.zeros(M)
            new_delta = np.zeros(M, dtype=bool)
            sh_idx, sh_o, sh_d, sh_tmax, sh_c = [], [], [], [], []

            order = np.argsort(mat, kind="stable")
            bounds = np.flatnonzero(np.diff(mat[order])) + 1
            for sel in np.split(order, bounds):
                if sel.size == 0:
                    continue
                mi = int(mat[sel[0]])
                info = s.materials[mi]
                model = self.models[mi]
                prm = info.params
                k = sel.size
                wo_s = wo_l[sel]
                ns_, txs, tys, ngs = n[sel], tx[sel], ty[sel], ng[sel]
                two = info.transmissive

                def local(w):
                    r = w.shape[0] // k
                    if r == 1:
                        return np.stack([_dot(w, txs), _dot(w, tys), _dot(w, ns_)], axis=1)
                    w3 = w.reshape(r, k, 3)
                    return np.stack([np.einsum("rij,ij->ri", w3, txs), np.einsum("rij,ij->ri", w3, tys),
                                     np.einsum("rij,ij->ri", w3, ns_)], axis=-1).reshape(-1, 3)

                def valid(wl, ww):
                    g = _dot(ngs, ww)
                    if two:
                        return wl[:, 2] * g > 0
                    return (wl[:, 2] > 0) & (g > 0)

                # ---- next-event estimation (not for pure delta lobes)
                if info.kind != "delta" and (lights or env_on):
                    dirs_w = [ld[sel] for ld in light_dirs]
                    if env_on:
                        dirs_w.append(e_dir[sel])
                    dw = np.concatenate(dirs_w)
                    dl = local(dw)
                    f = self._clean(model.eval(prm, dl, np.tile(wo_s, (len(dirs_w), 1))))
                    for j in range(len(dirs_w)):
                        sl = slice(j * k, (j + 1) * k)
                        wl, ww, fj = dl[sl], dw[sl], f[sl]
                        ok = valid(wl, ww)
                        c = Ta[sel] * fj * np.abs(wl[:, 2])[:, None]
                        if j < len(lights):
                            c = c * light_vals[j][sel]
                            tmax = light_tmax[j][sel]
                        else:
                            pb = self._clean(model.pdf(prm, wl, wo_s))
                            pe = e_pdf[sel]
                            ok &= pe > 0
                            wmis = _power(pe, pb) / np.where(pe > 0, pe, 1.0)
                            c = c * e_val[sel] * wmis[:, None]
                            tmax = np.full(k, np.inf)
                        ok &= np.any(c > 0, axis=1)
                        if np.any(ok):
                            side = np.where(_dot(ngs[ok], ww[ok]) < 0, -1.0, 1.0)
                            sh_idx.append(act[sel[ok]])
                            sh_o.append(p[sel[ok]] + (eps[sel[ok]] * side)[:, None] * ngs[ok])
                            sh_d.append(ww[ok])
                            sh_tmax.append(tmax[ok])
                            sh_c.append(c[ok])

                # ---- BSDF sampling
                wi_l, wgt, pdf_s = model.sample(prm, wo_s, rnd[sel, 0:2])
                wgt = self._clean(np.asarray(wgt, dtype=np.float64))
                pdf_s = self._clean(np.asarray(pdf_s, dtype=np.float64))
                bad_dir = ~np.all(np.isfinite(wi_l), axis=1)
                if np.any(bad_dir):
                    self.bad_values += int(np.count_nonzero(bad_dir))
                    wi_l = np.where(bad_dir[:, None], np.array([0.0, 0.0, 1.0]), wi_l)
                    wgt = np.where(bad_dir[:, None], 0.0, wgt)
                if info.kind == "delta":
                    disc = np.ones(k, dtype=bool)
                elif info.kind == "mixed":
                    pe_ = self._clean(model.pdf(prm, wi_l, wo_s))
                    disc = np.abs(pdf_s - pe_) > 1e-6 * np.maximum(pdf_s, 1e-300)
                else:
                    disc = np.zeros(k, dtype=bool)
                wi_w = wi_l[:, :1] * txs + wi_l[:, 1:2] * tys + wi_l[:, 2:3] * ns_
                ok = valid(wi_l, wi_w) & (pdf_s > 0) & np.any(wgt > 0, axis=1)
                new_dir[sel] = wi_w
                new_w[sel] = np.where(ok[:, None], wgt, 0.0)
                new_pdf[sel] = pdf_s
                new_delta[sel] = disc
                if env_on:
                    new_lpdf[sel] = np.where(disc, 0.0, env.pdf(wi_w, ns_, np.full(k, two)))
                if two:
                    inside_next = _dot(ng_raw[sel], wi_w) < 0
                    sigma[act[sel]] = np.where(inside_next[:, None], info.sigma_a, 0.0)

            # ---- shadow rays, all lights and materials at once
            if sh_idx:
                idx = np.concatenate(sh_idx)
                blocked = self.kernel.occluded(np.concatenate(sh_o), np.concatenate(sh_d), 0.0,
                                               np.concatenate(sh_tmax))
                c = np.concatenate(sh_c)
                free = ~blocked
                np.add.at(L, idx[free], c[free])

            # ---- continue
            Tn = Ta * new_w
            alive = np.any(Tn > 0, axis=1)
            if depth >= RR_START_DEPTH:
                q = np.clip(Tn.max(axis=1), RR_MIN, RR_MAX)
                survive = rnd[:, 4] < q
                Tn = Tn / q[:, None]
                alive &= survive
            T[act] = Tn
            prev_pdf[act] = new_pdf
            prev_lpdf[act] = new_lpdf
            prev_delta[act] = new_delta
            side = np.where(_dot(ng, new_dir) < 0, -1.0, 1.0)
            o = (p + (eps * side)[:, None] * ng)[alive]
            d = new_dir[alive]
            act = act[alive]
        bad = ~np.isfinite(L) | (L < 0)
        if np.any(bad):
            self.bad_values += int(np.count_nonzero(bad))
            L = np.where(bad, 0.0, L)
        return L
