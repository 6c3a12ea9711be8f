"""Order-2 spherical harmonics (9 coefficients per RGB channel) for irradiance environment maps.

Ramamoorthi & Hanrahan 2001, "An Efficient Representation for Irradiance Environment Maps"
(SIGGRAPH 2001). The real basis of their eq. 3, written with exact constants (their decimals in
brackets), in the order (l, m) = (0,0), (1,-1), (1,0), (1,1), (2,-2), (2,-1), (2,0), (2,1), (2,2):

    Y00  = 1 / (2 sqrt(pi))                  [0.282095]
    Y1-1 = sqrt(3 / 4pi) y,  Y10 = sqrt(3 / 4pi) z,  Y11 = sqrt(3 / 4pi) x        [0.488603]
    Y2-2 = sqrt(15 / 4pi) xy, Y2-1 = sqrt(15 / 4pi) yz, Y21 = sqrt(15 / 4pi) xz   [1.092548]
    Y20  = sqrt(5 / 16pi) (3 z^2 - 1)        [0.315392]
    Y22  = sqrt(15 / 16pi) (x^2 - y^2)       [0.546274]

with (x, y, z) the components of the unit direction *in world coordinates*. (The paper's z is
its "up"; ours is +y. Any orthonormal real basis serves as long as projection and evaluation use
the same one: the span of degrees 0-2 is invariant under rotations, so E(n) does not depend on
which axis is called z.)

Irradiance (eqs. 7-8, 12-13): E(n) = sum_lm A_l L_lm Y_lm(n), A_0 = pi, A_1 = 2 pi / 3,
A_2 = pi / 4 (the clamped-cosine kernel's coefficients); a Lambertian surface of albedo rho
reflects radiance rho / pi * E(n).

Error of order 2 (what the tests hold it to): by the Funk-Hecke theorem the exact irradiance of
a zonal environment is sum_l A_l L_l0 Y_l0(n); order 2 drops l >= 3, where A_3 = A_5 = ... = 0
and A_4 = -pi/24, A_6 = pi/64, A_8 = -pi/128, ... For the cosine-lobe sky L(d) = max(0, d.y),
whose own coefficients are L_l0 = A_l sqrt((2l+1)/4pi), the error is
sum_{l >= 4, even} A_l^2 (2l+1)/(4pi) P_l(cos beta), at most (beta = 0 or pi, P_l = 1)
0.01227 (l = 4) + 0.00249 (l = 6) + 0.00081 (l = 8) + ... = 0.01636, i.e. 0.78 % of the maximum
E = 2 pi / 3; at beta = pi/2 it is 0.0040. The measured error of ``project_latlong`` on a
256 x 512 map is 0.01637 (beta = 0). For arbitrary environments Ramamoorthi & Hanrahan bound
the order-2 irradiance error by 9 % (3 % on average); smooth lobes do far better.
"""

from __future__ import annotations

import math

import numpy as np

from viewer.environment.latlong import TWO_PI

C0 = 1.0 / (2.0 * math.sqrt(math.pi))
C1 = math.sqrt(3.0 / (4.0 * math.pi))
C2 = math.sqrt(15.0 / (4.0 * math.pi))
C20 = math.sqrt(5.0 / (16.0 * math.pi))
C22 = math.sqrt(15.0 / (16.0 * math.pi))
A_HAT = np.array([math.pi] + [2.0 * math.pi / 3.0] * 3 + [math.pi / 4.0] * 5)


def basis(d) -> np.ndarray:
    """(..., 9) real SH basis of unit directions d (..., 3) (Ramamoorthi & Hanrahan 2001, eq. 3)."""
    d = np.asarray(d, dtype=np.float64)
    x, y, z = d[..., 0], d[..., 1], d[..., 2]
    return np.stack([np.full_like(x, C0), C1 * y, C1 * z, C1 * x, C2 * x * y, C2 * y * z,
                     C20 * (3.0 * z * z - 1.0), C2 * x * z, C22 * (x * x - y * y)], axis=-1)


