"""The generic importance sampler of ``.brdf`` file materials (no sampler of their own), in numpy:
the twin of the GLSL ``custom_sample`` / ``custom_pdf`` that ``viewer.gl.brdf_glsl`` generates.

Half vectors h are drawn from a table of the file's f for the current parameters. The domain
is warped first: theta_h goes to s = t / (a^2 + t), t = tan^2 theta_h (the CDF of the GGX
distribution D cos theta_h of width ``a``, Walter et al. 2007 eq. 35), ``a`` fitted to the
file's lobe (the median theta_h of its reflected energy at normal view); phi_h is measured from
the view's azimuth and folded to [0, pi] (its sign drawn with equal odds). Over that square
(s, |phi|), for each of ``NV`` view angles theta_v (nodes ``view_angle``), a piecewise-constant
2D density of the energy f cos_i |dw_i/dw_h| = f cos_i 4 (wo.h) per (s, phi) (marginal CDF over
``NT`` bands of s, conditional CDFs over ``NP`` bands of |phi|), inverted exactly. A view
between two nodes takes one of them with the odds of linear interpolation, and the pdf is that
mixture's. Cosine-weighted directions (``COSINE_SHARE``) keep every direction above the surface
reachable; a BRDF that is 0 everywhere is sampled by cosine alone.

Density of a half vector in the band cell (i, j) of node k, per solid angle of h:
P_k(i) P_k(j | i) / (ds dphi) / 2 (the folded sign) times ds dphi / dw_h = 2 pi D_a(h) cos theta_h;
per solid angle of wi divided by 4 (wo.h) (Walter et al. 2007 eq. 14).

The table is one float array: [a, cosine share, NV, NT, NP, then per view node the marginal CDF
(NT floats) and the conditional CDFs (NT x NP)]; its sizes depend on its room (``sizes_for``),
the code reading it does not.
"""

from __future__ import annotations

import numpy as np

#: the table's sizes (view nodes NV, bands of s NT, bands of |phi| NP) where its room is not bounded
#: (the GPU engine's material texture), and the ones that fit a bounded room (the rasterizer's
#: material block), best first: ``sizes_for(room)`` takes the first that fits
FULL = (10, 32, 16)
SMALL = ((3, 16, 4), (4, 12, 3), (1, 24, 1), (1, 12, 1))
MAX_BANDS = 63  # the most bands of s or |phi| (the GLSL binary search takes a fixed count of steps)
assert all(max(sz[1:]) <= MAX_BANDS for sz in (FULL, *SMALL))
SUB_T, SUB_P = 4, 2  # evaluations per band (midpoints of sub-bands), building the table
DILATE = 0.25  # a cell's least share of its largest neighbour's energy (``_dilate``)
COSINE_SHARE = 0.02  # the cosine-weighted share of the mixture (the whole of it for a BRDF that is 0)
VIEW_MAX = np.radians(87.0)  # the last view node's theta_v (views beyond it take it)
HEADER = 5  # a, cosine share, NV, NT, NP
A_MIN, A_MAX = 1e-3, 4.0
INV_PI = 1.0 / np.pi


def _half_from(s, phi, a):
    """The half vector at warped coordinates (s, phi) (phi from the x axis) for width a."""
    s = np.clip(s, 0.0, 1.0 - 1e-7)
    t = a * a * s / (1.0 - s)  # tan^2 theta_h
    cz = 1.0 / np.sqrt(1.0 + t)
    sz = np.sqrt(t) * cz
    return np.stack([sz * np.cos(phi), sz * np.sin(phi), cz], axis=-1)


def _d_cos(cz, a):
    """D_a(h) cos theta_h of the GGX distribution of width a (a density over solid angle of h)."""
    c2 = cz * cz
    d = c2 * (a * a - 1.0) + 1.0
    return a * a / (np.pi * d * d) * cz


