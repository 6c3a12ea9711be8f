"""Fresnel reflectance (numpy; broadcasting; scalars in give scalars out).

Conventions (docs/conventions.md):
  * ``cos_i`` is the cosine of the angle of incidence measured on the incident side
    (``cos_i >= 0``). A negative ``cos_i`` means the light arrives from the other side of the
    interface: the dielectric functions then swap the media (eta -> 1/eta, cos_i -> -cos_i),
    which is pbrt-v4's ``FrDielectric`` convention.
  * ``eta = n_t / n_i`` (transmitted over incident index). ``eta < 1`` (leaving the denser medium)
    gives total internal reflection beyond the critical angle: R = 1.
  * Conductors: ``n_t = eta + i k`` seen from a medium of index 1.

All formulas are the lecture's (Frisvad, "BRDF, Fresnel Reflectance, and Absorption"):
  r_perp = (n_i cos_i - n_t cos_t) / (n_i cos_i + n_t cos_t)
  r_par  = (n_t cos_i - n_i cos_t) / (n_t cos_i + n_i cos_t)
  R = (|r_perp|^2 + |r_par|^2) / 2,   cos_t^2 = 1 - (n_i/n_t)^2 (1 - cos_i^2)
with complex n_t for conductors (Born & Wolf, Principles of Optics, sec. 14.2).
"""

from __future__ import annotations

import numpy as np

__all__ = [
    "fresnel_dielectric",
    "fresnel_dielectric_polarized",
    "fresnel_dielectric_transmittance",
    "fresnel_conductor",
    "fresnel_conductor_polarized",
    "fresnel_schlick",
    "fresnel_thin_film",
    "fresnel_thin_film_polarized",
    "refracted_cos",
]


def _out(x, scalar):
    return float(x) if scalar else x


def _is_scalar(*args):
    return all(np.ndim(a) == 0 for a in args)


def refracted_cos(cos_i, eta):
    """cos(theta_t) (>= 0) from Snell's law for eta = n_t/n_i, or NaN-free 0 under TIR.

    Written with sin^2 rather than 1 - cos^2 where it matters (float32 twins do the same):
    cos_t^2 = 1 - sin_i^2 / eta^2 (lecture, 'Total internal reflection')."""
    cos_i = np.abs(np.asarray(cos_i, dtype=np.float64))
    eta = np.asarray(eta, dtype=np.float64)
    sin2_i = np.maximum(0.0, 1.0 - cos_i * cos_i)
    sin2_t = sin2_i / (eta * eta)
    return np.sqrt(np.maximum(0.0, 1.0 - sin2_t))


def _snell_sides(cos_i, eta):
    """(|cos_i| clamped to 1, eta as seen from the incident side, sin^2 theta_t, cos theta_t
    (0 under TIR)): light from the other side (cos_i < 0) swaps the media (pbrt-v4 FrDielectric)."""
    cos_i = np.asarray(cos_i, dtype=np.float64)
    eta = np.asarray(eta, dtype=np.float64)
    eta = np.where(cos_i < 0, 1.0 / eta, eta)
    c = np.minimum(np.abs(cos_i), 1.0)
    sin2_t = np.maximum(0.0, 1.0 - c * c) / (eta * eta)
    return c, eta, sin2_t, np.sqrt(np.maximum(0.0, 1.0 - sin2_t))


def fresnel_dielectric_polarized(cos_i, eta):
    """(Rs, Rp): the perpendicular (s) and parallel (p) reflectances of a dielectric interface.

    Lecture: Fresnel equations r_perp, r_par with real indices; TIR when cos_t^2 < 0."""
    scalar = _is_scalar(cos_i, eta)
    c, eta, sin2_t, cos_t = _snell_sides(cos_i, eta)
    tir = sin2_t >= 1.0
    # n_i = 1, n_t = eta (only the ratio matters)
    num_s, den_s = c - eta * cos_t, c + eta * cos_t
    num_p, den_p = eta * c - cos_t, eta * c + cos_t
    # den == 0 only at grazing incidence with eta == 1: the limit of R there is taken as 1.
    rs = np.where(den_s > 0, num_s / np.where(den_s > 0, den_s, 1.0), 1.0)
    rp = np.where(den_p > 0, num_p / np.where(den_p > 0, den_p, 1.0), 1.0)
    Rs = np.where(tir, 1.0, rs * rs)
    Rp = np.where(tir, 1.0, rp * rp)
    return _out(Rs, scalar), _out(Rp, scalar)