def _texel_basis_integrals(height: int, width: int) -> tuple[np.ndarray, np.ndarray]:
    """Exact integrals of the 9 basis functions over every texel, as row factors (H, 9, 2) and
    column factors (W, 9, 2): weights[i, j, k] = sum_t rows[i, k, t] * cols[j, k, t].

    With mu = cos(theta) = d.y and phi = 2 pi (u - 0.5): d = (s sin phi, mu, -s cos phi),
    s = sqrt(1 - mu^2), dOmega = dmu dphi, and each basis function is g(mu) h(phi):
        1; mu; -s cos; s sin; mu s sin; -mu s cos; 3 s^2 cos^2 - 1; -s^2 sin cos; s^2 sin^2 - mu^2
    so texel integrals are (int g dmu) (int h dphi), both in closed form (Y20 and Y22 are sums
    of two such products, hence the trailing axis of 2 terms). This makes the
    projection exact for the piecewise-constant map (a constant map gives L_00 only)."""
    mu = np.cos(np.pi * np.arange(height + 1) / height)  # decreasing: row i spans mu[i] -> mu[i+1]
    ph = TWO_PI * (np.arange(width + 1) / width - 0.5)
    s = np.sqrt(np.maximum(0.0, 1.0 - mu * mu))
    asn = np.arcsin(np.clip(mu, -1.0, 1.0))

    def rows(F):  # integral over mu from mu[i+1] to mu[i] (dOmega is positive)
        return F[:-1] - F[1:]

    def cols(G):
        return G[1:] - G[:-1]

    g_1 = rows(mu)                                  # int 1 dmu
    g_mu = rows(mu * mu / 2.0)                      # int mu
    g_s = rows((mu * s + asn) / 2.0)                # int sqrt(1 - mu^2)
    g_mus = rows(-(s ** 3) / 3.0)                   # int mu sqrt(1 - mu^2)
    g_mu2 = rows(mu ** 3 / 3.0)                     # int mu^2
    g_s2 = g_1 - g_mu2                              # int (1 - mu^2)
    h_1 = cols(ph)
    h_sin = cols(-np.cos(ph))
    h_cos = cols(np.sin(ph))
    h_sin2 = cols(ph / 2.0 - np.sin(2.0 * ph) / 4.0)
    h_cos2 = cols(ph / 2.0 + np.sin(2.0 * ph) / 4.0)
    h_sincos = cols(np.sin(ph) ** 2 / 2.0)
    # x = s sin, y = mu, z = -s cos. Y20 = C20 (3 s^2 cos^2 - 1) and Y22 = C22 (s^2 sin^2 - mu^2)
    # are sums of two separable terms: the last axis holds up to two (row, column) factor pairs.
    R = np.zeros((height, 9, 2))
    Cc = np.zeros((width, 9, 2))
    R[:, 0, 0], Cc[:, 0, 0] = C0 * g_1, h_1
    R[:, 1, 0], Cc[:, 1, 0] = C1 * g_mu, h_1                 # y
    R[:, 2, 0], Cc[:, 2, 0] = -C1 * g_s, h_cos               # z
    R[:, 3, 0], Cc[:, 3, 0] = C1 * g_s, h_sin                # x
    R[:, 4, 0], Cc[:, 4, 0] = C2 * g_mus, h_sin              # xy
    R[:, 5, 0], Cc[:, 5, 0] = -C2 * g_mus, h_cos             # yz
    R[:, 6, 0], Cc[:, 6, 0] = 3.0 * C20 * g_s2, h_cos2       # 3 z^2
    R[:, 6, 1], Cc[:, 6, 1] = -C20 * g_1, h_1                # -1
    R[:, 7, 0], Cc[:, 7, 0] = -C2 * g_s2, h_sincos           # xz
    R[:, 8, 0], Cc[:, 8, 0] = C22 * g_s2, h_sin2             # x^2
    R[:, 8, 1], Cc[:, 8, 1] = -C22 * g_mu2, h_1              # -y^2
    return R, Cc


