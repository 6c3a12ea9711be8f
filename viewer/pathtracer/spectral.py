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

from viewer import spectral
from viewer.brdf.spec import Params
from viewer.pathtracer.integrator import (
    DIMS_PER_BOUNCE, EPS_REL, RR_MAX, RR_MIN, RR_START_DEPTH, Integrator, _dot, _power, philox)
from viewer.geometry.soup import hit_points, interpolate_shading, shading_frame

N_BINS = 420
STRIDE = N_BINS // 4
LAMBDA0 = 360.0
HERO = 4            # the hero-only path's weight: the four wavelengths' share in one


def bin_wavelengths() -> np.ndarray:
    return LAMBDA0 + np.arange(N_BINS, dtype=np.float64)


def bin_weights() -> np.ndarray:
    """(420, 3) CIE RGB weights of the 1 nm bins; they sum to (1, 1, 1)."""
    w = spectral.colorimetry.weights().T.copy()          # (421, 3) on 360..780
    out = w[:N_BINS].copy()
    out[-1] += w[N_BINS]
    return out


def uses_spectral(p) -> bool:
    """Whether a material (Params) names a spectral table anywhere."""
    if p.get("spectral", "none") != "none":
        return True
    return any(isinstance(v, Params) and uses_spectral(v) for v in p.values())


def is_dispersive(p) -> bool:
    """A spectral dielectric or layered coating: light refracts by n(lambda)."""
    if p.model == "dielectric" and p.get("spectral", "none") != "none":
        return True
    for v in p.values():
        if isinstance(v, Params) and (v.get("spectral", "none") != "none" and v.model == ""
                                      or v.model and is_dispersive(v)):
            return True
    return False


def scene_is_dispersive(scene) -> bool:
    """Whether a material some object uses is dispersive."""
    used = {o.material for o in scene.objects}
    return any(is_dispersive(p) for name, p in scene.materials.items() if name in used)


def params_at(p, lam3) -> Params:
    """The material's parameters at three wavelengths ``lam3`` (its three channels): spectral
    tables give eta, k = n, k at lam3 (and ior = n(lam3[0])); every other RGB parameter becomes
    its upsampled spectrum at lam3. Nested tables and materials likewise."""
    lam3 = np.asarray(lam3, dtype=np.float64)
    b = spectral.upsampling.basis_at(lam3)               # (3, 3): row = wavelength
    out = dict(p)
    name = p.get("spectral", "none")
    if name != "none":
        n = spectral.ior(name, lam3)
        out["spectral"] = "none"
        if "eta" in out:
            out["eta"] = np.maximum(n.real, 1e-3)
            out["k"] = n.imag.copy()
            if "fresnel" in out:
                out["fresnel"] = "conductor"
        if "ior" in out:
            out["ior"] = float(n[0].real)
    for key, v in p.items():
        if isinstance(v, Params):
            out[key] = params_at(v, lam3)
        elif isinstance(v, np.ndarray) and v.shape == (3,) and key in out and out[key] is v:
            if name != "none" and key in ("eta", "k"):
                continue
            out[key] = b @ v
    return Params(p.model, out)


