"""The CPU engine's caustic photon map (the ``photon`` integrator; the estimator, its radius
schedule and the emission are ``viewer.reference_common.caustics``'s, shared with the GPU engine).

``PhotonIntegrator`` and ``SpectralPhotonIntegrator`` are the RGB and spectral integrators with
three steps extended (``CausticPaths``): every vertex with a smooth lobe gathers from the pass's
photon map before its bounce; a path remembers whether a vertex scattered by a smooth lobe
(``seen_smooth``), and the environment reached through a delta lobe after one adds nothing (a
caustic path: the photon map's), so nothing is counted twice.

Photon tracing: a pass's photons (``emit_photons``, from the counter-based stream
``philox(seed, PHOTON_STREAM, pass)`` with the renderer's seed, which ``ReferenceRenderer`` puts
in ``setup.extra["seed"]``; pass = sample index + 1, so a pass's photons depend on the seed and
the pass only, never on the block or the worker) are traced with the engine's ray kernel. At a material with a
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

from viewer import brdf
from viewer.brdf import lobes
from viewer.brdf.lobes import drew_delta
from viewer.pathtracer.integrator import Integrator, material_groups, philox, surface_hits
from viewer.pathtracer.spectral import SpectralIntegrator
from viewer.reference_common import caustics
from viewer.reference_common.estimator import RR_MAX, RR_MIN

QUERY_BATCH = 4096       # gather queries per grid lookup (bounds the candidate pairs held at once)


class PhotonSpectra:
    """Wavelength photons (``caustics.spectral_photons``): a photon's flux is one number, its
    spectral flux at its bin; an RGB weight (a non-spectral material's, a Bouguer
    transmittance) is upsampled at that bin, a spectral material is sampled and evaluated with
    its parameters at the bin's wavelength (``brdf.params_at``, as the spectral path tracer's
    hero wavelength), so n(lambda) bends each photon its own way."""

    def __init__(self):
        from viewer import spectral
        from viewer.reference_common.wavelengths import bin_wavelengths, bin_weights

        self.nm = bin_wavelengths()
        self.basis = spectral.upsampling.basis_at(self.nm)    # (420, 3)
        self.w_bins = bin_weights()                            # (420, 3)
        self._params: dict = {}

    def up(self, rgb, bins):
        """(k,) RGB values (k, 3) upsampled at ``bins`` (k,)."""
        return np.einsum("kc,kc->k", self.basis[bins], np.asarray(rgb, dtype=np.float64))

    def params(self, prm, b: int):
        """``prm`` at the wavelength of bin ``b`` in all three channels."""
        key = (id(prm), int(b))
        if key not in self._params:
            self._params[key] = (prm, brdf.params_at(prm, [self.nm[b]] * 3))
        return self._params[key][1]

    def sample(self, g, u, bins):
        """(wi local, weight (k,) at each bin, pdf, lobe) of group ``g``'s material."""
        if not brdf.uses_spectral(g.prm):
            wi, wgt, pdf, lobe = g.model.sample_lobe(g.prm, g.wo, u)
            return wi, self.up(np.nan_to_num(np.asarray(wgt, dtype=np.float64)), bins), pdf, lobe
        k = bins.size
        wi, wgt, pdf = np.zeros((k, 3)), np.zeros(k), np.zeros(k)
        lobe = np.zeros(k, dtype=lobes.DTYPE)
        for b in np.unique(bins):
            s = np.flatnonzero(bins == b)
            wi[s], w_s, pdf[s], lobe[s] = g.model.sample_lobe(self.params(g.prm, b), g.wo[s], u[s])
            wgt[s] = np.asarray(w_s, dtype=np.float64)[:, 0]
        return wi, wgt, pdf, lobe

    def eval(self, g, wi, wo, bins):
        """(k,) f of group ``g``'s material at local directions (wi, wo) at each bin."""
        if not brdf.uses_spectral(g.prm):
            return self.up(np.nan_to_num(g.model.eval(g.prm, wi, wo)), bins)
        out = np.zeros(bins.size)
        for b in np.unique(bins):
            s = np.flatnonzero(bins == b)
            out[s] = np.nan_to_num(g.model.eval(self.params(g.prm, b), wi[s], wo[s]))[:, 0]
        return out


