"""The stochastic layered random walk: an unbiased Monte Carlo estimate of the ``layered`` model's
BSDF, the CPU reference's truth for it (``reference = "random_walk"`` on a layered material;
the default ``"closed_form"`` is the twins' formula in viewer/brdf/layered.py, which the
rasterizer always draws).

The layer is a slab between two interfaces with no extent in position ("position-free": Guo,
Hasan & Zhao 2018, "Position-free Monte Carlo simulation for arbitrary layered BSDFs", ACM TOG
37(6); the estimator of pbrt-v4's LayeredBxDF, Pharr, Jakob & Humphreys, Physically Based
Rendering, 4th ed., sec. 14.3): a path is a sequence of directions only, each segment through
the layer attenuated by Bouguer's law exp(-sigma_a thickness / |cos|).

* The top interface is the coat as a rough dielectric that scatters multiply on its
  microsurface: the random walk of Heitz, Hanika, d'Eon & Dachsbacher 2016 (sec. 6.2; the
  dielectric walk in viewer/brdf/microfacet_walk.py, beside the conductor one), with the
  ``dielectric`` model's ior, alpha and thin film (``top_interface``). Its first order is that
  model exactly (GGX, exact Fresnel, height-correlated Smith G2 for reflection and refraction,
  radiance-mode 1 / eta^2), so its single reflection from outside is the closed form's coat lobe
  f_coat; the higher orders are what a single-scattering interface loses at every crossing
  (R + T = 0.78 at alpha 0.3 seen from inside at 60 deg), which made the layer lose 8% of a white
  furnace at alpha 0.1 and 30-37% at 0.3. ``top_sample`` is the walk (exact sampling; weight 1
  for a lossless coat), ``top_eval`` the single scattering plus a one-walk next-event estimate of
  the rest (unbiased), ``top_pdf`` a positive stand-in density for the weights of multiple
  importance sampling (unbiased for any choice, since both strategies use the same function).
* The bottom interface is the base material (any non-delta model), evaluated at the directions
  inside the layer.

Estimate of f(wi, wo) (wo toward the viewer, wi toward the light, both outside): f_top(wi, wo)
(its multiple orders estimated per walk) plus, per walk, a path started by sampling the top from
wo and kept when it transmits (a reflection sample counts zero: unbiased for the transmitted
part); at every base vertex two connections to wi combined by the power heuristic (multiple
importance sampling): (a) through a direction w_s presampled once per walk by sampling the top
from wi (its transmitted samples), f_base(-w_s, wo_b) |cos w_s| Tr(w_s) f_top(wi, w_s) /
pdf_top(w_s | wi), written with the walk's sample weight; (b) through the base's own sample w_b,
f_base |cos| / pdf_b Tr(w_b) f_top(wi, -w_b). The walk continues with the base's sample, and at
the top from inside with the top's sample when it reflects (a transmission out counts zero: the
exits are the connections above); Russian roulette after 3 base vertices when the throughput is
below 0.25 (as pbrt-v4). Both strategies' densities are taken for the same direction, so the
weights sum to 1: the estimate is unbiased for any number of walks (``n_walks``), with no limit
but ``max_depth`` base vertices (64; a white lossless layer at normal incidence loses < 1e-4
there).

A base that reflects more than it receives (a Lafortune lobe with large coefficients) makes the
walk's series diverge under a nearly lossless coat, as the layer's own interreflections would:
estimates grow past float32's range. The walk is meant for energy-conserving bases.

In the reference the model samples directions with the closed form's sampler (its pdf is
exact) and weights them by the walk's f: unbiased, since the closed form's pdf covers every
direction the layer reflects into. A delta base (mirror) keeps the closed form (its walk would need a
discrete lobe at every base vertex).
"""

from __future__ import annotations

import hashlib

import numpy as np

from viewer.brdf.spec import Params

MAX_DEPTH = 64
RR_DEPTH = 3


def top_interface(p) -> Params:
    """The coat of layered material p as a ``dielectric`` BSDF (no absorption: the layer's is
    applied per segment)."""
    from viewer import brdf

    kw = {"ior": float(p.coating.ior), "alpha": float(p.coating.alpha)}
    tf = p.coating.get("thin_film")
    if tf is not None:
        kw["thin_film"] = {k: v for k, v in tf.items() if k != "lambda_nm"}
    top = brdf.get("dielectric").params(**kw)
    if tf is not None and tf.get("lambda_nm") is not None:
        # the spectral reference's film carries its wavelengths (viewer.brdf.params_at)
        top = top.replace(thin_film=Params(tf.model, dict(tf)))
    return top


def _power(a, b):
    a2, b2 = a * a, b * b
    s = a2 + b2
    return np.where(s > 0, a2 / np.where(s > 0, s, 1.0), 0.0)


