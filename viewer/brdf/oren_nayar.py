"""Oren-Nayar: rough diffuse surfaces made of V-cavities with Lambertian facets.

Oren & Nayar 1994, "Generalization of Lambert's Reflectance Model" (SIGGRAPH '94). ``variant``:
  full         Sec. 4 functional approximation: the direct term L1 with the coefficients C1, C2, C3
               plus the interreflection term L2 (the paper's final model; L1 + L2).
  qualitative  Sec. 5 ("A qualitative model"): rho/pi (A + B max(0, cos(phi_i - phi_o)) sin(a) tan(b)).
sigma is the standard deviation of the facet slope angle in degrees; sigma = 0 is Lambert exactly.
Where both directions are near grazing and on opposite sides (cos(phi) < 0) the full model's L1
bracket can go slightly negative (the approximation, not physics): it is clamped at 0.
"""

from __future__ import annotations

import numpy as np

from viewer.brdf.sampling import INV_PI, cosine_hemisphere, cosine_hemisphere_pdf
from viewer.brdf.lobes import Lobe
from viewer.brdf.spec import ModelSpec, Param

SPEC = ModelSpec(
    name="oren_nayar",
    title="Oren-Nayar",
    params=(
        Param("albedo", "rgb", [0.8, 0.8, 0.8], "facet albedo rho", lo=0.0, hi=1.0),
        Param("sigma", "float", 30.0, "roughness: std. dev. of the facet slope angle", unit="deg",
              lo=0.0, hi=90.0),
        Param("variant", "choice", "full", "full = L1 (C1, C2, C3) + interreflections L2; "
              "qualitative = A + B max(0, cos dphi) sin(a) tan(b)", choices=("full", "qualitative")),
    ),
    source="Oren & Nayar 1994, SIGGRAPH '94: Sec. 4 functional approximation (L1 with C1-C3, and the "
           "interreflection term L2); Sec. 5 qualitative model",
    doc="Reduces to Lambert (albedo / pi) at sigma = 0. Sampled with the cosine distribution.",
)


# The functional approximation is not exactly energy conserving: with albedo = 1 the directional
# albedo of the full model reaches ~1.05 near grazing (theta_o > 85 deg, sigma ~ 15-20 deg), measured
# by tests/test_brdf_properties.py; the qualitative model stays below 1.
ALBEDO_BOUND = 1.06
ALBEDO_BOUND_WHY = ("Oren & Nayar's 1994 functional approximation (L1 + L2) overshoots energy conservation "
                    "by up to ~5 % at grazing angles with albedo 1 (max measured 1.050 at theta_o = 89.99 deg, "
                    "sigma = 20 deg)")

TEST_PARAMS = {
    "default": {},
    "rough_qualitative": {"sigma": 90.0, "variant": "qualitative", "albedo": [0.9, 0.5, 0.2]},
    "smooth": {"sigma": 5.0},
}


def _angles(wi, wo):
    """cos(phi_i - phi_o), alpha = max(theta_i, theta_o), beta = min(...) and their sines and cosines,
    all from the vectors (sin theta = |w.xy|, theta = atan2(|w.xy|, w.z)): no acos, whose float32
    versions lose digits near the normal."""
    si = np.hypot(wi[:, 0], wi[:, 1])
    so = np.hypot(wo[:, 0], wo[:, 1])
    ci = np.maximum(wi[:, 2], 0.0)
    co = np.maximum(wo[:, 2], 0.0)
    # cos(phi_i - phi_o) from the tangential parts; 0 where either lies on the normal (then beta = 0
    # and every term that uses it vanishes, so any value is right)
    den = si * so
    dot = wi[:, 0] * wo[:, 0] + wi[:, 1] * wo[:, 1]
    cos_dphi = np.where(den > 1e-30, np.clip(dot / np.where(den > 1e-30, den, 1.0), -1.0, 1.0), 0.0)
    theta_i = np.arctan2(si, ci)
    theta_o = np.arctan2(so, co)
    i_larger = theta_i >= theta_o
    g = dict(
        cos_dphi=cos_dphi,
        alpha=np.where(i_larger, theta_i, theta_o),
        beta=np.where(i_larger, theta_o, theta_i),
        sin_alpha=np.where(i_larger, si, so), cos_alpha=np.where(i_larger, ci, co),
        sin_beta=np.where(i_larger, so, si), cos_beta=np.where(i_larger, co, ci),
        # pi/2 - beta, the elevation of the direction nearer the normal, from atan2 (accurate near grazing)
        elev_beta=np.where(i_larger, np.arctan2(co, so), np.arctan2(ci, si)),
    )
    # tan(beta) of the direction nearer the normal; the 1e-12 guard keeps grazing pairs finite
    g["tan_beta"] = g["sin_beta"] / np.maximum(g["cos_beta"], 1e-12)
    return g