def fit_width(energy) -> float:
    """The warp's width a: tan of the median theta_h of ``energy(h)`` (f cos_i 4 (wo.h) at normal
    view, per solid angle of h), so that the warped bands fit the file's lobe."""
    n = 2048
    th = (np.arange(n) + 0.5) * (0.5 * np.pi / n)
    h = np.stack([np.sin(th), np.zeros(n), np.cos(th)], axis=1)
    m = np.where(np.isfinite(e := energy(h, np.array([0.0, 0.0, 1.0]))), e, 0.0) * np.sin(th)
    c = np.cumsum(m)
    if not (c[-1] > 0) or not np.isfinite(c[-1]):
        return 1.0
    med = th[min(int(np.searchsorted(c, 0.5 * c[-1])), n - 1)]
    return float(np.clip(np.tan(med), A_MIN, A_MAX))


def size(sizes) -> int:
    """The floats of a table of ``sizes`` (NV, NT, NP)."""
    nv, nt, npp = sizes
    return HEADER + nv * (nt + nt * npp)


def sizes_for(room: int | None) -> tuple[int, int, int] | None:
    """The table's sizes for ``room`` floats (None: unbounded, ``FULL``); None where not even the
    smallest fits."""
    if room is None:
        return FULL
    return next((sz for sz in SMALL if size(sz) <= room), None)


def sizes_of(table) -> tuple[int, int, int]:
    return int(table[2] + 0.5), int(table[3] + 0.5), int(table[4] + 0.5)


#: the view's coordinate sqrt(1 - cos theta_v) = sqrt(2) sin(theta_v / 2), nearly theta_v / sqrt(2)
#: but found without acos (whose GLSL approximations differ from numpy's), at the last node
VIEW_X_MAX = float(np.sqrt(1.0 - np.cos(VIEW_MAX)))


def view_angle(k: float, nv: int) -> float:
    """theta_v of view node k of nv: equal steps in sqrt(1 - cos theta_v) from 0 to VIEW_MAX
    (one node: normal view); k between nodes is between them, clamped to [0, VIEW_MAX]."""
    x = min(max(k, 0.0), nv - 1.0) * VIEW_X_MAX / max(nv - 1, 1)
    return 0.0 if nv == 1 else float(np.arccos(1.0 - x * x))


