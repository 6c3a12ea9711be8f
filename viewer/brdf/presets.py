"""Material presets: name -> material table (``model`` plus parameters), usable in scene files
as ``preset = "gold"`` with any parameter overridden beside it.

Metals: complex index of refraction n + i k sampled at the three wavelengths 650 nm (R),
550 nm (G) and 450 nm (B), rounded, read from the tabulated data on refractiveindex.info:
  * Au, Ag, Cu: P. B. Johnson and R. W. Christy, "Optical constants of the noble metals",
    Phys. Rev. B 6, 4370 (1972).
  * Al: A. D. Rakic, "Algorithm for the determination of intrinsic optical constants of metal
    films: application to aluminum", Appl. Opt. 34, 4755 (1995).
  * Cr, Fe, Ti: P. B. Johnson and R. W. Christy, "Optical constants of transition metals",
    Phys. Rev. B 9, 5056 (1974) (cf. Palik, Handbook of Optical Constants of Solids, 1985).
Single-wavelength samples are a simple, documented choice; integrating the spectra against the
Rec.709 channel responses would change the colours by a few per cent (mostly gold's blue,
which comes out ~0.41 here instead of the ~0.34 of spectrally integrated tables).
``metal_f0(name)`` gives the normal-incidence reflectance ((n-1)^2 + k^2) / ((n+1)^2 + k^2);
tests/test_fresnel.py checks it against the familiar colours.

Dielectric indices (sodium D line, 589 nm): crown glass 1.5 (lecture: air-glass n = 1.5),
water 1.333, diamond 2.42, ice 1.31, sapphire 1.77, polycarbonate 1.58.
"""

from __future__ import annotations

import numpy as np

# name -> (eta RGB, k RGB) at (650, 550, 450) nm
METALS: dict[str, tuple[list[float], list[float]]] = {
    "gold": ([0.14, 0.43, 1.38], [3.70, 2.46, 1.91]),
    "silver": ([0.05, 0.06, 0.04], [4.48, 3.59, 2.66]),
    "copper": ([0.21, 1.00, 1.24], [3.67, 2.58, 2.40]),
    "aluminium": ([1.47, 0.96, 0.62], [7.79, 6.69, 5.47]),
    "chromium": ([3.21, 3.00, 2.28], [3.30, 3.30, 3.18]),
    "iron": ([2.94, 2.87, 2.50], [3.45, 3.36, 3.20]),
    "titanium": ([2.22, 1.86, 1.61], [2.95, 2.55, 2.19]),
}

DIELECTRICS: dict[str, float] = {
    "glass": 1.5,
    "water": 1.333,
    "diamond": 2.42,
    "ice": 1.31,
    "sapphire": 1.77,
    "polycarbonate": 1.58,
}


def metal_f0(name: str) -> np.ndarray:
    """Normal-incidence reflectance of a metal preset (RGB)."""
    eta, k = (np.asarray(v, dtype=np.float64) for v in METALS[name])
    return ((eta - 1.0) ** 2 + k * k) / ((eta + 1.0) ** 2 + k * k)


# the measured table (viewer.spectral) of each metal: presets are spectral, their Fresnel colour
# the spectral integral at every angle; eta and k above stay as the three-wavelength comparison
SPECTRAL_METALS = {"gold": "Au", "silver": "Ag", "copper": "Cu", "aluminium": "Al",
                   "chromium": "Cr", "iron": "Fe", "titanium": "Ti"}


def _metal(name, alpha=0.2, distribution="ggx"):
    eta, k = METALS[name]
    return {"model": "microfacet", "distribution": distribution, "shadowing": "smith",
            "fresnel": "conductor", "alpha": alpha, "eta": list(eta), "k": list(k),
            "spectral": SPECTRAL_METALS[name]}


def _glass(ior, alpha=0.0):
    return {"model": "dielectric", "ior": ior, "alpha": alpha, "sigma_a": [0.0, 0.0, 0.0]}


PRESETS: dict[str, dict] = {
    "white_lambert": {"model": "lambert", "albedo": [0.8, 0.8, 0.8]},
}

# rough metals (microfacet, GGX, Smith, exact conductor Fresnel) and polished mirrors
for _name, (_eta, _k) in METALS.items():
    PRESETS[_name] = _metal(_name)
    PRESETS[f"polished_{_name}"] = {"model": "mirror", "fresnel": "conductor",
                                    "eta": list(_eta), "k": list(_k),
                                    "spectral": SPECTRAL_METALS[_name]}
PRESETS["brushed_aluminium"] = dict(_metal("aluminium"), alpha_x=0.4, alpha_y=0.05)
del PRESETS["brushed_aluminium"]["alpha"]