def project_latlong(latlong: np.ndarray) -> np.ndarray:
    """(9, 3) SH coefficients L_lm of a lat-long radiance map (H, W, 3):
    L_lm = integral L(d) Y_lm(d) dOmega, with each texel's radiance constant over the texel and
    the basis integrated exactly over it (a solid-angle weighted sum)."""
    img = np.asarray(latlong, dtype=np.float64)
    h, w = img.shape[:2]
    R, Cc = _texel_basis_integrals(h, w)
    return np.einsum("ikt,jkt,ijc->kc", R, Cc, img, optimize=True)


def project_function(f, n: int = 256) -> np.ndarray:
    """(9, 3) coefficients of a radiance function f(dirs (N, 3)) -> (N, 3), by a lat-long
    sampling of n x 2n points (for tests and analytic environments)."""
    from viewer.environment.latlong import texel_directions

    dirs = texel_directions(n, 2 * n)
    vals = np.asarray(f(dirs.reshape(-1, 3)), dtype=np.float64).reshape(n, 2 * n, -1)
    if vals.shape[-1] == 1:
        vals = np.repeat(vals, 3, axis=-1)
    return project_latlong(vals)


def evaluate(coeffs, dirs) -> np.ndarray:
    """(N, 3) value of the SH expansion sum L_lm Y_lm(d) (the band-limited radiance)."""
    return basis(dirs) @ np.asarray(coeffs, dtype=np.float64)


def irradiance(coeffs, normals) -> np.ndarray:
    """(N, 3) irradiance E(n) = sum A_l L_lm Y_lm(n) (Ramamoorthi & Hanrahan 2001, eqs. 7-8,
    A_0 = pi, A_1 = 2 pi / 3, A_2 = pi / 4, eq. 12 and the explicit form of eq. 13)."""
    c = np.asarray(coeffs, dtype=np.float64) * A_HAT[:, None]
    return basis(normals) @ c


def lambert_radiance(coeffs, normals, albedo) -> np.ndarray:
    """(N, 3) radiance reflected by a Lambertian surface: albedo / pi * E(n)."""
    return np.asarray(albedo, dtype=np.float64) / math.pi * irradiance(coeffs, normals)


def cosine_lobe_irradiance(cos_beta) -> np.ndarray:
    """Exact irradiance at a normal n from the environment L(d) = max(0, d.a) (a unit axis),
    with cos_beta = n.a: E = integral max(0, d.a) max(0, d.n) dOmega
    = (2/3) ((pi - beta) cos(beta) + sin(beta)).

    Derivation: E = integral over the lune where d.a > 0 and d.n > 0 of (d.a)(d.n). Write
    n = cos(beta) a + sin(beta) b with b perpendicular to a, and use spherical coordinates about
    c = a x b: d.a = sin t cos p, d.b = sin t sin p, the lune is p in [beta - pi/2, pi/2], and
    integral sin^3 t dt = 4/3. Then
    E = (4/3) [cos(beta) int cos^2 p dp + sin(beta) int cos p sin p dp]
      = (4/3) [cos(beta) ((pi - beta)/2 + sin(2 beta)/4) + sin(beta) sin^2(beta) / 2]
      = (2/3) ((pi - beta) cos(beta) + sin(beta)).
    Checks: beta = 0 gives 2 pi / 3 (integral of cos^2 over a hemisphere), beta = pi/2 gives
    2/3, beta = pi gives 0."""
    cb = np.clip(np.asarray(cos_beta, dtype=np.float64), -1.0, 1.0)
    beta = np.arccos(cb)
    return (2.0 / 3.0) * ((np.pi - beta) * cb + np.sin(beta))
