"""The split-sum DFG table ("environment BRDF") for image-based lighting with GGX, and the
multiple-scattering energy compensation that uses it.

Karis 2013, "Real Shading in Unreal Engine 4" (SIGGRAPH course notes), eqs. 4-8: the specular
integral of an environment is split into prefiltered radiance times the directional albedo of
the BRDF, and with Schlick's Fresnel F = F0 + (1 - F0) Fc, Fc = (1 - v.h)^5, that albedo is

    E_ss(NoV, alpha, F0) = integral f cos(theta_i) dwi = F0 * A + B,
    A = integral (f / F) (1 - Fc) cos(theta_i) dwi,   B = integral (f / F) Fc cos(theta_i) dwi.

The table convention, once and for all (the axis and channel mix-ups are the most common IBL
bug):

* array ``table[i, j, c]`` of shape (size, size, 2), float32;
* axis 0 (i): NoV = cos(theta_o) = (i + 0.5) / size (texel centres, 0 < NoV < 1);
* axis 1 (j): alpha = (j + 0.5) / size, Walter et al. 2007's GGX alpha (docs/conventions.md),
  *not* perceptual roughness (alpha = r^2 only in the GUI);
* channel 0: A, the scale on F0; channel 1: B, the bias; E_ss = F0 * A + B (F90 = 1).

Uploaded to GL as a (width = size, height = size) RG texture straight from this array, rows are
t and columns s, so GLSL reads ``texture(u_dfg, vec2(alpha, NoV)).rg`` = (A, B) with linear
filtering, and ``lookup_dfg`` does the same bilinear lookup on the CPU.

The BRDF is GGX (Trowbridge-Reitz) with height-correlated Smith masking-shadowing, the
``microfacet`` model's ``distribution = "ggx"``, ``shadowing = "smith"``; the integrals use
``viewer.brdf.microfacet_dist`` (its VNDF sampler, Lambda and G2), so the table and the numpy
BRDF cannot drift apart.
"""

from __future__ import annotations

import math

import numpy as np

from viewer.brdf.microfacet_dist import lambda_ggx, sample_vndf_ggx, smith_g2_height_correlated

DFG_SIZE = 32


def table_coords(size: int = DFG_SIZE) -> np.ndarray:
    """(size,) texel-centre values (k + 0.5) / size of either axis."""
    return (np.arange(size) + 0.5) / size


def _wo(nov):
    nov = np.asarray(nov, dtype=np.float64)
    return np.stack([np.sqrt(np.maximum(0.0, 1.0 - nov * nov)), np.zeros_like(nov), nov], axis=-1)


def vndf_quadrature(samples: int) -> tuple[np.ndarray, np.ndarray]:
    """(u (N, 2), weights (N,)) over the VNDF sampler's unit square, about ``samples`` points.

    GGX has a heavy tail: a fraction ~ alpha^2 of the visible normals lies in the sampler's
    outermost ring 1 - u0 < alpha^2 (tan(theta_m) > 1 there: tan(theta_m) = alpha r / sqrt(1 - r^2)
    with r = sqrt(u0)), and that is where wi dips below the horizon and energy is lost. A uniform
    grid of 64 x 64 never puts a point there and overestimates A + B by up to 2e-3 near
    alpha = 0.05. So u0 = 1 - t^4 with Gauss-Legendre nodes in t (weights times du0/dt = 4 t^3),
    which grades the points toward the rim, and a midpoint rule in u1 (the azimuth)."""
    n = max(2, int(round(math.sqrt(samples))))
    x, wx = np.polynomial.legendre.leggauss(n)
    t = 0.5 * (x + 1.0)
    wt = 0.5 * wx * 4.0 * t ** 3
    u0 = 1.0 - t ** 4
    u1 = (np.arange(n) + 0.5) / n
    U0, U1 = np.meshgrid(u0, u1, indexing="ij")
    W = np.outer(wt, np.full(n, 1.0 / n))
    return np.stack([U0.ravel(), U1.ravel()], axis=-1), W.ravel()


