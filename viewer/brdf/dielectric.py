"""Dielectric interface (glass, water): reflection and refraction, smooth or rough.

* ``alpha = 0``: smooth interface, two delta lobes (lecture: 'Reflectance of perfectly specular
  materials', 'Total internal reflection', 'Transmitted radiance': rho_t = 1 - rho_s).
  ``sample`` reflects with probability R = fresnel_dielectric(cos_o, eta) and refracts otherwise
  (probability T = 1 - R); ``pdf`` = R or T (the probability of the chosen lobe); ``eval`` and
  ``pdf`` are 0 as functions.
* ``alpha > 0``: rough interface, GGX microfacets with height-correlated Smith G (Walter et al.
  2007, 'Microfacet Models for Refraction through Rough Surfaces': eq. 20 reflection, eq. 21
  transmission, eq. 16 generalized half vector, eqs. 14 and 17 the Jacobians). G2 for reflection
  is Heitz 2014 eq. 99, 1 / (1 + Lambda_i + Lambda_o); for refraction it is Heitz 2014's
  height-correlated form B(1 + Lambda_o, 1 + Lambda_i) (Beta function; sec. 5.3), which is
  smaller: the points seen from above are the high ones, those seen from below the low ones. Sampling: GGX
  visible normals for wo (Heitz 2018), then reflect with probability F(wo.m) or refract.

Sides and eta: the relative index seen from wo is eta = ior when wo is outside (wo.z > 0) and
1 / ior when wo is inside (wo.z < 0); total internal reflection follows from it.

Radiance transport (pbrt-v4's TransportMode::Radiance): radiance is not conserved across a
refraction, L n^-2 is, so the transmitted f (and the smooth lobe's weight) carries the factor
1 / eta^2 with eta the relative index seen from wo: a camera ray entering glass gets
weight T / 1.5^2 ... per unit of pdf, i.e. weight = 1 / eta^2 for the smooth transmission lobe
(and eta^2 on the way out, so a slab round trip has weight 1). This is why the model is not
reciprocal: f(wi, wo) = f(wo, wi) * (eta_o / eta_i)^2 across the interface.

``sigma_a`` is the absorption coefficient (per metre) of the medium inside: Bouguer's law
L = L0 exp(-sigma_a s) (lecture: 'Transmitted radiance') is applied by the path tracer over the
distance s travelled inside; the BSDF itself does not absorb.
"""

from __future__ import annotations

import numpy as np

from viewer.brdf import spectral_fresnel, thin_film
from viewer.brdf.fresnel import fresnel_dielectric, fresnel_dielectric_transmittance
from viewer.brdf.microfacet_dist import Distribution
from viewer.brdf.sampling import F_MAX, dot, normalize, ratio_capped, reflect, reflect_z, split_uniform
from viewer.brdf.lobes import Lobe
from viewer.brdf.spec import ModelSpec, Param

SPEC = ModelSpec(
    name="dielectric",
    title="Dielectric (glass), smooth or rough",
    params=(
        Param("ior", "float", 1.5, "index of refraction of the inside (outside is 1)", lo=1.0, hi=3.0),
        Param("alpha", "float", 0.0, "GGX roughness (Walter 2007 alpha); 0 = smooth glass",
              lo=0.0, hi=1.0),
        Param("sigma_a", "rgb", [0.0, 0.0, 0.0], "absorption coefficient inside (Bouguer's law, "
              "applied by the path tracer along the path inside)", unit="1/m", lo=0.0, hi=1000.0),
        spectral_fresnel.param(dielectric_only=True),
        thin_film.param(),
    ),
    source="Fresnel equations and Snell's law (lecture); Walter et al. 2007 eqs. 14-21 (rough); "
           "Heitz 2014 eq. 99 and sec. 5.3 (G2 reflection / refraction); Heitz 2018 (VNDF); pbrt-v4 radiance-mode eta^2 scaling",
    reciprocal=False,
    reciprocal_why="radiance changes by (n_t / n_i)^2 across a refraction (L / n^2 is invariant), "
                   "so f_t(wi, wo) = f_t(wo, wi) (eta_o / eta_i)^2",
    delta=True,  # when alpha = 0 (the default): two delta lobes
    transmissive=True,
)

SMOOTH_ALPHA = 0.0


def _is_smooth(p):
    return p.alpha <= SMOOTH_ALPHA


def refract(w, m, eta):
    """Refract w (pointing away, on the side m points to) through the facet m; eta = n_t / n_i.
    Returns (wt, ok); ok is False under total internal reflection (Snell's law, vector form:
    wt = -w / eta + (cos_i / eta - cos_t) m)."""
    cos_i = dot(w, m)
    sin2_t = np.maximum(0.0, 1.0 - cos_i * cos_i) / (eta * eta)
    ok = sin2_t < 1.0
    cos_t = np.sqrt(np.maximum(0.0, 1.0 - sin2_t))
    wt = -w / eta[..., None] + (cos_i / eta - cos_t)[..., None] * m
    return wt, ok


