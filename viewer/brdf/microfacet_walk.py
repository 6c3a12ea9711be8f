"""Multiple scattering between microfacets: the stochastic random walk on the microsurface of
Heitz, Hanika, d'Eon & Dachsbacher 2016, "Multiple-scattering microfacet BSDFs with the Smith
model" (ACM TOG 35(4), SIGGRAPH 2016): the conductor walk for the reflection-only ``microfacet``
model, and the dielectric walk (sec. 6.2, at the end of this module) for the layered model's
rough coat in the CPU reference (viewer/brdf/layered_walk.py).

The Smith microsurface is treated as a volume-like medium of heights and normals (sec. 3-5 of
the paper): heights have the uniform distribution on [-1, 1] (C1(h) = (h + 1) / 2; the walk's
result does not depend on this choice, sec. 5.1), normals the model's GGX or Beckmann
distribution. A ray leaves height h upward in direction w unoccluded with probability
G1(w, h) = C1(h)^Lambda(w); Lambda is extended to downward directions by
Lambda(-w) = -1 - Lambda(w), so that the projected area (1 + Lambda(w)) cos(theta_w) of the
microsurface is positive for every direction (sec. 4.2). At each intersection the walk samples
a visible normal m of the direction the ray came from, D_w(m) = <w, m> D(m) / ((1 + Lambda(w))
cos(theta_w)), and reflects about it, multiplying its weight by F(w . m) (the conductor phase
function, sec. 6.1; the model's dielectric Fresnel is used the same way, its transmitted part
being what the model hands to its diffuse base or loses, as its single-scattering lobe does).

* Sampling is exact: the walk IS the sampling procedure. Its exit direction, weighted by the
  product of the Fresnel terms, has the expectation of f cos over the hemisphere (every order).
* Evaluation is stochastic: the paper's next-event estimator (sec. 7): along a walk from wo,
  each vertex k adds weight_k F(w_k . m) p(w_k -> wi) G1(wi, h_k), with the phase function
  p(w -> wi) = D_w(m) / (4 |wi . m|) and m the half vector; the sum estimates f(wi, wo) cos_i
  without bias. The first vertex's expectation is exactly the single-scattering lobe
  f_ss cos_i (F D G2 / 4 cos_o with the height-correlated G2), so it is replaced by the
  analytic value: only orders >= 2 are estimated, which removes most of the noise and makes the
  estimate equal the single-scattering BRDF as alpha -> 0 (the walk then escapes after one
  event). One walk per call; ``eval_mean`` averages several (plots).
* pdf: the walk's density of exit directions has no closed form. The path tracer needs a pdf
  only to weight BSDF sampling against light sampling (MIS) and as a test "density > 0"; any
  positive function gives weights that sum to one and so an unbiased estimate (Veach 1997,
  sec. 9.2). ``pdf_approx`` is the single-scattering pdf mixed with a cosine lobe for the
  multiply scattered part (weight ``ms_fraction``), a heuristic named as one.

Randomness: ``sample`` gets 2 numbers per sample, the walk needs more; both functions draw the
rest from a generator seeded by a hash of their inputs, so results are deterministic functions
of their arguments (the reference's renders stay reproducible).

The walk stops after ``MAX_EVENTS`` intersections; paths still on the surface then count as
absorbed (measured: none of 100,000 walks at GGX alpha = 1, F = 1 needed more than 10; mean
2.3 events at normal incidence, 1.4 at alpha 0.5).
"""

from __future__ import annotations

import hashlib

import numpy as np

from viewer.brdf.microfacet_dist import Distribution, sample_vndf_beckmann, sample_vndf_ggx

MAX_EVENTS = 64
SQRT_PI = np.sqrt(np.pi)
INV_SQRT_PI = 1.0 / SQRT_PI


def rng_for(*arrays) -> np.random.Generator:
    """A generator seeded by a hash of the arrays' bytes (deterministic in the inputs)."""
    h = hashlib.blake2b(digest_size=16)
    for a in arrays:
        h.update(np.ascontiguousarray(a, dtype=np.float64).tobytes())
    return np.random.default_rng(np.frombuffer(h.digest(), dtype=np.uint64))


# ----------------------------------------------------------------------------- microsurface

