"""Display encoding in numpy, the twin of ``shaders/common/colour.glsl`` and
``shaders/passes/tonemap.frag``: exposure (EV), optional tone mapping, the piecewise sRGB
curve (IEC 61966-2-1), then 8 bits as GL stores a float in an RGBA8 target
(round(clamp(c, 0, 1) * 255)). NaN/Inf become magenta, as in the shader."""

from __future__ import annotations

import numpy as np

TONEMAPS = ("none", "reinhard", "aces", "filmic")


def srgb_encode(c: np.ndarray) -> np.ndarray:
    c = np.maximum(c, 0.0)
    lo = 12.92 * c
    hi = 1.055 * np.power(c, 1.0 / 2.4) - 0.055
    return np.where(c >= 0.0031308, hi, lo)


def tonemap_reinhard(c):
    """Reinhard et al. 2002, simple global operator L / (1 + L)."""
    return c / (1.0 + c)


def tonemap_aces(c):
    """Narkowicz 2015, 'ACES Filmic Tone Mapping Curve'."""
    a, b, cc, d, e = 2.51, 0.03, 2.43, 0.59, 0.14
    return np.clip((c * (a * c + b)) / (c * (cc * c + d) + e), 0.0, 1.0)


def _hable(x):
    A, B, C, D, E, F = 0.15, 0.50, 0.10, 0.20, 0.02, 0.30
    return ((x * (A * x + C * B) + D * E) / (x * (A * x + B) + D * F)) - E / F


def tonemap_filmic(c):
    """Hable 2010, 'Filmic Tonemapping for Real-time Rendering' (Uncharted 2), white point 11.2."""
    return _hable(2.0 * c) / _hable(np.float64(11.2))


def tonemap(c: np.ndarray, name: str = "none") -> np.ndarray:
    if name == "reinhard":
        return tonemap_reinhard(c)
    if name == "aces":
        return tonemap_aces(c)
    if name == "filmic":
        return tonemap_filmic(c)
    return c


def to_srgb8(linear: np.ndarray, exposure: float = 0.0, tonemap_name: str = "none") -> np.ndarray:
    """(H, W, 3) linear radiance -> (H, W, 3) uint8 sRGB, as the rasterizer's tone-map pass."""
    c = np.asarray(linear, dtype=np.float64)
    bad = ~np.all(np.isfinite(c), axis=-1)
    c = np.where(np.isfinite(c), c, 0.0) * (2.0 ** float(exposure))
    e = np.clip(srgb_encode(tonemap(c, tonemap_name)), 0.0, 1.0)
    out = np.floor(e * 255.0 + 0.5).astype(np.uint8)
    out[bad] = (255, 0, 255)
    return out