def dfg_ab(nov, alpha, samples: int = 4096) -> tuple[np.ndarray, np.ndarray]:
    """(A, B) for arrays of NoV and alpha (same shape), estimated with GGX visible-normal
    sampling (Heitz 2018) on the fixed quadrature pattern of ``vndf_quadrature`` (deterministic).
    With pdf(wi) = D_wo(m) / (4 wo.m) the weight f cos / pdf is F G2 / G1(wo) (Heitz 2018,
    sec. 2), and for height-correlated G2 (Heitz 2014, eq. 99)
    G2 / G1(wo) = (1 + Lambda(wo)) / (1 + Lambda(wo) + Lambda(wi))."""
    nov = np.asarray(nov, dtype=np.float64).ravel()
    alpha = np.asarray(alpha, dtype=np.float64).ravel()
    u, qw = vndf_quadrature(samples)
    ns = len(u)
    a_out = np.zeros(nov.size)
    b_out = np.zeros(nov.size)
    chunk = max(1, 262144 // ns)
    for s in range(0, nov.size, chunk):
        wo1 = _wo(nov[s:s + chunk])
        k = len(wo1)
        wo = np.repeat(wo1, ns, axis=0)
        al = np.repeat(alpha[s:s + chunk], ns)
        uu = np.tile(u, (k, 1))
        m = sample_vndf_ggx(wo, uu, al, al)
        vom = np.sum(wo * m, axis=-1)
        wi = 2.0 * vom[:, None] * m - wo
        lam_o = lambda_ggx(wo, al, al)
        lam_i = lambda_ggx(wi, al, al)
        ok = (wi[:, 2] > 0) & (vom > 0)
        w = np.where(ok, (1.0 + lam_o) / np.where(ok, 1.0 + lam_o + lam_i, 1.0), 0.0)
        fc = (1.0 - np.clip(vom, 0.0, 1.0)) ** 5
        a_out[s:s + k] = (w * (1.0 - fc)).reshape(k, ns) @ qw
        b_out[s:s + k] = (w * fc).reshape(k, ns) @ qw
    return a_out, b_out


def dfg_table(size: int = DFG_SIZE, samples: int = 4096) -> np.ndarray:
    """(size, size, 2) float32 table of (A, B) over (NoV, alpha) at texel centres; see the module
    notes for the convention. 32 x 32 with 4096 samples per texel takes about a second."""
    c = table_coords(size)
    nov, alpha = np.meshgrid(c, c, indexing="ij")
    a, b = dfg_ab(nov, alpha, samples)
    return np.stack([a.reshape(size, size), b.reshape(size, size)], axis=-1).astype(np.float32)


DFG_ESTIMATOR = 1  # raise when dfg_ab's estimate changes: the stored tables are then rebuilt


def stored_dfg_table(size: int = DFG_SIZE, samples: int = 4096) -> np.ndarray:
    """``dfg_table``, kept in the disk cache (viewer/environment/cache.py): it is deterministic,
    and about a second of numpy that every process would spend again (the window's first glass
    or rough metal, its compile-ahead child, each reference worker)."""
    from viewer.environment import cache

    key = cache.content_key(None, {"size": size, "samples": samples, "estimator": DFG_ESTIMATOR}, kind="dfg")
    got = cache.load(key, "dfg", expect={"table": (size, size, 2)})
    if got is not None:
        return got["table"].astype(np.float32)
    table = dfg_table(size, samples)
    cache.store(key, {"table": table}, "dfg")
    return table


def dfg_reference(nov: float, alpha: float, n: int = 512) -> tuple[float, float]:
    """(A, B) by plain deterministic quadrature, independent of the VNDF sampler: over half
    vectors m, with Gauss-Legendre rules of n nodes in xi and n / 2 in phi (phi in [0, pi],
    doubled by the symmetry about the plane of wo), through the D(m) cos(theta_m) CDF map
    tan^2(theta_m) = alpha^2 xi / (1 - xi) (Walter et al. 2007, eq. 35), so the peak of D is
    resolved at any alpha. Per unit (xi, phi / 2 pi) the integrand of A (or B) is
    f cos(theta_i) |dwi/dm| / (D cos theta_m) = G2 (1 - Fc) (wo.m) / (NoV cos theta_m)
    (the Jacobian dwi/dm = 4 wo.m, Walter et al. 2007 eq. 14)."""
    x, wx = np.polynomial.legendre.leggauss(n)
    xi = 0.5 * (x + 1.0)
    wxi = 0.5 * wx
    y, wy = np.polynomial.legendre.leggauss(max(2, n // 2))
    phi = 0.5 * np.pi * (y + 1.0)
    wphi = 0.5 * np.pi * wy
    XI, PHI = np.meshgrid(xi, phi, indexing="ij")
    W = np.outer(wxi, wphi) * 2.0 / (2.0 * np.pi)
    tan2 = alpha * alpha * XI / (1.0 - XI)
    cos_m = 1.0 / np.sqrt(1.0 + tan2)
    sin_m = np.sqrt(np.maximum(0.0, 1.0 - cos_m * cos_m))
    m = np.stack([sin_m * np.cos(PHI), sin_m * np.sin(PHI), cos_m], axis=-1).reshape(-1, 3)
    wo = np.broadcast_to(_wo(nov), m.shape)
    vom = np.sum(wo * m, axis=-1)
    wi = 2.0 * vom[:, None] * m - wo
    g2 = smith_g2_height_correlated(lambda_ggx(wi, alpha, alpha), lambda_ggx(wo, alpha, alpha), wi, wo, m)
    g2 = np.where((wi[:, 2] > 0) & (vom > 0), g2, 0.0)
    base = g2 * np.maximum(vom, 0.0) / (nov * cos_m.ravel())
    fc = (1.0 - np.clip(vom, 0.0, 1.0)) ** 5
    Wf = W.ravel()
    return float(np.sum(Wf * base * (1.0 - fc))), float(np.sum(Wf * base * fc))


def lookup_dfg(table: np.ndarray, nov, alpha) -> tuple[np.ndarray, np.ndarray]:
    """(A, B) bilinear in the table (clamped to the edge texels), as GL's linear filtering with
    CLAMP_TO_EDGE reads ``texture(u_dfg, vec2(alpha, NoV))``."""
    size_n, size_a = table.shape[:2]
    x = np.clip(np.asarray(nov, dtype=np.float64) * size_n - 0.5, 0.0, size_n - 1.0)
    y = np.clip(np.asarray(alpha, dtype=np.float64) * size_a - 0.5, 0.0, size_a - 1.0)
    x0 = np.minimum(np.floor(x).astype(int), max(size_n - 2, 0))
    y0 = np.minimum(np.floor(y).astype(int), max(size_a - 2, 0))
    fx = (x - x0)[..., None]
    fy = (y - y0)[..., None]
    x1 = np.minimum(x0 + 1, size_n - 1)
    y1 = np.minimum(y0 + 1, size_a - 1)
    t = table.astype(np.float64)
    v = ((t[x0, y0] * (1 - fy) + t[x0, y1] * fy) * (1 - fx)
         + (t[x1, y0] * (1 - fy) + t[x1, y1] * fy) * fx)
    return v[..., 0], v[..., 1]


def ms_compensation(A, B, f0) -> tuple[np.ndarray, np.ndarray]:
    """Multiple-scattering terms of Fdez-Agüera 2019, "A Multiple-Scattering Microfacet Model
    for Real-Time Image-based Lighting" (JCGT 8(1)), sec. 3-4 and listing 1, from the DFG
    values A, B (broadcast against ``f0``, e.g. A[..., None] with an RGB f0):

        FssEss = F0 A + B                   single scattering, Fresnel-weighted (Karis 2013)
        Ess    = A + B                      single-scattering albedo with F = 1
        Ems    = 1 - Ess                    energy the single-scattering lobe loses
        Favg   = F0 + (1 - F0) / 21         Schlick's Fresnel averaged over the hemisphere
        Fms    = FssEss Favg / (1 - Ems Favg)   (the geometric series of bounces)

    Returns (FssEss, Fms * Ems). The specular radiance is then
    FssEss * prefiltered_radiance + Fms Ems * E / pi, where E / pi is the cosine-weighted mean
    radiance (the SH irradiance over pi): the multiply scattered light is spread out like a
    diffuse lobe. In a white furnace with F0 = 1 the two add up to exactly 1."""
    A = np.asarray(A, dtype=np.float64)
    B = np.asarray(B, dtype=np.float64)
    f0 = np.asarray(f0, dtype=np.float64)
    fss_ess = f0 * A + B
    e_ms = 1.0 - (A + B)
    f_avg = f0 + (1.0 - f0) / 21.0
    f_ms = fss_ess * f_avg / (1.0 - e_ms * f_avg)
    return fss_ess, f_ms * e_ms
