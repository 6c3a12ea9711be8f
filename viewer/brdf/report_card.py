"""The report card of a BRDF (``brdf-viewer check``): physical plausibility checks over a dense set
of direction pairs, the same for a ``.brdf`` file and a built-in model.

* ``finite``: no NaN or Inf at any pair (``pairs``: a grid with normal incidence and grazing
  angles up to 89.9 degrees, plus random pairs); the first such pair is the ``example``.
* ``non_negative``: the smallest value of f (of the finite ones).
* ``reciprocity``: f(L, V) against f(V, L) over ``pairs`` and ``near_mirror_pairs`` (light
  directions 1e-4 to 0.5 rad from the mirror direction and from the view, where a sharp lobe is,
  which uniform pairs almost never reach). A pair fails when the difference exceeds
  ``RECIPROCITY_TOL`` = 1e-3 of the larger value plus ``ROUNDING_STEPS`` = 2 times how much f
  moves when both directions are lengthened by two units in the last place of the arithmetic f
  runs in (float32 for a file's GLSL): a rounding of the formula's dot products moves f by that
  much, so a sharp lobe whose formula rounds differently with L and V exchanged passes (c ** n
  with c near 1 moves by n units), while an asymmetry of the formula does not. The constants'
  measurements are beside them: a 2% asymmetry (of a Lambert, or of a Phong lobe of exponent up
  to 12,000) fails; ``tolerance`` is RECIPROCITY_TOL, ``rounding`` the largest rounding allowance
  (relative) that any pair got, and a failing check gives an ``example`` pair with both values.
* ``energy``: the directional albedo a(theta) = integral of f cos over the upper hemisphere, for
  the view at ``THETA_DEG`` (light and view exchange for a reciprocal BRDF), by ``albedo_curve``:
  multiple importance sampling (the balance heuristic) of cosine-weighted directions, a table of
  f cos around the mirror direction (rings from 1e-4 rad to pi, refined where f cos varies) and
  the model's own sampler where it has a pdf for every direction (built-in models, a file's
  numpy twin), with the smallest f times cos as a control variate; ``N_REPLICAS`` independent
  replicas, each stratified, give the estimate (their mean) and its ``noise`` (the standard
  error of that mean: stratified points taken as independent would overstate it, 8 times for
  BRDF Explorer's published Cook-Torrance, and a margin of 4 such errors hides an excess). Fails
  where the albedo exceeds the model's bound (1, or a built-in model's documented
  ``ALBEDO_BOUND``) by more than the ``tolerance``, ``ENERGY_SIGMAS`` = 4 noises plus
  ``ENERGY_FLOOR`` = 1e-4 of the bound (float32 and pi written to 5 decimals move an albedo of 1
  by under 1e-6). ``albedo``, ``noise`` and ``tolerance`` are RGB rows, one per angle. A delta
  model (mirror, smooth glass) has no f to integrate: its albedo is the mean of its sampler's
  weights (independent samples: the plain standard error); a model with delta and smooth lobes
  (a coat on a mirror) adds its delta lobes' mean weight to the smooth lobes' integral.
* ``twin`` (a file with a numpy twin): the largest relative difference of the GLSL and numpy f
  (the twin at the float32 directions the GLSL gets), for directions up to 88 degrees from the
  normal; passes within 1e-4 relative + 1e-6 absolute (the GLSL runs in float32: the tolerance of
  the built-in models' twins). Closer to the horizon a microfacet BRDF's 1 / cos factors and the
  cancellation in L + V for nearly opposite directions make float32 rounding errors of 1e-4 and more.
* ``sampling`` (a model with a sampler of its own): the chi-square test of the sampler against
  its pdf (``viewer.brdf.chi2``, at a view 40 degrees from the normal) where a pdf exists; a
  file's ``isFunc`` sampler, which gives its pdf only where it samples, is tested instead for
  its estimate of the albedo (the mean weight f cos / pdf against ``albedo_curve``'s, a z test)
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
#: reciprocity: a pair fails above RECIPROCITY_TOL relative plus ROUNDING_STEPS times the change of
#: f when both directions are lengthened or shortened by two float32 units in the last place
#: (``reciprocity``). Measured on files (float32 GLSL): a Cook-Torrance that takes V.H where L.H
#: is meant differs by up to 5e-4 at grazing pairs (1e-3 leaves a factor 2); a Phong lobe whose
#: R = normalize(2 (N.V) N - V) rounds differently from its exchange differs by 2.4e-7 n (2.4e-3
#: at n = 10^4, 2.4e-2 at 10^5) where the rounding term allows 1.5e-6 n (6 times more) at the
#: worst pairs; a 2% asymmetry (of a Lambert, or of a Phong lobe n = 1000) is 20 times
#: RECIPROCITY_TOL and found. The smallest asymmetry found: 1e-3 where f is smooth, 1e-3 +
#: 1.5e-6 n in a lobe of exponent n (a 2% one up to n = 12,000); in a lobe so sharp that float32
#: rounding alone moves f by percents (Beckmann m = 0.001: 12% per unit in the last place of
#: N.H) it is tested only to that precision.
RECIPROCITY_TOL, ROUNDING_STEPS = 1e-3, 2.0
#: the views and angular distances of ``near_mirror_pairs``
NEAR_THETA = (0.0, 10.0, 30.0, 50.0, 70.0, 85.0, 89.0)
NEAR_PHI = (0.0, 135.0)
NEAR_ALPHA = tuple(np.geomspace(1e-4, 0.5, 14))
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


def _cosine_dirs(u):
    """Cosine-weighted directions (Malley's method: the unit disk lifted to the hemisphere)."""
    r = np.sqrt(u[:, 0])
    phi = 2 * np.pi * u[:, 1]
    return np.stack([r * np.cos(phi), r * np.sin(phi), np.sqrt(np.maximum(0.0, 1 - u[:, 0]))], axis=1)


# ----------------------------------------------------------------------------- the directional albedo

#: independent randomized replicas of the albedo estimate: the noise is the standard error of their
#: means (32: the estimated standard error is itself within about 13% of the true one, and a
#: model exactly at its bound exceeds 4 of them at one of the 19 angles with probability 0.35%
#: under Student's t with 31 degrees of freedom, 0.06% under the normal law; measured over 2,500
#: estimates of 44 BRDFs against a fine quadrature, the errors over the noise have an rms of 1.04)
N_REPLICAS = 32
#: per replica and view: cosine-weighted directions (a jittered 12 x 12 grid: the mixture's
#: component that reaches every direction of the hemisphere), 512 directions drawn from the table
#: of f cos (stratified in its CDF) and from the model's own sampler (a jittered 12 x 12 grid of
#: u): 32 x 800 evaluations per view, 0.3 to 2 s for a card
N_COSINE_SIDE, N_TABLE, N_OWN_SIDE = 12, 512, 12
#: the table: rings around the mirror direction R, the first a cap of ALPHA_MIN radians, then
#: geometric out to pi (ratio (pi / ALPHA_MIN) ** (1 / 63) = 1.18: each ring 18% wider than the
#: one inside it, so a lobe of any width from 1e-4 rad to 1 rad spans a dozen rings), times
#: TABLE_SECTORS sectors in azimuth around R. 1e-4 rad is 40 times narrower than the sharpest lobe
#: of the built-in models (microfacet alpha 0.0025: half-vector width 0.0025, about 0.005 in
#: the light direction) and 20 times the float32 spacing of unit vectors' components near 1.
TABLE_RINGS, TABLE_SECTORS, ALPHA_MIN = 64, 32, 1e-4
#: a cell of the table whose f cos (at its 4 corners and its centre) varies by more than a factor
#: REFINE_RATIO is refined into REFINE x REFINE sub-cells, each weighted like the cells, by the
#: largest f cos at its corners and centre (plus a tenth of the cell's share, so a sub-cell whose
#: five points miss a peak keeps some probability); only cells where (largest - smallest) f cos
#: times their solid angle is at least REFINE_MIN_SHARE of the table's weight are refined: in
#: the others a better split moves too little probability to matter
REFINE, REFINE_RATIO, REFINE_MIN_SHARE = 4, 2.0, 1e-4
#: the energy check fails where the estimate exceeds the bound by more than ENERGY_SIGMAS standard
#: errors (the noise above) plus ENERGY_FLOOR: the float32 GLSL (1e-7 relative per operation) and
#: pi written with 5 or 6 decimals (1 / 3.14159 is 8.4e-7 high) move an albedo of 1 by less than
#: 1e-6; 1e-4 of the bound is far below any error of a formula and too little light to see
ENERGY_SIGMAS, ENERGY_FLOOR = 4.0, 1e-4


def _frame(r):
    """Two unit vectors that make (t1, t2, r) a right-handed orthonormal frame."""
    a = np.array([0.0, 1.0, 0.0]) if abs(r[1]) < 0.9 else np.array([1.0, 0.0, 0.0])
    t1 = np.cross(a, r)
    t1 /= np.linalg.norm(t1)
    return t1, np.cross(r, t1)


def _cosine_grid(side, rng, copies=1):
    """``copies`` independently jittered side x side grids of points in the unit square, one after
    the other."""
    i, j = np.meshgrid(np.arange(side), np.arange(side), indexing="ij")
    i, j = np.tile(i.ravel(), copies), np.tile(j.ravel(), copies)
    return np.stack([(i + rng.random(i.size)) / side, (j + rng.random(i.size)) / side], axis=1)


def _finite_rgb(f):
    f = np.asarray(f, float)
    if f.ndim == 1:
        f = np.repeat(f[:, None], 3, axis=1)
    return np.where(np.isfinite(f), f, 0.0)


class _MirrorTable:
    """A piecewise-constant density over the sphere on cells around the mirror direction R of
    the view (``TABLE_RINGS`` rings x ``TABLE_SECTORS`` sectors, each split into ``REFINE`` x
    ``REFINE`` sub-cells of equal solid angle), proportional to a bound on f cos in each cell
    found from f at its corners and centre and, where it varies, at its sub-cells' centres."""

    def __init__(self, fcos, wo):
        self.r = np.array([-wo[0], -wo[1], wo[2]])
        self.t1, self.t2 = _frame(self.r)
        alpha = np.concatenate([[0.0], np.geomspace(ALPHA_MIN, np.pi, TABLE_RINGS)])
        self.s_edge = 2.0 * np.sin(alpha / 2.0) ** 2  # s = 1 - cos(angle from R): solid angle ds dphi
        self.s_edge[-1] = 2.0
        nr, ns, k = TABLE_RINGS, TABLE_SECTORS, REFINE
        dphi = 2 * np.pi / ns
        area = np.diff(self.s_edge)[:, None] * dphi * np.ones((1, ns))  # (rings, sectors)
        phi_c = np.arange(ns) * dphi
        S, P = np.meshgrid(self.s_edge, phi_c, indexing="ij")  # corners
        Sm, Pm = np.meshgrid(0.5 * (self.s_edge[:-1] + self.s_edge[1:]), phi_c + 0.5 * dphi, indexing="ij")
        g = fcos(np.concatenate([self.direction(S.ravel(), P.ravel()), self.direction(Sm.ravel(), Pm.ravel())]))
        gc = g[:S.size].reshape(nr + 1, ns)
        gm = g[S.size:].reshape(nr, ns)
        pts = np.stack([gc[:-1], gc[1:], np.roll(gc[:-1], -1, axis=1), np.roll(gc[1:], -1, axis=1), gm])
        hi, lo = pts.max(axis=0), pts.min(axis=0)
        coarse = hi * area
        fine = np.repeat(np.repeat(coarse / (k * k), k, axis=0), k, axis=1)  # (nr k, ns k)
        total = coarse.sum()
        if total > 0:
            refine = (hi > REFINE_RATIO * lo) & ((hi - lo) * area >= REFINE_MIN_SHARE * total)
            ri, si = np.nonzero(refine)
            if ri.size:  # each refined cell: f cos at the corners and centres of its sub-cells
                c = np.arange(k + 1) / k
                m = (np.arange(k) + 0.5) / k
                s0, ds = self.s_edge[ri][:, None, None], np.diff(self.s_edge)[ri][:, None, None]
                p0 = si[:, None, None] * dphi

                def at(x):  # f cos at (s0 + ds x_i, p0 + dphi x_j) of every refined cell
                    ss, pp = np.broadcast_arrays(s0 + ds * x[None, :, None], p0 + dphi * x[None, None, :])
                    return fcos(self.direction(ss.ravel(), pp.ravel())).reshape(ri.size, x.size, x.size)

                gc, gm = at(c), at(m)
                sub_hi = np.max(np.stack([gc[:, :-1, :-1], gc[:, 1:, :-1], gc[:, :-1, 1:], gc[:, 1:, 1:], gm]), axis=0)
                share = (area[ri, si] / (k * k))[:, None, None]
                floor = 0.1 * (coarse[ri, si] / (k * k))[:, None, None]
                fine.reshape(nr, k, ns, k)[ri, :, si, :] = sub_hi * share + floor
        self.ok = bool(total > 0)
        w = fine.ravel()
        self.cdf = np.cumsum(w) / max(w.sum(), 1e-300)
        self.prob = w / max(w.sum(), 1e-300)
        self.fine_area = np.repeat(np.diff(self.s_edge) / k, k)[:, None] * (dphi / k)  # (nr k, 1)

    def direction(self, s, phi):
        ca = 1.0 - s
        sa = np.sqrt(np.maximum(0.0, s * (2.0 - s)))
        return (ca[:, None] * self.r + (sa * np.cos(phi))[:, None] * self.t1
                + (sa * np.sin(phi))[:, None] * self.t2)

    def sample(self, u):
        k, ns = REFINE, TABLE_SECTORS * REFINE
        cell = np.minimum(np.searchsorted(self.cdf, u[:, 0] * self.cdf[-1], side="right"), self.cdf.size - 1)
        fr, fs = cell // ns, cell % ns
        ring, sub = fr // k, fr % k
        ds = np.diff(self.s_edge)[ring] / k
        s = self.s_edge[ring] + ds * (sub + u[:, 1])
        phi = (fs + u[:, 2]) * (2 * np.pi / ns)
        return self.direction(s, phi)

    def pdf(self, wi):
        k, ns = REFINE, TABLE_SECTORS * REFINE
        d = wi - self.r
        s = 0.5 * np.einsum("ij,ij->i", d, d)  # 1 - cos, without the cancellation of 1 - wi.r
        phi = np.arctan2(wi @ self.t2, wi @ self.t1) % (2 * np.pi)
        ring = np.clip(np.searchsorted(self.s_edge, s, side="right") - 1, 0, TABLE_RINGS - 1)
        ds = np.diff(self.s_edge)[ring] / k
        sub = np.clip(((s - self.s_edge[ring]) / ds).astype(int), 0, k - 1)
        fs = np.clip((phi / (2 * np.pi) * ns).astype(int), 0, ns - 1)
        fr = ring * k + sub
        return self.prob[fr * ns + fs] / self.fine_area[fr, 0]


def _own_sampler(model, p):
    """Whether the model's own sampler (with a pdf for any direction) joins the mixture: a built-in
    model without delta lobes, or a file whose numpy twin samples (an ``isFunc`` sampler gives its
    pdf only at the directions it draws, so the balance heuristic cannot weigh it)."""
    from viewer.brdf import FileModel

    if isinstance(model, FileModel):
        return model.sampled_by == "numpy twin"
    return not model.has_delta(p)


def albedo_curve(model, p, thetas=THETA_DEG, seed: int = 1):
    """(albedo (T, 3), noise (T, 3)): the directional albedo, the integral of f cos over the
    upper hemisphere, for the view at each theta, and one standard error of it.

    Each of ``N_REPLICAS`` independent replicas is a multi-sample importance-sampling estimate
    with the balance heuristic (Veach 1997, sec. 9.2) over three strategies: cosine-weighted
    directions, the table of f cos around the mirror direction (``_MirrorTable``) and the
    model's own sampler (``_own_sampler``); within a replica each strategy's directions are
    stratified, so they are not independent of each other, but the replicas are: the estimate is
    the mean of the replicas' and its noise the standard error of that mean. The smallest f the
    table saw times cos is a control variate (its integral is known), so a constant f is exact.
    A smooth model's delta lobes (a layered coat on a mirror) add the mean of their sampler
    weights."""
    rng = np.random.default_rng(seed)
    own = _own_sampler(model, p)
    discrete = model.has_delta(p) and not model.is_delta(p)
    alb, noise = [], []
    for t in thetas:
        wo = _dir(float(t), 0.0)
        lowest = [np.full(3, np.inf)]

        def fcos(wi):
            f = _finite_rgb(model.eval(p, wi, np.broadcast_to(wo, wi.shape)))
            if np.any(wi[:, 2] > 0):
                lowest[0] = np.minimum(lowest[0], f[wi[:, 2] > 0].min(axis=0))
            return np.max(np.abs(f), axis=1) * np.maximum(wi[:, 2], 0.0)

        table = _MirrorTable(fcos, wo)
        # the control variate: beta cos, whose integral is beta pi, with beta the smallest f the
        # table saw (fixed before any random direction is drawn, so the estimate stays unbiased):
        # a constant f (a Lambertian) is integrated exactly, and a lobe over a diffuse floor
        # keeps only the lobe's noise
        beta = np.where(np.isfinite(lowest[0]), np.maximum(lowest[0], 0.0), 0.0)
        nc, nm = N_COSINE_SIDE ** 2, (N_OWN_SIDE ** 2 if own else 0)
        nt = N_TABLE if table.ok else 0
        k = N_REPLICAS  # every replica's directions at once, replica by replica within each strategy
        parts = [_cosine_dirs(_cosine_grid(N_COSINE_SIDE, rng, k))]
        rep_of = [np.repeat(np.arange(k), nc)]
        if nt:
            u0 = ((np.arange(nt)[None, :] + rng.random((k, nt))) / nt).ravel()
            parts.append(table.sample(np.column_stack([u0, rng.random((k * nt, 2))])))
            rep_of.append(np.repeat(np.arange(k), nt))
        if nm:
            wi_m = np.asarray(model.sample(p, np.broadcast_to(wo, (k * nm, 3)).copy(),
                                           _cosine_grid(N_OWN_SIDE, rng, k))[0], float)
            parts.append(np.where(np.all(np.isfinite(wi_m), axis=1)[:, None], wi_m, [0.0, 0.0, -1.0]))
            rep_of.append(np.repeat(np.arange(k), nm))
        wi = np.concatenate(parts)
        rep_of = np.concatenate(rep_of)
        up = wi[:, 2] > 0
        wob = np.broadcast_to(wo, wi.shape)
        mix = nc * np.maximum(wi[:, 2], 0.0) / np.pi
        if nt:
            mix = mix + nt * table.pdf(wi)
        if nm:
            pdf = np.asarray(model.pdf(p, wi, wob), float)
            mix = mix + nm * np.where(up & np.isfinite(pdf), pdf, 0.0)
        f = _finite_rgb(model.eval(p, wi, wob))
        with np.errstate(divide="ignore", invalid="ignore"):
            c = np.where((up & (mix > 0))[:, None], (f - beta) * wi[:, 2:3] / mix[:, None], 0.0)
        per = np.stack([np.bincount(rep_of, weights=c[:, j], minlength=N_REPLICAS) for j in range(3)], axis=1)
        per = per + beta * np.pi
        a, e2 = per.mean(axis=0), per.var(axis=0, ddof=1) / N_REPLICAS
        if discrete:
            da, de = _delta_part(model, p, wo, rng)
            a, e2 = a + da, e2 + de ** 2
        alb.append(a)
        noise.append(np.sqrt(e2))
    return np.array(alb), np.array(noise)


def _delta_part(model, p, wo, rng, n=20000):
    """The mean weight of a mixed model's samples that drew a delta lobe (independent samples:
    the plain standard error is honest) and its standard error."""
    wi, w, _, disc = model.sample_lobe(p, np.broadcast_to(wo, (n, 3)).copy(), rng.random((n, 2)))
    w = _finite_rgb(w) * (np.asarray(disc, bool) & (np.asarray(wi)[:, 2] > 0))[:, None]
    return w.mean(axis=0), w.std(axis=0) / math.sqrt(n)


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


def _rows(a):
    return [[float(x) for x in row] for row in a]


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

    checks["reciprocity"] = reciprocity(model, p, wi, wo, f)
    if not model.spec.reciprocal:
        checks["reciprocity"]["why"] = model.spec.reciprocal_why

    alb, err = (_delta_albedo if delta else albedo_curve)(model, p)
    bound = float(model.hook("ALBEDO_BOUND", 1.0))
    tol = ENERGY_SIGMAS * err + ENERGY_FLOOR * bound
    checks["energy"] = {"pass": bool(np.all(alb - bound <= tol)), "max_albedo": float(np.max(alb)),
                        "bound": bound, "theta_deg": list(THETA_DEG), "albedo": _rows(alb), "noise": _rows(err),
                        "tolerance": _rows(tol)}
    if bound != 1.0:
        checks["energy"]["why"] = model.hook("ALBEDO_BOUND_WHY", "")

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


def near_mirror_pairs() -> tuple[np.ndarray, np.ndarray]:
    """(wi, wo) of the reciprocity check besides ``pairs``: for views at ``NEAR_THETA`` x
    ``NEAR_PHI``, light directions at ``NEAR_ALPHA`` from the mirror direction and from the view
    itself in 8 azimuths (upper ones only), where a sharp lobe is: uniform pairs rarely land in
    a lobe of width 0.01 (about 1 in 10^5), so an asymmetry confined to it would go unseen."""
    out_i, out_o = [], []
    b = np.arange(8) * (np.pi / 4) + 0.3
    for t in NEAR_THETA:
        for ph in NEAR_PHI:
            wo = _dir(t, ph)
            for c in (np.array([-wo[0], -wo[1], wo[2]]), wo):
                t1, t2 = _frame(c)
                a = np.asarray(NEAR_ALPHA)[:, None]
                d = (np.cos(a)[..., None] * c + np.sin(a)[..., None]
                     * (np.cos(b)[None, :, None] * t1 + np.sin(b)[None, :, None] * t2)).reshape(-1, 3)
                d = d[d[:, 2] > 0]
                out_i.append(d)
                out_o.append(np.broadcast_to(wo, d.shape))
    return np.concatenate(out_i), np.concatenate(out_o)


def _rounding_unit(model) -> float:
    """Two units in the last place of 1 in the arithmetic f is evaluated in: a file's GLSL runs in
    float32, the built-in models' numpy in float64."""
    from viewer.brdf import FileModel

    return 2.0 ** -22 if isinstance(model, FileModel) else 2.0 ** -51


def reciprocity(model, p, wi, wo, f) -> dict:
    """The reciprocity check over ``pairs`` (f given) and ``near_mirror_pairs``: a pair fails when
    |f(L, V) - f(V, L)| exceeds RECIPROCITY_TOL of the larger (or of 1e-6 of the largest f: below
    that a difference is rounding of nearly nothing) plus ROUNDING_STEPS times how much f moves
    when both directions are lengthened or shortened by ``_rounding_unit``:
    the change a rounding of the formula's dot products makes (exact arithmetic would not see it;
    c ** n with c near 1 moves by n times the rounding unit), so a sharp lobe whose formula rounds
    differently with L and V exchanged keeps passing, while an asymmetry of the formula does not."""
    ni, no = near_mirror_pairs()
    wi, wo = np.concatenate([wi, ni]), np.concatenate([wo, no])
    f = np.concatenate([f, np.asarray(model.eval(p, ni, no), float)])
    fr = np.asarray(model.eval(p, wo, wi), float)
    eps = _rounding_unit(model)
    moved = np.zeros_like(f)
    for s in (1.0 + eps, 1.0 - eps):
        for a, b, base in ((wi, wo, f), (wo, wi, fr)):
            with np.errstate(invalid="ignore"):  # inf - inf: not finite, no allowance
                d = np.abs(np.asarray(model.eval(p, a * s, b * s), float) - base)
            moved = np.maximum(moved, np.where(np.isfinite(d), d, 0.0))
    ok = np.all(np.isfinite(f) & np.isfinite(fr), axis=1)
    if not np.any(ok):
        return {"pass": True, "max_rel_error": 0.0, "tolerance": RECIPROCITY_TOL, "rounding": 0.0}
    f, fr, moved = f[ok], fr[ok], moved[ok]
    scale = max(float(np.max(np.abs(f))), 1e-30)
    denom = np.maximum(np.maximum(np.abs(f), np.abs(fr)), 1e-6 * scale)
    rel = np.abs(f - fr) / denom
    rounding = ROUNDING_STEPS * moved / denom
    excess = rel - (RECIPROCITY_TOL + rounding)
    out = {"pass": bool(np.all(excess <= 0.0)), "max_rel_error": float(np.max(rel)), "tolerance": RECIPROCITY_TOL,
           "rounding": float(np.max(rounding))}
    if not out["pass"]:
        k = int(np.argmax(np.max(excess, axis=1)))
        out.update(count=int(np.count_nonzero(np.any(excess > 0, axis=1))),
                   example={"wi": wi[ok][k].tolist(), "wo": wo[ok][k].tolist(),
                            "f": f[k].tolist(), "f_exchanged": fr[k].tolist()})
    return out


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
