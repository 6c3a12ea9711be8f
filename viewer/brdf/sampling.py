"""Shared sampling helpers (numpy, shading frame z = normal). Vectorized over rows."""

from __future__ import annotations

import numpy as np

from viewer.spectral.colorimetry import LUMINANCE_REC709, luminance  # public here too (the models' samplers)

INV_PI = 1.0 / np.pi

# BRDF values are capped at F_MAX = e^80 (about 5.5e34) in both twins (GLSL: common/math.glsl):
# at grazing angles 1 / (4 cos_i cos_o) outgrows float32 (3.4e38), the shader's inf would turn
# into NaN at the next multiplication by 0, and float64 would carry a value no image can hold.
# Lafortune's lobe clamp (LOG_CLAMP = 80) is the same bound.
F_MAX = float(np.exp(80.0))


def ratio_capped(a, b):
    """a / b for a >= 0, capped at F_MAX; 0 where a <= 0; F_MAX where a > 0 and b <= 0 (the
    GLSL twin ``ratio_capped`` computes the same without overflowing)."""
    a = np.asarray(a, dtype=np.float64)
    b = np.asarray(b, dtype=np.float64)
    with np.errstate(divide="ignore", over="ignore", invalid="ignore"):
        r = np.minimum(a / np.where(b > 0, b, 1.0), F_MAX)
    return np.where(a > 0, np.where(b > 0, r, F_MAX), 0.0)


def cos_theta(w):
    return w[..., 2]


def cosine_hemisphere(u):
    """Malley's method: uniform disk (concentric map, Shirley-Chiu 1997) lifted to the hemisphere.
    pdf = cos(theta) / pi."""
    a = 2.0 * u[..., 0] - 1.0
    b = 2.0 * u[..., 1] - 1.0
    use_a = np.abs(a) > np.abs(b)
    safe_a = np.where(a == 0, 1.0, a)
    safe_b = np.where(b == 0, 1.0, b)
    r = np.where(use_a, a, b)
    phi = np.where(use_a, (np.pi / 4) * (b / safe_a), (np.pi / 2) - (np.pi / 4) * (a / safe_b))
    zero = (a == 0) & (b == 0)
    r = np.where(zero, 0.0, r)
    out = np.empty(a.shape + (3,))
    x = np.multiply(r, np.cos(phi), out=out[..., 0])
    y = np.multiply(r, np.sin(phi), out=out[..., 1])
    out[..., 2] = np.sqrt(np.maximum(0.0, 1.0 - x * x - y * y))
    return out


def cosine_hemisphere_pdf(w):
    return np.maximum(w[..., 2], 0.0) * INV_PI


def reflect_z(w):
    """Mirror direction about the normal (0, 0, 1)."""
    return w * np.array([-1.0, -1.0, 1.0])


def dot(a, b):
    """Row-wise a . b of (..., 3) arrays (broadcasting). einsum: about three times faster than
    np.sum(a * b, axis=-1) on (N, 3) rows, equal to it up to the order of the roundings."""
    return np.einsum("...i,...i->...", a, b)


def reflect(w, m):
    """Reflect w about the unit vector m: 2 (w.m) m - w."""
    d = dot(w, m)[..., None]
    return 2.0 * d * m - w


def normalize(v):
    n = np.sqrt(dot(v, v))[..., None]
    return v / np.where(n > 0, n, 1.0)


def frame_from_z(z):
    """An orthonormal basis (x, y) around unit vectors z (Duff et al. 2017, branchless ONB)."""
    sign = np.where(z[..., 2] >= 0.0, 1.0, -1.0)
    a = -1.0 / (sign + z[..., 2])
    b = z[..., 0] * z[..., 1] * a
    x = np.empty(z.shape)
    y = np.empty(z.shape)
    x[..., 0] = 1.0 + sign * z[..., 0] ** 2 * a
    x[..., 1] = sign * b
    x[..., 2] = -sign * z[..., 0]
    y[..., 0] = b
    y[..., 1] = sign + z[..., 1] ** 2 * a
    y[..., 2] = -z[..., 1]
    return x, y


# ---- power-cosine lobes and mixtures (added for phong / blinn_phong / lafortune / ashikhmin_shirley)


def power_cosine(u, n):
    """Directions around +z with pdf (n + 1) / (2 pi) cos^n(theta) (Phong lobe sampling,
    Lafortune & Willems 1994, Sec. 4: cos theta = u1^(1 / (n + 1)), phi = 2 pi u2)."""
    n = np.broadcast_to(np.asarray(n, dtype=np.float64), u.shape[:-1])
    out = np.empty(u.shape[:-1] + (3,))
    cos_t = np.power(u[..., 0], 1.0 / (n + 1.0), out=out[..., 2])
    sin_t = np.sqrt(np.maximum(0.0, 1.0 - cos_t * cos_t))
    phi = 2.0 * np.pi * u[..., 1]
    np.multiply(sin_t, np.cos(phi), out=out[..., 0])
    np.multiply(sin_t, np.sin(phi), out=out[..., 1])
    return out