def _side(p, wo):
    """(s, eta): s = sign that maps wo to the upper hemisphere, eta = relative IOR seen from wo."""
    s = np.where(wo[:, 2] < 0, -1.0, 1.0)
    eta = np.where(s > 0, p.ior, 1.0 / p.ior)
    return s, eta


def _flip(w, s):
    return w * np.stack([np.ones_like(s), np.ones_like(s), s], axis=-1)


def _transmittance_cos(cos_i, cos_t, eta):
    """T = 1 - R of a dielectric interface from both cosines (no square root, no cancellation):
    4 eta cos_i cos_t / (cos_i + eta cos_t)^2 (s) and / (eta cos_i + cos_t)^2 (p), averaged."""
    num = 4.0 * eta * cos_i * cos_t
    ds, dp = cos_i + eta * cos_t, eta * cos_i + cos_t
    Ts = np.where(ds > 0, num / np.where(ds > 0, ds * ds, 1.0), 0.0)
    Tp = np.where(dp > 0, num / np.where(dp > 0, dp * dp, 1.0), 0.0)
    return 0.5 * (Ts + Tp)


def _rough_eval_pdf(p, wi, wo):
    """(f (N,), pdf (N,)) of the rough interface, in the frame where wo is up (the caller flips)."""
    s, eta = _side(p, wo)
    wo = _flip(wo, s)
    wi = _flip(wi, s)
    co, ci = wo[:, 2], wi[:, 2]
    reflect_ = ci > 0
    etap = np.where(reflect_, 1.0, eta)
    # generalized half vector, Walter et al. 2007 eq. 16 (h_t = -(eta_i wi + eta_o wo), up to sign)
    h = wi * etap[:, None] + wo
    hlen2 = dot(h, h)
    valid = (ci != 0) & (co > 0) & (hlen2 > 0)
    wm = normalize(h)
    wm = np.where((wm[:, 2] < 0)[:, None], -wm, wm)
    im = dot(wi, wm)
    om = dot(wo, wm)
    valid &= (im * ci > 0) & (om * co > 0)
    dist = Distribution("ggx", p.alpha, p.alpha)
    D = dist.D(wm)
    # height-correlated Smith G2: Heitz 2014 eq. 99 for reflection, the Beta-function form of
    # sec. 5.3 for refraction
    G = np.where(reflect_, dist.G2(wi, wo, wm), dist.G2_transmission(wi, wo, wm))
    F, T = film_or_fresnel(p, np.clip(om, 0.0, 1.0), eta)  # (N, 3) each
    aci = np.where(valid, np.abs(ci), 1.0)
    co = np.where(valid, co, 1.0)
    safe_h2 = np.where(valid, hlen2, 1.0)
    # reflection: Walter et al. 2007 eq. 20, f = F G D / (4 |cos_i| |cos_o|)
    f_r = F * ratio_capped(G * D, 4.0 * aci * co)[:, None]  # capped at F_MAX (sampling.py)
    # transmission: Walter et al. 2007 eq. 21 with (eta_i (i.h) + eta_o (o.h))^2 written as
    # |wi etap + wo|^2 / etap^2 (no cancellation), then the radiance factor 1 / etap^2:
    # f_t = T G D |i.m| |o.m| / (|h|^2 |cos_i| |cos_o|)
    # T from both facet cosines: Snell's law holds at the generalized half vector, so cos_t = |i.m|
    # (well conditioned near total internal reflection, where sqrt(1 - sin_i^2 / eta^2) turns a
    # 1e-7 error of the inputs' length into 1e-7 / cos_t^2; the float GLSL twin does the same).
    # A thin film's RGB transmittance is 1 - R (thin_film.py).
    # A film's T = 1 - R at the outside cosine, for a transmission pair also a facet cosine:
    # |i.m| when wo is inside, |o.m| when outside (the same conditioning argument).
    if thin_film.at_point(p):
        inside = eta < 1.0
        c_out = np.where(inside, np.minimum(np.abs(im), 1.0), np.clip(om, 0.0, 1.0))
        T_f = 1.0 - thin_film.dielectric_reflectance_rgb(p, c_out, np.where(inside, 1.0 / eta, eta))
    else:
        T_f = _transmittance_cos(np.clip(om, 0.0, 1.0), np.minimum(np.abs(im), 1.0), eta)[:, None]
    f_t = np.minimum(np.minimum(T_f * (np.abs(im) * np.abs(om) / safe_h2)[:, None], F_MAX)
                     * ratio_capped(G * D, aci * co)[:, None], F_MAX)
    f = np.where(valid[:, None], np.where(reflect_[:, None], f_r, f_t), 0.0)
    F, T = F.mean(axis=1), T.mean(axis=1)  # the lobe probabilities of the sampler
    # pdf: visible normals times the Jacobians (eq. 14: 1 / (4 |o.m|); eq. 17 with the half-vector
    # length: |i.m| etap^2 / |h|^2), times the probability of the branch
    pm = dist.D_visible(wo, wm)
    pdf_r = pm / (4.0 * np.where(valid, np.abs(om), 1.0)) * F
    pdf_t = pm * np.abs(im) * etap * etap / safe_h2 * T
    pdf = np.where(valid, np.where(reflect_, pdf_r, pdf_t), 0.0)
    return f, pdf


