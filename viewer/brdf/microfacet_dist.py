"""Microfacet normal distributions and their masking-shadowing functions (numpy).

Each distribution is a few small functions named by term and source (Filament style), and a
small ``Distribution`` object bundles them the way pbrt-v4's ``TrowbridgeReitzDistribution``
does (D, Lambda, G1, G2, sample_m, pdf_m) so that several BSDFs (microfacet, rough dielectric,
layered coating) reuse one implementation.

Conventions: shading frame with the normal +z and the tangent +x; ``alpha_x`` is the roughness
along +x, ``alpha_y`` along +y (Walter et al. 2007's alpha; Beckmann: RMS slope; GGX:
Trowbridge-Reitz width). Directions are (N, 3) float64 unit vectors; alphas are scalars or (N,)
arrays. D is a density of microfacet normals per unit solid angle, normalized so that
integral D(m) (m.n) dm = 1 (Heitz 2014, "Understanding the Masking-Shadowing Function in
Microfacet-Based BRDFs", JCGT 3(2), eq. 4).
"""

from __future__ import annotations

import numpy as np


# scipy.special is imported on first use (Beckmann and the transmission G2 only): its import costs
# the window's start-up most of a second, and the first frame rarely needs it.
def erfc(x):
    from scipy.special import erfc as _erfc

    return _erfc(x)


def erfinv(x):
    from scipy.special import erfinv as _erfinv

    return _erfinv(x)


def betaln(a, b):
    from scipy.special import betaln as _betaln

    return _betaln(a, b)


SQRT_PI = np.sqrt(np.pi)

DISTRIBUTIONS = ("beckmann", "ggx", "blinn_phong")
SHADOWING = ("smith", "v_cavity")


def _dot(a, b):
    return np.einsum("...i,...i->...", a, b)  # np.sum(a * b, axis=-1), three times faster on (N, 3)


def _normalize(v):
    n = np.sqrt(_dot(v, v))[..., None]
    return v / np.where(n > 0, n, 1.0)


def _stretched(ax, x, ay, y, z):
    """The (N, 3) rows (ax x, ay y, z) (written into one array: no np.stack)."""
    out = np.empty((len(x), 3))
    np.multiply(ax, x, out=out[:, 0])
    np.multiply(ay, y, out=out[:, 1])
    out[:, 2] = z
    return out


def _slope_sq(w, ax, ay):
    """alpha^2 tan^2(theta) of direction w, generalized to anisotropy:
    (ax^2 wx^2 + ay^2 wy^2) / wz^2 (Heitz 2014, eq. 80 with alpha_o of eq. 87)."""
    wz2 = w[..., 2] ** 2
    num = (ax * w[..., 0]) ** 2 + (ay * w[..., 1]) ** 2
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(wz2 > 0, num / np.where(wz2 > 0, wz2, 1.0), np.inf)


def _ellipse_term(m, ax, ay):
    """mx^2/ax^2 + my^2/ay^2: the anisotropic tan^2 term times cos^2 (Heitz 2014 eq. 82 / 85)."""
    return (m[..., 0] / ax) ** 2 + (m[..., 1] / ay) ** 2


# ---------------------------------------------------------------------------------------------
# GGX / Trowbridge-Reitz
# ---------------------------------------------------------------------------------------------

def D_ggx(m, ax, ay):
    """Trowbridge & Reitz 1975 / Walter et al. 2007 eq. 33, anisotropic form of Heitz 2014 eq. 85:
    D(m) = 1 / (pi ax ay (mx^2/ax^2 + my^2/ay^2 + mz^2)^2) for mz > 0."""
    mz = m[..., 2]
    t = _ellipse_term(m, ax, ay) + mz * mz
    ok = (mz > 0) & (t > 0)
    d = 1.0 / (np.pi * ax * ay * np.where(ok, t * t, 1.0))
    return np.where(ok, d, 0.0)


def lambda_ggx(w, ax, ay):
    """Smith Lambda for GGX, Heitz 2014 eq. 86: Lambda = (-1 + sqrt(1 + a^2 tan^2)) / 2, written as
    s / (2 (1 + sqrt(1 + s))) with s = alpha^2 tan^2 to avoid cancellation when s is small."""
    s = _slope_sq(w, ax, ay)
    with np.errstate(invalid="ignore"):
        lam = s / (2.0 * (1.0 + np.sqrt(1.0 + s)))
    return np.where(np.isinf(s), np.inf, lam)


