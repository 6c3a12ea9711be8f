"""Thin-film interference in the RGB renderers: ``thin_film = { ior, thickness_nm }`` on
``dielectric``, ``mirror`` and ``microfacet`` replaces the Fresnel reflectance by that of a film of
index ``ior`` and thickness ``thickness_nm`` on the material's surface (a soap bubble: a
``dielectric`` with ``ior = 1.0`` under a water film; oil on water; an oxide on a metal; an
anti-reflection coating). ``thickness_nm = 0`` (the default) is no film: the plain Fresnel term.

Colour: the spectral reflectance R(theta, lambda) (``fresnel.fresnel_thin_film``, Airy summation,
both polarizations averaged) at the WAVELENGTHS_NM below (32 from 380 to 780 nm, 12.5 nm apart)
turned into linear Rec.709 RGB by ``viewer.spectral.to_rgb`` (CIE 1931 2 deg, D65), which is linear
in the spectrum: RGB = sum_k R(lambda_k) W_k with W = to_rgb(identity). The GLSL twin
(shaders/common/fresnel.glsl) holds the same W (tests check them against to_rgb). 32 samples
resolve the fringes up to the 1,000 nm the thickness allows: the optical path 2 n d of a 1 um
water film changes the phase by ~0.2 cycles between neighbouring blue samples; the RGB then
differs from a 1 nm integration by at most ~0.02 (measured in tests/test_thin_film.py).

The base's index over wavelength: a tabulated material's own n(lambda) + i k(lambda)
(``spectral = "Au"`` etc.: viewer.spectral ``ior`` at the 32 wavelengths, rounded to float32,
the numbers the GLSL twin reads from the material block, ``packed_base``); else the dielectric's
``ior`` (constant), or a conductor's RGB ``eta``, ``k`` taken as the values at 650 / 550 / 450 nm
(the presets' three wavelengths) and interpolated linearly in wavelength between them (held
beyond).

Range: the RGB of a film on a conductor is kept as integrated, > 1 where the spectrum lies outside
the Rec.709 gamut (gold's red, as in viewer/brdf/spectral_fresnel.py), and only clipped at 0; on a
dielectric it is clipped to [0, 1], since 1 - R is its transmittance.

Thickness over height (``thickness_top_nm``): gravity drains a soap film, so a bubble is thinner
at its top. With ``thickness_top_nm >= 0`` the film is ``thickness_nm`` at the bottom of the
object (the lowest world y of its mesh) and ``thickness_top_nm`` at its top (the highest y),
linear in y between: d(y) = thickness_nm + (thickness_top_nm - thickness_nm) t,
t = (y - y_min) / (y_max - y_min). The default -1 is a uniform film. The renderers substitute
d(y) per shading point (``local``): the rasterizer from the fragment's world position and the
object's y range (``brdf_film_height`` in the generated GLSL), the CPU reference per hit (in
0.25 nm steps; the colour changes by < 1e-3 over one). A material evaluated without a position
(plots, albedo tables) has its bottom thickness ``thickness_nm``; the GPU reference engine,
which shades a hit without its height, refuses a film over height (viewer/gpupt/refusals.py). A
layered coating's film is an exception in the rasterizer: its reflectance is a table computed
once per material on the CPU (viewer/brdf/layered.py ``film_table``, so that no wavelength loop
is compiled into the layered model's many Fresnel calls), hence the bottom's thickness there.
"""

from __future__ import annotations

import functools

import numpy as np

from viewer.brdf.fresnel import fresnel_thin_film
from viewer.brdf.spec import film_table_active

N_WAVELENGTHS = 32
WAVELENGTHS_NM = 380.0 + (np.arange(N_WAVELENGTHS) + 0.5) * (400.0 / N_WAVELENGTHS)
RGB_NM = (650.0, 550.0, 450.0)
MAX_THICKNESS_NM = 1000.0


@functools.lru_cache(maxsize=None)
def _weights() -> np.ndarray:
    from viewer import spectral

    w = spectral.to_rgb(np.eye(N_WAVELENGTHS), WAVELENGTHS_NM)
    w.setflags(write=False)
    return w