def fresnel_dielectric(cos_i, eta):
    """Unpolarized R = (Rs + Rp) / 2 of a dielectric interface; eta = n_t / n_i (lecture)."""
    Rs, Rp = fresnel_dielectric_polarized(cos_i, eta)
    return 0.5 * (Rs + Rp)


def fresnel_dielectric_transmittance(cos_i, eta):
    """T = 1 - R of a dielectric interface, computed without the cancellation of 1 - R near total
    internal reflection: with the lecture's r_perp, r_par (n_i = 1, n_t = eta),
    1 - r_perp^2 = 4 eta cos_i cos_t / (cos_i + eta cos_t)^2 and
    1 - r_par^2 = 4 eta cos_i cos_t / (eta cos_i + cos_t)^2. Same side convention as R."""
    scalar = _is_scalar(cos_i, eta)
    c, eta, sin2_t, cos_t = _snell_sides(cos_i, eta)
    num = 4.0 * eta * c * cos_t
    den_s = (c + eta * cos_t) ** 2
    den_p = (eta * c + cos_t) ** 2
    Ts = np.where(den_s > 0, num / np.where(den_s > 0, den_s, 1.0), 0.0)
    Tp = np.where(den_p > 0, num / np.where(den_p > 0, den_p, 1.0), 0.0)
    T = np.where(sin2_t >= 1.0, 0.0, 0.5 * (Ts + Tp))
    return _out(T, scalar)


def fresnel_conductor_polarized(cos_i, eta, k):
    """(Rs, Rp) for a conductor n_t = eta + i k seen from index 1 (lecture's r_perp, r_par with a
    complex n_t; Born & Wolf sec. 14.2).

    With w = n_t cos_t = sqrt(n_t^2 - sin_i^2) (principal complex root):
      r_perp = (cos_i - w) / (cos_i + w),   r_par = (n_t^2 cos_i - w) / (n_t^2 cos_i + w).
    With k = 0 this is exactly ``fresnel_dielectric_polarized`` (including TIR for eta < 1,
    where w becomes imaginary and |r| = 1). cos_i is clamped to [0, 1]."""
    scalar = _is_scalar(cos_i, eta, k)
    c = np.clip(np.asarray(cos_i, dtype=np.float64), 0.0, 1.0)
    eta = np.asarray(eta, dtype=np.float64)
    k = np.asarray(k, dtype=np.float64)
    shape = np.broadcast_shapes(c.shape, eta.shape, k.shape)
    if len(shape) == 2 and c.shape == (shape[0], 1) and 1 < shape[1] <= 4 \
            and all(v.ndim < 2 or v.shape[0] == 1 for v in (eta, k)):
        # (N, 1) cosines against per-channel indices (the models' RGB Fresnel): one channel at a time
        # on a contiguous column is about 1.7 times faster than numpy's broadcasting of (N, 1)
        # against (1, 3), whose inner loops run over 3 elements; the same arithmetic per element
        Rs, Rp = np.empty(shape), np.empty(shape)
        eta, k = (np.broadcast_to(v, (1, shape[1]))[0] for v in (eta, k))
        for j in range(shape[1]):
            Rs[:, j], Rp[:, j] = _conductor(c[:, 0], eta[j], k[j])
        return Rs, Rp
    Rs, Rp = _conductor(c, eta, k)
    return _out(Rs, scalar), _out(Rp, scalar)


def _conductor(c, eta, k):
    """(Rs, Rp) of ``fresnel_conductor_polarized`` for c already clamped to [0, 1]."""
    n = eta + 1j * k
    sin2 = (1.0 - c * c).astype(np.complex128)
    n2 = n * n
    w = np.sqrt(n2 - sin2)
    a = n2 * c
    den_s = np.abs(c + w) ** 2
    den_p = np.abs(a + w) ** 2
    Rs = np.where(den_s > 0, np.abs(c - w) ** 2 / np.where(den_s > 0, den_s, 1.0), 1.0)
    Rp = np.where(den_p > 0, np.abs(a - w) ** 2 / np.where(den_p > 0, den_p, 1.0), 1.0)
    return np.minimum(Rs, 1.0), np.minimum(Rp, 1.0)


def fresnel_conductor(cos_i, eta, k):
    """Unpolarized R for a conductor n_t = eta + i k seen from index 1."""
    Rs, Rp = fresnel_conductor_polarized(cos_i, eta, k)
    return 0.5 * (Rs + Rp)


