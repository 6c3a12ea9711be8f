"""The RGB Fresnel reflectance of a spectral material: R_rgb(theta) = to_rgb(R(theta, lambda)).

For ``spectral = "NAME"`` in a microfacet or mirror material the RGB renderers (the GLSL
rasterizer and the numpy twins) read the Fresnel colour from one table per material:

  * TABLE_N samples at cos theta_j = (j / (TABLE_N - 1))^2 (dense near grazing, where R climbs
    to 1), j = 0 .. TABLE_N - 1;
  * each entry is the spectral integral of the exact unpolarized Fresnel reflectance of
    n(lambda) + i k(lambda) (``fresnel_conductor``; k = 0 for a dielectric) seen under D65 by the
    CIE 1931 observer, on the 5 nm grid 360-780 nm, kept as integrated (only clipped at 0) and
    rounded to float32, the numbers the GLSL twin receives. Gold's red is 1.038 at normal
    incidence: its spectrum lies outside the Rec.709 gamut, and linear RGB may exceed 1 there.
    Clipping it to 1 shifted the hue away from the spectral reference, which integrates the same
    spectrum and shows 1.038; every spectral reflectance is <= 1 at every wavelength, so no
    energy is created (a white furnace of the spectral reference has the same value).
    Where 1 - F is a transmittance (the microfacet model's diffuse base) it is clipped at 0;
  * between samples both twins interpolate linearly in sqrt(cos theta).

The table reaches GLSL through the material block ``u_mat``: a ``spectral`` parameter packs its
choice index and the float offset of its 3 * TABLE_N values, appended after the material's
block (``viewer.gl.brdf_glsl``).

A spectral dielectric (``dielectric`` model, a ``layered`` coating) has no table: its RGB
reflectance is grey to within 1e-3 (the spectral R(theta) of BK7 or diamond differs between
channels by less than that below the critical angle), so the RGB renderers use one ``ior``,
n at the helium d line (587.56 nm), and only the spectral reference traces n(lambda).
"""

from __future__ import annotations

import functools

import numpy as np

from viewer import spectral

TABLE_N = 24
D_LINE_NM = 587.56
RGB_WAVELENGTHS_NM = (650.0, 550.0, 450.0)   # the three-wavelength RGB approximation (presets)
GRID_NM = np.arange(360.0, 781.0, 5.0)
NONE = "none"


def choices() -> tuple[str, ...]:
    return (NONE,) + tuple(spectral.materials())


def dielectric_choices() -> tuple[str, ...]:
    return (NONE,) + tuple(n for n in spectral.materials() if not spectral.is_conductor(n))


def table_cos() -> np.ndarray:
    return (np.arange(TABLE_N) / (TABLE_N - 1.0)) ** 2


def spectral_reflectance(name: str, cos, wavelength_nm=GRID_NM) -> np.ndarray:
    """R(cos theta, lambda): (..., len(wavelength_nm)), from index 1 onto n + i k."""
    from viewer.brdf.fresnel import fresnel_conductor

    n = spectral.ior(name, np.asarray(wavelength_nm, dtype=np.float64))
    c = np.asarray(cos, dtype=np.float64)[..., None]
    return fresnel_conductor(c, n.real, n.imag)


@functools.lru_cache(maxsize=None)
def _table(name: str) -> np.ndarray:
    rgb = spectral.to_rgb(spectral_reflectance(name, table_cos()), GRID_NM)
    t = np.maximum(rgb, 0.0).astype(np.float32).astype(np.float64)
    t.setflags(write=False)
    return t


def table(name: str) -> np.ndarray:
    """(TABLE_N, 3) RGB Fresnel reflectance of a spectral material at ``table_cos()``."""
    return _table(name)


def lookup(name: str, cos) -> np.ndarray:
    """R_rgb(cos) (N, 3) from the table, interpolated as the GLSL twin does."""
    t = _table(name)
    x = np.sqrt(np.clip(np.asarray(cos, dtype=np.float64).reshape(-1), 0.0, 1.0)) * (TABLE_N - 1)
    i = np.minimum(np.floor(x).astype(np.int64), TABLE_N - 2)
    f = (x - i)[:, None]
    return t[i] * (1.0 - f) + t[i + 1] * f


def packed(name: str) -> np.ndarray:
    """The 3 * TABLE_N floats the material block carries (r, g, b per sample)."""
    return _table(name).reshape(-1)


def rgb_defaults(name: str) -> dict:
    """The scalar parameters a spectral material implies where the file does not give them:
    ``ior`` = n(d line) for dielectrics; ``eta``, ``k`` = n, k at 650 / 550 / 450 nm (the
    three-wavelength approximation the plots compare against)."""
    n3 = spectral.ior(name, np.array(RGB_WAVELENGTHS_NM))
    out = {"eta": np.maximum(n3.real, 0.01), "k": n3.imag.copy()}
    if not spectral.is_conductor(name):
        out["ior"] = float(spectral.ior(name, D_LINE_NM).real)
    return out


def implied_scalars(name: str) -> dict:
    """What a ``spectral`` choice fills in where the file does not give it: nothing for
    ``none``, else ``rgb_defaults``."""
    return {} if name == NONE else rgb_defaults(name)


def param(dielectric_only: bool = False):
    """The ``spectral`` parameter of a model's spec."""
    from viewer.brdf.spec import Param

    if dielectric_only:
        return Param("spectral", "choice", NONE,
                     "a tabulated dielectric (viewer.spectral): ior becomes its n at 587.56 nm; the "
                     "spectral reference traces n(lambda) (dispersion)",
                     choices=dielectric_choices(), fills=implied_scalars)
    return Param("spectral", "choice", NONE,
                 "a tabulated material (viewer.spectral): the Fresnel colour becomes the spectral "
                 "integral of its n(lambda) + i k(lambda) at every angle, instead of eta, k / ior",
                 choices=choices(), spectral_table=True, fills=implied_scalars)