def sample_vndf_ggx(wo, u, ax, ay):
    """Visible-normal sampling of GGX, Heitz 2018, 'Sampling the GGX Distribution of Visible
    Normals', JCGT 7(4), listing 1: stretch wo to the alpha = 1 configuration, sample a point on
    the projected hemisphere (a disk with a warped half), unstretch. wo.z must be > 0."""
    vh = _normalize(_stretched(ax, wo[:, 0], ay, wo[:, 1], wo[:, 2]))
    lensq = vh[:, 0] ** 2 + vh[:, 1] ** 2
    some = lensq > 0
    inv = np.where(some, 1.0 / np.sqrt(np.where(some, lensq, 1.0)), 0.0)
    # t1 = (-vh.y, vh.x, 0) / |vh.xy| (or +x where vh = +z), t2 = vh x t1
    t1 = np.zeros((len(vh), 3))
    t1[:, 0] = np.where(some, -vh[:, 1] * inv, 1.0)
    t1[:, 1] = np.where(some, vh[:, 0] * inv, 0.0)
    t2 = np.empty((len(vh), 3))
    t2[:, 0] = -vh[:, 2] * t1[:, 1]
    t2[:, 1] = vh[:, 2] * t1[:, 0]
    t2[:, 2] = vh[:, 0] * t1[:, 1] - vh[:, 1] * t1[:, 0]
    r = np.sqrt(u[:, 0])
    phi = 2.0 * np.pi * u[:, 1]
    p1 = r * np.cos(phi)
    p2 = r * np.sin(phi)
    s = 0.5 * (1.0 + vh[:, 2])
    p2 = (1.0 - s) * np.sqrt(np.maximum(0.0, 1.0 - p1 * p1)) + s * p2
    nh = (p1[:, None] * t1 + p2[:, None] * t2
          + np.sqrt(np.maximum(0.0, 1.0 - p1 * p1 - p2 * p2))[:, None] * vh)
    return _normalize(_stretched(ax, nh[:, 0], ay, nh[:, 1], np.maximum(1e-12, nh[:, 2])))


# ---------------------------------------------------------------------------------------------
# Beckmann
# ---------------------------------------------------------------------------------------------

def D_beckmann(m, ax, ay):
    """Beckmann & Spizzichino 1963; Walter et al. 2007 eq. 25, anisotropic form of Heitz 2014
    eq. 83: D(m) = exp(-(mx^2/ax^2 + my^2/ay^2) / mz^2) / (pi ax ay mz^4) for mz > 0."""
    mz = m[..., 2]
    mz2 = mz * mz
    safe = np.where(mz > 0, mz2, 1.0)
    d = np.exp(-_ellipse_term(m, ax, ay) / safe) / (np.pi * ax * ay * safe * safe)
    return np.where(mz > 0, d, 0.0)


def lambda_beckmann(w, ax, ay):
    """Smith Lambda for Beckmann, Heitz 2014 eq. 80 (Walter 2007 eq. 27 before its rational
    approximation): with a = 1 / (alpha tan theta),
    Lambda = (erf(a) - 1) / 2 + exp(-a^2) / (2 a sqrt(pi)) = (exp(-a^2)/(a sqrt(pi)) - erfc(a)) / 2."""
    s = _slope_sq(w, ax, ay)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        a = 1.0 / np.sqrt(s)
        lam = 0.5 * (np.exp(-a * a) / (a * SQRT_PI) - erfc(a))
    lam = np.where(s == 0, 0.0, lam)
    lam = np.where(np.isinf(s), np.inf, lam)
    return np.maximum(lam, 0.0)


