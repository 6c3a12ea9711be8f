"""Ashikhmin-Shirley: an anisotropic Phong-style specular lobe with Schlick Fresnel over a diffuse
term that takes the energy the specular layer leaves.

Ashikhmin & Shirley 2000, "An Anisotropic Phong BRDF Model", Journal of Graphics Tools 5(2):
  specular (eq. 4) rho_s = sqrt((nu + 1)(nv + 1)) / (8 pi) (n.h)^(nu cos^2 phi_h + nv sin^2 phi_h)
                           / ((h.k) max(n.k1, n.k2)) F(k.h),  F = Schlick 1994 with F0 = rs
  diffuse  (eq. 5) rho_d = 28 rd / (23 pi) (1 - rs) (1 - (1 - n.k1 / 2)^5) (1 - (1 - n.k2 / 2)^5)
  sampling (eqs. 9-10) phi_h = atan(sqrt((nu + 1) / (nv + 1)) tan(pi u1 / 2)) (per quadrant),
                       cos theta_h = (1 - u2)^(1 / (nu cos^2 phi_h + nv sin^2 phi_h + 1)),
  pdf      (eq. 8) p(k2) = p_h(h) / (4 k1.h), p_h = sqrt((nu + 1)(nv + 1)) / (2 pi) (n.h)^(...).
nu acts along the tangent x (docs/conventions.md: anisotropic nu runs along x), nv along y. The model is
reciprocal (every factor is symmetric in k1, k2).
"""

from __future__ import annotations

import numpy as np

from viewer.brdf.sampling import (cosine_hemisphere, cosine_hemisphere_pdf, dot, luminance, normalize,
                                  phong_alpha, pick_lobe, pow_one_minus, ratio_capped, reflect,
                                  sample_weight)
from viewer.brdf.lobes import Lobe
from viewer.brdf.spec import ModelSpec, Param

SPEC = ModelSpec(
    name="ashikhmin_shirley",
    title="Ashikhmin-Shirley (anisotropic Phong)",
    params=(
        Param("rd", "rgb", [0.5, 0.5, 0.5], "diffuse reflectance (of the substrate)", lo=0.0, hi=1.0),
        Param("rs", "rgb", [0.05, 0.05, 0.05], "specular reflectance at normal incidence (Schlick F0)",
              lo=0.0, hi=1.0),
        Param("nu", "float", 100.0, "Phong exponent along the tangent x", lo=1.0, hi=10000.0,
              ui_lo=1.0, ui_hi=1000.0, log=True),
        Param("nv", "float", 100.0, "Phong exponent along the bitangent y", lo=1.0, hi=10000.0,
              ui_lo=1.0, ui_hi=1000.0, log=True),
    ),
    source="Ashikhmin & Shirley 2000, JGT 5(2): eq. 4 (specular), eq. 5 (diffuse), eq. 8 (pdf), "
           "eqs. 9-10 (half-vector sampling); Schlick 1994 Fresnel",
    doc="Sampling: cosine for the diffuse term, the paper's half-vector distribution for the specular "
        "term, picked in proportion to luminance(rd)(1 - luminance(rs)) vs. the Schlick reflectance at wo.",
)


TEST_PARAMS = {
    "default": {},
    "rough": {"rd": [0.2, 0.2, 0.2], "rs": [0.6, 0.6, 0.6], "nu": 3.0, "nv": 8.0},
    "sharp_anisotropic": {"rd": [0.1, 0.1, 0.1], "rs": [0.9, 0.9, 0.9], "nu": 1000.0, "nv": 20.0},
}

def F_Schlick(f0, cos):
    """Schlick 1994: F0 + (1 - F0)(1 - cos)^5 (Ashikhmin & Shirley 2000, eq. 4's F)."""
    return f0[None, :] + (1.0 - f0[None, :]) * ((1.0 - np.clip(cos, 0.0, 1.0)) ** 5)[:, None]


def as_exponent(h, nu, nv):
    """nu cos^2 phi_h + nv sin^2 phi_h = (nu h.x^2 + nv h.y^2) / (1 - h.z^2); any value at h = n (then
    (n.h)^e = 1), so the 0/0 there is replaced by nu."""
    t2 = h[:, 0] ** 2 + h[:, 1] ** 2
    return np.where(t2 > 0, (nu * h[:, 0] ** 2 + nv * h[:, 1] ** 2) / np.where(t2 > 0, t2, 1.0), nu)


def D_AshikhminShirley(h, nu, nv):
    """Ashikhmin & Shirley 2000, eq. 8 without 1/(4 k.h): the half-vector density
    sqrt((nu + 1)(nv + 1)) / (2 pi) (n.h)^(nu cos^2 phi + nv sin^2 phi); 1 - n.h = (h.x^2 + h.y^2) / (1 + h.z)."""
    x = (h[:, 0] ** 2 + h[:, 1] ** 2) / (1.0 + np.maximum(h[:, 2], 0.0))
    val = np.sqrt((nu + 1.0) * (nv + 1.0)) / (2.0 * np.pi) * pow_one_minus(x, as_exponent(h, nu, nv))
    return np.where(h[:, 2] > 0, val, 0.0)


def _half_terms(p, wi, wo):
    """(h, h.k, D(h)): the half vector's terms that f and the pdf share."""
    h = normalize(wi + wo)
    return h, dot(h, wo), D_AshikhminShirley(h, p.nu, p.nv)