class SpectralIntegrator(Integrator):
    """``Integrator`` with four wavelengths per path instead of RGB channels."""

    def __init__(self, setup):
        super().__init__(setup)
        self.bins_nm = bin_wavelengths()
        self.w_bins = bin_weights()
        self.basis = spectral.upsampling.basis_at(self.bins_nm)          # (420, 3)
        self.category = []
        for m in setup.materials:
            p = m.params
            if not uses_spectral(p):
                self.category.append("rgb")
            elif is_dispersive(p) or m.kind == "mixed":
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

    def _params(self, mi, key, lam3):
        ck = (mi, key)
        if ck not in self._cache:
            self._cache[ck] = params_at(self.s.materials[mi].params, self.bins_nm[list(lam3)])
        return self._cache[ck]

    def render_block(self, row0, row1, samples, seed, block_id):
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
        lam_u = np.concatenate([g.random((npix, 2)) for g in gens])
        c = np.minimum((lam_u[:, 0] * STRIDE).astype(np.int64), STRIDE - 1)
        hero = np.minimum((lam_u[:, 1] * 4).astype(np.int64), 3)
        lam = c[:, None] + STRIDE * np.arange(4)[None, :]
        o, d = self.camera_rays(np.tile(rows, ns), np.tile(cols, ns), jit)
        Ls = self.trace_spectral(o, d, lam, hero,
                                 lambda: np.concatenate([g.random((npix, DIMS_PER_BOUNCE)) for g in gens]))
        rgb = (N_BINS / 4.0) * np.einsum("nj,njc->nc", Ls, self.w_bins[lam])
        rgb = rgb.reshape(ns, row1 - row0, W, 3)
        return rgb.sum(axis=0), (rgb * rgb).sum(axis=0)

    def trace(self, o, d, draw):  # pragma: no cover - the RGB entry point is not this class's
        raise NotImplementedError("SpectralIntegrator traces wavelengths: use render_block")

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
                f012 = self._clean(model.eval(self._params(mi, ("c", int(cval)), l4[:3]), wi[g], wo[g]))
                f3 = self._clean(model.eval(self._params(mi, ("h", int(l4[3])), [l4[3]] * 3), wi[g], wo[g]))
                out[g, :3] = f012
                out[g, 3] = f3[:, 0]
            return out
        lh = lam[np.arange(k), hero]
        for b in np.unique(lh):
            g = np.flatnonzero(lh == b)
            f = self._clean(model.eval(self._params(mi, ("h", int(b)), [b] * 3), wi[g], wo[g]))
            out[g, hero[g]] = f[:, 0]
        return out

    def _sample4(self, mi, model, info, cat, lam, hero, wo, u):
        """(wi (k, 3), weight (k, 4), pdf (k,), hero_only (k,) bool)."""
        k = wo.shape[0]
        prm = info.params
        if cat == "rgb":
            wi, wgt, pdf = model.sample(prm, wo, u)
            wgt = self._clean(np.asarray(wgt, dtype=np.float64))
            return wi, self.up(wgt, lam), pdf, np.zeros(k, dtype=bool)
        wi = np.zeros((k, 3))
        wgt4 = np.zeros((k, 4))
        pdf = np.zeros(k)
        if cat == "table":
            cls = lam[:, 0]
            for cval in np.unique(cls):
                g = np.flatnonzero(cls == cval)
                l4 = lam[g[0]]
                p012 = self._params(mi, ("c", int(cval)), l4[:3])
                p3 = self._params(mi, ("h", int(l4[3])), [l4[3]] * 3)
                w_g, wg, pg = model.sample(p012, wo[g], u[g])
                wg = self._clean(np.asarray(wg, dtype=np.float64))
                if info.kind == "delta":   # the same direction at every wavelength (a mirror)
                    _, w3, _ = model.sample(p3, wo[g], u[g])
                    w3 = self._clean(np.asarray(w3, dtype=np.float64))[:, 0]
                else:
                    f3 = self._clean(model.eval(p3, w_g, wo[g]))[:, 0]
                    w3 = np.where(pg > 0, f3 * np.abs(w_g[:, 2]) / np.where(pg > 0, pg, 1.0), 0.0)
                wi[g], pdf[g] = w_g, pg
                wgt4[g, :3] = wg
                wgt4[g, 3] = w3
            return wi, wgt4, pdf, np.zeros(k, dtype=bool)
        lh = lam[np.arange(k), hero]
        for b in np.unique(lh):
            g = np.flatnonzero(lh == b)
            w_g, wg, pg = model.sample(self._params(mi, ("h", int(b)), [b] * 3), wo[g], u[g])
            wg = self._clean(np.asarray(wg, dtype=np.float64))
            wi[g], pdf[g] = w_g, pg
            wgt4[g, hero[g]] = wg[:, 0]
        return wi, wgt4, pdf, np.ones(k, dtype=bool)

    def trace_spectral(self, o, d, lam, hero, draw):
        """Spectral radiance (N, 4) at the wavelengths ``lam`` (N, 4) of each path."""
        s = self.s
        geom = self.geom
        env = s.env
        env_on = not env.is_black
        N = o.shape[0]
        L = np.zeros((N, 4))
        T = np.ones((N, 4))
        solo = np.zeros(N, dtype=bool)       # secondaries terminated: T holds the hero alone
        sigma = np.zeros((N, 3))
        prev_pdf = np.zeros(N)
        prev_lpdf = np.zeros(N)
        prev_delta = np.ones(N, dtype=bool)
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
                Le = self.up(env.eval(d[miss]), lam[idx])
                w = np.where(prev_delta[idx], 1.0, _power(prev_pdf[idx], prev_lpdf[idx]))
                L[idx] += T[idx] * Le * w[:, None]
            if depth > s.max_depth:
                break
            hit = ~miss
            act, o, d, t, prim, bu, bv = act[hit], o[hit], d[hit], t[hit], prim[hit], bu[hit], bv[hit]
            if act.size == 0:
                break
            sig = sigma[act]
            inside = np.any(sig > 0, axis=1)
            if np.any(inside):
                ia = act[inside]
                T[ia] *= self.up(np.exp(-sig[inside] * t[inside, None]), lam[ia])
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
            lam_a, hero_a = lam[act], hero[act]

            light_dirs, light_vals, light_tmax = [], [], []
            for kind, a, val in lights:
                if kind == "point":
                    dv = a - p
                    r2 = np.maximum(_dot(dv, dv), 1e-300)
                    r = np.sqrt(r2)
                    light_dirs.append(dv / r[:, None])
                    light_vals.append(self.up(val, lam_a) / r2[:, None])
                    light_tmax.append(r - eps)
                else:
                    light_dirs.append(np.broadcast_to(-a, (M, 3)))
                    light_vals.append(self.up(val, lam_a))
                    light_tmax.append(np.full(M, np.inf))
            if env_on:
                e_dir, e_val, e_pdf = env.sample(rnd[:, 2:4], n, trans)
                e_pdf = self._clean(e_pdf)
            new_dir = np.zeros((M, 3))
            new_w = np.zeros((M, 4))
            new_pdf = np.zeros(M)
            new_lpdf = np.zeros(M)
            new_delta = np.zeros(M, dtype=bool)
            new_solo = np.zeros(M, dtype=bool)
            sh_idx, sh_o, sh_d, sh_tmax, sh_c = [], [], [], [], []

            order = np.argsort(mat, kind="stable")
            bounds = np.flatnonzero(np.diff(mat[order])) + 1
            for sel in np.split(order, bounds):
                if sel.size == 0:
                    continue
                mi = int(mat[sel[0]])
                info = s.materials[mi]
                model = self.models[mi]
                cat = self.category[mi]
                prm = info.params
                k = sel.size
                wo_s = wo_l[sel]
                ns_, txs, tys, ngs = n[sel], tx[sel], ty[sel], ng[sel]
                two = info.transmissive
                lam_s, hero_s = lam_a[sel], hero_a[sel]
                # a hero-only evaluation stands for all four wavelengths (4x) unless the path is
                # already reduced to its hero (its throughput holds the 4x)
                share = np.where(solo[act[sel]], 1.0, HERO) if cat == "hero" else np.ones(k)

                def local(w):
                    return np.stack([_dot(w, txs), _dot(w, tys), _dot(w, ns_)], axis=1)

                def valid(wl, ww):
                    g = _dot(ngs, ww)
                    if two:
                        return wl[:, 2] * g > 0
                    return (wl[:, 2] > 0) & (g > 0)

                if info.kind != "delta" and (lights or env_on):
                    dirs_w = [ld[sel] for ld in light_dirs]
                    if env_on:
                        dirs_w.append(e_dir[sel])
                    for j, ww in enumerate(dirs_w):
                        wl = local(ww)
                        fj = self._eval4(mi, model, prm, cat, lam_s, hero_s, wl, wo_s)
                        ok = valid(wl, ww)
                        c = Ta[sel] * fj * (np.abs(wl[:, 2]) * share)[:, None]
                        if j < len(lights):
                            c = c * light_vals[j][sel]
                            tmax = light_tmax[j][sel]
                        else:
                            pb = self._pdf4(mi, model, cat, lam_s, hero_s, wl, wo_s)
                            pe = e_pdf[sel]
                            ok &= pe > 0
                            wmis = _power(pe, pb) / np.where(pe > 0, pe, 1.0)
                            c = c * self.up(e_val[sel], lam_s) * wmis[:, None]
                            tmax = np.full(k, np.inf)
                        ok &= np.any(c > 0, axis=1)
                        if np.any(ok):
                            side = np.where(_dot(ngs[ok], ww[ok]) < 0, -1.0, 1.0)
                            sh_idx.append(act[sel[ok]])
                            sh_o.append(p[sel[ok]] + (eps[sel[ok]] * side)[:, None] * ngs[ok])
                            sh_d.append(ww[ok])
                            sh_tmax.append(tmax[ok])
                            sh_c.append(c[ok])

                wi_l, wgt, pdf_s, hero_only = self._sample4(mi, model, info, cat, lam_s, hero_s, wo_s,
                                                            rnd[sel, 0:2])
                pdf_s = self._clean(np.asarray(pdf_s, dtype=np.float64))
                bad_dir = ~np.all(np.isfinite(wi_l), axis=1)
                if np.any(bad_dir):
                    self.bad_values += int(np.count_nonzero(bad_dir))
                    wi_l = np.where(bad_dir[:, None], np.array([0.0, 0.0, 1.0]), wi_l)
                    wgt = np.where(bad_dir[:, None], 0.0, wgt)
                if info.kind == "delta":
                    disc = np.ones(k, dtype=bool)
                elif info.kind == "mixed":
                    pe_ = self._pdf4(mi, model, cat, lam_s, hero_s, wi_l, wo_s)
                    disc = np.abs(pdf_s - pe_) > 1e-6 * np.maximum(pdf_s, 1e-300)
                else:
                    disc = np.zeros(k, dtype=bool)
                wi_w = wi_l[:, :1] * txs + wi_l[:, 1:2] * tys + wi_l[:, 2:3] * ns_
                ok = valid(wi_l, wi_w) & (pdf_s > 0) & np.any(wgt > 0, axis=1)
                new_dir[sel] = wi_w
                new_w[sel] = np.where(ok[:, None], wgt, 0.0)
                new_pdf[sel] = pdf_s
                new_delta[sel] = disc
                new_solo[sel] = hero_only
                if env_on:
                    new_lpdf[sel] = np.where(disc, 0.0, env.pdf(wi_w, ns_, np.full(k, two)))
                if two:
                    inside_next = _dot(ng_raw[sel], wi_w) < 0
                    sigma[act[sel]] = np.where(inside_next[:, None], info.sigma_a, 0.0)

            if sh_idx:
                idx = np.concatenate(sh_idx)
                blocked = self.kernel.occluded(np.concatenate(sh_o), np.concatenate(sh_d), 0.0,
                                               np.concatenate(sh_tmax))
                c = np.concatenate(sh_c)
                free = ~blocked
                np.add.at(L, idx[free], c[free])

            # a path that becomes hero-only: the model weighted only the hero's channel; the hero
            # now carries the four wavelengths' share (4x), the others are terminated
            was_solo = solo[act]
            became = new_solo & ~was_solo
            Tn = Ta * new_w
            if np.any(became):
                Tn[became] *= HERO
            solo[act] = was_solo | new_solo
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

    def _pdf4(self, mi, model, cat, lam, hero, wi, wo):
        """The pdf the group's sampling used (the same parameters as ``_sample4``)."""
        k = wi.shape[0]
        if cat == "rgb":
            return self._clean(model.pdf(self.s.materials[mi].params, wi, wo))
        out = np.zeros(k)
        if cat == "table":
            cls = lam[:, 0]
            for cval in np.unique(cls):
                g = np.flatnonzero(cls == cval)
                out[g] = model.pdf(self._params(mi, ("c", int(cval)), lam[g[0], :3]), wi[g], wo[g])
            return self._clean(out)
        lh = lam[np.arange(k), hero]
        for b in np.unique(lh):
            g = np.flatnonzero(lh == b)
            out[g] = model.pdf(self._params(mi, ("h", int(b)), [b] * 3), wi[g], wo[g])
        return self._clean(out)