def _beckmann_slope_x(mu, u):
    """Sample the x slope of the alpha = 1 Beckmann visible-slope density for cot(theta) = mu:
    q(x) = (mu - x) exp(-x^2) / sqrt(pi) for x < mu (Heitz & d'Eon 2014, 'Importance Sampling
    Microfacet-Based BSDFs using the Distribution of Visible Normals', sec. 4 / appendix), by
    inverting its CDF C(x) = mu (1 + erf x) / 2 + exp(-x^2) / (2 sqrt pi) with safeguarded Newton
    steps (the idea of Jakob 2014, 'An Improved Visible Normal Sampling Routine for the Beckmann
    Distribution'; the iteration here is our own)."""
    mu = np.minimum(mu, 1e8)

    def cdf(x):
        return 0.5 * mu * (2.0 - erfc(x)) + np.exp(-x * x) / (2.0 * SQRT_PI)

    lo = np.full_like(mu, -7.0)
    hi = np.minimum(mu, 7.0)
    target = u * cdf(hi)
    x = np.clip(erfinv(np.clip(2.0 * u - 1.0, -1 + 1e-15, 1 - 1e-15)), lo, hi)
    for _ in range(40):
        c = cdf(x) - target
        lo = np.where(c < 0, x, lo)
        hi = np.where(c >= 0, x, hi)
        q = np.maximum(mu - x, 0.0) * np.exp(-x * x) / SQRT_PI
        with np.errstate(divide="ignore", invalid="ignore"):
            xn = x - c / q
        bad = ~np.isfinite(xn) | (xn <= lo) | (xn >= hi)
        xn = np.where(bad, 0.5 * (lo + hi), xn)
        if np.all(np.abs(xn - x) < 1e-12):
            x = xn
            break
        x = xn
    return x


def sample_vndf_beckmann(wo, u, ax, ay):
    """Visible-normal sampling of Beckmann (Heitz & d'Eon 2014, algorithm 1): stretch wo to the
    alpha = 1 configuration, sample the slopes (x, y) of visible facets in the frame where wo has
    azimuth 0, rotate back, unstretch the slopes, m = normalize(-x, -y, 1)."""
    ax = np.broadcast_to(np.asarray(ax, dtype=np.float64), wo.shape[:1])
    ay = np.broadcast_to(np.asarray(ay, dtype=np.float64), wo.shape[:1])
    w = _normalize(_stretched(ax, wo[:, 0], ay, wo[:, 1], wo[:, 2]))
    sin_t = np.sqrt(w[:, 0] ** 2 + w[:, 1] ** 2)
    with np.errstate(divide="ignore"):
        mu = np.where(sin_t > 0, w[:, 2] / np.where(sin_t > 0, sin_t, 1.0), np.inf)
    cos_p = np.where(sin_t > 0, w[:, 0] / np.where(sin_t > 0, sin_t, 1.0), 1.0)
    sin_p = np.where(sin_t > 0, w[:, 1] / np.where(sin_t > 0, sin_t, 1.0), 0.0)
    x = _beckmann_slope_x(mu, u[:, 0])
    y = erfinv(np.clip(2.0 * u[:, 1] - 1.0, -1 + 1e-15, 1 - 1e-15))
    sx = (cos_p * x - sin_p * y) * ax
    sy = (sin_p * x + cos_p * y) * ay
    return _normalize(np.stack([-sx, -sy, np.ones_like(sx)], axis=-1))


# ---------------------------------------------------------------------------------------------
# Blinn-Phong distribution
# ---------------------------------------------------------------------------------------------

def blinn_exponent(alpha):
    """Walter et al. 2007, sec. 5.2: the Phong exponent equivalent to a Beckmann alpha,
    n = 2 / alpha^2 - 2 (so alpha = 1 gives n = 0, the uniform-cosine distribution)."""
    return np.maximum(2.0 / (np.asarray(alpha, dtype=np.float64) ** 2) - 2.0, 0.0)


def D_blinn_phong(m, alpha):
    """Blinn 1977 ('Models of light reflection for computer synthesized pictures'), normalized as in
    Walter et al. 2007 eq. 30: D(m) = (n + 2) / (2 pi) cos^n(theta_m) for mz > 0 (isotropic)."""
    n = blinn_exponent(alpha)
    mz = m[..., 2]
    safe = np.where(mz > 0, mz, 1.0)
    with np.errstate(under="ignore"):
        d = (n + 2.0) / (2.0 * np.pi) * np.exp(n * np.log(safe))
    return np.where(mz > 0, d, 0.0)


