"""The report card of a BRDF (``brdf-viewer check``): physical plausibility checks over a dense set
of direction pairs, the same for a ``.brdf`` file and a built-in model.

* ``finite``: no NaN or Inf at any pair (``PAIRS``: a grid with normal incidence and grazing
  angles up to 89.9 degrees, plus random pairs).
* ``non_negative``: the smallest value of f (of the finite ones).
* ``reciprocity``: the largest relative |f(L, V) - f(V, L)| over the pairs, relative to the
  larger of the two. Passes below ``RECIPROCITY_TOL`` = 1e-3: a file's GLSL runs in float32, where
  evaluating one formula with L and V exchanged rounds differently (about 1e-7 per operation), and
  a sharp lobe (exponent n) multiplies relative errors by about n (n = 1000 gives 1e-4).
* ``energy``: the directional albedo a(theta) = integral of f cos over the hemisphere, for the
  view at ``THETA_DEG`` (light and view exchange for a reciprocal BRDF). Estimated by stratified
  cosine-weighted quadrature (``N_ALBEDO`` directions); fails where it exceeds the model's bound
  (1, or a built-in model's documented ``ALBEDO_BOUND``) by more than 4 standard errors of the
  estimate. A delta model (mirror, smooth glass) has no f to integrate: its albedo is the mean
  of its sampler's weights.
* ``twin`` (a file with a numpy twin): the largest relative difference of the GLSL and numpy f
  (the twin at the float32 directions the GLSL gets), for directions up to 88 degrees from the
  normal; passes within 1e-4 relative + 1e-6 absolute (the GLSL runs in float32: the tolerance of
  the built-in models' twins). Closer to the horizon a microfacet BRDF's 1 / cos factors and the
  cancellation in L + V for nearly opposite directions make float32 rounding errors of 1e-4 and more.
* ``sampling`` (a model with a sampler of its own): the chi-square test of the sampler against
  its pdf (``viewer.brdf.chi2``, at a view 40 degrees from the normal) where a pdf exists; a
  file's ``isFunc`` sampler, which gives its pdf only where it samples, is tested instead for
  its estimate of the albedo (the mean weight f cos / pdf against the quadrature's, a z test)
  and for its pdf being the density of its samples (a chi-square over equal-area bins of each
  bin's solid angle estimated as the mean of 1 / pdf there, ``_pdf_consistency``). Passes when
  the p-value is above ``P_MIN`` = 0.001.
"""

from __future__ import annotations

import math

import numpy as np

THETA_DEG = (0, 5, 10, 15, 20, 25, 30, 35, 40, 45, 50, 55, 60, 65, 70, 75, 80, 85, 89)
GRID_THETA = (0.0, 1.0, 10.0, 25.0, 40.0, 55.0, 70.0, 80.0, 85.0, 89.0, 89.9)
GRID_PHI = (0.0, 30.0, 90.0, 135.0, 180.0, 250.0)
N_RANDOM = 6000
N_ALBEDO = 64 * 64
RECIPROCITY_TOL = 1e-3
TWIN_RTOL, TWIN_ATOL = 1e-4, 1e-6
TWIN_MIN_COS = 0.035  # 88 degrees
P_MIN = 1e-3
N_SAMPLING = 100_000


def _dir(theta_deg, phi_deg):
    t, f = np.radians(theta_deg), np.radians(phi_deg)
    return np.stack([np.sin(t) * np.cos(f), np.sin(t) * np.sin(f), np.cos(t)], axis=-1)


def pairs(seed: int = 0) -> tuple[np.ndarray, np.ndarray]:
    """(wi, wo) of the checks: every pair of the grid directions, plus random upper pairs."""
    grid = [_dir(0.0, 0.0)] + [_dir(t, f) for t in GRID_THETA[1:] for f in GRID_PHI]
    g = np.array(grid)
    a, b = np.meshgrid(np.arange(len(g)), np.arange(len(g)), indexing="ij")
    wi, wo = g[a.ravel()], g[b.ravel()]
    rng = np.random.default_rng(seed)

    def rand(n):
        z = rng.random(n)
        phi = 2 * np.pi * rng.random(n)
        r = np.sqrt(np.maximum(0.0, 1 - z * z))
        return np.stack([r * np.cos(phi), r * np.sin(phi), z], axis=1)

    return np.concatenate([wi, rand(N_RANDOM)]), np.concatenate([wo, rand(N_RANDOM)])


