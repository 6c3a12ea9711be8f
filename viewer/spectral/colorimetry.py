"""Spectrum -> colour: the CIE 1931 2 degree observer under illuminant D65, linear Rec.709 RGB.

The tables (``data/cie1931_d65.csv``, 360-780 nm at 1 nm) are the CIE's, written once from
colour-science by ``tools/spectral_tables.py``; they are shipped as data so that the viewer does
not import colour-science (about a second of start-up) for two fixed standard tables.

A reflectance (or transmittance, or relative radiance) spectrum v(lambda) is seen under D65:

    XYZ = sum_l cmf(l) D65(l) v(l) / sum_l y_bar(l) D65(l)      (1 nm sums, CIE 015 sec. 7)
    RGB = M XYZ

with M the Rec.709 / sRGB matrix built from the primaries' chromaticities (ITU-R BT.709:
r (0.64, 0.33), g (0.30, 0.60), b (0.15, 0.06)) and the white point of the D65 table itself, so
that a flat spectrum v = 1 gives exactly (1, 1, 1). ``weights()`` is the (3, N) matrix W with
RGB = W v on the 1 nm grid.
"""

from __future__ import annotations

import functools
import pathlib

import numpy as np

DATA = pathlib.Path(__file__).resolve().parent / "data"
#: Rec.709 luminance of linear RGB: the Y row of the RGB -> XYZ matrix (ITU-R BT.709), the one
#: place the weights are written (GLSL: ``luminance`` in shaders/common/math.glsl)
LUMINANCE_REC709 = np.array([0.2126, 0.7152, 0.0722])


def luminance(rgb):
    """Rec.709 luminance of linear RGB (..., 3) -> (...)."""
    return np.asarray(rgb, dtype=np.float64) @ LUMINANCE_REC709
REC709_XY = ((0.64, 0.33), (0.30, 0.60), (0.15, 0.06))


def read_csv(path: pathlib.Path) -> np.ndarray:
    """The numeric rows of one of the data files (comment lines start with '#', one header)."""
    lines = [ln for ln in path.read_text().splitlines() if ln.strip() and not ln.startswith("#")]
    return np.array([[float(v) for v in ln.split(",")] for ln in lines[1:]], dtype=np.float64)


@functools.lru_cache(maxsize=None)
def tables() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(wavelengths (N,), CMFs (N, 3), D65 (N,)) on the 1 nm grid 360-780 nm."""
    a = read_csv(DATA / "cie1931_d65.csv")
    return a[:, 0], a[:, 1:4], a[:, 4]


def rgb_to_xyz_matrix(white_xyz) -> np.ndarray:
    """RGB -> XYZ for the Rec.709 primaries and the given white (the standard construction:
    columns = primaries' XYZ scaled so that RGB (1, 1, 1) maps to the white)."""
    prim = np.array([[x / y, 1.0, (1.0 - x - y) / y] for x, y in REC709_XY]).T
    s = np.linalg.solve(prim, np.asarray(white_xyz, dtype=np.float64))
    return prim * s[None, :]


def rgb_to_xyz(rgb) -> np.ndarray:
    """Linear Rec.709 RGB (..., 3) of this package (white: the flat spectrum) back to CIE XYZ."""
    _, cmf, d65 = tables()
    white = (cmf * d65[:, None]).sum(axis=0) / np.sum(cmf[:, 1] * d65)
    return np.asarray(rgb, np.float64) @ rgb_to_xyz_matrix(white).T


@functools.lru_cache(maxsize=None)
def _weights() -> np.ndarray:
    wl, cmf, d65 = tables()
    norm = np.sum(cmf[:, 1] * d65)
    xyz_w = cmf.T * d65[None, :] / norm          # (3, N): XYZ = xyz_w @ v
    white = xyz_w.sum(axis=1)                    # XYZ of the flat spectrum (Y = 1)
    m = np.linalg.inv(rgb_to_xyz_matrix(white))
    w = m @ xyz_w
    w.setflags(write=False)
    return w


def weights() -> np.ndarray:
    """(3, N) weights: RGB = weights() @ v for a spectrum v sampled on ``tables()[0]``."""
    return _weights()


def resample(values, wavelength_nm) -> np.ndarray:
    """Spectra (..., M) given at ``wavelength_nm`` (M,) resampled linearly onto the 1 nm grid
    (..., N); beyond the given range the end values hold."""
    wl_grid = tables()[0]
    wl = np.asarray(wavelength_nm, dtype=np.float64).reshape(-1)
    v = np.asarray(values, dtype=np.float64)
    if v.shape[-1:] != wl.shape:
        raise ValueError(f"to_rgb: values have {v.shape[-1] if v.ndim else 0} samples along the last "
                         f"axis but there are {wl.size} wavelengths")
    if not np.all(np.isfinite(wl)):
        raise ValueError("to_rgb: wavelengths must be finite")
    order = np.argsort(wl, kind="stable")
    wl, v = wl[order], v[..., order]
    if wl.size == 1:
        return np.broadcast_to(v, v.shape[:-1] + wl_grid.shape).copy()
    idx = np.clip(np.searchsorted(wl, wl_grid, side="right") - 1, 0, wl.size - 2)
    w0, w1 = wl[idx], wl[idx + 1]
    t = np.clip((wl_grid - w0) / np.where(w1 > w0, w1 - w0, 1.0), 0.0, 1.0)
    return v[..., idx] * (1.0 - t) + v[..., idx + 1] * t


def to_rgb(values, wavelength_nm) -> np.ndarray:
    """Linear Rec.709 RGB (..., 3) of spectra (..., M) sampled at ``wavelength_nm`` (M,)."""
    return resample(values, wavelength_nm) @ weights().T


def rgb_weight(wavelength_nm) -> np.ndarray:
    """W(lambda) (..., 3) per nanometre, linearly interpolated: the integrand of ``to_rgb`` for a
    Monte Carlo estimate RGB ~ W(lambda) v(lambda) / pdf(lambda)."""
    wl_grid = tables()[0]
    lam = np.asarray(wavelength_nm, dtype=np.float64)
    return np.stack([np.interp(lam, wl_grid, weights()[c], left=0.0, right=0.0) for c in range(3)],
                    axis=-1)