def trace_photons(it, o, d, flux, gen: np.random.Generator, bins=None, spectra=None):
    """Trace photons (o, d, flux) through the delta surfaces of integrator ``it``'s scene;
    returns (positions, directions toward where they came from, flux, normals) of the stored ones.
    ``bins``: the photons' wavelength bins (``caustics.spectral_photons``; ``flux`` their
    spectral flux (n,), ``spectra`` a ``PhotonSpectra``): the stored flux is then (spectral
    flux, bin, 0) per photon."""
    mats = it.s.materials
    has_delta = np.array([m.lobes.has_delta for m in mats] or [False])
    has_smooth = np.array([m.lobes.has_smooth for m in mats] or [False])
    n = o.shape[0]
    sigma = np.zeros((n, 3))
    passed = np.zeros(n, dtype=bool)
    out = [], [], [], []
    wavelengths = bins is not None
    if wavelengths:
        bins = np.asarray(bins, dtype=np.int64)
        flux = np.asarray(flux, dtype=np.float64).reshape(n, 1).copy()
    else:
        bins = np.zeros(n, dtype=np.int64)
        flux = np.asarray(flux, dtype=np.float64).copy()
    for bounce in range(caustics.MAX_PHOTON_BOUNCES + 1):
        if o.shape[0] == 0:
            break
        t, prim, bu, bv = it.kernel.intersect(o, d, 0.0, np.inf)
        hit = prim >= 0
        d, flux, sigma, passed, bins = d[hit], flux[hit], sigma[hit], passed[hit], bins[hit]
        t, prim, bu, bv = t[hit], prim[hit], bu[hit], bv[hit]
        if prim.size == 0:
            break
        inside = np.any(sigma > 0, axis=1)
        if np.any(inside):
            a = np.exp(-sigma[inside] * t[inside, None])
            flux[inside] *= spectra.up(a, bins[inside])[:, None] if wavelengths else a
        hits = surface_hits(it, d, prim, bu, bv)
        store = has_smooth[hits.mat] & passed
        if np.any(store):
            ng = hits.ng_raw[store]
            side = np.where(np.einsum("ij,ij->i", ng, d[store]) > 0, -1.0, 1.0)
            out[0].append(hits.p[store])
            out[1].append(-d[store])
            if wavelengths:
                out[2].append(np.stack([flux[store, 0], bins[store], np.zeros(int(store.sum()))], axis=1))
            else:
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
        for g in material_groups(it, hits, act):
            if not g.info.lobes.has_delta:
                continue
            if wavelengths:
                wi_l, wgt, pdf, lobe = spectra.sample(g, u[g.sel, :2], bins[g.sel])
                wgt = wgt[:, None]
            else:
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
        d, flux, sigma, bins = new_d[keep], (flux * w)[keep], sigma[keep], bins[keep]
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
        # photons of one wavelength each (a dispersive or spectral delta surface, spectral estimator)
        self.spectra = PhotonSpectra() if caustics.spectral_photons(s) else None

    def photons(self, seed: int, pass_index: int):
        """(positions, directions, flux, normals) of the stored photons of pass ``pass_index``
        (1-based); with wavelengths the flux rows are (spectral flux, bin, 0)."""
        gen = self.stream(seed, caustics.PHOTON_STREAM, pass_index)
        o, d, f = caustics.emit_photons(self.it.s, self.n_photons, gen)
        if self.spectra is None:
            return trace_photons(self.it, o, d, f, gen)
        bins = caustics.photon_bins(gen, o.shape[0])
        return trace_photons(self.it, o, d, caustics.spectral_flux(f, bins), gen, bins, self.spectra)

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
        # the sample index of each path (pass = sample + 1), as the integrator's block set it
        sample_of = getattr(it, "sample_of_path", None)
        if sample_of is None or sample_of.size != paths.L.shape[0]:   # ``trace`` called outside a block: pass 1
            passes = np.zeros(g.k, dtype=np.int64)
        else:
            passes = sample_of[g.act]
        seed = int(it.s.extra.get("seed", 0))   # the renderer's seed (ReferenceRenderer puts it there)
        for s_idx in np.unique(passes):
            grid = self.grid(seed, int(s_idx) + 1)
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
                if self.spectra is not None:
                    self._gather_wavelengths(pg, paths, Tg[j], wi, grid.powers[rows], norm)
                    continue
                ((wl, f),) = it.eval_directions(pg, paths, [wi])
                valid = pg.valid(wl, wi)
                share = it.emission_share(pg, paths)
                c = Tg[j] * f * it.spectrum(grid.powers[rows], paths, pg.act) * norm
                if share is not None:
                    c = c * share[:, None]
                c = np.where(valid[:, None], c, 0.0)
                np.add.at(paths.L, pg.act, c)


    def _gather_wavelengths(self, pg, paths, T, wi, power, norm):
        """Photons of one wavelength each (power rows: spectral flux, bin, 0): each adds
        T f(lambda_p) Phi(lambda_p) / (pi r^2) converted to RGB, N_BINS W(lambda_p) times it (the
        one-sample estimate of sum_lambda W(lambda) L(lambda) for a bin drawn with probability
        1 / N_BINS), to the path sample's RGB (``paths.rgb``, which the spectral estimator adds
        to its four wavelengths' RGB): the photon's wavelength is none of the path's. T is the
        mean of the path's throughput over its wavelengths (a hero-only path: its hero's), exact
        where the throughput is flat in wavelength (a camera ray, achromatic mirrors and glass:
        the first diffuse vertex of the lecture's caustics), the spectral mean of it otherwise."""
        from viewer.reference_common.wavelengths import N_BINS

        sp = self.spectra
        bins = power[:, 1].astype(np.int64)
        wl = pg.local(wi)
        f = sp.eval(pg, wl, pg.wo, bins)
        valid = pg.valid(wl, wi)
        c = np.where(valid, T.mean(axis=1) * f * power[:, 0] * (norm * N_BINS), 0.0)
        np.add.at(paths.rgb, pg.act, c[:, None] * sp.w_bins[bins])