def _stratified_cosine(n_side: int, seed: int = 1):
    rng = np.random.default_rng(seed)
    i, j = np.meshgrid(np.arange(n_side), np.arange(n_side), indexing="ij")
    u = np.stack([(i.ravel() + rng.random(i.size)) / n_side, (j.ravel() + rng.random(i.size)) / n_side], axis=1)
    r = np.sqrt(u[:, 0])
    phi = 2 * np.pi * u[:, 1]
    return np.stack([r * np.cos(phi), r * np.sin(phi), np.sqrt(np.maximum(0.0, 1 - u[:, 0]))], axis=1)


def albedo_curve(model, p, thetas=THETA_DEG):
    """(albedo (T, 3), standard error (T, 3)) for the view at each theta: the mean of f pi over
    stratified cosine-weighted light directions (the standard error counts them as independent,
    which over-states it for a stratified set: a conservative noise)."""
    n_side = int(round(math.sqrt(N_ALBEDO)))
    wi = _stratified_cosine(n_side)
    n = len(wi)
    alb, err = [], []
    wos = [_dir(float(t), 0.0) for t in thetas]
    f = np.asarray(model.eval(p, np.tile(wi, (len(wos), 1)), np.repeat(np.array(wos), n, axis=0)), float)
    for k in range(len(wos)):
        v = f[k * n:(k + 1) * n] * np.pi
        v = np.where(np.isfinite(v), v, 0.0)
        alb.append(v.mean(axis=0))
        err.append(v.std(axis=0) / math.sqrt(n))
    return np.array(alb), np.array(err)


def _delta_albedo(model, p, thetas=THETA_DEG, n=20000):
    rng = np.random.default_rng(2)
    alb, err = [], []
    for t in thetas:
        wo = np.broadcast_to(_dir(float(t), 0.0), (n, 3))
        _, w, _ = model.sample(p, wo, rng.random((n, 2)))
        w = np.where(np.isfinite(w), w, 0.0)
        alb.append(w.mean(axis=0))
        err.append(w.std(axis=0) / math.sqrt(n))
    return np.array(alb), np.array(err)


def _rel(a, b, floor):
    return np.abs(a - b) / np.maximum(np.maximum(np.abs(a), np.abs(b)), floor)