def weights() -> np.ndarray:
    """(N_WAVELENGTHS, 3): RGB = sum_k R(lambda_k) W_k (from viewer.spectral.to_rgb)."""
    return _weights()


def rgb_to_spectral(v) -> np.ndarray:
    """(..., 3) values at 650 / 550 / 450 nm -> (..., N_WAVELENGTHS), linear in wavelength."""
    v = np.asarray(v, dtype=np.float64)
    return np.stack([np.interp(WAVELENGTHS_NM, RGB_NM[::-1], x[::-1]) for x in v.reshape(-1, 3)]).reshape(
        v.shape[:-1] + (N_WAVELENGTHS,))


def rgb_to_spectral_at(v, lam_nm) -> np.ndarray:
    """RGB values at 650 / 550 / 450 nm at the wavelengths lam_nm, linear in wavelength (held
    beyond): the base's index the RGB renderers integrate the film over."""
    v = np.asarray(v, dtype=np.float64).reshape(3)
    return np.interp(np.asarray(lam_nm, dtype=np.float64), RGB_NM[::-1], v[::-1])


def param():
    """The ``thin_film`` parameter of a model's spec."""
    from viewer.brdf.spec import Param

    return Param("thin_film", "table", {}, "a thin film on the surface (interference colours)", fields=(
        Param("ior", "float", 1.33, "index of refraction of the film (water 1.33, oil 1.47, MgF2 1.38)",
              lo=1.0, hi=3.0),
        Param("thickness_nm", "float", 0.0, "film thickness (at the object's bottom when thickness_top_nm "
              ">= 0); 0 = no film", unit="nm", lo=0.0, hi=MAX_THICKNESS_NM),
        Param("thickness_top_nm", "float", -1.0, "film thickness at the object's top, linear in height "
              "from thickness_nm at its bottom (a draining soap bubble); -1 = uniform thickness_nm. On a "
              "layered coating the rasterizer draws thickness_nm all over (its film is tabulated once per "
              "material, not per point); the CPU reference follows the height; the GPU engine refuses it",
              unit="nm", lo=-1.0, hi=MAX_THICKNESS_NM),
    ))


def film_of(p):
    """The material's thin_film table: its own, or its layered coating's (None if neither)."""
    if "thin_film" in p:
        return p.thin_film
    coat = p.get("coating")
    return coat.get("thin_film") if coat is not None else None


def varies(p) -> bool:
    """Whether the material's film (if any) changes thickness with height."""
    tf = film_of(p)
    return tf is not None and float(tf.get("thickness_top_nm", -1.0)) >= 0.0


def thickness_at(tf, t):
    """The film thickness at relative height t in [0, 1] (0 bottom, 1 top) of the object."""
    d0 = float(tf.thickness_nm)
    d1 = float(tf.get("thickness_top_nm", -1.0))
    if d1 < 0.0:
        return np.full(np.shape(t), d0)
    return d0 + (d1 - d0) * np.clip(np.asarray(t, dtype=np.float64), 0.0, 1.0)


def local(p, d_nm: float):
    """The material p with a uniform film of thickness d_nm (what a shading point sees)."""
    if "thin_film" not in p:
        return p.replace(coating=local(p.coating, d_nm))
    tf = p.thin_film.replace(thickness_nm=float(d_nm), thickness_top_nm=-1.0)
    return p.replace(thin_film=tf)


def active(p) -> bool:
    """Whether the material carries an active thin film: its own ``thin_film`` or its layered
    coating's, thicker than 0 at the object's bottom (``thickness_nm``) or top
    (``thickness_top_nm``). The one definition of a material's film (the models' ``has_film``
    default, ``viewer.brdf.has_film``): the film the renderers compile, trace per wavelength or
    refuse. Where a point of the material is evaluated its local thickness applies instead
    (``at_point``)."""
    return film_table_active(film_of(p))


def at_point(owner) -> bool:
    """Whether the film of ``owner`` (a material or a layered coating table with ``thin_film``)
    reflects where ``owner`` is evaluated: its ``thickness_nm`` > 0. That is the local thickness
    once the renderers substituted d(y) (``local``), else the bottom's (plots, albedo tables):
    the test the Fresnel of the numpy twins makes, as their GLSL twins test
    ``p.thin_film.thickness_nm > 0.0`` after the height substitution (``brdf_film_height``)."""
    tf = owner.get("thin_film")
    return tf is not None and float(tf.get("thickness_nm", 0.0)) > 0.0