def lambda_any(dist: Distribution, w):
    """Smith Lambda of any direction: Lambda(w) for w.z > 0, -1 - Lambda(-w) below (sec. 4.2)."""
    up = w[:, 2] >= 0
    ws = np.where(up[:, None], w, -w)
    lam = dist.Lambda(ws)
    return np.where(up, lam, -1.0 - lam)


def projected_area(dist: Distribution, w):
    """(1 + Lambda(w)) cos(theta_w): the microsurface's area projected along w, per unit of
    macro-surface (> 0 for every direction that is not straight up)."""
    lam = lambda_any(dist, w)
    with np.errstate(invalid="ignore"):
        a = (1.0 + lam) * w[:, 2]
    return np.where(np.isfinite(a), a, 0.0)


def c1(h):
    """The uniform height distribution's CDF on [-1, 1] (+inf: above the surface)."""
    return np.clip(0.5 * (h + 1.0), 0.0, 1.0)


def c1_inv(c):
    return 2.0 * c - 1.0


def g1_height(dist: Distribution, w, h):
    """Probability that a ray leaving height h in direction w escapes: C1(h)^Lambda(w) for
    w.z > 0, 0 for a downward ray (the height field below is unbounded)."""
    up = w[:, 2] > 0
    lam = dist.Lambda(np.where(up[:, None], w, np.array([0.0, 0.0, 1.0])))
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        g = np.power(c1(h), lam)
    return np.where(up & np.isfinite(g), g, 0.0)


def sample_height(dist: Distribution, wr, h, u):
    """(next intersection height, escaped) of a ray of direction ``wr`` from height ``h``
    (sec. 5.2): upward, it escapes with probability G1(wr, h), else it stops where
    C1(h') = C1(h) / (1 - u)^(1 / Lambda(wr)); downward it always hits, at
    C1(h') = C1(h) (1 - u)^(1 / (1 + Lambda(-wr)))."""
    z = wr[:, 2]
    up = z > 0
    c = c1(h)
    lam = lambda_any(dist, wr)
    one_u = np.maximum(1.0 - u, 1e-300)
    g = g1_height(dist, wr, h)
    escaped = up & (u >= 1.0 - g)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore", under="ignore"):
        c_up = c / np.power(one_u, 1.0 / np.where(up & (lam > 0), lam, 1.0))
        c_dn = c * np.power(one_u, 1.0 / np.where(~up, -lam, 1.0))   # -lam = 1 + Lambda(-wr)
    c_new = np.where(up, c_up, c_dn)
    c_new = np.where(np.isfinite(c_new), np.clip(c_new, 0.0, 1.0), c)
    hn = c1_inv(c_new)
    return np.where(np.abs(z) < 1e-9, h, hn), escaped


def d_visible(dist: Distribution, w, m):
    """Visible normals of direction w (either hemisphere): <w, m> D(m) / projected_area(w)."""
    a = projected_area(dist, w)
    wm = np.sum(w * m, axis=-1)
    v = np.maximum(wm, 0.0) * dist.D(m) / np.where(a > 0, a, 1.0)
    return np.where((a > 0) & (m[:, 2] > 0), v, 0.0)


def _beckmann_slope_x_below(mu, u):
    """x slope of the alpha = 1 Beckmann visible slopes for cot(theta) = mu <= 0 (a direction
    below the horizon): density (mu - x) exp(-x^2) on x < mu (Heitz & d'Eon 2014, sec. 4),
    CDF C(x) = exp(-x^2) (mu erfcx(-x) + 1 / sqrt(pi)) / 2, solved for C(x) = u C(mu) in log
    space (d log C / dx = 2 (mu - x) / (sqrt(pi) mu erfcx(-x) + 1)) by safeguarded Newton steps;
    the scaled form has no cancellation where the mass is tiny (mu << 0)."""
    from scipy.special import erfcx

    mu = np.maximum(mu, -1e4)

    def logc(x):
        return -x * x + np.log(np.maximum(mu * erfcx(-x) + INV_SQRT_PI, 1e-300))

    target = np.log(np.maximum(u, 1e-300)) + logc(mu)
    lo = mu - 8.0 / (1.0 + np.abs(mu)) - 6.0
    hi = mu.copy()
    x = mu - 1.0 / (1.0 + np.abs(mu))
    for _ in range(60):
        c = logc(x) - target
        lo = np.where(c < 0, x, lo)
        hi = np.where(c >= 0, x, hi)
        d = 2.0 * (mu - x) / (SQRT_PI * mu * erfcx(-x) + 1.0)
        with np.errstate(divide="ignore", invalid="ignore"):
            xn = x - c / d
        bad = ~np.isfinite(xn) | (xn <= lo) | (xn >= hi)
        xn = np.where(bad, 0.5 * (lo + hi), xn)
        done = np.all(np.abs(xn - x) < 1e-12 * (1.0 + np.abs(x)))
        x = xn
        if done:
            break
    return x