def report(model, p, name: str) -> dict:
    """The report card of ``model`` at parameters ``p`` as the contract's JSON object."""
    from viewer.brdf import FileModel

    checks: dict = {}
    wi, wo = pairs()
    delta = model.is_delta(p)
    f = np.asarray(model.eval(p, wi, wo), float)
    fin = np.isfinite(f)
    bad = int(np.count_nonzero(~np.all(fin, axis=1)))
    checks["finite"] = {"pass": bad == 0}
    if bad:
        k = int(np.flatnonzero(~np.all(fin, axis=1))[0])
        checks["finite"].update(count=bad, example={"wi": wi[k].tolist(), "wo": wo[k].tolist()})
    fmin = float(np.min(np.where(fin, f, np.inf))) if np.any(fin) else 0.0
    fmin = 0.0 if not math.isfinite(fmin) else fmin
    checks["non_negative"] = {"pass": fmin >= 0.0, "min": fmin}

    fr = np.asarray(model.eval(p, wo, wi), float)
    ok = np.all(fin & np.isfinite(fr), axis=1)
    scale = float(np.max(np.abs(f[ok]))) if np.any(ok) else 1.0
    # below 1e-6 of the largest value a difference is float32 rounding of nearly nothing
    rel = _rel(f[ok], fr[ok], 1e-6 * max(scale, 1e-30)) if np.any(ok) else np.zeros(1)
    max_rel = float(np.max(rel)) if rel.size else 0.0
    checks["reciprocity"] = {"pass": max_rel <= RECIPROCITY_TOL, "max_rel_error": max_rel}
    if not model.spec.reciprocal:
        checks["reciprocity"]["why"] = model.spec.reciprocal_why

    alb, err = (_delta_albedo if delta else albedo_curve)(model, p)
    bound = float(model.hook("ALBEDO_BOUND", 1.0))
    over = alb - 4.0 * err - bound
    checks["energy"] = {"pass": bool(np.all(over <= 1e-6)), "max_albedo": float(np.max(alb)),
                        "theta_deg": list(THETA_DEG), "albedo": [[float(x) for x in row] for row in alb]}
    if bound != 1.0:
        checks["energy"].update(bound=bound, why=model.hook("ALBEDO_BOUND_WHY", ""))

    if isinstance(model, FileModel) and model.twin is not None:
        # the twin at the float32 directions the GLSL received; pairs within TWIN_MIN_COS of the
        # horizon are left out: there 1 / cos factors and the cancellation in L + V for nearly
        # opposite directions turn float32 rounding into relative errors of 1e-4 and more
        wi32, wo32 = wi.astype(np.float32).astype(float), wo.astype(np.float32).astype(float)
        ft = np.asarray(model.twin_eval(p, wi32, wo32), float)
        inner = (wi[:, 2] >= TWIN_MIN_COS) & (wo[:, 2] >= TWIN_MIN_COS)
        both = np.all(fin & np.isfinite(ft), axis=1) & inner
        diff = np.abs(f - ft)
        tol = TWIN_RTOL * np.abs(ft) + TWIN_ATOL
        good = both & np.all(diff <= tol, axis=1)
        rel_t = float(np.max(diff[both] / (np.abs(ft[both]) + TWIN_ATOL))) if np.any(both) else 0.0
        checks["twin"] = {"pass": bool(np.all(good[inner]) and np.all(both[inner] == np.all(fin[inner], axis=1))),
                          "max_rel_error": rel_t}

    sampler = _sampler_kind(model, p)
    if sampler is not None:
        checks["sampling"] = _sampling(model, p, sampler, alb, err)
    return {"file": name, "pass": all(c["pass"] for c in checks.values()), "checks": checks}


def _sampler_kind(model, p):
    from viewer.brdf import FileModel

    if isinstance(model, FileModel):
        return {"numpy twin": "pdf", "isFunc": "weights"}.get(model.sampled_by)
    if model.has_delta(p):
        return None  # a discrete lobe has no density to histogram
    return "pdf"


def _sampling(model, p, kind, alb, err) -> dict:
    rng = np.random.default_rng(5)
    if kind == "pdf":
        from viewer.brdf.chi2 import chi2_test

        wo = _dir(40.0, 0.0)
        res = chi2_test(model, p, wo, N_SAMPLING, rng, P_MIN, sphere=bool(model.spec.transmissive))
        out = {"pass": bool(res.ok), "p_value": float(res.p_value)}
        if not res.ok and res.message:
            out["message"] = str(res.message)
        return out
    # the isFunc sampler: its mean weight estimates the albedo the quadrature gives
    k = THETA_DEG.index(40)
    n = N_SAMPLING
    wo = np.broadcast_to(_dir(40.0, 0.0), (n, 3))
    _, w, pdf = model.sample(p, wo, rng.random((n, 2)))
    w = np.where(np.isfinite(w), w, 0.0)
    mean, se = w.mean(axis=0), w.std(axis=0) / math.sqrt(n)
    z = np.abs(mean - alb[k]) / np.sqrt(se ** 2 + err[k] ** 2 + 1e-30)
    zmax = float(np.max(z))
    p_albedo = float(math.erfc(zmax / math.sqrt(2.0)))
    p_albedo = min(1.0, 3.0 * p_albedo)  # three channels (Bonferroni)
    p_density, bins = _pdf_consistency(model, p, wo[0], *model.sample(p, wo, rng.random((n, 2)))[:2])
    p_value = min(1.0, 2.0 * min(p_albedo, p_density))  # both tests (Bonferroni)
    return {"pass": p_value > P_MIN, "p_value": p_value, "albedo_p_value": p_albedo,
            "density_p_value": p_density, "density_bins": bins,
            "mean_weight": [float(x) for x in mean], "albedo": [float(x) for x in alb[k]]}