def _absorb(p, w):
    """(N, 3) Bouguer transmittance of one crossing of the layer along w."""
    tau = np.asarray(p.coating.sigma_a, dtype=np.float64) * float(p.coating.thickness)
    return np.exp(-tau[None, :] / np.maximum(np.abs(w[:, 2]), 1e-12)[:, None])


def _fresnel_rt(top):
    from viewer.brdf.dielectric import film_or_fresnel

    return lambda cos, eta: film_or_fresnel(top, cos, eta)


def _index(top, w):
    """(N,) refractive index of the side w points into (outside 1, inside the coat's ior)."""
    return np.where(w[:, 2] > 0, 1.0, float(top.ior))


def top_eval(top, wi, wo, rng):
    """(N, 3) radiance-mode f_top(wi, wo) of the multiply scattering coat, either side: the
    dielectric model's single scattering (exact) plus a one-walk estimate of the higher orders
    (viewer/brdf/microfacet_walk.py; unbiased, so the layered estimate stays unbiased)."""
    from viewer import brdf
    from viewer.brdf import microfacet_walk as mw
    from viewer.brdf.microfacet_dist import Distribution

    dist = Distribution("ggx", float(top.alpha), float(top.alpha))
    g = mw.eval_dielectric_multiple(dist, float(top.ior), _fresnel_rt(top), wi, wo, rng)
    r = _index(top, wo) / _index(top, wi)
    return brdf.get("dielectric").eval(top, wi, wo) + g * (r * r)[:, None]


def top_sample(top, wo, u, rng):
    """(wi, radiance-mode weight, pdf) of the coat's random walk from wo: the walk is the exact
    sampling procedure, so the weight is its particle weight (1 for a lossless coat without a
    film) times (n_wo / n_wi)^2; the pdf is ``top_pdf``, a weight for multiple importance
    sampling only (the walk's density has no closed form)."""
    from viewer.brdf import microfacet_walk as mw
    from viewer.brdf.microfacet_dist import Distribution

    dist = Distribution("ggx", float(top.alpha), float(top.alpha))
    wi, wt, _ = mw.sample_dielectric(dist, float(top.ior), _fresnel_rt(top), wo, u, rng)
    r = _index(top, wo) / _index(top, wi)
    pdf = top_pdf(top, wi, wo)
    ok = (pdf > 0) & np.any(wt > 0, axis=1)
    return wi, np.where(ok[:, None], wt * (r * r)[:, None], 0.0), np.where(ok, pdf, 0.0)


def top_pdf(top, wi, wo):
    """The coat's MIS density of wi given wo: the single-scattering pdf mixed with |cos| / 2 pi
    over the sphere (weight ``ms_fraction(alpha)``) for the multiply scattered light. Any
    positive density keeps the weights summing to 1 (the same function weights both
    strategies), so the estimate stays unbiased; only the noise depends on the choice."""
    from viewer import brdf
    from viewer.brdf.microfacet_walk import ms_fraction

    q = max(ms_fraction(float(top.alpha)), 0.02)
    return (1.0 - q) * brdf.get("dielectric").pdf(top, wi, wo) + q * np.abs(wi[:, 2]) / (2.0 * np.pi)


def eval_walk(p, wi, wo, rng: np.random.Generator, n_walks: int = 1, max_depth: int = MAX_DEPTH):
    """(N, 3) unbiased estimate of the layered BSDF f(wi, wo) by ``n_walks`` random walks each."""
    from viewer import brdf

    top = top_interface(p)
    base_m = brdf.get(p.base.model)
    base = p.base
    wi = np.asarray(wi, dtype=np.float64)
    wo = np.asarray(wo, dtype=np.float64)
    n = wi.shape[0]
    ok = (wi[:, 2] > 0) & (wo[:, 2] > 0)
    acc = np.zeros((n, 3))
    for _ in range(int(n_walks)):
        acc += np.where(ok[:, None], top_eval(top, wi, wo, rng), 0.0)
        acc += _one_walk(p, top, base_m, base, wi, wo, ok, rng, max_depth)
    return acc / float(n_walks)


