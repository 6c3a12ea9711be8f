"""Microfacet BRDF: f = F G D / (4 cos_i cos_o) (lecture; Torrance & Sparrow 1967, Blinn 1977,
Cook & Torrance 1981, Walter et al. 2007 eq. 20), plus an optional Lambertian base.

  * D: beckmann | ggx | blinn_phong (see ``microfacet_dist``); anisotropic alpha_x along the
    tangent +x and alpha_y along +y (blinn_phong is isotropic and uses alpha_x).
  * G: smith = height-correlated Smith G2 (Heitz 2014 eq. 99), v_cavity = Cook-Torrance 1981.
    blinn_phong + smith uses Beckmann's Lambda (Walter 2007 sec. 5.2), blended toward the V-cavity
    G only where the borrowed Lambda would let the albedo exceed 1 (grazing wo, alpha >= 0.2; see
    ``microfacet_dist.BLINN_SMITH_CAP``); elsewhere it is the plain Smith G2.
  * F at the microfacet: F(wi . h) with h = normalize(wi + wo): dielectric (ior, exact),
    conductor (eta + i k, exact) or Schlick (f0).
  * kd: the diffuse base, f_d = kd / pi (1 - F(cos_i)) (1 - F(cos_o)), F evaluated with the
    macro-normal cosines (the light that enters and leaves through a Fresnel interface; the
    coupling idea of Shirley et al. 1997 / Ashikhmin & Shirley 2000, simplified to Fresnel
    transmittances). This keeps kd + specular from doubling energy near grazing angles; it is
    not a proof of energy conservation, but the directional albedo stays <= 1 over the full
    parameter grid checked in tests/test_microfacet.py (kd <= 1).

multiple_scattering = true (GGX or Beckmann with Smith G): the light scattered between microfacets
too, by the random walk on the microsurface of Heitz et al. 2016 (``microfacet_walk``): sampling
is the walk itself (weight = the product of the Fresnel terms), eval = the analytic
single-scattering lobe + a one-walk unbiased estimate of the higher orders (so f is a random
variable: mean-correct, noisy), pdf = a heuristic used only as an MIS weight. The rasterizer has no
walk; it approximates the same light with its multiple-scattering compensation (Fdez-Aguera 2019).

Sampling: visible normals (GGX, Beckmann) or D cos (blinn_phong) for the specular lobe, cosine
for the diffuse lobe, chosen with probability P_d = mean(kd (1 - F(cos_o))) /
(mean(kd (1 - F(cos_o))) + mean(F(cos_o))); the pdf is the matching mixture and the weight is
f cos / pdf (one-sample MIS over the two lobes).
"""

from __future__ import annotations

import numpy as np

from viewer.brdf.fresnel import f0_conductor, fresnel_conductor, fresnel_dielectric, fresnel_schlick
from viewer.brdf.microfacet_dist import DISTRIBUTIONS, SHADOWING, Distribution, G_blinn_smith, G_v_cavity
from viewer.brdf import microfacet_walk, spectral_fresnel, thin_film
from viewer.brdf.presets import METALS
from viewer.brdf.sampling import INV_PI, cosine_hemisphere, dot, normalize, ratio_capped, reflect
from viewer.brdf.lobes import Lobe
from viewer.brdf.spec import ModelSpec, Param

_GOLD_ETA, _GOLD_K = METALS["gold"]
_GOLD_F0 = [round(float(x), 3) for x in f0_conductor(np.array(_GOLD_ETA), np.array(_GOLD_K))]