@functools.lru_cache(maxsize=None)
def _spectral_base(name: str) -> np.ndarray:
    from viewer import spectral

    n = spectral.ior(name, WAVELENGTHS_NM)
    out = (n.real.astype(np.float32).astype(np.float64)
           + 1j * n.imag.astype(np.float32).astype(np.float64))
    out.setflags(write=False)
    return out


def spectral_base(name: str) -> np.ndarray:
    """(N_WAVELENGTHS,) complex index n + i k of a tabulated material at WAVELENGTHS_NM (float32
    values: what the GLSL twin gets)."""
    return _spectral_base(name)


def packed_base(name: str) -> np.ndarray:
    """(2 N_WAVELENGTHS,) the floats the material block carries after its spectral RGB table for
    a film on a tabulated base: n, k per wavelength."""
    b = _spectral_base(name)
    return np.stack([b.real, b.imag], axis=-1).reshape(-1)


def reflectance_rgb(p, cos, base_eta, base_k=None, spectral_name=None) -> np.ndarray:
    """(N, 3) RGB reflectance of the film p.thin_film on a base: base_eta a float (dielectric) or
    RGB eta with RGB k (conductor), or with ``spectral_name`` a tabulated material's own index
    (``spectral_base``), seen from index 1 at cos (N,)."""
    c = np.clip(np.asarray(cos, dtype=np.float64).reshape(-1), 0.0, 1.0)[:, None]
    lam3 = p.thin_film.get("lambda_nm")
    if lam3 is not None:
        # the spectral reference: channel j is the film's R at wavelength lam3[j], over the base's
        # index there (eta, k already taken at lam3 by viewer.brdf.params_at)
        n2 = (np.full(3, float(base_eta), dtype=np.complex128) if base_k is None
              else np.asarray(base_eta, dtype=np.float64) + 1j * np.asarray(base_k, dtype=np.float64))
        return fresnel_thin_film(c, np.asarray(lam3, dtype=np.float64)[None, :], p.thin_film.ior,
                                 p.thin_film.thickness_nm, n2[None, :])
    if spectral_name is not None:
        n2 = spectral_base(spectral_name)
    elif base_k is None:
        n2 = np.full(N_WAVELENGTHS, float(base_eta), dtype=np.complex128)
    else:
        n2 = rgb_to_spectral(base_eta) + 1j * rgb_to_spectral(base_k)
    R = fresnel_thin_film(c, WAVELENGTHS_NM[None, :], p.thin_film.ior, p.thin_film.thickness_nm, n2[None, :])
    conductor = base_k is not None or spectral_name is not None
    return np.maximum(R @ weights(), 0.0) if conductor else np.clip(R @ weights(), 0.0, 1.0)


def dielectric_reflectance_rgb(p, cos, eta):
    """(N, 3) film reflectance of a dielectric interface seen from the side where the relative
    index is eta (eta = ior outside, 1 / ior inside), the film on the outside (index 1) face. A
    lossless stack reflects the same fraction from both sides, so from inside R is the film's R at
    the outside angle given by Snell's law, and 1 beyond the critical angle."""
    c = np.clip(np.asarray(cos, dtype=np.float64).reshape(-1), 0.0, 1.0)
    eta = np.broadcast_to(np.asarray(eta, dtype=np.float64), c.shape)
    inside = eta < 1.0
    ior = np.where(inside, 1.0 / eta, eta)
    s2_out = np.where(inside, (1.0 - c * c) * ior * ior, 1.0 - c * c)
    tir = s2_out >= 1.0
    c_out = np.sqrt(np.maximum(0.0, 1.0 - s2_out))
    out = np.ones((c.size, 3))
    for v in np.unique(ior):
        sel = (ior == v) & ~tir
        if np.any(sel):
            out[sel] = reflectance_rgb(p, c_out[sel], float(v))
    return out