def build(f, sizes=FULL) -> np.ndarray:
    """The table of the BRDF ``f(wi, wo)`` (arrays (N, 3) -> luminance (N,), any value; NaN,
    Inf and negatives count as 0) at ``sizes`` (NV, NT, NP): float64 array of ``size(sizes)``
    in the layout of the module doc."""
    NV, NT, NP = sizes
    NODE = NT + NT * NP

    def energy(h, wo):
        woh = h @ wo
        wi = 2.0 * woh[:, None] * h - wo
        ok = (wi[:, 2] > 0) & (woh > 0)
        v = np.asarray(f(np.where(ok[:, None], wi, [0.0, 0.0, 1.0]), np.broadcast_to(wo, wi.shape)), float)
        v = np.where(np.isfinite(v), np.maximum(v, 0.0), 0.0)
        return np.where(ok, v * wi[:, 2] * 4.0 * woh, 0.0)

    a = fit_width(energy)
    ns, npp = NT * SUB_T, NP * SUB_P
    s = (np.arange(ns) + 0.5) / ns
    phi = (np.arange(npp) + 0.5) * (np.pi / npp)
    S, P = np.meshgrid(s, phi, indexing="ij")
    h = _half_from(S.ravel(), P.ravel(), a)
    jac = 1.0 / (2.0 * np.pi * _d_cos(h[:, 2], a))  # dw_h / (ds dphi)
    out = np.zeros(size(sizes))
    out[0], out[2], out[3], out[4] = a, NV, NT, NP
    for k in range(NV):
        # per (s, phi) cell: the energy at the node's view and halfway to its neighbours (weights
        # 1/4, 1/2, 1/4: the node's share of linear interpolation), so that a view between two
        # nodes finds what it reflects in both (a half vector whose wi is above the surface at
        # the view but below it at the nearer node would else have the other node's odds alone);
        # a single node serves every view: the mean over views up to 75 degrees
        if NV > 1:
            views = [(view_angle(k - 0.5, NV), 0.25), (view_angle(k, NV), 0.5), (view_angle(k + 0.5, NV), 0.25)]
        else:
            views = [(t, 0.25) for t in np.radians([0.0, 30.0, 60.0, 75.0])]
        e = 0.0
        for tv, wt in views:
            wo = np.array([np.sin(tv), 0.0, np.cos(tv)])
            e = e + wt * (energy(h, wo) * jac).reshape(NT, SUB_T, NP, SUB_P).mean(axis=(1, 3))
        e = _dilate(e)
        row = e.sum(axis=1)
        total = row.sum()
        base = HEADER + k * NODE
        if not (total > 0) or not np.isfinite(total):
            continue
        marg = np.cumsum(row) / total
        marg[-1] = 1.0
        cond = np.cumsum(e, axis=1) / np.where(row > 0, row, 1.0)[:, None]
        cond[row <= 0] = (np.arange(NP) + 1.0) / NP  # never chosen: any valid CDF
        cond[:, -1] = 1.0
        out[base:base + NT] = marg
        out[base + NT:base + NODE] = cond.ravel()
    # every node must hold a distribution where the sampler may choose it: a node whose f was 0
    # takes its nearest filled one's (the pdf is the mixture's of what is stored, whatever it is)
    filled = [k for k in range(NV) if out[HEADER + k * NODE + NT - 1] > 0]
    if not filled:
        out[1] = 1.0  # f is 0 (or not finite) everywhere: cosine alone
        return out
    for k in range(NV):
        if k not in filled:
            src = min(filled, key=lambda j: abs(j - k))
            out[HEADER + k * NODE:HEADER + (k + 1) * NODE] = out[HEADER + src * NODE:HEADER + (src + 1) * NODE]
    out[1] = COSINE_SHARE
    return out


def _dilate(e):
    """Each cell at least DILATE times its largest neighbour's (the 8 around it): a cell whose
    sample points all missed what it reflects (wi below the surface there, above it elsewhere in
    the cell, or at a view between nodes) still has some odds, so its weights stay bounded."""
    pad = np.pad(e, 1, mode="edge")
    n, m = e.shape
    near = np.max([pad[1 + di:1 + di + n, 1 + dj:1 + dj + m] for di in (-1, 0, 1) for dj in (-1, 0, 1)
                   if di or dj], axis=0)
    return np.maximum(e, DILATE * near)


def _view(table, wo):
    """(node below, the odds of the node above) of each view, and its azimuth."""
    nv = sizes_of(table)[0]
    if nv == 1:
        return np.zeros(len(wo), int), np.zeros(len(wo)), np.arctan2(wo[:, 1], wo[:, 0])
    x = np.clip(np.sqrt(np.maximum(1.0 - wo[:, 2], 0.0)) / VIEW_X_MAX * (nv - 1), 0.0, nv - 1.0)
    k = np.minimum(x.astype(int), nv - 2)
    return k, x - k, np.arctan2(wo[:, 1], wo[:, 0])


def _node_pdf_h(table, k, s, phi_abs):
    """Density over (s, |phi|) of node k (arrays), as P(i) P(j|i) / (ds dphi)."""
    _, NT, NP = sizes_of(table)
    i = np.minimum((s * NT).astype(int), NT - 1)
    j = np.minimum((phi_abs / np.pi * NP).astype(int), NP - 1)
    base = HEADER + k * (NT + NT * NP)
    m = table[base + i] - np.where(i > 0, table[base + np.maximum(i - 1, 0)], 0.0)
    cb = base + NT + i * NP
    c = table[cb + j] - np.where(j > 0, table[cb + np.maximum(j - 1, 0)], 0.0)
    return m * c * (NT * NP / np.pi)


