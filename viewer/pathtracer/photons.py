"""The CPU engine's caustic photon map (the ``photon`` integrator; the estimator, its radius
schedule and the emission are ``viewer.reference_common.caustics``'s, shared with the GPU engine).

Photon tracing: a pass's photons (``emit_photons``, from the counter-based stream
``philox(seed, PHOTON_STREAM, pass)``, so a pass's photons depend on the seed and the pass only,
never on the block or the worker) are traced with the engine's ray kernel. At a material with a
delta lobe the material's own sampler (``sample_lobe``) draws the next direction; the photon goes
on only where it drew a delta lobe, its flux times the sample's weight f cos / pdf. At a material
with a smooth lobe a photon that has passed a delta vertex is stored (position, direction toward
where it came from, flux, winding normal turned toward that side); a mixed material (a coat over a
mirror) both stores and, through its delta lobe, sends on. Bouguer absorption exp(-sigma_a t) on
segments inside a medium, as on eye paths. Russian roulette from the PHOTON_RR_START-th delta vertex:
survival max(weight) clamped to [RR_MIN, RR_MAX], survivors divided by it (unbiased).

Radiance and flux across a refraction: the smooth dielectric's weight T / eta^2 is radiance's
(L / n^2 is what is conserved); flux has weight T. The factors eta^2 of entering and leaving a
closed object cancel, and photons are stored only outside every object (objects are closed and
not nested, as the integrator already assumes), so the stored flux is exact.

Gather (``CausticMap.gather``, at every vertex with a smooth lobe): over photons within r_i of
the vertex with |n_p . n_g| >= NORMAL_COS whose direction passes the rasterizer's light test there
(``valid``, as next-event estimation), throughput * f(wo, wi_p) * Phi_p / (pi r_i^2) (uniform
kernel). A worker keeps the photon grids of the last few passes (chunks of one pass's samples
over many blocks come together).
"""

from __future__ import annotations

import math
from collections import OrderedDict

import numpy as np

from viewer.brdf.lobes import drew_delta
from viewer.reference_common import caustics
from viewer.reference_common.estimator import RR_MAX, RR_MIN

QUERY_BATCH = 4096       # gather queries per grid lookup (bounds the candidate pairs held at once)


def trace_photons(it, o, d, flux, gen: np.random.Generator):
    """Trace photons (o, d, flux) through the delta surfaces of integrator ``it``'s scene;
    returns (positions, directions toward where they came from, flux, normals) of the stored ones."""
    mats = it.s.materials
    has_delta = np.array([m.lobes.has_delta for m in mats] or [False])
    has_smooth = np.array([m.lobes.has_smooth for m in mats] or [False])
    n = o.shape[0]
    sigma = np.zeros((n, 3))
    passed = np.zeros(n, dtype=bool)
    out = [], [], [], []
    flux = np.asarray(flux, dtype=np.float64).copy()
    for bounce in range(caustics.MAX_PHOTON_BOUNCES + 1):
        if o.shape[0] == 0:
            break
        t, prim, bu, bv = it.kernel.intersect(o, d, 0.0, np.inf)
        hit = prim >= 0
        d, flux, sigma, passed = d[hit], flux[hit], sigma[hit], passed[hit]
        t, prim, bu, bv = t[hit], prim[hit], bu[hit], bv[hit]
        if prim.size == 0:
            break
        inside = np.any(sigma > 0, axis=1)
        if np.any(inside):
            flux[inside] *= np.exp(-sigma[inside] * t[inside, None])
        hits = it.surface_hits(d, prim, bu, bv)
        store = has_smooth[hits.mat] & passed
        if np.any(store):
            ng = hits.ng_raw[store]
            side = np.where(np.einsum("ij,ij->i", ng, d[store]) > 0, -1.0, 1.0)
            out[0].append(hits.p[store])
            out[1].append(-d[store])
            out[2].append(flux[store])
            out[3].append(ng * side[:, None])
        go = has_delta[hits.mat]
        if bounce == caustics.MAX_PHOTON_BOUNCES or not np.any(go):
            break
        u = gen.random((prim.size, 3))
        new_d = np.zeros_like(d)
        w = np.zeros_like(flux)
        keep = np.zeros(prim.size, dtype=bool)
        act = np.arange(prim.size)
        for g in it.material_groups(hits, act):
            if not g.info.lobes.has_delta:
                continue
            wi_l, wgt, pdf, lobe = g.model.sample_lobe(g.prm, g.wo, u[g.sel, :2])
            wgt = np.asarray(wgt, dtype=np.float64)
            wi_w = g.world(wi_l)
            ok = drew_delta(lobe) & (np.asarray(pdf) > 0) & np.all(np.isfinite(wgt), axis=1) \
                & np.all(np.isfinite(wi_l), axis=1)
            ok &= g.valid(wi_l, wi_w) & np.any(wgt > 0, axis=1)
            new_d[g.sel], w[g.sel], keep[g.sel] = wi_w, np.where(ok[:, None], wgt, 0.0), ok
            if g.transmissive:
                inside_next = np.einsum("ij,ij->i", hits.ng_raw[g.sel], wi_w) < 0
                sigma[g.sel] = np.where(inside_next[:, None], g.info.sigma_a, 0.0)
        if bounce + 1 >= caustics.PHOTON_RR_START:
            q = np.clip(w.max(axis=1), RR_MIN, RR_MAX)
            keep &= u[:, 2] < q
            w = w / q[:, None]
        side = np.where(np.einsum("ij,ij->i", hits.ng, new_d) < 0, -1.0, 1.0)
        o = (hits.p + (hits.eps * side)[:, None] * hits.ng)[keep]
        d, flux, sigma = new_d[keep], (flux * w)[keep], sigma[keep]
        passed = np.ones(o.shape[0], dtype=bool)
    if not out[0]:
        z = np.zeros((0, 3))
        return z, z.copy(), z.copy(), z.copy()
    return tuple(np.concatenate(a) for a in out)