DENSITY_BANDS, DENSITY_SECTORS, DENSITY_MIN_COUNT = 8, 16, 50


def _pdf_consistency(model, p, wo, wi, w) -> tuple[float, int]:
    """Whether a sampler's pdf is the density of its samples where f is not 0, from its weights
    w = f cos / pdf: for any region A, E[1_A(wi) w] = the integral of f cos over A. Over equal-area
    bins of the hemisphere (DENSITY_BANDS in cos theta x DENSITY_SECTORS in phi), each bin's
    estimate (luminance) against the bin's integral by midpoint quadrature (16 x 16 points; its
    error, taken as the difference from 8 x 8, joins the variance), a z value from the samples'
    own variance; the sum of the squares is chi-square distributed with one degree of freedom
    per bin (bins with at least DENSITY_MIN_COUNT samples: the albedo test catches a sampler that
    misses where f is not 0). A wrong pdf scales each bin by (true density / reported pdf).
    (p-value, bins used)."""
    from scipy import stats

    from viewer.brdf.sampling import luminance

    wi = np.asarray(wi, float)
    n = len(wi)
    lw = luminance(np.where(np.isfinite(w), w, 0.0))
    ok = np.all(np.isfinite(wi), axis=1) & (wi[:, 2] > 0)
    band = np.minimum((np.clip(wi[:, 2], 0.0, 1.0) * DENSITY_BANDS).astype(int), DENSITY_BANDS - 1)
    sector = np.minimum(((np.arctan2(wi[:, 1], wi[:, 0]) % (2 * np.pi)) / (2 * np.pi) * DENSITY_SECTORS).astype(int),
                        DENSITY_SECTORS - 1)
    b = (band * DENSITY_SECTORS + sector)[ok]
    nb = DENSITY_BANDS * DENSITY_SECTORS
    count = np.bincount(b, minlength=nb)
    s1 = np.bincount(b, weights=lw[ok], minlength=nb) / n
    s2 = np.bincount(b, weights=lw[ok] ** 2, minlength=nb) / n
    var = np.maximum(s2 - s1 ** 2, 0.0) / n

    def quadrature(k):  # k x k midpoints per bin, in (cos theta, phi): equal solid angle each
        c = (np.arange(DENSITY_BANDS * k) + 0.5) / (DENSITY_BANDS * k)
        ph = (np.arange(DENSITY_SECTORS * k) + 0.5) / (DENSITY_SECTORS * k) * 2 * np.pi
        C, P = np.meshgrid(c, ph, indexing="ij")
        S = np.sqrt(1.0 - C * C)
        d = np.stack([S * np.cos(P), S * np.sin(P), C], axis=-1).reshape(-1, 3)
        f = np.asarray(model.eval(p, d, np.broadcast_to(wo, d.shape)), float)
        val = luminance(np.where(np.isfinite(f), np.maximum(f, 0.0), 0.0)) * d[:, 2] * (2 * np.pi / len(d))
        return val.reshape(DENSITY_BANDS, k, DENSITY_SECTORS, k).sum(axis=(1, 3)).ravel()

    fine, coarse = quadrature(16), quadrature(8)
    var = var + (fine - coarse) ** 2
    use = (count >= DENSITY_MIN_COUNT) & (var > 0)
    if not np.any(use):
        return 0.0, 0
    stat = float(np.sum((s1[use] - fine[use]) ** 2 / var[use]))
    return float(stats.chi2.sf(stat, int(use.sum()))), int(use.sum())