SPEC = ModelSpec(
    name="microfacet",
    title="Microfacet (Torrance-Sparrow / Cook-Torrance / Walter)",
    params=(
        Param("distribution", "choice", "ggx", "microfacet normal distribution D",
              choices=DISTRIBUTIONS),
        Param("shadowing", "choice", "smith", "geometric attenuation G: height-correlated Smith "
              "(Heitz 2014) or V-cavity (Cook-Torrance 1981)", choices=SHADOWING),
        Param("fresnel", "choice", "conductor", "Fresnel term F at the microfacet",
              choices=("dielectric", "conductor", "schlick")),
        Param("alpha_x", "float", 0.2, "roughness along the tangent +x (Walter 2007 alpha)",
              lo=1e-4, hi=1.0, ui_lo=0.001, log=True),
        Param("alpha_y", "float", 0.2, "roughness along the bitangent +y (unused by blinn_phong)",
              lo=1e-4, hi=1.0, ui_lo=0.001, log=True),
        Param("ior", "float", 1.5, "index of refraction (fresnel = dielectric)", lo=1.0, hi=3.0),
        Param("eta", "rgb", list(_GOLD_ETA), "real part of the complex IOR (fresnel = conductor); "
              "default: gold", lo=0.01, hi=10.0),
        Param("k", "rgb", list(_GOLD_K), "extinction coefficient (fresnel = conductor)",
              lo=0.0, hi=20.0),
        Param("f0", "rgb", _GOLD_F0, "normal-incidence reflectance (fresnel = schlick)",
              lo=0.0, hi=1.0),
        Param("kd", "rgb", [0.0, 0.0, 0.0], "diffuse base albedo, weighted by the Fresnel "
              "transmittances (1 - F(cos_i)) (1 - F(cos_o))", lo=0.0, hi=1.0),
        thin_film.param(),
        spectral_fresnel.param(),
        Param("multiple_scattering", "bool", False, "light scattered between microfacets too: the "
              "reference's random walk on the microsurface (Heitz et al. 2016; GGX or Beckmann with "
              "Smith G); the rasterizer approximates it with its compensation (Fdez-Aguera 2019 "
              "under environment light, Kulla & Conty 2017 for point and directional lights)"),
    ),
    source="Torrance & Sparrow 1967; Blinn 1977; Cook & Torrance 1981; Walter et al. 2007 eq. 20 "
           "(f = F G D / (4 cos_i cos_o)); Heitz 2014 eq. 99 (Smith G2); Heitz 2018 (GGX VNDF); "
           "Heitz & d'Eon 2014 (Beckmann VNDF)",
    doc="Lecture: 'The origins' / 'Microfacet models in graphics'.",
    aliases={"alpha": ("alpha_x", "alpha_y")},
)


def distribution(p) -> Distribution:
    return Distribution(p.distribution, p.alpha_x, p.alpha_y)


def fresnel_rgb(p, cos):
    """F(cos) as (N, 3) for the chosen Fresnel variant (a thin film on the dielectric or
    conductor first: viewer/brdf/thin_film.py; Schlick has no film)."""
    if thin_film.at_point(p) and p.fresnel != "schlick":
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
    if p.fresnel == "schlick":
        return fresnel_schlick(c, p.f0[None, :])
    return np.broadcast_to(fresnel_dielectric(c, p.ior), (c.shape[0], 3))


def _half(wi, wo):
    return normalize(wi + wo)


def fdg(p, wi, wo):
    """(F (N,3), D (N,), G (N,), h) for reflection; the term views show these."""
    h = _half(wi, wo)
    dist = distribution(p)
    D = dist.D(h)
    if p.shadowing == "smith":
        G = dist.G2(wi, wo, h)
        if p.distribution == "blinn_phong":
            # Beckmann's Lambda is only an approximation for the Phong distribution (Walter et al.
            # 2007 sec. 5.2): near grazing wo it lets the albedo exceed 1. The V-cavity cap (valid
            # for any D, Heitz 2014 sec. 4.3) is blended in only as far as that requires.
            G = G_blinn_smith(dist, wi, wo, h)
    else:
        G = G_v_cavity(wi, wo, h)
    F = fresnel_rgb(p, dot(wi, h))
    return F, D, G, h


def eval_specular(p, wi, wo):
    ci, co = wi[:, 2], wo[:, 2]
    ok = (ci > 0) & (co > 0)
    F, D, G, _ = fdg(p, wi, wo)
    den = 4.0 * np.where(ok, ci * co, 1.0)
    return np.where(ok[:, None], F * ratio_capped(D * G, den)[:, None], 0.0)