def power_cosine_pdf(cos_t, n):
    """pdf (solid angle) of ``power_cosine``: (n + 1) / (2 pi) max(cos, 0)^n; 0 for cos <= 0
    (so n = 0 never meets pow(0, 0))."""
    c = np.asarray(cos_t, dtype=np.float64)
    pos = c > 0
    val = (np.asarray(n) + 1.0) / (2.0 * np.pi) * np.power(np.where(pos, c, 1.0), n)
    return np.where(pos, val, 0.0)


def to_world(local, axis):
    """Rotate directions given in a frame whose z is ``axis`` (unit, (..., 3)) to the shading frame."""
    x, y = frame_from_z(axis)
    out = local[..., 0:1] * x  # (l0 x + l1 y) + l2 axis, summed in place
    out += local[..., 1:2] * y
    out += local[..., 2:3] * axis
    return out


def uniform_hemisphere(u):
    """Uniform directions on the upper hemisphere; pdf 1 / (2 pi)."""
    z = u[..., 0]
    r = np.sqrt(np.maximum(0.0, 1.0 - z * z))
    phi = 2.0 * np.pi * u[..., 1]
    return np.stack([r * np.cos(phi), r * np.sin(phi), z], axis=-1)


def pick_lobe(u0, probs):
    """Choose a lobe per row from probabilities ``probs`` (N, K) (rows sum to 1) with the uniform
    ``u0`` (N,); return the index (N,) and u0 rescaled to [0, 1) within the chosen interval, so one
    2-D sample drives both the choice and the lobe (the usual mixture-sampling trick)."""
    # the running sum and the count a column at a time: numpy's reductions along a short axis
    # (cumsum, sum(axis=1)) are several times slower than these few whole-column operations
    cdf = np.empty(probs.shape)
    cdf[:, 0] = probs[:, 0]
    for j in range(1, probs.shape[1]):
        np.add(cdf[:, j - 1], probs[:, j], out=cdf[:, j])
    cdf[:, -1] = np.maximum(cdf[:, -1], 1.0)
    k = np.zeros(len(u0), dtype=np.intp)
    for j in range(probs.shape[1]):
        k += u0 >= cdf[:, j]
    k = np.minimum(k, probs.shape[1] - 1)
    lo = np.where(k > 0, np.take_along_axis(cdf, np.maximum(k - 1, 0)[:, None], 1)[:, 0], 0.0)
    width = np.take_along_axis(probs, k[:, None], 1)[:, 0]
    u_new = np.where(width > 0, (u0 - lo) / np.where(width > 0, width, 1.0), 0.0)
    return k, np.clip(u_new, 0.0, np.nextafter(1.0, 0.0))



# ---- (added for dielectric / layered) splitting one uniform into two independent ones
def split_uniform(u, levels=65536):
    """Two independent uniforms from one: a discrete one on ``levels`` cell centres (for a lobe
    choice) and the continuous position inside the cell (for the direction). Exactly independent
    and both uniform when u is; the discrete one is off by at most 0.5 / levels."""
    q = np.asarray(u, dtype=np.float64) * levels
    cell = np.minimum(np.floor(q), levels - 1)
    return (cell + 0.5) / levels, np.clip(q - cell, 0.0, np.nextafter(1.0, 0.0))


def pow_one_minus(x, n):
    """(1 - x)^n for x in [0, 1), 0 at x >= 1, computed as exp(n log1p(-x)): for a sharp lobe
    x = 1 - cos is tiny and rounding 1 - x first would cost n ulps (float32: 6e-4 relative error
    at n = 10000)."""
    inside = x < 1.0
    return np.where(inside, np.exp(n * np.log1p(-np.where(inside, x, 0.0))), 0.0)


def energy_conserving_kd_ks(p):
    """The nearest energy-conserving parameters of a kd + ks model whose specular lobe reflects
    at most ks (normalized Phong, Blinn-Phong): kd and ks scaled by 1 / max(1, kd + ks) per channel."""
    s = np.maximum(1.0, p.kd + p.ks)
    return p.replace(kd=p.kd / s, ks=p.ks / s)


def specular_probability(kd, ks):
    """Probability of sampling the specular lobe of a kd + ks model: the lobes' share of the
    albedo luminance (0.5 for a black material)."""
    ld, ls = luminance(kd), luminance(ks)
    return 0.5 if ld + ls <= 0 else ls / (ld + ls)


def sample_weight(f, wi, pdf):
    """(weight f cos / pdf, pdf) of sampled directions; a sample with pdf <= 0 or a weight that
    overflows fails (the sampling convention: weight = pdf = 0)."""
    ok = pdf > 0
    with np.errstate(over="ignore"):
        weight = np.where(ok[:, None], f * wi[:, 2:3] / np.where(ok, pdf, 1.0)[:, None], 0.0)
    finite = np.isfinite(weight)
    for j in range(weight.shape[1]):  # np.all(finite, axis=1), a column at a time (faster)
        ok &= finite[:, j]
    return np.where(ok[:, None], weight, 0.0), np.where(ok, pdf, 0.0)


def phong_alpha(n):
    """The GGX / Beckmann alpha of a lobe of similar width to a cos^n Phong lobe,
    alpha = sqrt(2 / (n + 2)) (Walter et al. 2007, the Phong-Beckmann relation below eq. 33)."""
    return float(np.sqrt(2.0 / (float(n) + 2.0)))