class CausticPaths:
    """The ``photon`` integrator's steps over an integrator's (the mixin of ``PhotonIntegrator``
    and ``SpectralPhotonIntegrator``): the gather, and the path tracer's share of the split."""

    def __init__(self, setup):
        super().__init__(setup)
        self.caustics = CausticMap(self, philox)

    def trace_paths(self, paths, o, d, draw):
        paths.seen_smooth = np.zeros(o.shape[0], dtype=bool)   # a vertex scattered by a smooth lobe
        return super().trace_paths(paths, o, d, draw)

    def _bsdf_hits_environment(self, paths, idx, d):
        # a caustic path (a smooth vertex, then delta ones, to the environment): the photon map's
        keep = ~(paths.prev_delta[idx] & paths.seen_smooth[idx])
        super()._bsdf_hits_environment(paths, idx[keep], d[keep])

    def _bounce(self, paths, act, hits, rnd):
        T_before = paths.T[act]
        for g in material_groups(self, hits, act):
            if g.info.lobes.has_smooth:
                self.caustics.gather(g, paths, T_before[g.sel], hits)
        return super()._bounce(paths, act, hits, rnd)

    def _continue(self, paths, act, hits, new, u_rr, depth):
        paths.seen_smooth[act] |= ~new.delta
        return super()._continue(paths, act, hits, new, u_rr, depth)


class PhotonIntegrator(CausticPaths, Integrator):
    """Path tracing plus a progressive caustic photon map, RGB."""


class SpectralPhotonIntegrator(CausticPaths, SpectralIntegrator):
    """Path tracing plus a progressive caustic photon map, hero wavelengths (photons carry RGB, or
    one wavelength each through dispersive or spectral delta surfaces: ``caustics.spectral_photons``)."""


def integrator_for(setup):
    """The CPU integrator of ``setup``: RGB or spectral (``extra["spectral"]``), with the photon
    map where ``setup.integrator`` is "photon"."""
    spectral = bool(setup.extra.get("spectral"))
    if setup.integrator == "photon":
        return (SpectralPhotonIntegrator if spectral else PhotonIntegrator)(setup)
    return (SpectralIntegrator if spectral else Integrator)(setup)