def terms(p, wi, wo):
    """The term view's factors (the ``terms`` hook): D(h), F(wi . h), G(wi, wo, h) and
    1 / (4 cos_i cos_o), whose product is ``eval_specular`` (the same arrays, multiplied in
    another order: the two agree to a few float64 roundings, below ``F_MAX`` where f is capped), and 'other' = the diffuse base where kd > 0 and
    the random walk's mean where multiple scattering is on (f = product + other). 0 below the
    horizon, as f."""
    ci, co = wi[:, 2], wo[:, 2]
    ok = (ci > 0) & (co > 0)
    F, D, G, _ = fdg(p, wi, wo)
    inv = np.where(ok, 1.0 / (4.0 * np.where(ok, ci * co, 1.0)), 0.0)
    out = {"D": np.where(ok, D, 0.0), "F": np.where(ok[:, None], F, 0.0), "G": np.where(ok, G, 0.0),
           "1/(4 cos cos)": inv}
    other = np.zeros((wi.shape[0], 3))
    if np.any(p.kd > 0):
        other = other + eval_diffuse(p, wi, wo)
    if walks(p):
        other = other + microfacet_walk.eval_multiple_mean(distribution(p), _fresnel_fn(p), wi, wo, walks=48)
    if np.any(other != 0):
        out["other"] = other
    return out


def eval_diffuse(p, wi, wo):
    ci, co = wi[:, 2], wo[:, 2]
    ok = (ci > 0) & (co > 0)
    fd = p.kd[None, :] * INV_PI * np.maximum(1.0 - fresnel_rgb(p, ci), 0.0) * np.maximum(1.0 - fresnel_rgb(p, co), 0.0)
    return np.where(ok[:, None], fd, 0.0)


def walks(p) -> bool:
    """Whether the random walk is on (multiple_scattering with GGX or Beckmann and Smith G; the
    flag is ignored for blinn_phong, which has no visible-normal sampling, and V-cavity G, which is
    not a Smith microsurface)."""
    return bool(p.get("multiple_scattering", False)) and p.distribution != "blinn_phong" \
        and p.shadowing == "smith"


def _fresnel_fn(p):
    return lambda cos: fresnel_rgb(p, cos)


def eval_multiple(p, wi, wo):
    """One random-walk estimate of the orders >= 2 (zero unless ``walks(p)``)."""
    if not walks(p):
        return np.zeros((wi.shape[0], 3))
    return microfacet_walk.eval_multiple(distribution(p), _fresnel_fn(p), wi, wo)


def eval(p, wi, wo):
    f = eval_specular(p, wi, wo)
    if walks(p):
        f = f + eval_multiple(p, wi, wo)
    if np.any(p.kd > 0):
        f = f + eval_diffuse(p, wi, wo)
    return f


def eval_mean(p, wi, wo, n_walks: int = 48):
    """``eval`` with the random walk's part averaged over ``n_walks`` walks (plots: a smoother
    curve than one walk per point); equal to ``eval`` without the walk."""
    if not walks(p):
        return eval(p, wi, wo)
    f = eval_specular(p, wi, wo) + microfacet_walk.eval_multiple_mean(
        distribution(p), _fresnel_fn(p), wi, wo, walks=n_walks)
    if np.any(p.kd > 0):
        f = f + eval_diffuse(p, wi, wo)
    return f


def _p_diffuse(p, wo):
    """Probability of sampling the diffuse lobe for each wo."""
    if not np.any(p.kd > 0):
        return np.zeros(wo.shape[0])
    Fo = fresnel_rgb(p, wo[:, 2])
    wd = np.mean(p.kd[None, :] * np.maximum(1.0 - Fo, 0.0), axis=-1)
    ws = np.mean(Fo, axis=-1)
    tot = wd + ws
    return np.where(tot > 0, wd / np.where(tot > 0, tot, 1.0), 0.0)


def _pdf_specular(p, wi, wo):
    h = _half(wi, wo)
    oh = dot(wo, h)
    ok = (wi[:, 2] > 0) & (wo[:, 2] > 0) & (oh > 0)
    # reflection Jacobian dm/dwi = 1 / (4 |wo.m|) (Walter et al. 2007, eq. 14)
    pm = distribution(p).pdf_m(wo, h)
    return np.where(ok, pm / (4.0 * np.where(ok, oh, 1.0)), 0.0)


def pdf(p, wi, wo):
    ok = (wi[:, 2] > 0) & (wo[:, 2] > 0)
    pd = _p_diffuse(p, wo)
    ps = _pdf_specular(p, wi, wo)
    if walks(p):  # the walk's density has no closed form: a heuristic, an MIS weight only
        q = microfacet_walk.ms_fraction(np.sqrt(p.alpha_x * p.alpha_y))
        ps = (1.0 - q) * ps + q * np.maximum(wi[:, 2], 0.0) * INV_PI
    out = (1.0 - pd) * ps + pd * np.maximum(wi[:, 2], 0.0) * INV_PI
    return np.where(ok, out, 0.0)