def _vndf_beckmann_below(w, u, ax, ay):
    """Beckmann visible normals for downward-looking w (the slope analogue of
    ``sample_vndf_beckmann``: stretch, sample the slopes in the frame of w's azimuth, rotate,
    unstretch)."""
    from scipy.special import erfinv

    ws = w * np.array([ax, ay, 1.0])
    ws /= np.linalg.norm(ws, axis=1, keepdims=True)
    sin_t = np.hypot(ws[:, 0], ws[:, 1])
    safe = np.where(sin_t > 0, sin_t, 1.0)
    mu = np.where(sin_t > 0, ws[:, 2] / safe, -1e4)
    cos_p = np.where(sin_t > 0, ws[:, 0] / safe, 1.0)
    sin_p = np.where(sin_t > 0, ws[:, 1] / safe, 0.0)
    x = _beckmann_slope_x_below(mu, u[:, 0])
    y = erfinv(np.clip(2.0 * u[:, 1] - 1.0, -1 + 1e-15, 1 - 1e-15))
    sx = (cos_p * x - sin_p * y) * ax
    sy = (sin_p * x + cos_p * y) * ay
    m = np.stack([-sx, -sy, np.ones_like(sx)], axis=-1)
    return m / np.linalg.norm(m, axis=1, keepdims=True)


def sample_visible_normal(dist: Distribution, w, u):
    """A normal of D_w for any direction w (not straight up). GGX: Heitz 2018's disk warp, whose
    half-ellipse of height w.z (after stretching) becomes a cut-out for w.z < 0 (the visible part
    of the upper hemisphere seen from below), so the same formula holds below the horizon;
    Beckmann: Heitz & d'Eon 2014's slopes (``sample_vndf_beckmann`` above the horizon)."""
    ax, ay = float(dist.ax), float(dist.ay)
    if dist.name == "ggx":
        return sample_vndf_ggx(w, u, ax, ay)
    up = w[:, 2] > 0
    m = np.empty_like(w)
    if np.any(up):
        m[up] = sample_vndf_beckmann(w[up], u[up], ax, ay)
    if np.any(~up):
        m[~up] = _vndf_beckmann_below(w[~up], u[~up], ax, ay)
    return m


def _reflect(w, m):
    return 2.0 * np.sum(w * m, axis=-1, keepdims=True) * m - w


# ----------------------------------------------------------------------------- the walk

def sample(dist: Distribution, fresnel, wo, u):
    """Random walk from wo (wo.z > 0): (exit direction wi, weight = product of F, events).
    ``fresnel(cos)`` -> (N, 3). The first normal uses ``u`` (N, 2); the rest comes from a
    generator seeded by (wo, u). Walks that have not escaped after MAX_EVENTS weigh 0."""
    n = wo.shape[0]
    rng = rng_for(wo, u)
    wi = np.tile(np.array([0.0, 0.0, 1.0]), (n, 1))
    weight = np.zeros((n, 3))
    events = np.zeros(n, dtype=np.int64)
    act = np.flatnonzero(wo[:, 2] > 0)
    wr = -wo[act]
    h = np.full(act.size, np.inf)
    wt = np.ones((act.size, 3))
    for k in range(MAX_EVENTS + 1):
        if act.size == 0:
            break
        h, esc = sample_height(dist, wr, h, rng.random(act.size))
        if np.any(esc):
            done = act[esc]
            wi[done] = wr[esc]
            weight[done] = wt[esc]
            events[done] = k
            keep = ~esc
            act, wr, h, wt = act[keep], wr[keep], h[keep], wt[keep]
        if k == MAX_EVENTS or act.size == 0:
            break
        w_in = -wr
        uu = u[act] if k == 0 else rng.random((act.size, 2))
        m = sample_visible_normal(dist, w_in, np.clip(uu, 0.0, 1.0 - 1e-16))
        cos_m = np.clip(np.sum(w_in * m, axis=-1), 0.0, 1.0)
        wt = wt * fresnel(cos_m)
        wr = _reflect(w_in, m)
        wr /= np.linalg.norm(wr, axis=1, keepdims=True)
    return wi, weight, events