def _one_walk(p, top, base_m, base, wi, wo, ok, rng, max_depth):
    n = wi.shape[0]
    out = np.zeros((n, 3))
    eta2 = float(top.ior) ** 2
    # enter from wo: the top's walk, kept when it transmits (w1 points down into the layer)
    w1, b1, _ = top_sample(top, wo, rng.random((n, 2)), rng)
    alive = ok & (w1[:, 2] < 0) & np.any(b1 > 0, axis=1)
    # the presampled exit direction: the top's walk from wi, kept when it transmits. Its weight
    # bs = f_top(w_s, wi) |cos w_s| / p(w_s) gives the exit's f_top(wi, w_s) |cos w_s| / p(w_s)
    # as bs (n_s / n_i)^2 = bs ior^2 (the interface's reciprocity, viewer/brdf/dielectric.py)
    ws, bs, ps = top_sample(top, wi, rng.random((n, 2)), rng)
    exit_ok = (ws[:, 2] < 0) & (ps > 0) & np.any(bs > 0, axis=1)
    e_ws = np.where(exit_ok[:, None], bs * eta2, 0.0)
    tr_ws = _absorb(p, ws)
    idx = np.flatnonzero(alive)
    beta = b1[idx] * _absorb(p, w1[idx])
    d = w1[idx]                                   # the direction travelled down to the base
    for depth in range(max_depth):
        if idx.size == 0:
            break
        if depth >= RR_DEPTH:
            m = beta.max(axis=1)
            q = np.where(m < 0.25, np.maximum(0.0, 1.0 - m), 0.0)
            keep = rng.random(idx.size) >= q
            beta = beta[keep] / (1.0 - q[keep])[:, None]
            idx, d = idx[keep], d[keep]
            if idx.size == 0:
                break
        wo_b = -d                                 # at the base: toward the top (z > 0)
        # (a) the connection through w_s
        ea = exit_ok[idx]
        if np.any(ea):
            j = idx[ea]
            up = -ws[j]
            fb = base_m.eval(base, up, wo_b[ea])
            pb = base_m.pdf(base, up, wo_b[ea])
            wgt = _power(ps[j], pb)
            c = beta[ea] * fb * tr_ws[j] * e_ws[j] * wgt[:, None]
            np.add.at(out, j, np.where(np.isfinite(c), c, 0.0))
        # (b) the base's sample, then the connection through it
        wb, bb, pbs = base_m.sample(base, wo_b, rng.random((idx.size, 2)))
        good = (wb[:, 2] > 0) & (pbs > 0) & np.any(bb > 0, axis=1)
        beta = beta * bb * _absorb(p, wb)
        if np.any(good):
            g = np.flatnonzero(good)
            j = idx[g]
            down = -wb[g]                         # at the top: toward the base (z < 0)
            fe = top_eval(top, wi[j], down, rng)
            pe = top_pdf(top, down, wi[j])        # strategy (a)'s density of the same direction
            wgt = _power(pbs[g], pe)
            c = beta[g] * fe * wgt[:, None]
            np.add.at(out, j, np.where(np.isfinite(c), c, 0.0))
        idx, beta, wb = idx[good], beta[good], wb[good]
        if idx.size == 0:
            break
        # at the top from inside: continue when the walk returns down into the layer
        wr, br, _ = top_sample(top, -wb, rng.random((idx.size, 2)), rng)
        down_ok = (wr[:, 2] < 0) & np.any(br > 0, axis=1)
        beta = beta[down_ok] * br[down_ok] * _absorb(p, wr[down_ok])
        idx, d = idx[down_ok], wr[down_ok]
    return out


def seeded_rng(*arrays) -> np.random.Generator:
    """A generator seeded by the bytes of the inputs: the same directions give the same
    estimate (the reference's images depend only on its seed)."""
    h = hashlib.blake2b(digest_size=8)
    for a in arrays:
        h.update(np.ascontiguousarray(a).tobytes())
    return np.random.default_rng(int.from_bytes(h.digest(), "little"))


class WalkModel:
    """The layered model for the CPU reference with ``reference = "random_walk"``: eval is the
    walk's estimate, pdf and the sampled directions the closed form's, the sample's weight the
    walk's f cos / pdf. Same interface as a registry model (spec, module, eval, pdf, sample)."""

    def __init__(self, model, n_walks: int = 1):
        self._m = model
        self.spec = model.spec
        self.module = self
        self.name = getattr(model, "name", "layered")
        self.n_walks = int(n_walks)

    def __getattr__(self, key):
        return getattr(self._m, key)

    def params(self, **kw):
        return self._m.params(**kw)

    def eval(self, p, wi, wo):
        return eval_walk(p, wi, wo, seeded_rng(wi, wo, np.array([1])), self.n_walks)

    def pdf(self, p, wi, wo):
        return self._m.pdf(p, wi, wo)

    def sample(self, p, wo, u):
        wi, _, pdf = self._m.sample(p, wo, u)
        f = eval_walk(p, wi, wo, seeded_rng(wi, wo, np.array([2])), self.n_walks)
        ok = (pdf > 0) & (wi[:, 2] > 0)
        w = f * (np.abs(wi[:, 2]) / np.where(ok, pdf, 1.0))[:, None]
        return wi, np.where(ok[:, None], w, 0.0), np.where(ok, pdf, 0.0)

    def sample_lobe(self, p, wo, u):
        """``sample`` plus the lobes drawn: the walk runs over a smooth base only, so each is the
        layer's smooth reflection (``lobes``; never DELTA)."""
        from viewer.brdf import lobes

        wi, w, pdf = self.sample(p, wo, u)
        kind = self._m.lobes(p) & lobes.SMOOTH
        return wi, w, pdf, np.full(len(pdf), lobes.Lobe.REFLECTION | kind, dtype=lobes.DTYPE)
