"""A material at given wavelengths: the default of the model protocol's ``params_at`` hook
(``viewer.brdf.params_at`` asks the model), by parameter names, for the hero-wavelength spectral
reference (viewer/pathtracer/spectral.py) and the GPU engine's spectral pass.

Spectral tables (``spectral = "NAME"``) give eta, k = n, k at the wavelengths (ior = n at the
first); a thin film (of positive thickness where it is evaluated, ``thin_film.at_point``)
carries the wavelengths (``lambda_nm``) and is evaluated there, over a non-spectral conductor
base's eta, k interpolated in wavelength as the RGB renderers do (viewer/brdf/thin_film.py);
every other RGB value becomes its upsampled spectrum there (Mallett & Yuksel 2019,
``viewer.spectral.upsampling``). Nested tables and materials likewise (materials through their
own model's hook).
"""

from __future__ import annotations

import numpy as np

from viewer import spectral
from viewer.brdf import thin_film
from viewer.brdf.spec import Params


def uses_spectral_by_names(p) -> bool:
    """The ``uses_spectral`` default for p's own values: a spectral table named in p or a table
    parameter of it (a layered coating), or an active thin film (``thin_film.active``)."""
    if p.get("spectral", "none") != "none" or thin_film.active(p):
        return True
    return any(isinstance(v, Params) and not v.model and v.get("spectral", "none") != "none" for v in p.values())


def params_at(p, lam3, nested=None) -> Params:
    """The material's parameters at three wavelengths ``lam3`` (nm; its three channels).
    ``nested(v, lam3)`` gives a nested material's (its model's hook; by default this function)."""
    nested = nested or (lambda v, lam: params_at(v, lam))
    lam3 = np.asarray(lam3, dtype=np.float64)
    b = spectral.upsampling.basis_at(lam3)               # (3, 3): row = wavelength
    out = dict(p)
    name = p.get("spectral", "none")
    if name != "none":
        n = spectral.ior(name, lam3)
        out["spectral"] = "none"
        if "eta" in out:
            out["eta"] = np.maximum(n.real, 1e-3)
            out["k"] = n.imag.copy()
            if "fresnel" in out:
                out["fresnel"] = "conductor"
        if "ior" in out:
            out["ior"] = float(n[0].real)
    film = key_film = None
    if "thin_film" in p and thin_film.at_point(p):
        # a thin film is evaluated at the wavelengths themselves (viewer/brdf/thin_film.py);
        # a non-spectral conductor base's eta, k at them as the RGB renderers interpolate them
        film = dict(p.thin_film)
        film["lambda_nm"] = lam3.copy()
        key_film = "thin_film"
        if name == "none" and "eta" in out and "k" in out:
            out["eta"] = thin_film.rgb_to_spectral_at(p.eta, lam3)
            out["k"] = thin_film.rgb_to_spectral_at(p.k, lam3)
    for key, v in p.items():
        if key == key_film:
            out[key] = Params(v.model, film)
            continue
        if film is not None and key in ("eta", "k") and name == "none":
            continue
        if isinstance(v, Params):
            out[key] = nested(v, lam3) if v.model else params_at(v, lam3, nested)
        elif isinstance(v, np.ndarray) and v.shape == (3,) and key in out and out[key] is v:
            if name != "none" and key in ("eta", "k"):
                continue
            out[key] = b @ v
    return Params(p.model, out)