def fresnel_schlick(cos_i, f0):
    """Schlick 1994, 'An Inexpensive BRDF Model for Physically-based Rendering', eq. 15:
    F = f0 + (1 - f0) (1 - cos_i)^5."""
    scalar = _is_scalar(cos_i, f0)
    c = np.clip(np.asarray(cos_i, dtype=np.float64), 0.0, 1.0)
    f0 = np.asarray(f0, dtype=np.float64)
    F = f0 + (1.0 - f0) * (1.0 - c) ** 5
    return _out(F, scalar)


def f0_dielectric(eta):
    """Normal-incidence reflectance ((n-1)/(n+1))^2 (lecture's R at cos_i = 1)."""
    eta = np.asarray(eta, dtype=np.float64)
    return ((eta - 1.0) / (eta + 1.0)) ** 2


def f0_conductor(eta, k):
    """Normal-incidence reflectance ((n-1)^2 + k^2) / ((n+1)^2 + k^2) of a conductor."""
    eta = np.asarray(eta, dtype=np.float64)
    k = np.asarray(k, dtype=np.float64)
    return ((eta - 1.0) ** 2 + k * k) / ((eta + 1.0) ** 2 + k * k)


def fresnel_thin_film_polarized(cos_i, wavelength_nm, film_ior, thickness_nm, base_ior):
    """(Rs, Rp) of a thin film (real index film_ior, thickness_nm) on a base of index base_ior
    (real, or complex n + i k with k >= 0), seen from index 1: the Airy summation of the waves
    reflected back and forth inside the film (Born & Wolf, Principles of Optics, sec. 7.6.1;
    Hecht, Optics, sec. 9.7):

      r = (r01 + r12 e^{i phi}) / (1 + r01 r12 e^{i phi}),  phi = (2 pi / lambda) 2 d n1 cos_1,

    with the amplitude coefficients of the two interfaces written with w_j = n_j cos_j =
    sqrt(n_j^2 - sin_0^2) (principal root: a decaying wave when w_j is complex):
    s: r_ij = (w_i - w_j) / (w_i + w_j);  p: r_ij = (n_j^2 w_i - n_i^2 w_j) / (n_j^2 w_i + n_i^2 w_j).
    Zero thickness gives r = r02, the plain Fresnel coefficient of the base."""
    scalar = _is_scalar(cos_i, wavelength_nm, film_ior, thickness_nm, base_ior)
    c = np.clip(np.asarray(cos_i, dtype=np.float64), 0.0, 1.0)
    lam = np.asarray(wavelength_nm, dtype=np.float64)
    n1 = np.asarray(film_ior, dtype=np.complex128)
    n2 = np.asarray(base_ior, dtype=np.complex128)
    d = np.asarray(thickness_nm, dtype=np.float64)
    sin2 = 1.0 - c * c
    w0 = c.astype(np.complex128)
    w1 = np.sqrt(n1 * n1 - sin2)
    w2 = np.sqrt(n2 * n2 - sin2)
    e = np.exp(1j * (4.0 * np.pi / lam) * d * w1)
    out = []
    for pol in ("s", "p"):
        if pol == "s":
            r01 = _ratio(w0 - w1, w0 + w1)
            r12 = _ratio(w1 - w2, w1 + w2)
        else:
            r01 = _ratio(n1 * n1 * w0 - w1, n1 * n1 * w0 + w1)
            r12 = _ratio(n2 * n2 * w1 - n1 * n1 * w2, n2 * n2 * w1 + n1 * n1 * w2)
        num = r01 + r12 * e
        den = 1.0 + r01 * r12 * e
        R = np.where(np.abs(den) > 1e-300, np.abs(num) ** 2 / np.maximum(np.abs(den) ** 2, 1e-300), 1.0)
        out.append(np.clip(R, 0.0, 1.0))
    return _out(out[0], scalar), _out(out[1], scalar)


def _ratio(a, b):
    """a / b, and -1 where b = 0 (grazing incidence on an interface of equal indices: the limit)."""
    ok = np.abs(b) > 0
    return np.where(ok, a / np.where(ok, b, 1.0), -1.0)


def fresnel_thin_film(cos_i, wavelength_nm, film_ior, thickness_nm, base_ior):
    """Unpolarized reflectance (Rs + Rp) / 2 of a thin film on a base, from index 1 (see
    ``fresnel_thin_film_polarized``). Arrays broadcast; wavelength and thickness in nm."""
    rs, rp = fresnel_thin_film_polarized(cos_i, wavelength_nm, film_ior, thickness_nm, base_ior)
    return 0.5 * (rs + rp)