def table_pdf(table, wi, wo):
    """The density (per solid angle of wi) of the tabulated part alone."""
    a = table[0]
    h = wi + wo
    ln = np.linalg.norm(h, axis=1)
    h = h / np.where(ln > 0, ln, 1.0)[:, None]
    woh = np.sum(wo * h, axis=1)
    ok = (ln > 0) & (h[:, 2] > 0) & (woh > 0)
    cz = np.clip(h[:, 2], 1e-12, 1.0)
    t = np.maximum(1.0 - cz * cz, 0.0) / (cz * cz)
    s = t / (a * a + t)
    k, w, az = _view(table, wo)
    phi = np.abs(np.arctan2(h[:, 1], h[:, 0]) - az)
    phi = np.where(phi > np.pi, 2.0 * np.pi - phi, phi)
    q = (1.0 - w) * _node_pdf_h(table, k, s, phi)
    if sizes_of(table)[0] > 1:
        q = q + w * _node_pdf_h(table, k + 1, s, phi)
    ph = 0.5 * q * 2.0 * np.pi * _d_cos(cz, a)
    return np.where(ok, ph / (4.0 * np.where(ok, woh, 1.0)), 0.0)


def pdf(table, wi, wo):
    """The sampler's density per solid angle of wi (0 below either horizon)."""
    c = table[1]
    ok = (wi[:, 2] > 0) & (wo[:, 2] > 0)
    p = c * np.maximum(wi[:, 2], 0.0) * INV_PI
    if c < 1.0:
        p = p + (1.0 - c) * table_pdf(table, wi, wo)
    return np.where(ok, p, 0.0)


def _invert(cdf, u):
    """(index, position in the band) of u under the CDF rows ``cdf`` (N, n): the first band whose
    CDF exceeds u, as the GLSL binary search finds it."""
    n = cdf.shape[1]
    i = np.minimum(np.sum(cdf <= u[:, None], axis=1), n - 1)
    lo = np.where(i > 0, np.take_along_axis(cdf, np.maximum(i - 1, 0)[:, None], 1)[:, 0], 0.0)
    hi = np.take_along_axis(cdf, i[:, None], 1)[:, 0]
    return i, np.clip((u - lo) / np.maximum(hi - lo, 1e-30), 0.0, 1.0)


def sample(table, wo, u):
    """(wi, pdf) for views wo (N, 3) and uniforms u (N, 3): u.z chooses cosine (below the share)
    or the table, and then, rescaled, the view node; u.x the band of s and the position in it,
    u.y the sign of phi (below 1/2: +), then, rescaled, its band and the position in it (as
    GLSL ``custom_sample``). Directions of the table below the surface have pdf 0."""
    _, NT, NP = sizes_of(table)
    c = table[1]
    cos_ = u[:, 2] < c
    r = np.sqrt(u[:, 0])
    ph = 2.0 * np.pi * u[:, 1]
    wi_c = np.stack([r * np.cos(ph), r * np.sin(ph), np.sqrt(np.maximum(0.0, 1.0 - u[:, 0]))], axis=1)
    if c >= 1.0:
        return wi_c, pdf(table, wi_c, wo)
    k, w, az = _view(table, wo)
    uz = (u[:, 2] - c) / (1.0 - c)
    k = k + (uz >= 1.0 - w)  # the node above with the odds w
    base = HEADER + k * (NT + NT * NP)
    i, ts = _invert(table[base[:, None] + np.arange(NT)], u[:, 0])
    s = (i + ts) / NT
    sign = np.where(u[:, 1] < 0.5, 1.0, -1.0)
    uy = np.where(u[:, 1] < 0.5, 2.0 * u[:, 1], 2.0 * u[:, 1] - 1.0)
    j, tp = _invert(table[(base + NT + i * NP)[:, None] + np.arange(NP)], uy)
    h = _half_from(s, az + sign * (j + tp) * (np.pi / NP), table[0])
    wi_t = 2.0 * np.sum(wo * h, axis=1)[:, None] * h - wo
    wi = np.where(cos_[:, None], wi_c, wi_t)
    return wi, pdf(table, wi, wo)
