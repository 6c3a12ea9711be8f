"""Perfect mirror: a delta lobe in the mirror direction wi = (-wo.x, -wo.y, wo.z) with throughput
F(cos_o) (lecture: 'Reflectance of perfectly specular materials', L_r,s = rho_s L_i with
rho_s = R the Fresnel reflectance).

Delta-lobe conventions (docs/conventions.md): ``eval`` and ``pdf`` are 0 for every pair of
directions; ``sample`` returns the mirror direction with pdf = 1 (the probability of choosing
the only lobe) and weight = F.
"""

from __future__ import annotations

import numpy as np

from viewer.brdf.fresnel import fresnel_conductor, fresnel_dielectric
from viewer.brdf import spectral_fresnel, thin_film
from viewer.brdf.presets import METALS
from viewer.brdf.sampling import reflect_z
from viewer.brdf.spec import ModelSpec, Param

_GOLD_ETA, _GOLD_K = METALS["gold"]

SPEC = ModelSpec(
    name="mirror",
    title="Perfect mirror",
    params=(
        Param("fresnel", "choice", "conductor", "reflectance: exact conductor (eta + i k), "
              "exact dielectric (ior) or none (R = 1)", choices=("conductor", "dielectric", "none")),
        Param("eta", "rgb", list(_GOLD_ETA), "real part of the complex IOR (conductor); default: gold",
              lo=0.01, hi=10.0),
        Param("k", "rgb", list(_GOLD_K), "extinction coefficient (conductor)", lo=0.0, hi=20.0),
        Param("ior", "float", 1.5, "index of refraction (dielectric)", lo=1.0, hi=3.0),
        spectral_fresnel.param(),
        thin_film.param(),
    ),
    source="Law of reflection; Fresnel equations (lecture: 'Reflectance of perfectly specular "
           "materials')",
    delta=True,
)


def reflectance(p, cos):
    """F(cos) as (N, 3); a thin film on the conductor or dielectric first (thin_film.py)."""
    if thin_film.at_point(p) and p.fresnel != "none":
        if p.spectral != spectral_fresnel.NONE:  # the tabulated index at the film's wavelengths
            return thin_film.reflectance_rgb(p, cos, None, spectral_name=p.spectral)
        if p.fresnel == "conductor":
            return thin_film.reflectance_rgb(p, cos, p.eta, p.k)
        return thin_film.reflectance_rgb(p, cos, p.ior)
    if p.spectral != spectral_fresnel.NONE:
        return spectral_fresnel.lookup(p.spectral, cos)
    c = np.clip(cos, 0.0, 1.0)[:, None]
    if p.fresnel == "conductor":
        return fresnel_conductor(c, p.eta[None, :], p.k[None, :])
    if p.fresnel == "dielectric":
        return np.broadcast_to(fresnel_dielectric(c, p.ior), (c.shape[0], 3)).copy()
    return np.ones((c.shape[0], 3))


def eval(p, wi, wo):
    return np.zeros((wi.shape[0], 3))


def pdf(p, wi, wo):
    return np.zeros(wi.shape[0])


def sample(p, wo, u):
    wi = reflect_z(wo)
    ok = wo[:, 2] > 0
    weight = np.where(ok[:, None], reflectance(p, wo[:, 2]), 0.0)
    return wi, weight, np.where(ok, 1.0, 0.0)


def fresnel_source(p):
    if p.fresnel == "conductor":
        return {"type": "conductor", "eta": np.asarray(p.eta, float), "k": np.asarray(p.k, float),
                "field": "eta, k"}
    if p.fresnel == "dielectric":
        return {"type": "dielectric", "ior": float(p.ior), "field": "ior"}
    return None


def ibl_split(p):
    """Image-based lighting: all of it is the (delta) specular lobe, alpha 0."""
    return p, 0.0
