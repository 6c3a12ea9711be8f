"""Spectral reference rendering: hero-wavelength path tracing (Wilkie et al. 2014, "Hero
Wavelength Spectral Sampling", EGSR), the same estimator as ``integrator`` otherwise.

Wavelengths: 420 bins of 1 nm (360-779 nm; the CIE weight of 780 nm is added to the last bin).
Each path carries four wavelengths, lambda_j = 360 + (c + 105 j) nm, j = 0..3, with c uniform in
0..104: every lambda_j is uniform over the 420 bins, the four stratify the range (Wilkie's
rotation by a quarter of it), and one of them, the hero h (uniform in 0..3), is the path's
own: where the path cannot be shared (a refraction through a dispersive dielectric, a spectral
coating, a spectral delta layer) the other three are terminated and the hero keeps 4x its
weight (pbrt-v4's ``TerminateSecondary``; both estimators are unbiased, the four-wavelength one
has less colour noise). A pixel sample is
    RGB = (420 / 4) sum_j W(lambda_j) L(lambda_j)
with W the 1 nm CIE 1931 / D65 / Rec.709 weights of ``viewer.spectral.colorimetry`` (sum W = 1:
a flat spectrum is white), so the image converges to to_rgb of the pixel's spectral radiance.

Spectra of the scene:
  * RGB albedos, BRDF values and weights, emitters (point and directional intensities, the
    environment) and Bouguer transmittances exp(-sigma_a d) are upsampled with the Mallett &
    Yuksel (2019) basis (``viewer.spectral.upsampling``): the spectrum of a colour x is
    sum_c x_c b_c(lambda), linear in x and exact on the round trip, so a non-spectral scene
    under direct white light gives the RGB reference's image (one bounce of an RGB BRDF value
    times a white light round-trips exactly; deeper paths multiply spectra, which differs from
    multiplying RGB by the spectral mixing of the colours).
  * A spectral material (``spectral = "NAME"``) is evaluated at the path's wavelengths: its
    n(lambda) + i k(lambda) replaces eta, k (microfacet, mirror: all four wavelengths, in two
    calls of the model, lambda_0..2 as its three channels and lambda_3), its n(lambda_hero)
    replaces ior (dielectric, layered coating: the hero only, so refraction disperses), and its
    other RGB parameters are upsampled at the same wavelengths.
"""

from __future__ import annotations

import numpy as np

from viewer import brdf, spectral
from viewer.brdf import lobes
from viewer.pathtracer.integrator import Integrator, PathState
from viewer.reference_common.wavelengths import HERO, N_BINS, STRIDE, bin_wavelengths, bin_weights


class SpectralPaths(PathState):
    """``PathState`` with four wavelength bins ``lam`` (N, 4) per path, its hero index ``hero``
    (N,) and whether the path has been reduced to its hero (``hero_only``: T holds the hero alone)."""

    def __init__(self, lam, hero):
        super().__init__(lam.shape[0], 4)
        self.lam = lam
        self.hero = hero
        self.hero_only = np.zeros(lam.shape[0], dtype=bool)
        # RGB added to the sample's beside its wavelengths' (a photon map's photons of their own
        # wavelengths: viewer.pathtracer.photons)
        self.rgb = np.zeros((lam.shape[0], 3))