def sample_blinn_phong(u, alpha):
    """Sample m proportional to D(m) cos(theta_m) (Walter et al. 2007 eqs. 35, 36 for the Phong
    distribution): cos(theta_m) = u1^(1 / (n + 2)), phi = 2 pi u2."""
    n = blinn_exponent(alpha)
    cos_t = np.power(np.maximum(u[:, 0], 1e-300), 1.0 / (n + 2.0))
    sin_t = np.sqrt(np.maximum(0.0, 1.0 - cos_t * cos_t))
    phi = 2.0 * np.pi * u[:, 1]
    return np.stack([sin_t * np.cos(phi), sin_t * np.sin(phi), cos_t], axis=-1)


# ---------------------------------------------------------------------------------------------
# Masking-shadowing
# ---------------------------------------------------------------------------------------------

def smith_g1(lam, w, m):
    """Smith 1967 masking with the local visibility test: G1 = chi+((w.m)(w.n)) / (1 + Lambda(w))
    (Heitz 2014, eq. 43; Walter et al. 2007, eq. 7)."""
    ok = _dot(w, m) * w[..., 2] > 0
    return np.where(ok, 1.0 / (1.0 + lam), 0.0)


def smith_g2_height_correlated(lam_i, lam_o, wi, wo, m):
    """Height-correlated Smith masking-shadowing, Heitz 2014, eq. 99:
    G2 = chi+(wi.m) chi+(wo.m) / (1 + Lambda(wo) + Lambda(wi)) (with the side tests of eq. 43,
    so that it also serves transmission where wi is below the surface)."""
    ok = (_dot(wi, m) * wi[..., 2] > 0) & (_dot(wo, m) * wo[..., 2] > 0)
    with np.errstate(invalid="ignore"):
        g = 1.0 / (1.0 + lam_i + lam_o)
    return np.where(ok, g, 0.0)


def G_v_cavity(wi, wo, m):
    """V-cavity geometric attenuation: Torrance & Sparrow 1967 / Blinn 1977 eq. (G), as written in
    Cook & Torrance 1981 (eq. for G): G = min(1, 2 (n.m)(n.wo)/(wo.m), 2 (n.m)(n.wi)/(wo.m)).
    For reflection wo.m = wi.m, so the two ratios share their denominator. Heitz 2014 sec. 4.3
    shows this is a valid (normalized) masking function of its own V-groove microsurface."""
    nm = m[..., 2]
    om = _dot(wo, m)
    im = _dot(wi, m)
    safe_o = np.where(om > 0, om, 1.0)
    safe_i = np.where(im > 0, im, 1.0)
    g = np.minimum(1.0, np.minimum(2.0 * nm * wo[..., 2] / safe_o, 2.0 * nm * wi[..., 2] / safe_i))
    ok = (om > 0) & (im > 0) & (nm > 0)
    return np.where(ok, np.maximum(g, 0.0), 0.0)


def G1_v_cavity(w, m):
    """V-cavity masking of one direction (Heitz 2014, eq. 47): min(1, 2 (n.m)(n.w) / (w.m))."""
    nm = m[..., 2]
    wm = _dot(w, m)
    safe = np.where(wm > 0, wm, 1.0)
    g = np.minimum(1.0, 2.0 * nm * w[..., 2] / safe)
    return np.where((wm > 0) & (nm > 0) & (w[..., 2] > 0), np.maximum(g, 0.0), 0.0)


# ---------------------------------------------------------------------------------------------
# One object per distribution (pbrt-v4 layout)
# ---------------------------------------------------------------------------------------------