def as_specular(p, wi, wo, terms=None):
    """Ashikhmin & Shirley 2000, eq. 4: p_h(h) / (4 (h.k) max(n.k1, n.k2)) F(k.h)
    (= sqrt((nu+1)(nv+1)) / (8 pi) (n.h)^e F / ((h.k) max(n.k1, n.k2)));
    ``terms``: ``_half_terms(p, wi, wo)`` when the caller has them."""
    _, hk, D = _half_terms(p, wi, wo) if terms is None else terms
    den = 4.0 * hk * np.maximum(wi[:, 2], wo[:, 2])
    ok = den > 0
    s = ratio_capped(D, den)
    return np.where(ok, s, 0.0)[:, None] * F_Schlick(p.rs, hk)


def as_diffuse(p, wi, wo):
    """Ashikhmin & Shirley 2000, eq. 5: 28 rd / (23 pi) (1 - rs)(1 - (1 - n.k1/2)^5)(1 - (1 - n.k2/2)^5)."""
    a = 1.0 - (1.0 - 0.5 * wi[:, 2]) ** 5
    b = 1.0 - (1.0 - 0.5 * wo[:, 2]) ** 5
    return (28.0 / (23.0 * np.pi)) * p.rd[None, :] * (1.0 - p.rs[None, :]) * (a * b)[:, None]


def eval(p, wi, wo, terms=None):
    ok = (wi[:, 2] > 0) & (wo[:, 2] > 0)
    f = as_diffuse(p, wi, wo) + as_specular(p, wi, wo, terms)
    return np.where(ok[:, None], f, 0.0)


def _specular_probability(p, wo):
    ls = luminance(p.rs)
    ws = ls + (1.0 - ls) * (1.0 - np.clip(wo[:, 2], 0.0, 1.0)) ** 5
    wd = luminance(p.rd) * (1.0 - ls)
    tot = ws + wd
    return np.where(tot > 0, ws / np.where(tot > 0, tot, 1.0), 0.5)


def _pdf(p, wi, wo, ps, terms=None):
    _, hk, D = _half_terms(p, wi, wo) if terms is None else terms
    spec = np.where(hk > 0, D / (4.0 * np.where(hk > 0, hk, 1.0)), 0.0)
    val = ps * spec + (1.0 - ps) * cosine_hemisphere_pdf(wi)
    return np.where((wi[:, 2] > 0) & (wo[:, 2] > 0), val, 0.0)


def pdf(p, wi, wo):
    return _pdf(p, wi, wo, _specular_probability(p, wo))


def sample_half_vector(u, nu, nv):
    """Ashikhmin & Shirley 2000, eqs. 9-10. u1 picks the quadrant and phi within it (atan2 form of
    atan(sqrt((nu+1)/(nv+1)) tan(pi u / 2)), finite at u -> 1); cos theta_h = (1 - u2)^(1 / (e + 1))."""
    q = np.floor(4.0 * u[:, 0])
    v = 4.0 * u[:, 0] - q
    a = np.sqrt((nu + 1.0) / (nv + 1.0))
    phi = np.arctan2(a * np.sin(0.5 * np.pi * v), np.cos(0.5 * np.pi * v))
    phi = np.select([q == 0, q == 1, q == 2], [phi, np.pi - phi, np.pi + phi], 2.0 * np.pi - phi)
    c, s = np.cos(phi), np.sin(phi)
    e = nu * c * c + nv * s * s
    cos_t = np.power(1.0 - u[:, 1], 1.0 / (e + 1.0))
    sin_t = np.sqrt(np.maximum(0.0, 1.0 - cos_t * cos_t))
    return np.stack([sin_t * c, sin_t * s, cos_t], axis=-1)


def sample(p, wo, u):
    ps = _specular_probability(p, wo)
    probs = np.empty((len(u), 2))
    probs[:, 0] = ps
    probs[:, 1] = 1.0 - ps
    k, u0 = pick_lobe(u[:, 0], probs)
    uu = np.empty((len(u), 2))
    uu[:, 0] = u0
    uu[:, 1] = u[:, 1]
    wi = np.empty((len(u), 3))
    spec = k == 0  # each lobe's directions for its own rows only
    wi[spec] = reflect(wo[spec], sample_half_vector(uu[spec], p.nu, p.nv))
    wi[~spec] = cosine_hemisphere(uu[~spec])
    wi = normalize(wi)
    terms = _half_terms(p, wi, wo)
    weight, pdf_ = sample_weight(eval(p, wi, wo, terms), wi, _pdf(p, wi, wo, ps, terms))
    return wi, weight, pdf_


def fresnel_source(p):
    return {"type": "schlick", "f0": np.asarray(p.rs, float), "field": "rs"}


def ibl_split(p):
    """Image-based lighting proxy: the specular lobe alone (rd = 0), and the GGX alpha of an
    isotropic lobe of the geometric-mean exponent sqrt(nu nv): alpha = sqrt(2 / (n + 2))."""
    return p.replace(rd=np.zeros(3)), phong_alpha(np.sqrt(p.nu * p.nv))


def lobes(p):
    """The coupled diffuse term and the anisotropic specular lobe."""
    return Lobe.REFLECTION | Lobe.DIFFUSE | Lobe.GLOSSY