class CausticMap:
    """The photon maps of integrator ``it``'s passes and the gather at its eye vertices."""

    KEEP = 8   # photon grids a worker keeps (the passes of the chunks it renders next)

    def __init__(self, it, stream):
        self.it = it
        self.stream = stream   # stream(seed, block, sample): the integrator's counter-based generator
        s = it.s
        _centre, self.scene_radius = caustics.scene_bounds(s)
        # ``extra["photons_per_pass"]``: a fixed count (tests, benchmarks); else by the image size
        self.n_photons = int(s.extra.get("photons_per_pass") or caustics.photons_per_pass(s.width, s.height))
        self.r1 = caustics.initial_radius(self.scene_radius, self.n_photons)
        self._grids: OrderedDict = OrderedDict()

    def photons(self, seed: int, pass_index: int):
        """(positions, directions, flux, normals) of the stored photons of pass ``pass_index`` (1-based)."""
        gen = self.stream(seed, caustics.PHOTON_STREAM, pass_index)
        o, d, f = caustics.emit_photons(self.it.s, self.n_photons, gen)
        return trace_photons(self.it, o, d, f, gen)

    def grid(self, seed: int, pass_index: int) -> caustics.PhotonGrid:
        key = (int(seed), int(pass_index))
        if key in self._grids:
            self._grids.move_to_end(key)
            return self._grids[key]
        g = caustics.build_grid(*self.photons(seed, pass_index), caustics.pass_radius(self.r1, pass_index))
        self._grids[key] = g
        while len(self._grids) > self.KEEP:
            self._grids.popitem(last=False)
        return g

    def gather(self, g, paths, Tg, hits):
        """Add the photon estimate at the hits of material group ``g`` (paths ``g.act`` with
        throughput ``Tg``) to the paths' radiance."""
        it = self.it
        pass_of = it.pass_of_path
        if pass_of is None or pass_of.size != paths.L.shape[0]:   # ``trace`` called outside a block: pass 1
            passes = np.zeros(g.k, dtype=np.int64)
        else:
            passes = pass_of[g.act]
        for s_idx in np.unique(passes):
            grid = self.grid(it.block_seed, int(s_idx) + 1)
            if len(grid) == 0:
                continue
            norm = 1.0 / (math.pi * grid.radius * grid.radius)
            rows_of = np.flatnonzero(passes == s_idx)
            for b0 in range(0, rows_of.size, QUERY_BATCH):
                sub = rows_of[b0:b0 + QUERY_BATCH]
                qi, rows = grid.query(hits.p[g.sel[sub]])
                if qi.size == 0:
                    continue
                j = sub[qi]                         # rows of the group, one per pair
                ok = np.abs(np.einsum("ij,ij->i", grid.normals[rows], g.ng[j])) >= caustics.NORMAL_COS
                j, rows = j[ok], rows[ok]
                if j.size == 0:
                    continue
                pg = type(g)(g.sel[j], g.info, g.model, hits.wo_l, hits.n, hits.tx, hits.ty, hits.ng,
                             mi=g.mi, act=g.act[j])
                pg.prm = g.prm
                wi = grid.directions[rows]
                ((wl, f),) = it.eval_directions(pg, paths, [wi])
                valid = pg.valid(wl, wi)
                share = it.emission_share(pg, paths)
                c = Tg[j] * f * it.spectrum(grid.powers[rows], paths, pg.act) * norm
                if share is not None:
                    c = c * share[:, None]
                c = np.where(valid[:, None], c, 0.0)
                np.add.at(paths.L, pg.act, c)