class Distribution:
    """A microfacet distribution with Smith masking: D, Lambda, G1, G2, sample_m, pdf_m.

    ``name`` is one of beckmann | ggx | blinn_phong. blinn_phong is isotropic (uses alpha_x); its
    Smith Lambda is Beckmann's with the same alpha (Walter et al. 2007, sec. 5.2: the two
    distributions are nearly identical for n = 2/alpha^2 - 2), so its weak white furnace holds
    only approximately. Sampling: visible normals for ggx (Heitz 2018) and beckmann (Heitz &
    d'Eon 2014); D(m) cos(theta_m) for blinn_phong (Walter 2007)."""

    def __init__(self, name, alpha_x, alpha_y=None):
        if name not in DISTRIBUTIONS:
            raise ValueError(name)
        self.name = name
        self.ax = np.asarray(alpha_x, dtype=np.float64)
        self.ay = np.asarray(alpha_x if alpha_y is None else alpha_y, dtype=np.float64)
        if name == "blinn_phong":
            self.ay = self.ax

    @property
    def visible_sampling(self) -> bool:
        return self.name != "blinn_phong"

    def D(self, m):
        if self.name == "ggx":
            return D_ggx(m, self.ax, self.ay)
        if self.name == "beckmann":
            return D_beckmann(m, self.ax, self.ay)
        return D_blinn_phong(m, self.ax)

    def Lambda(self, w):
        if self.name == "ggx":
            return lambda_ggx(w, self.ax, self.ay)
        return lambda_beckmann(w, self.ax, self.ay)

    def G1(self, w, m):
        return smith_g1(self.Lambda(w), w, m)

    def G2(self, wi, wo, m):
        return smith_g2_height_correlated(self.Lambda(wi), self.Lambda(wo), wi, wo, m)

    def G2_transmission(self, wi, wo, m):
        """G2 for refraction (wi and wo on opposite sides): B(1 + Lambda(wo), 1 + Lambda(wi))."""
        return smith_g2_height_correlated_transmission(self.Lambda(wi), self.Lambda(wo), wi, wo, m)

    def D_visible(self, w, m):
        """Heitz & d'Eon 2014 eq. 2: D_w(m) = G1(w, m) max(0, w.m) D(m) / (w.n), for w.z > 0."""
        wz = w[..., 2]
        safe = np.where(wz > 0, wz, 1.0)
        v = self.G1(w, m) * np.maximum(0.0, _dot(w, m)) * self.D(m) / safe
        return np.where(wz > 0, v, 0.0)

    def sample_m(self, wo, u):
        """A microfacet normal for the (upper-hemisphere) direction wo."""
        if self.name == "ggx":
            return sample_vndf_ggx(wo, u, self.ax, self.ay)
        if self.name == "beckmann":
            return sample_vndf_beckmann(wo, u, self.ax, self.ay)
        return sample_blinn_phong(u, self.ax)

    def pdf_m(self, wo, m):
        """Density (per solid angle of m) of ``sample_m``."""
        if self.visible_sampling:
            return self.D_visible(wo, m)
        return self.D(m) * np.maximum(m[..., 2], 0.0)


# ---------------------------------------------------------------------------------------------
# Blinn-Phong distribution + Smith: where the borrowed Lambda overshoots
# ---------------------------------------------------------------------------------------------