def eval_multiple(dist: Distribution, fresnel, wi, wo, rng=None):
    """One-walk estimate of the multiply scattered part (orders >= 2) of f(wi, wo) (no cosine):
    a walk from wo with next-event estimation toward wi at every vertex after the first."""
    n = wi.shape[0]
    rng = rng_for(wi, wo) if rng is None else rng
    out = np.zeros((n, 3))
    act = np.flatnonzero((wo[:, 2] > 0) & (wi[:, 2] > 0))
    wr = -wo[act]
    h = np.full(act.size, np.inf)
    wt = np.ones((act.size, 3))
    for k in range(MAX_EVENTS):
        if act.size == 0:
            break
        h, esc = sample_height(dist, wr, h, rng.random(act.size))
        keep = ~esc
        act, wr, h, wt = act[keep], wr[keep], h[keep], wt[keep]
        if act.size == 0:
            break
        w_in = -wr
        if k > 0:  # next event toward wi (the first vertex is the analytic single scattering)
            l = wi[act]
            hv = w_in + l
            hn = np.linalg.norm(hv, axis=1, keepdims=True)
            m = hv / np.where(hn > 0, hn, 1.0)
            lm = np.sum(l * m, axis=-1)
            phase = d_visible(dist, w_in, m) / (4.0 * np.where(lm > 0, lm, 1.0))
            phase = np.where((lm > 0) & (hn[:, 0] > 0), phase, 0.0)
            contrib = wt * fresnel(np.clip(lm, 0.0, 1.0)) * (phase * g1_height(dist, l, h))[:, None]
            out[act] += np.where(np.isfinite(contrib), contrib, 0.0)
        m = sample_visible_normal(dist, w_in, np.clip(rng.random((act.size, 2)), 0.0, 1.0 - 1e-16))
        cos_m = np.clip(np.sum(w_in * m, axis=-1), 0.0, 1.0)
        wt = wt * fresnel(cos_m)
        wr = _reflect(w_in, m)
        wr /= np.linalg.norm(wr, axis=1, keepdims=True)
    ci = wi[:, 2]
    return out / np.where(ci > 0, ci, 1.0)[:, None]


def eval_multiple_mean(dist, fresnel, wi, wo, walks: int = 64, seed: int = 0):
    """Mean of ``walks`` independent estimates (plots and tests)."""
    rng = np.random.default_rng(seed)
    acc = np.zeros((wi.shape[0], 3))
    for _ in range(walks):
        acc += eval_multiple(dist, fresnel, wi, wo, rng)
    return acc / walks


def ms_fraction(alpha) -> float:
    """Heuristic share of the multiply scattered light for the MIS pdf: 0.7 alpha^1.6, close to
    the F = 1 energy that single-scattering GGX loses at normal incidence (0.04, 0.31, 0.69 at
    alpha 0.2, 0.5, 1; measured by tests/test_microfacet_walk.py's furnace). A weight only, see
    the module docstring: any value in [0, 1) keeps the estimate unbiased."""
    a = float(alpha)
    return float(np.clip(0.7 * a ** 1.6, 0.0, 0.7))


