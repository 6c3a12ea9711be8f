"""Modified Phong, energy-normalized: f = kd / pi + ks (n + 2) / (2 pi) cos^n(alpha_r).

Phong 1975 put a cos^n lobe around the mirror direction; Lafortune & Willems 1994 ("Using the
modified Phong reflectance model for physically based rendering", Tech. Rep. CW197, eqs. 1-3)
dropped the division by cos(theta_i) and normalized the lobe so that its directional albedo is ks
at normal incidence and less elsewhere. With kd + ks <= 1 in every channel the BRDF conserves
energy; larger sums are accepted (as in Mitsuba's phong) but then reflect more than they receive:
``energy_conserving`` scales them back and the tests draw only such values.
"""

from __future__ import annotations

import numpy as np

from viewer.brdf.sampling import (cosine_hemisphere, cosine_hemisphere_pdf, dot,
                                  energy_conserving_kd_ks, INV_PI, phong_alpha,
                                  pick_lobe, pow_one_minus, power_cosine, reflect_z, sample_weight,
                                  specular_probability, to_world)
from viewer.brdf.lobes import Lobe
from viewer.brdf.spec import ModelSpec, Param

SPEC = ModelSpec(
    name="phong",
    title="Phong (modified, normalized)",
    params=(
        Param("kd", "rgb", [0.5, 0.5, 0.5], "diffuse reflectance (kd + ks <= 1 conserves energy)",
              lo=0.0, hi=1.0),
        Param("ks", "rgb", [0.3, 0.3, 0.3], "specular reflectance at normal incidence", lo=0.0, hi=1.0),
        Param("shininess", "float", 100.0, "Phong exponent n (lobe width ~ 1 / sqrt(n) rad)",
              lo=1.0, hi=10000.0, ui_lo=1.0, ui_hi=1000.0, log=True),
    ),
    source="Phong 1975; Lafortune & Willems 1994 (modified Phong, eqs. 1-3; sampling Sec. 4)",
    doc="f = kd/pi + ks (n+2)/(2 pi) max(0, wi . reflect(wo))^n. Energy conserving when kd + ks <= 1 "
        "per channel (rule not enforced: see energy_conserving). Sampling: cosine for kd and the cos^n "
        "lobe around the mirror direction for ks, picked in proportion to their luminance.",
)


TEST_PARAMS = {
    "default": {},
    "rough": {"kd": [0.2, 0.2, 0.2], "ks": [0.7, 0.7, 0.7], "shininess": 3.0},
    "sharp": {"kd": [0.1, 0.1, 0.1], "ks": [0.8, 0.8, 0.8], "shininess": 1000.0},
}

energy_conserving = energy_conserving_kd_ks  # the test harness hook


def one_minus_cos_mirror(wi, wo):
    """1 - cos(alpha_r) = |wi - r|^2 / 2 with r the mirror of wo: exact where wi ~ r (no cancellation)."""
    d = wi - reflect_z(wo)
    return 0.5 * dot(d, d)


def phong_lobe_normalized(wi, wo, n):
    """Lafortune & Willems 1994, eq. 3: (n + 2) / (2 pi) cos^n(alpha_r), alpha_r = angle(wi, mirror(wo))."""
    return (n + 2.0) / (2.0 * np.pi) * pow_one_minus(one_minus_cos_mirror(wi, wo), n)


def _cos_n(p, wi, wo):
    """cos^n(alpha_r) (``pow_one_minus`` of ``one_minus_cos_mirror``), the factor f and pdf share."""
    return pow_one_minus(one_minus_cos_mirror(wi, wo), p.shininess)


def _eval(p, wi, wo, cos_n):
    ok = (wi[:, 2] > 0) & (wo[:, 2] > 0)
    lobe = (p.shininess + 2.0) / (2.0 * np.pi) * cos_n  # phong_lobe_normalized
    f = p.kd[None, :] * INV_PI + p.ks[None, :] * lobe[:, None]
    return np.where(ok[:, None], f, 0.0)


def eval(p, wi, wo):
    return _eval(p, wi, wo, _cos_n(p, wi, wo))


def _specular_probability(p):
    return specular_probability(p.kd, p.ks)


def _pdf(p, wi, wo, ps, cos_n):
    lobe = (p.shininess + 1.0) / (2.0 * np.pi) * cos_n
    val = ps * lobe + (1.0 - ps) * cosine_hemisphere_pdf(wi)
    return np.where((wi[:, 2] > 0) & (wo[:, 2] > 0), val, 0.0)


def pdf(p, wi, wo):
    return _pdf(p, wi, wo, _specular_probability(p), _cos_n(p, wi, wo))


def sample(p, wo, u):
    ps = _specular_probability(p)
    k, u0 = pick_lobe(u[:, 0], np.tile([[ps, 1.0 - ps]], (len(u), 1)))
    uu = np.empty((len(u), 2))
    uu[:, 0] = u0
    uu[:, 1] = u[:, 1]
    wi = np.empty((len(u), 3))
    spec = k == 0  # each lobe's directions for its own rows only
    wi[spec] = to_world(power_cosine(uu[spec], p.shininess), reflect_z(wo[spec]))
    wi[~spec] = cosine_hemisphere(uu[~spec])
    cos_n = _cos_n(p, wi, wo)
    weight, pdf_ = sample_weight(_eval(p, wi, wo, cos_n), wi, _pdf(p, wi, wo, ps, cos_n))
    return wi, weight, pdf_


def ibl_split(p):
    """Image-based lighting proxy: the specular lobe alone, and the GGX alpha of a lobe of similar
    width (``phong_alpha``)."""
    return p.replace(kd=np.zeros(3)), phong_alpha(p.shininess)


def lobes(p):
    """The diffuse kd lobe and the specular Phong lobe."""
    return Lobe.REFLECTION | Lobe.DIFFUSE | Lobe.GLOSSY