class SpectralIntegrator(Integrator):
    """``Integrator`` with four wavelengths per path instead of RGB channels: the same steps,
    with the channel hooks below, so the setup's ``strategy``, ``mis_heuristic`` and
    ``russian_roulette`` apply to it as to the RGB estimator."""

    CHANNELS = 4
    COMPILED_MODELS = False   # the models are called with the parameters at each wavelength

    def __init__(self, setup):
        super().__init__(setup)
        self.bins_nm = bin_wavelengths()
        self.w_bins = bin_weights()
        self.basis = spectral.upsampling.basis_at(self.bins_nm)          # (420, 3)
        self.category = []
        for m in setup.materials:
            p = m.params
            if not brdf.uses_spectral(p):
                self.category.append("rgb")
            elif (brdf.is_dispersive(p) or m.lobes.is_mixed
                  or (brdf.has_film(p) and brdf.model_of(p).spec.transmissive)):
                # (a smooth or rough film-coated dielectric chooses reflection or refraction with
                # its R: one wavelength per path)
                self.category.append("hero")
            else:
                self.category.append("table")
        self._cache: dict = {}

    # -- spectra of RGB quantities at each path's wavelengths
    def up(self, rgb, lam):
        """(M, 4) spectrum of the colours ``rgb`` (M, 3) or (3,) at bins ``lam`` (M, 4)."""
        b = self.basis[lam]                                              # (M, 4, 3)
        rgb = np.asarray(rgb, dtype=np.float64)
        if rgb.ndim == 1:
            return b @ rgb
        return np.einsum("mjc,mc->mj", b, rgb)

    def _params(self, mi, key, lam3, prm=None):
        """The material's parameters at wavelengths lam3 (bins); ``prm`` the material at one hit
        where it differs from the scene's (a thin film over height: the integrator's groups)."""
        prm = self.s.materials[mi].params if prm is None else prm
        ck = (mi, key, id(prm))
        if ck not in self._cache:
            self._cache[ck] = (prm, brdf.params_at(prm, self.bins_nm[list(lam3)]))
        return self._cache[ck][1]

    def render_blocks(self, blocks, samples, seed):
        """One block at a time (each draws its wavelengths before its bounces)."""
        return [self.render_block(r0, r1, samples, seed, b) for r0, r1, b in blocks]

    def render_block(self, row0, row1, samples, seed, block_id):
        samples = list(samples)
        gens, counts, rows, cols, jit = self._block_streams([(row0, row1, block_id)], samples, seed)
        npix = counts[0]
        lam_u = np.concatenate([g.random((npix, 2)) for g in gens])
        c = np.minimum((lam_u[:, 0] * STRIDE).astype(np.int64), STRIDE - 1)
        hero = np.minimum((lam_u[:, 1] * 4).astype(np.int64), 3)
        lam = c[:, None] + STRIDE * np.arange(4)[None, :]
        o, d = self.camera_rays(rows, cols, jit)
        paths = SpectralPaths(lam, hero)
        Ls = self.trace_paths(paths, o, d, self._bounce_draws(gens, npix))
        rgb = (N_BINS / 4.0) * np.einsum("nj,njc->nc", Ls, self.w_bins[lam]) + paths.rgb
        rgb = rgb.reshape(len(samples), row1 - row0, self.s.width, 3)
        return rgb.sum(axis=0), (rgb * rgb).sum(axis=0)

    def trace(self, o, d, draw):  # pragma: no cover - the RGB entry point is not this class's
        raise NotImplementedError("SpectralIntegrator traces wavelengths: use render_block")

    def trace_spectral(self, o, d, lam, hero, draw):
        """Spectral radiance (N, 4) at the wavelengths ``lam`` (N, 4) of each path."""
        return self.trace_paths(SpectralPaths(lam, hero), o, d, draw)

    # -- the channel hooks of Integrator's steps
    def spectrum(self, rgb, paths, idx):
        return self.up(rgb, paths.lam[idx])

    def emission_share(self, g, paths):
        # a hero-only evaluation stands for all four wavelengths (4x) unless the path is
        # already reduced to its hero (its throughput holds the 4x)
        if self.category[g.mi] != "hero":
            return None
        return np.where(paths.hero_only[g.act], 1.0, HERO)

    def eval_directions(self, g, paths, dirs_w):
        lam_s, hero_s, cat = paths.lam[g.act], paths.hero[g.act], self.category[g.mi]
        out = []
        for ww in dirs_w:
            wl = g.local(ww)
            out.append((wl, self._eval4(g.mi, g.model, g.prm, cat, lam_s, hero_s, wl, g.wo)))
        return out

    def material_pdf(self, g, paths, wi_l):
        return self._pdf4(g.mi, g.model, self.category[g.mi], paths.lam[g.act], paths.hero[g.act],
                          wi_l, g.wo, g.prm)

    def sample_material(self, g, paths, rnd_g):
        return self._sample4(g.mi, g.model, g.info, self.category[g.mi], paths.lam[g.act],
                             paths.hero[g.act], g.wo, rnd_g, g.prm)

    def throughput(self, paths, act, T_before, new):
        # a path that becomes hero-only: the model weighted only the hero's channel; the hero
        # now carries the four wavelengths' share (4x), the others are terminated
        was_hero_only = paths.hero_only[act]
        became = new.hero_only & ~was_hero_only
        T_after = T_before * new.w
        if np.any(became):
            T_after[became] *= HERO
        paths.hero_only[act] = was_hero_only | new.hero_only
        return T_after

    # -- evaluation of one material group at the paths' wavelengths
    def _eval4(self, mi, model, prm, cat, lam, hero, wi, wo):
        """(k, 4) f at the wavelengths of each path (wi, wo local; lam (k, 4), hero (k,))."""
        k = wi.shape[0]
        if cat == "rgb":
            return self.up(self._clean(model.eval(prm, wi, wo)), lam)
        out = np.zeros((k, 4))
        if cat == "table":
            cls = lam[:, 0]
            for cval in np.unique(cls):
                g = np.flatnonzero(cls == cval)
                l4 = lam[g[0]]
                f012 = self._clean(model.eval(self._params(mi, ("c", int(cval)), l4[:3], prm), wi[g], wo[g]))
                f3 = self._clean(model.eval(self._params(mi, ("h", int(l4[3])), [l4[3]] * 3, prm), wi[g], wo[g]))
                out[g, :3] = f012
                out[g, 3] = f3[:, 0]
            return out
        lh = lam[np.arange(k), hero]
        for b in np.unique(lh):
            g = np.flatnonzero(lh == b)
            f = self._clean(model.eval(self._params(mi, ("h", int(b)), [b] * 3, prm), wi[g], wo[g]))
            out[g, hero[g]] = f[:, 0]
        return out

    def _sample4(self, mi, model, info, cat, lam, hero, wo, u, prm=None):
        """(wi (k, 3), weight (k, 4), pdf (k,), hero_only (k,) bool, lobe (k,): the lobe
        each sample drew, ``Lobe`` values)."""
        k = wo.shape[0]
        prm = info.params if prm is None else prm
        if cat == "rgb":
            wi, wgt, pdf, lobe = model.sample_lobe(prm, wo, u)
            wgt = self._clean(np.asarray(wgt, dtype=np.float64))
            return wi, self.up(wgt, lam), pdf, np.zeros(k, dtype=bool), lobe
        wi = np.zeros((k, 3))
        lobe = np.zeros(k, dtype=lobes.DTYPE)
        wgt4 = np.zeros((k, 4))
        pdf = np.zeros(k)
        if cat == "table":
            cls = lam[:, 0]
            for cval in np.unique(cls):
                g = np.flatnonzero(cls == cval)
                l4 = lam[g[0]]
                p012 = self._params(mi, ("c", int(cval)), l4[:3], prm)
                p3 = self._params(mi, ("h", int(l4[3])), [l4[3]] * 3, prm)
                w_g, wg, pg, lobe[g] = model.sample_lobe(p012, wo[g], u[g])
                wg = self._clean(np.asarray(wg, dtype=np.float64))
                if info.lobes.is_delta:   # the same direction at every wavelength (a mirror)
                    _, w3, _ = model.sample(p3, wo[g], u[g])
                    w3 = self._clean(np.asarray(w3, dtype=np.float64))[:, 0]
                else:
                    f3 = self._clean(model.eval(p3, w_g, wo[g]))[:, 0]
                    w3 = np.where(pg > 0, f3 * np.abs(w_g[:, 2]) / np.where(pg > 0, pg, 1.0), 0.0)
                wi[g], pdf[g] = w_g, pg
                wgt4[g, :3] = wg
                wgt4[g, 3] = w3
            return wi, wgt4, pdf, np.zeros(k, dtype=bool), lobe
        lh = lam[np.arange(k), hero]
        for b in np.unique(lh):
            g = np.flatnonzero(lh == b)
            w_g, wg, pg, lobe[g] = model.sample_lobe(self._params(mi, ("h", int(b)), [b] * 3, prm), wo[g], u[g])
            wg = self._clean(np.asarray(wg, dtype=np.float64))
            wi[g], pdf[g] = w_g, pg
            wgt4[g, hero[g]] = wg[:, 0]
        return wi, wgt4, pdf, np.ones(k, dtype=bool), lobe

    def _pdf4(self, mi, model, cat, lam, hero, wi, wo, prm=None):
        """The pdf the group's sampling used (the same parameters as ``_sample4``)."""
        k = wi.shape[0]
        if cat == "rgb":
            return self._clean(model.pdf(self.s.materials[mi].params if prm is None else prm, wi, wo))
        out = np.zeros(k)
        if cat == "table":
            cls = lam[:, 0]
            for cval in np.unique(cls):
                g = np.flatnonzero(cls == cval)
                out[g] = model.pdf(self._params(mi, ("c", int(cval)), lam[g[0], :3], prm), wi[g], wo[g])
            return self._clean(out)
        lh = lam[np.arange(k), hero]
        for b in np.unique(lh):
            g = np.flatnonzero(lh == b)
            out[g] = model.pdf(self._params(mi, ("h", int(b)), [b] * 3, prm), wi[g], wo[g])
        return self._clean(out)