# ----------------------------------------------------------------------------- dielectric walk
#
# The rough dielectric interface (sec. 6.2 of the paper): the microsurface separates the outside
# (upper side, index 1) from the inside (index ``ior``); a ray on either side walks the same
# height field, seen flipped from inside (heights -h, directions -w: the uniform C1 is symmetric,
# so the inside sees the same statistics). At an intersection it samples a visible normal of its
# side, then reflects with probability F(w . m) or refracts through the facet (Snell's law with the
# relative index of its side) and changes side. A lossless interface loses nothing: every walk
# leaves on one side or the other, so R + T = 1 at every direction, which the single-scattering
# model (viewer/brdf/dielectric.py, the walk's first order) does not give at large alpha.
#
# Units: the walk moves particles, so ``sample_dielectric``'s weight and ``eval_dielectric_multiple``'s
# value carry no radiance factor (the particle density of exits, g(wi, wo) |cos wi|); radiance-mode
# callers multiply by (n_wo / n_wi)^2 (viewer/brdf/dielectric.py's convention).
# ``fresnel_rt(cos, eta)`` -> (R, T), each (N, 3), at a facet cosine seen from the side whose
# relative index (n_other / n_this) is eta; with RGB values (a thin film) the branch is chosen
# with the mean R and weighted by R / mean(R) or T / (1 - mean(R)).


def _side_normal(dist, w_in, outside, u):
    """A visible normal of w_in on its side: D_w for outside, -D_{-w}(-m) for inside."""
    s = np.where(outside, 1.0, -1.0)[:, None]
    return s * sample_visible_normal(dist, s * w_in, u)


def _side_height(dist, wr, h, outside, u):
    s = np.where(outside, 1.0, -1.0)
    hn, esc = sample_height(dist, s[:, None] * wr, s * h, u)
    return s * hn, esc


def _side_g1(dist, w, h, outside):
    """Escape probability of a ray leaving height h in direction w on the given side."""
    s = np.where(outside, 1.0, -1.0)
    return g1_height(dist, s[:, None] * w, s * h)


def _refract_facet(w_in, m, eta):
    """w_in (pointing away, on m's side) refracted through m, eta = n_t / n_i: (wt, ok)."""
    cos_i = np.sum(w_in * m, axis=-1)
    sin2_t = np.maximum(0.0, 1.0 - cos_i * cos_i) / (eta * eta)
    ok = sin2_t < 1.0
    cos_t = np.sqrt(np.maximum(0.0, 1.0 - sin2_t))
    wt = -w_in / eta[:, None] + (cos_i / eta - cos_t)[:, None] * m
    n = np.linalg.norm(wt, axis=1, keepdims=True)
    return wt / np.where(n > 0, n, 1.0), ok


def _scatter_dielectric(dist, ior, fresnel_rt, w_in, outside, wt, u2, uc):
    """One event: normal, Fresnel choice, new direction, side and weight."""
    m = _side_normal(dist, w_in, outside, np.clip(u2, 0.0, 1.0 - 1e-16))
    cos_m = np.clip(np.sum(w_in * m, axis=-1), 0.0, 1.0)
    eta = np.where(outside, ior, 1.0 / ior)
    R, T = fresnel_rt(cos_m, eta)
    P = np.clip(R.mean(axis=1), 0.0, 1.0)
    wt_ref, ok_t = _refract_facet(w_in, m, eta)
    refl = (uc < P) | ~ok_t
    w_rf = _reflect(w_in, m)
    w_rf /= np.linalg.norm(w_rf, axis=1, keepdims=True)
    wr = np.where(refl[:, None], w_rf, wt_ref)
    with np.errstate(divide="ignore", invalid="ignore"):
        gain = np.where(refl[:, None], np.where(ok_t[:, None], R / P[:, None], 1.0),
                        T / (1.0 - P)[:, None])
    gain = np.where(np.isfinite(gain), gain, 0.0)
    return wr, np.where(refl, outside, ~outside), wt * gain


def sample_dielectric(dist: Distribution, ior: float, fresnel_rt, wo, u, rng):
    """Random walk from wo (either side; wo.z > 0 is outside): (exit direction wi, particle
    weight (N, 3), events). The first normal uses ``u`` (N, 2), the rest ``rng``. Its exits
    have the density g(wi, wo) |cos wi| of the multiply scattering interface (every order)."""
    n = wo.shape[0]
    wi = np.tile(np.array([0.0, 0.0, 1.0]), (n, 1))
    weight = np.zeros((n, 3))
    events = np.zeros(n, dtype=np.int64)
    act = np.flatnonzero(wo[:, 2] != 0)
    wr = -wo[act]
    outside = wo[act, 2] > 0
    h = np.where(outside, np.inf, -np.inf)
    wt = np.ones((act.size, 3))
    for k in range(MAX_EVENTS + 1):
        if act.size == 0:
            break
        h, esc = _side_height(dist, wr, h, outside, rng.random(act.size))
        if np.any(esc):
            done = act[esc]
            wi[done] = wr[esc]
            weight[done] = wt[esc]
            events[done] = k
            keep = ~esc
            act, wr, h, wt, outside = act[keep], wr[keep], h[keep], wt[keep], outside[keep]
        if k == MAX_EVENTS or act.size == 0:
            break
        uu = u[act] if k == 0 else rng.random((act.size, 2))
        wr, outside, wt = _scatter_dielectric(dist, ior, fresnel_rt, -wr, outside, wt, uu,
                                              rng.random(act.size))
    return wi, weight, events