def film_or_fresnel(p, cos, eta):
    """(R, T), each (N, 3), at cos on the side with relative index eta: a thin film's RGB
    reflectance and 1 - R (thin_film.py), or the plain Fresnel R and T."""
    if thin_film.at_point(p):
        R = thin_film.dielectric_reflectance_rgb(p, cos, eta)
        return R, 1.0 - R
    R = fresnel_dielectric(cos, eta)
    T = fresnel_dielectric_transmittance(cos, eta)
    return np.repeat(R[:, None], 3, axis=1), np.repeat(T[:, None], 3, axis=1)


def eval(p, wi, wo):
    if _is_smooth(p):
        return np.zeros((wi.shape[0], 3))
    f, _ = _rough_eval_pdf(p, wi, wo)
    return f


def pdf(p, wi, wo):
    if _is_smooth(p):
        return np.zeros(wi.shape[0])
    return _rough_eval_pdf(p, wi, wo)[1]


def _sample_smooth(p, wo, u):
    s, eta = _side(p, wo)
    wo_u = _flip(wo, s)
    co = wo_u[:, 2]
    R3, T3 = film_or_fresnel(p, np.clip(co, 0.0, 1.0), eta)
    R = R3.mean(axis=1)
    T = 1.0 - R
    choose_r = u[:, 0] < R
    n = np.array([0.0, 0.0, 1.0])
    wt, ok_t = refract(wo_u, np.broadcast_to(n, wo_u.shape), eta)
    wi_u = np.where(choose_r[:, None], reflect_z(wo_u), wt)
    ok = (co > 0) & (choose_r | ok_t)
    pdf_ = np.where(choose_r, R, T)
    # throughput f cos / pdf: 1 for reflection, 1 / eta^2 for transmission (radiance mode)
    # (with a film, R is RGB: the lobe is chosen with the mean R, weight R / mean R)
    safe = np.where(pdf_ > 0, pdf_, 1.0)
    wgt = np.where(choose_r[:, None], R3 / safe[:, None], T3 / (safe * eta * eta)[:, None])
    ok &= pdf_ > 0
    return _flip(wi_u, s), np.where(ok[:, None], wgt, 0.0), np.where(ok, pdf_, 0.0)


def _sample_rough(p, wo, u):
    s, eta = _side(p, wo)
    wo_u = _flip(wo, s)
    uc, u0 = split_uniform(u[:, 0])
    up = wo_u[:, 2] > 0
    wo_s = np.where(up[:, None], wo_u, np.array([0.0, 0.0, 1.0]))
    dist = Distribution("ggx", p.alpha, p.alpha)
    m = dist.sample_m(wo_s, np.stack([u0, u[:, 1]], axis=-1))
    om = dot(wo_s, m)
    F = film_or_fresnel(p, np.clip(om, 0.0, 1.0), eta)[0].mean(axis=1)
    choose_r = uc < F
    wr = reflect(wo_s, m)
    wt, ok_t = refract(wo_s, m, eta)
    wi_u = np.where(choose_r[:, None], wr, normalize(wt))
    ok = up & np.where(choose_r, wi_u[:, 2] > 0, ok_t & (wi_u[:, 2] < 0))
    wi = _flip(wi_u, s)
    f, pdf_ = _rough_eval_pdf(p, wi, wo)
    ok &= pdf_ > 0
    w = f * (np.abs(wi[:, 2]) / np.where(ok, pdf_, 1.0))[:, None]
    return wi, np.where(ok[:, None], w, 0.0), np.where(ok, pdf_, 0.0)


def sample(p, wo, u):
    if _is_smooth(p):
        return _sample_smooth(p, wo, u)
    return _sample_rough(p, wo, u)


def lobes(p):
    """Reflection and transmission: two delta lobes for smooth glass (alpha = 0), glossy ones for
    a rough interface. A sample's side is where its wi went (the GLSL dielectric_sample's branch)."""
    kind = Lobe.DELTA if _is_smooth(p) else Lobe.GLOSSY
    return Lobe.REFLECTION | Lobe.TRANSMISSION | kind


def is_dispersive(p):
    """A spectral dielectric (``spectral = "NAME"``): light refracts by n(lambda)."""
    return p.spectral != spectral_fresnel.NONE


def fresnel_source(p):
    return {"type": "dielectric", "ior": float(p.ior), "field": "ior"}


def ibl_split(p):
    """Image-based lighting: reflection and transmission are both specular lobes of width alpha."""
    return p, float(p.alpha)


def splits_u(p):
    """The rough interface's sample splits u[:, 0] into the Fresnel choice and the direction
    (``split_uniform``); the GLSL twin takes those as u.z and u.x (viewer.gl.brdf_glsl.glsl_u)."""
    return not _is_smooth(p)
