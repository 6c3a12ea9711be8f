"""Spectral optics: indices of refraction n(lambda) + i k(lambda) and spectrum -> RGB.

    materials()                    tabulated names ("Au", "Ag", "Cu", "Al", "Cr", "Fe", "Ti",
                                   "BK7", "F2", "SF11", "SiO2", "H2O", "diamond", "sapphire")
    ior(name, wavelength_nm)       complex n + i k (k >= 0 absorbs; 0 for the dielectrics)
    to_rgb(values, wavelength_nm)  spectrum -> linear Rec.709 RGB (CIE 1931 2 deg, D65;
                                   a flat 1 gives (1, 1, 1))
    channel_ior(name)              one real index per RGB channel: n(lambda) averaged with the
                                   channel's colour-matching weights (the rasterizer's dispersion)

Wavelengths are in nanometres. Metals are measured tables (``data/<name>.csv``, each naming its
source), interpolated linearly in wavelength and held constant beyond their ends; dielectrics
are dispersion formulas (``dispersion.FORMULAS``). ``colorimetry`` holds the observer,
``upsampling`` the RGB -> spectrum basis of the spectral reference renderer.
"""

from __future__ import annotations

import functools

import numpy as np

from viewer.spectral import colorimetry, dispersion, upsampling
from viewer.spectral.colorimetry import rgb_weight, to_rgb
from viewer.spectral.upsampling import rgb_to_spectrum

__all__ = ["materials", "ior", "to_rgb", "channel_ior", "is_conductor", "describe", "source", "rgb_weight",
           "rgb_to_spectrum", "colorimetry", "dispersion", "upsampling", "LAMBDA_MIN", "LAMBDA_MAX"]

METALS = ("Au", "Ag", "Cu", "Al", "Cr", "Fe", "Ti")
LAMBDA_MIN, LAMBDA_MAX = 360.0, 780.0      # the range the observer is tabulated (and sampled) on

_METAL_NAMES = {"Au": "gold", "Ag": "silver", "Cu": "copper", "Al": "aluminium", "Cr": "chromium",
                "Fe": "iron", "Ti": "titanium"}


def materials() -> list[str]:
    """Every name ``ior`` knows: metals first, then dielectrics."""
    return list(METALS) + list(dispersion.FORMULAS)


def _check(name):
    if not isinstance(name, str) or name not in materials():
        raise KeyError(f"unknown spectral material {name!r}; known: {', '.join(materials())}")


@functools.lru_cache(maxsize=None)
def metal_table(name: str) -> np.ndarray:
    """(M, 3) rows wavelength_nm, n, k of a tabulated metal."""
    return colorimetry.read_csv(colorimetry.DATA / f"{name}.csv")


def source(name: str) -> str:
    """The published source of a material's data."""
    _check(name)
    if name in METALS:
        for line in (colorimetry.DATA / f"{name}.csv").read_text().splitlines():
            if line.startswith("# source:"):
                return line[len("# source:"):].strip()
    return dispersion.FORMULAS[name][4]


def describe(name: str) -> str:
    _check(name)
    if name in METALS:
        return _METAL_NAMES[name]
    return dispersion.FORMULAS[name][3]


def is_conductor(name: str) -> bool:
    _check(name)
    return name in METALS


def ior(name: str, wavelength_nm):
    """Complex index of refraction n + i k at ``wavelength_nm`` (scalar -> complex, array -> array
    of complex128 of the same shape)."""
    _check(name)
    lam = np.asarray(wavelength_nm, dtype=np.float64)
    if not np.all(np.isfinite(lam)) or np.any(lam <= 0):
        raise ValueError(f"ior({name!r}): wavelengths must be finite and positive (nanometres)")
    if name in METALS:
        t = metal_table(name)
        out = np.interp(lam, t[:, 0], t[:, 1]) + 1j * np.interp(lam, t[:, 0], t[:, 2])
    else:
        out = dispersion.sellmeier(name, lam).astype(np.complex128)
    return complex(out) if np.ndim(out) == 0 else out


@functools.lru_cache(maxsize=None)
def _channel_ior(name: str) -> tuple[float, float, float]:
    wl = colorimetry.tables()[0]
    w = colorimetry.weights()                    # (3, N), each row sums to 1 (a flat spectrum is white)
    n = np.real(ior(name, wl))
    return tuple(float(x) for x in (w @ n) / w.sum(axis=1))


def channel_ior(name: str) -> np.ndarray:
    """(3,) real index of refraction per linear Rec.709 channel (R, G, B): the spectral centroid
    of n(lambda) weighted by that channel's colour-matching response,

        n_c = sum_l W_c(l) n(l) / sum_l W_c(l)      (1 nm grid, W = ``colorimetry.weights()``,
                                                      the CIE 1931 observer under D65 in Rec.709)

    the weights the channel's value is made of (RGB_c = sum_l W_c(l) v(l)). Why this average: a
    channel renders sum_l W_c(l) L(n(l)); with L expanded to first order about n_c the linear
    term is sum_l W_c(l) (n(l) - n_c) L'(n_c) = 0, so tracing the channel with n_c alone errs
    only at second order in the spread of n over the channel (W is signed: the red channel's
    negative lobe near 500 nm is kept, as it is in ``to_rgb``). For normal dispersion n falls
    with wavelength, so n_B > n_G > n_R. The real part only: for a metal this is no model of
    its colour (the Fresnel tables are), only of how a refracting ray would bend."""
    _check(name)
    return np.array(_channel_ior(name))