def _phase_dielectric(dist, ior, fresnel_rt, w_in, outside, l):
    """Density (per solid angle of l) of the event at a vertex seen from w_in on its side
    scattering into l, and the side l leaves on: reflection F D_w / (4 |l.m|), refraction
    T D_w n_t^2 |l.m| / (n_i (w.m) + n_t (l.m))^2 (Walter et al. 2007 eqs. 14, 17)."""
    same = (l[:, 2] > 0) == outside
    n_i = np.where(outside, 1.0, ior)
    n_t = np.where(outside, ior, 1.0)
    eta = n_t / n_i
    hv = np.where(same[:, None], w_in + l, -(n_i[:, None] * w_in + n_t[:, None] * l))
    hn = np.linalg.norm(hv, axis=1, keepdims=True)
    m = hv / np.where(hn > 0, hn, 1.0)
    # orient m toward the current side's normal (outside: up; inside: down)
    s = np.where(outside, 1.0, -1.0)
    m = np.where((m[:, 2] * s < 0)[:, None], -m, m)
    wm = np.sum(w_in * m, axis=-1)
    lm = np.sum(l * m, axis=-1)
    R, T = fresnel_rt(np.clip(wm, 0.0, 1.0), eta)
    dv = d_visible(dist, s[:, None] * w_in, s[:, None] * m)
    with np.errstate(divide="ignore", invalid="ignore"):
        p_r = R * (dv / (4.0 * np.abs(lm)))[:, None]
        den = n_i * wm + n_t * lm
        p_t = T * (dv * n_t * n_t * np.abs(lm) / (den * den))[:, None]
    ok = (hn[:, 0] > 0) & (wm > 0) & np.where(same, lm > 0, lm < 0)
    p = np.where(same[:, None], p_r, p_t)
    p = np.where(ok[:, None] & np.isfinite(p), p, 0.0)
    return p, np.where(same, outside, ~outside)


def eval_dielectric_multiple(dist: Distribution, ior: float, fresnel_rt, wi, wo, rng,
                             first: bool = False):
    """One-walk estimate of the multiply scattered part (orders >= 2; with ``first`` also the
    first order, for tests) of the particle BSDF g(wi, wo) (no cosine) of the rough dielectric:
    a walk from wo with next-event estimation toward wi (either side) at every vertex."""
    n = wi.shape[0]
    out = np.zeros((n, 3))
    act = np.flatnonzero((wo[:, 2] != 0) & (wi[:, 2] != 0))
    wr = -wo[act]
    outside = wo[act, 2] > 0
    h = np.where(outside, np.inf, -np.inf)
    wt = np.ones((act.size, 3))
    for k in range(MAX_EVENTS):
        if act.size == 0:
            break
        h, esc = _side_height(dist, wr, h, outside, rng.random(act.size))
        keep = ~esc
        act, wr, h, wt, outside = act[keep], wr[keep], h[keep], wt[keep], outside[keep]
        if act.size == 0:
            break
        w_in = -wr
        if k > 0 or first:
            l = wi[act]
            ph, side_l = _phase_dielectric(dist, ior, fresnel_rt, w_in, outside, l)
            c = wt * ph * _side_g1(dist, l, h, side_l)[:, None]
            out[act] += np.where(np.isfinite(c), c, 0.0)
        wr, outside, wt = _scatter_dielectric(dist, ior, fresnel_rt, w_in, outside, wt,
                                              rng.random((act.size, 2)), rng.random(act.size))
    ci = np.abs(wi[:, 2])
    return out / np.where(ci > 0, ci, 1.0)[:, None]
