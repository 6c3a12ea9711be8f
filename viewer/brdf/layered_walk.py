"""The stochastic layered random walk: an unbiased Monte Carlo estimate of the ``layered`` model's
BSDF, the CPU reference's truth for it (``reference = "random_walk"`` on a layered material;
the default ``"closed_form"`` is the twins' formula in viewer/brdf/layered.py, which the
rasterizer always draws).

The layer is a slab between two interfaces with no extent in position ("position-free": Guo,
Hasan & Zhao 2018, "Position-free Monte Carlo simulation for arbitrary layered BSDFs", ACM TOG
37(6); the estimator of pbrt-v4's LayeredBxDF, Pharr, Jakob & Humphreys, Physically Based
Rendering, 4th ed., sec. 14.3): a path is a sequence of directions only, each segment through
the layer attenuated by Bouguer's law exp(-sigma_a thickness / |cos|).

* The top interface is the coat as a rough dielectric BSDF: the ``dielectric`` model with the
  coating's ior, alpha and thin film (GGX, exact Fresnel, height-correlated Smith G2 for
  reflection and its refraction form, radiance-mode 1 / eta^2: its numpy twin). Its reflection
  from outside is exactly the closed form's coat lobe f_coat.
* The bottom interface is the base material (any non-delta model), evaluated at the directions
  inside the layer.

Estimate of f(wi, wo) (wo toward the viewer, wi toward the light, both outside): f_top(wi, wo)
plus, per walk, a path started by sampling the top from wo and kept when it transmits (a
reflection sample counts zero: unbiased for the transmitted part); at every base vertex two
connections to wi combined by the power heuristic (multiple importance sampling): (a) through a
direction w_s presampled once per walk by sampling the top from wi (its transmitted samples),
f_base(-w_s, wo_b) |cos w_s| Tr(w_s) f_top(wi, w_s) / pdf_top(w_s | wi); (b) through the
base's own sample w_b, f_base |cos| / pdf_b Tr(w_b) f_top(wi, -w_b). The walk continues with
the base's sample, and at the top from inside with the top's sample when it reflects (a
transmission out counts zero: the exits are the connections above); Russian roulette after 3
base vertices when the throughput is below 0.25 (as pbrt-v4). Both strategies' densities are
taken for the same direction, so the weights sum to 1: the estimate is unbiased for any number
of walks (``n_walks``), with no limit but ``max_depth`` base vertices (64; a white lossless layer
at normal incidence loses < 1e-4 there).

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
        # the spectral reference's film carries its wavelengths (viewer.pathtracer.spectral.params_at)
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


def eval_walk(p, wi, wo, rng: np.random.Generator, n_walks: int = 1, max_depth: int = MAX_DEPTH):
    """(N, 3) unbiased estimate of the layered BSDF f(wi, wo) by ``n_walks`` random walks each."""
    from viewer import brdf

    top_m = brdf.get("dielectric")
    top = top_interface(p)
    base_m = brdf.get(p.base.model)
    base = p.base
    wi = np.asarray(wi, dtype=np.float64)
    wo = np.asarray(wo, dtype=np.float64)
    n = wi.shape[0]
    ok = (wi[:, 2] > 0) & (wo[:, 2] > 0)
    f = np.where(ok[:, None], top_m.eval(top, wi, wo), 0.0)
    acc = np.zeros((n, 3))
    for _ in range(int(n_walks)):
        acc += _one_walk(p, top_m, top, base_m, base, wi, wo, ok, rng, max_depth)
    return f + acc / float(n_walks)


def _one_walk(p, top_m, top, base_m, base, wi, wo, ok, rng, max_depth):
    n = wi.shape[0]
    out = np.zeros((n, 3))
    # enter from wo: the top's sample, kept when it transmits (w1 points down into the layer)
    w1, b1, _ = top_m.sample(top, wo, rng.random((n, 2)))
    alive = ok & (w1[:, 2] < 0) & np.any(b1 > 0, axis=1)
    # the presampled exit direction: the top sampled from wi, kept when it transmits
    ws, bs, ps = top_m.sample(top, wi, rng.random((n, 2)))
    exit_ok = (ws[:, 2] < 0) & (ps > 0)
    f_ws = np.where(exit_ok[:, None], top_m.eval(top, wi, ws), 0.0)       # f_top(wi, w_s)
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
            c = beta[ea] * fb * np.abs(up[:, 2])[:, None] * tr_ws[j] * f_ws[j] \
                * (wgt / np.where(ps[j] > 0, ps[j], 1.0))[:, None]
            np.add.at(out, j, np.where(np.isfinite(c), c, 0.0))
        # (b) the base's sample, then the connection through it
        wb, bb, pbs = base_m.sample(base, wo_b, rng.random((idx.size, 2)))
        good = (wb[:, 2] > 0) & (pbs > 0) & np.any(bb > 0, axis=1)
        beta = beta * bb * _absorb(p, wb)
        if np.any(good):
            g = np.flatnonzero(good)
            j = idx[g]
            down = -wb[g]                         # at the top: toward the base (z < 0)
            fe = top_m.eval(top, wi[j], down)
            pe = top_m.pdf(top, down, wi[j])       # strategy (a)'s density of the same direction
            wgt = _power(pbs[g], pe)
            c = beta[g] * fe * wgt[:, None]
            np.add.at(out, j, np.where(np.isfinite(c), c, 0.0))
        idx, beta, wb = idx[good], beta[good], wb[good]
        if idx.size == 0:
            break
        # at the top from inside: continue when it reflects back down
        wr, br, _ = top_m.sample(top, -wb, rng.random((idx.size, 2)))
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
        """``sample`` plus the discrete flags: the walk runs over a smooth base only (none)."""
        wi, w, pdf = self.sample(p, wo, u)
        return wi, w, pdf, np.zeros(len(pdf), dtype=bool)