# Beckmann's Lambda with the Phong distribution (Walter et al. 2007 sec. 5.2) is not the Smith
# Lambda of that distribution, and near grazing wo its F = 1 directional albedo exceeds 1 (1.48 at
# alpha = 1, cos 0.05; 1.03 at alpha = 0.3, cos 0.002), while elsewhere it is below 1. Capping G
# by the V-cavity G (a valid masking function for any D, Heitz 2014 sec. 4.3) bounds the albedo,
# but costs up to 0.3 of it where nothing needs correcting. So the cap is blended in only as far
# as the albedo requires:  G = G_smith - t (G_smith - min(G_smith, G_vcavity)),
# t = max(t(alpha, cos_i), t(alpha, cos_o)) (the max keeps f reciprocal), where t(alpha, mu) =
# (A_s - 1) / (A_s - A_c) when the uncapped albedo A_s exceeds 1 and 0 otherwise (A_c: the capped
# albedo), so that the directional albedo at cos_o is at most 1 and equals the uncapped one where
# that is <= 1. Table: alpha = 0, 0.1, .., 1 (rows) by cos = 0, 0.025, .., 0.3 (columns; 0 beyond),
# interpolated bilinearly; computed by midpoint quadrature over wi (800 x 800 in theta x phi;
# cos 0 evaluated at 0.002); tests/test_microfacet.py recomputes entries of it.
BLINN_SMITH_CAP_ALPHA_STEP = 0.1
BLINN_SMITH_CAP_COS_STEP = 0.025
BLINN_SMITH_CAP = np.array([
    [0.0] * 13,
    [0.0] * 13,
    [0.0409, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
    [0.1015, 0.0458, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
    [0.1781, 0.1381, 0.0891, 0.0328, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
    [0.2673, 0.2360, 0.1987, 0.1573, 0.1109, 0.0582, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
    [0.3644, 0.3378, 0.3065, 0.2722, 0.2344, 0.1923, 0.1450, 0.0914, 0.0304, 0.0, 0.0, 0.0, 0.0],
    [0.4646, 0.4393, 0.4094, 0.3766, 0.3404, 0.3001, 0.2550, 0.2042, 0.1465, 0.0807, 0.0054, 0.0, 0.0],
    [0.5633, 0.5353, 0.5021, 0.4654, 0.4247, 0.3792, 0.3281, 0.2704, 0.2050, 0.1305, 0.0453, 0.0, 0.0],
    [0.6565, 0.6204, 0.5790, 0.5336, 0.4833, 0.4269, 0.3635, 0.2919, 0.2105, 0.1179, 0.0121, 0.0, 0.0],
    [0.7403, 0.6901, 0.6369, 0.5794, 0.5156, 0.4440, 0.3631, 0.2714, 0.1670, 0.0480, 0.0, 0.0, 0.0],
])


def blinn_smith_cap_weight(alpha, cos):
    """t(alpha, cos) of the table above, bilinear (0 for cos >= 0.3)."""
    fa = np.clip(np.asarray(alpha, dtype=np.float64) / BLINN_SMITH_CAP_ALPHA_STEP, 0.0, 10.0)
    fm = np.clip(np.abs(np.asarray(cos, dtype=np.float64)) / BLINN_SMITH_CAP_COS_STEP, 0.0, 12.0)
    ia = np.minimum(np.floor(fa).astype(int), 9)
    im = np.minimum(np.floor(fm).astype(int), 11)
    ta, tm = fa - ia, fm - im
    t = BLINN_SMITH_CAP
    return ((1 - ta) * ((1 - tm) * t[ia, im] + tm * t[ia, im + 1])
            + ta * ((1 - tm) * t[ia + 1, im] + tm * t[ia + 1, im + 1]))


def G_blinn_smith(dist, wi, wo, m):
    """Smith G2 with Beckmann's Lambda for the Phong distribution, blended toward the V-cavity cap
    only where the albedo would exceed 1 (see BLINN_SMITH_CAP)."""
    g = dist.G2(wi, wo, m)
    gc = np.minimum(g, G_v_cavity(wi, wo, m))
    t = np.maximum(blinn_smith_cap_weight(dist.ax, wi[..., 2]), blinn_smith_cap_weight(dist.ax, wo[..., 2]))
    return g - t * (g - gc)


def smith_g2_height_correlated_transmission(lam_i, lam_o, wi, wo, m):
    """Height-correlated Smith masking-shadowing for refraction (wo and wi on opposite sides),
    Heitz 2014 sec. 5.3: a point at height h is visible from wo with probability C(h)^Lambda(wo)
    and, from below, from wi with (1 - C(h))^Lambda(wi) (C: the CDF of heights), so
    G2 = integral_0^1 C^Lambda(wo) (1 - C)^Lambda(wi) dC = B(1 + Lambda(wo), 1 + Lambda(wi)),
    the Beta function (not 1 / (1 + Lambda_i + Lambda_o), which holds for reflection only: both
    directions above see the same highest points). Side tests as in eq. 43."""
    ok = (_dot(wi, m) * wi[..., 2] > 0) & (_dot(wo, m) * wo[..., 2] > 0)
    a = np.asarray(lam_o, dtype=np.float64)
    b = np.asarray(lam_i, dtype=np.float64)
    fin = np.isfinite(a) & np.isfinite(b)
    with np.errstate(over="ignore", under="ignore"):
        g = np.exp(betaln(1.0 + np.where(fin, a, 0.0), 1.0 + np.where(fin, b, 0.0)))
    return np.where(ok & fin, g, 0.0)