# dielectrics: smooth and frosted
for _name, _ior in DIELECTRICS.items():
    PRESETS[_name] = _glass(_ior)
PRESETS["frosted_glass"] = _glass(1.5, alpha=0.3)
PRESETS["green_glass"] = {"model": "dielectric", "ior": 1.5, "alpha": 0.0,
                          "sigma_a": [8.0, 0.5, 6.0]}

# plastics / coatings
PRESETS["red_plastic"] = {"model": "microfacet", "distribution": "ggx", "shadowing": "smith",
                          "fresnel": "dielectric", "ior": 1.5, "alpha": 0.15,
                          "kd": [0.6, 0.05, 0.05]}
PRESETS["car_paint"] = {"model": "layered",
                        "coating": {"ior": 1.5, "alpha": 0.05, "thickness": 0.0,
                                    "sigma_a": [0.0, 0.0, 0.0]},
                        "base": {"model": "lambert", "albedo": [0.5, 0.05, 0.05]}}
PRESETS["varnished_gold"] = {"model": "layered",
                             "coating": {"ior": 1.5, "alpha": 0.02, "thickness": 10.0,
                                         "sigma_a": [0.001, 0.003, 0.008]},
                             "base": _metal("gold", alpha=0.3)}

# the lecture's examples (Frisvad, "BRDF, Fresnel Reflectance, and Absorption")
PRESETS["lecture_air_glass"] = _glass(1.5)  # "air-glass boundary with index of refraction 1.5"
PRESETS["lecture_gold"] = dict(PRESETS["polished_gold"])
PRESETS["lecture_lambert"] = {"model": "lambert", "albedo": [0.8, 0.8, 0.8]}
# Torrance-Sparrow with Blinn's (modified Phong) distribution and V-cavity G (Blinn 1977)
PRESETS["lecture_torrance_sparrow_blinn"] = {
    "model": "microfacet", "distribution": "blinn_phong", "shadowing": "v_cavity",
    "fresnel": "dielectric", "ior": 1.5, "alpha": 0.2, "kd": [0.5, 0.5, 0.5]}
PRESETS["lecture_beckmann"] = {
    "model": "microfacet", "distribution": "beckmann", "shadowing": "smith",
    "fresnel": "dielectric", "ior": 1.5, "alpha": 0.2, "kd": [0.5, 0.5, 0.5]}
PRESETS["lecture_ggx"] = {
    "model": "microfacet", "distribution": "ggx", "shadowing": "smith",
    "fresnel": "dielectric", "ior": 1.5, "alpha": 0.2, "kd": [0.5, 0.5, 0.5]}
PRESETS["lecture_layered"] = dict(PRESETS["car_paint"])
# Oren-Nayar 1994 against Lambert: the same albedo, rough (sigma = 30 deg) Lambertian facets
PRESETS["lecture_oren_nayar"] = {"model": "oren_nayar", "albedo": [0.8, 0.8, 0.8], "sigma": 30.0,
                                 "variant": "full"}
# Lafortune et al. 1997: a diffuse base, a forward lobe (Cx = Cy < 0, a generalized Phong lobe
# about the mirror direction) and a retro-reflective lobe (Cx = Cy > 0) for dusty surfaces
PRESETS["lecture_lafortune"] = {"model": "lafortune", "kd": [0.4, 0.3, 0.2],
                                "lobes": [{"cx": -1.0, "cy": -1.0, "cz": 1.0, "n": 20.0},
                                          {"cx": 0.7, "cy": 0.7, "cz": 0.7, "n": 5.0}]}
# Ashikhmin & Shirley 2000: anisotropy, highlights stretched across the tangent (brushed metal)
PRESETS["lecture_ashikhmin_shirley"] = {"model": "ashikhmin_shirley", "rd": [0.3, 0.1, 0.05],
                                        "rs": [0.5, 0.5, 0.5], "nu": 10.0, "nv": 1000.0}
# Bouguer's law: glass that absorbs red and blue over its path inside (sigma_a per metre)
PRESETS["lecture_absorbing_glass"] = dict(PRESETS["green_glass"])
# a soap bubble (Glassner 2000, "Soap bubbles", IEEE CG&A): no refraction (air on both sides,
# ior 1), a water film (n 1.33) a few hundred nanometres thick; its colour is interference only
PRESETS["soap_bubble"] = {"model": "dielectric", "ior": 1.0, "alpha": 0.0,
                          "thin_film": {"ior": 1.33, "thickness_nm": 400.0}}
PRESETS["lecture_soap_bubble"] = dict(PRESETS["soap_bubble"])


def get_preset(name: str) -> dict:
    """A copy of a preset's material table."""
    import copy

    return copy.deepcopy(PRESETS[name])
