"""Shared sampling helpers (numpy, shading frame z = normal). Vectorized over rows."""

from __future__ import annotations

import numpy as np

INV_PI = 1.0 / np.pi


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
    x = r * np.cos(phi)
    y = r * np.sin(phi)
    z = np.sqrt(np.maximum(0.0, 1.0 - x * x - y * y))
    return np.stack([x, y, z], axis=-1)


def cosine_hemisphere_pdf(w):
    return np.maximum(w[..., 2], 0.0) * INV_PI


def reflect_z(w):
    """Mirror direction about the normal (0, 0, 1)."""
    return w * np.array([-1.0, -1.0, 1.0])


def reflect(w, m):
    """Reflect w about the unit vector m: 2 (w.m) m - w."""
    d = np.sum(w * m, axis=-1, keepdims=True)
    return 2.0 * d * m - w


def normalize(v):
    n = np.linalg.norm(v, axis=-1, keepdims=True)
    return v / np.where(n > 0, n, 1.0)


def frame_from_z(z):
    """An orthonormal basis (x, y) around unit vectors z (Duff et al. 2017, branchless ONB)."""
    sign = np.where(z[..., 2] >= 0.0, 1.0, -1.0)
    a = -1.0 / (sign + z[..., 2])
    b = z[..., 0] * z[..., 1] * a
    x = np.stack([1.0 + sign * z[..., 0] ** 2 * a, sign * b, -sign * z[..., 0]], axis=-1)
    y = np.stack([b, sign + z[..., 1] ** 2 * a, -z[..., 1]], axis=-1)
    return x, y
