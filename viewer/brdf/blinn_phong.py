"""Blinn-Phong, energy-normalized: f = kd / pi + ks N(n) cos^n(theta_h), theta_h = angle(h, normal).

Blinn 1977 replaced Phong's mirror angle by the half vector h = (wi + wo) / |wi + wo|. The lobe is
normalized with the exact factor of Giesen 2009 ("Derivation of Phong and Blinn-Phong BRDF
normalization factors"): N(n) = (n + 2)(n + 4) / (8 pi (2^(-n/2) + n)), which makes the directional
albedo of the lobe exactly ks at normal incidence and smaller at every other angle (the popular
approximation (n + 8) / (8 pi), Akenine-Moeller et al., Real-Time Rendering 3rd ed., eq. 7.49 /
Sloan & Hoffman, overshoots by up to 7.5 % near n = 10). With kd + ks <= 1 per channel the BRDF
conserves energy; larger sums are accepted and ``energy_conserving`` scales them back.
"""

from __future__ import annotations

import numpy as np

from viewer.brdf.sampling import (cosine_hemisphere, cosine_hemisphere_pdf, dot,
                                  energy_conserving_kd_ks, INV_PI, normalize, phong_alpha,
                                  pick_lobe, pow_one_minus, power_cosine, reflect, sample_weight,
                                  specular_probability)
from viewer.brdf.lobes import Lobe
from viewer.brdf.spec import ModelSpec, Param

SPEC = ModelSpec(
    name="blinn_phong",
    title="Blinn-Phong (normalized)",
    params=(
        Param("kd", "rgb", [0.5, 0.5, 0.5], "diffuse reflectance (kd + ks <= 1 conserves energy)",
              lo=0.0, hi=1.0),
        Param("ks", "rgb", [0.3, 0.3, 0.3], "specular reflectance at normal incidence", lo=0.0, hi=1.0),
        Param("shininess", "float", 100.0, "exponent n of cos(theta_h)", lo=1.0, hi=10000.0,
              ui_lo=1.0, ui_hi=1000.0, log=True),
    ),
    source="Blinn 1977; normalization Giesen 2009 (exact), cf. Real-Time Rendering 3rd ed. eq. 7.49",
    doc="f = kd/pi + ks (n+2)(n+4)/(8 pi (2^(-n/2) + n)) (n . h)^n. Lobe albedo = ks at normal incidence "
        "(its maximum), so kd + ks <= 1 per channel conserves energy (not enforced: see energy_conserving). "
        "Sampling: cosine for kd; h from the cos^n lobe about the normal, wi = reflect(wo, h), "
        "pdf = p(h) / (4 wo . h).",
)


TEST_PARAMS = {
    "default": {},
    "rough": {"kd": [0.2, 0.2, 0.2], "ks": [0.7, 0.7, 0.7], "shininess": 3.0},
    "sharp": {"kd": [0.1, 0.1, 0.1], "ks": [0.8, 0.8, 0.8], "shininess": 1000.0},
}

energy_conserving = energy_conserving_kd_ks  # the test harness hook


def normalization_giesen(n):
    """Giesen 2009: (n + 2)(n + 4) / (8 pi (2^(-n/2) + n)), the exact Blinn-Phong normalization."""
    return (n + 2.0) * (n + 4.0) / (8.0 * np.pi * (np.exp2(-0.5 * n) + n))


def half_vector(wi, wo):
    return normalize(wi + wo)


def one_minus_cos_h(h):
    """1 - h.z = (h.x^2 + h.y^2) / (1 + h.z): no cancellation near the normal."""
    return (h[:, 0] ** 2 + h[:, 1] ** 2) / (1.0 + np.maximum(h[:, 2], 0.0))


def _cos_n(h, n):
    """cos^n(theta_h) of half vectors h (0 below the surface), the factor f and pdf share."""
    return np.where(h[:, 2] > 0, pow_one_minus(one_minus_cos_h(h), n), 0.0)


def blinn_lobe_normalized(wi, wo, n):
    """Blinn 1977 cos^n(theta_h) with Giesen's 2009 normalization."""
    return normalization_giesen(n) * _cos_n(half_vector(wi, wo), n)


def _eval(p, wi, wo, cos_n):
    ok = (wi[:, 2] > 0) & (wo[:, 2] > 0)
    lobe = normalization_giesen(p.shininess) * cos_n  # blinn_lobe_normalized
    f = p.kd[None, :] * INV_PI + p.ks[None, :] * lobe[:, None]
    return np.where(ok[:, None], f, 0.0)


def eval(p, wi, wo):
    return _eval(p, wi, wo, _cos_n(half_vector(wi, wo), p.shininess))


def _specular_probability(p):
    return specular_probability(p.kd, p.ks)


def _pdf(p, wi, wo, ps, h, cos_n):
    n = p.shininess
    cos_oh = dot(wo, h)
    # Walter et al. 2007, eq. 14: p(wi) = p(h) / (4 |wo . h|); p(h) = (n + 1) / (2 pi) cos^n(theta_h)
    ph = (n + 1.0) / (2.0 * np.pi) * cos_n
    spec = np.where(cos_oh > 0, ph / (4.0 * np.where(cos_oh > 0, cos_oh, 1.0)), 0.0)
    val = ps * spec + (1.0 - ps) * cosine_hemisphere_pdf(wi)
    return np.where((wi[:, 2] > 0) & (wo[:, 2] > 0), val, 0.0)


def pdf(p, wi, wo):
    h = half_vector(wi, wo)
    return _pdf(p, wi, wo, _specular_probability(p), h, _cos_n(h, p.shininess))


def sample(p, wo, u):
    ps = _specular_probability(p)
    k, u0 = pick_lobe(u[:, 0], np.tile([[ps, 1.0 - ps]], (len(u), 1)))
    uu = np.empty((len(u), 2))
    uu[:, 0] = u0
    uu[:, 1] = u[:, 1]
    wi = np.empty((len(u), 3))
    spec = k == 0  # each lobe's directions for its own rows only
    wi[spec] = reflect(wo[spec], power_cosine(uu[spec], p.shininess))
    wi[~spec] = cosine_hemisphere(uu[~spec])
    wi = normalize(wi)
    h = half_vector(wi, wo)
    cos_n = _cos_n(h, p.shininess)
    weight, pdf_ = sample_weight(_eval(p, wi, wo, cos_n), wi, _pdf(p, wi, wo, ps, h, cos_n))
    return wi, weight, pdf_


def ibl_split(p):
    """Image-based lighting proxy: the specular lobe alone, and the GGX alpha of a lobe of similar
    width (``phong_alpha``)."""
    return p.replace(kd=np.zeros(3)), phong_alpha(p.shininess)


def lobes(p):
    """The diffuse kd lobe and the specular Blinn-Phong lobe."""
    return Lobe.REFLECTION | Lobe.DIFFUSE | Lobe.GLOSSY