def on_qualitative_AB(s2):
    """Oren & Nayar 1994, Sec. 5: A = 1 - 0.5 s^2 / (s^2 + 0.33), B = 0.45 s^2 / (s^2 + 0.09)."""
    return 1.0 - 0.5 * s2 / (s2 + 0.33), 0.45 * s2 / (s2 + 0.09)


def on_qualitative(rho, s2, g):
    """Oren & Nayar 1994, Sec. 5 (qualitative model), divided by E0 cos(theta_i)."""
    A, B = on_qualitative_AB(s2)
    k = A + B * np.maximum(0.0, g["cos_dphi"]) * g["sin_alpha"] * g["tan_beta"]
    return rho[None, :] * INV_PI * k[:, None]


def on_full_L1(s2, g):
    """Oren & Nayar 1994, Sec. 4 functional approximation of the direct term (the bracket of L1):
    C1 + cos(dphi) C2 tan(beta) + (1 - |cos(dphi)|) C3 tan((alpha + beta) / 2), with
    C1 = 1 - 0.5 s^2/(s^2 + 0.33);
    C2 = 0.45 s^2/(s^2 + 0.09) sin(alpha) if cos(dphi) >= 0, else 0.45 s^2/(s^2 + 0.09) (sin(alpha) - (2 beta/pi)^3);
    C3 = 0.125 s^2/(s^2 + 0.09) (4 alpha beta / pi^2)^2.
    Near grazing sin(alpha) - (2 beta / pi)^3 cancels; it is evaluated as (1 - t)(1 + t + t^2) - cos^2(alpha) / (1 + sin(alpha))
    with 1 - t = elevation(beta) 2 / pi, and tan((alpha + beta) / 2) = (sin a + sin b) / (cos a + cos b) (no tan near its pole)."""
    cos_dphi, alpha, beta = g["cos_dphi"], g["alpha"], g["beta"]
    C1 = 1.0 - 0.5 * s2 / (s2 + 0.33)
    b = 0.45 * s2 / (s2 + 0.09)
    t = 2.0 * beta / np.pi
    one_minus_t = 2.0 * g["elev_beta"] / np.pi
    sin_a_minus_t3 = one_minus_t * (1.0 + t + t * t) - g["cos_alpha"] ** 2 / (1.0 + g["sin_alpha"])
    C2 = b * np.where(cos_dphi >= 0, g["sin_alpha"], sin_a_minus_t3)
    C3 = 0.125 * s2 / (s2 + 0.09) * (4.0 * alpha * beta / np.pi ** 2) ** 2
    tan_half_sum = (g["sin_alpha"] + g["sin_beta"]) / np.maximum(g["cos_alpha"] + g["cos_beta"], 1e-12)
    L1 = C1 + cos_dphi * C2 * g["tan_beta"] + (1.0 - np.abs(cos_dphi)) * C3 * tan_half_sum
    return np.maximum(L1, 0.0)


def on_full_L2(s2, cos_dphi, beta):
    """Oren & Nayar 1994, Sec. 4 interreflection term (bracket of L2, times rho^2 / pi):
    0.17 s^2 / (s^2 + 0.13) (1 - cos(dphi) (2 beta / pi)^2)."""
    return 0.17 * s2 / (s2 + 0.13) * (1.0 - cos_dphi * (2.0 * beta / np.pi) ** 2)


def eval(p, wi, wo):
    ok = (wi[:, 2] > 0) & (wo[:, 2] > 0)
    s = np.radians(p.sigma)
    s2 = s * s
    g = _angles(wi, wo)
    if p.variant == "qualitative":
        f = on_qualitative(p.albedo, s2, g)
    else:
        rho = p.albedo[None, :]
        f = rho * INV_PI * on_full_L1(s2, g)[:, None] \
            + rho * rho * INV_PI * on_full_L2(s2, g["cos_dphi"], g["beta"])[:, None]
    return np.where(ok[:, None], f, 0.0)


def pdf(p, wi, wo):
    return np.where(wo[:, 2] > 0, cosine_hemisphere_pdf(wi), 0.0)


def sample(p, wo, u):
    wi = cosine_hemisphere(u)
    pdf_ = pdf(p, wi, wo)
    ok = pdf_ > 0
    # f cos / (cos / pi) = pi f
    weight = np.where(ok[:, None], np.pi * eval(p, wi, wo), 0.0)
    return wi, weight, pdf_


def lobes(p):
    return Lobe.REFLECTION | Lobe.DIFFUSE