def _sample_walk(p, wo, u):
    """Lobe choice as in ``sample``, then the random walk or the cosine lobe, each weighted by
    its own ratio (no one-sample MIS over the lobes: the walk has no closed-form density)."""
    n = wo.shape[0]
    up = wo[:, 2] > 0
    wo_s = np.where(up[:, None], wo, np.array([0.0, 0.0, 1.0]))
    pd = _p_diffuse(p, wo_s)
    choose_d = u[:, 0] < pd
    u0 = np.where(choose_d, u[:, 0] / np.where(pd > 0, pd, 1.0),
                  (u[:, 0] - pd) / np.where(pd < 1, 1.0 - pd, 1.0))
    uu = np.stack([np.clip(u0, 0.0, 1.0 - 1e-16), u[:, 1]], axis=-1)
    wi = np.empty((n, 3))
    weight = np.zeros((n, 3))
    s = ~choose_d
    if np.any(s):
        wi_s, w_s, _ = microfacet_walk.sample(distribution(p), _fresnel_fn(p), wo_s[s], uu[s])
        wi[s] = wi_s
        weight[s] = w_s / (1.0 - pd[s])[:, None]
    if np.any(choose_d):
        d = choose_d
        wi[d] = cosine_hemisphere(uu[d])
        weight[d] = eval_diffuse(p, wi[d], wo_s[d]) * (np.pi / np.where(pd[d] > 0, pd[d], 1.0))[:, None]
    pdf_ = pdf(p, wi, wo)
    ok = up & (wi[:, 2] > 0) & (pdf_ > 0)
    return wi, np.where(ok[:, None], weight, 0.0), np.where(ok, pdf_, 0.0)


def sample(p, wo, u):
    if walks(p):
        return _sample_walk(p, wo, u)
    n = wo.shape[0]
    up = wo[:, 2] > 0
    wo_s = np.where(up[:, None], wo, np.array([0.0, 0.0, 1.0]))
    pd = _p_diffuse(p, wo_s)
    choose_d = u[:, 0] < pd
    u0 = np.where(choose_d, u[:, 0] / np.where(pd > 0, pd, 1.0),
                  (u[:, 0] - pd) / np.where(pd < 1, 1.0 - pd, 1.0))
    uu = np.stack([np.clip(u0, 0.0, 1.0 - 1e-16), u[:, 1]], axis=-1)
    wi = np.empty((n, 3))
    if np.any(~choose_d):
        m = distribution(p).sample_m(wo_s, uu)
        wi_s = reflect(wo_s, m)
        wi[:] = wi_s
    if np.any(choose_d):
        wi[choose_d] = cosine_hemisphere(uu[choose_d])
    pdf_ = pdf(p, wi, wo)
    ok = up & (wi[:, 2] > 0) & (pdf_ > 0)
    f = eval(p, wi, wo)
    weight = np.where(ok[:, None], f * (wi[:, 2] / np.where(ok, pdf_, 1.0))[:, None], 0.0)
    return wi, weight, np.where(ok, pdf_, 0.0)


def fresnel_source(p):
    if p.fresnel == "dielectric":
        return {"type": "dielectric", "ior": float(p.ior), "field": "ior"}
    if p.fresnel == "conductor":
        return {"type": "conductor", "eta": np.asarray(p.eta, float), "k": np.asarray(p.k, float),
                "field": "eta, k"}
    return {"type": "schlick", "f0": np.asarray(p.f0, float), "field": "f0"}


def ibl_split(p):
    """Image-based lighting (split sum): the specular lobe alone (kd = 0) and its alpha (the
    geometric mean of alpha_x and alpha_y for anisotropic lobes; alpha_x for blinn_phong)."""
    a = p.alpha_x if p.distribution == "blinn_phong" else float(np.sqrt(p.alpha_x * p.alpha_y))
    return p.replace(kd=np.zeros(3)), float(a)


def lobes(p):
    """The specular lobe, and the diffuse base where kd > 0 (the GLSL microfacet_sample says the same)."""
    diffuse = Lobe.DIFFUSE if np.any(np.asarray(p.kd, dtype=np.float64) > 0.0) else Lobe.NONE
    return Lobe.REFLECTION | Lobe.GLOSSY | diffuse
