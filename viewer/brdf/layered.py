"""Layered BRDF: a rough dielectric coating over any base material (Weidlich & Wilkie 2007,
'Arbitrarily layered micro-facet surfaces', GRAPHITE 2007; lecture: 'The layered model').

  f(wi, wo) = f_coat(wi, wo)
            + T(cos_i) T(cos_o) a(wi', wo') f_base(wi', wo') / eta^2

* f_coat: GGX microfacet reflection of the coating's surface, F(wi.h) with exact dielectric
  Fresnel, height-correlated Smith G2 (Walter et al. 2007 eq. 20, Heitz 2014 eq. 99); this is
  Weidlich-Wilkie's top-layer term.
* wi', wo': wi and wo refracted through the (mean) coating surface into the layer, pointing up
  toward the interface: w' = (w.x / eta, w.y / eta, cos_t) (Weidlich-Wilkie sec. 4, 'the
  second layer is evaluated with the refracted directions').
* T = 1 - F: Fresnel transmittance into and out of the layer at the macro-surface angles
  (Weidlich-Wilkie's T12 and T21; the transmittance is the same in both directions).
* a = exp(-sigma_a * thickness * (1/cos_ti' + 1/cos_to')): Bouguer absorption along the two
  refracted paths through the layer (Weidlich-Wilkie's absorption term; lecture 'Transmitted
  radiance').
* 1 / eta^2: radiance entering the layer is multiplied by eta^2 and divided by it on the way
  out, while the refracted solid angle shrinks by cos_i / (eta^2 cos_i'): the net factor on
  f is 1 / eta^2 (flux is conserved: integral of T_i f_base cos_i dw_i over the outside
  hemisphere = eta^2 integral over the refracted cone). Weidlich-Wilkie's equation leaves this
  factor implicit; without it a white Lambert base under a clear coat would reflect more than
  it receives.
Light that is internally reflected inside the layer (beyond the critical cone, or by the
coating from below) is not followed, as in Weidlich-Wilkie: the model loses that energy, so
its albedo stays below 1 and with coating ior = 1, sigma_a = 0 it reduces exactly to the base.

Units: thickness in micrometres, sigma_a in 1/micrometre (only the optical depth
sigma_a * thickness matters).

Reciprocal: yes. T(cos_i) T(cos_o), the absorption, the 1 / eta^2 and f_coat are symmetric in
(wi, wo), and f_base is evaluated at the symmetric pair (wi', wo'); so f is reciprocal when the
base is.

Sampling: the coat lobe (GGX visible normals) with probability P_c = F(cos_o), else the base
(its own ``sample`` with wo', the result refracted out; pdf converted by the solid-angle
Jacobian cos_i / (eta^2 cos_i')). pdf is the matching mixture; weight = f cos / pdf. A delta
base (mirror) is a discrete lobe: its sample has pdf (1 - P_c) pdf_base and its throughput.
"""

from __future__ import annotations

import numpy as np

from viewer.brdf import spectral_fresnel
from viewer.brdf.fresnel import fresnel_dielectric, fresnel_dielectric_transmittance
from viewer.brdf.microfacet_dist import Distribution
from viewer.brdf.sampling import normalize, ratio_capped, reflect, split_uniform
from viewer.brdf.spec import ModelSpec, Param

SPEC = ModelSpec(
    name="layered",
    title="Layered (Weidlich-Wilkie coating over a base)",
    params=(
        Param("coating", "table", {}, "the dielectric coating", fields=(
            Param("ior", "float", 1.5, "index of refraction of the coating", lo=1.0, hi=3.0),
            Param("alpha", "float", 0.1, "GGX roughness of the coating surface", lo=0.001, hi=1.0,
                  log=True),
            Param("thickness", "float", 10.0, "coating thickness", unit="um", lo=0.0, hi=1000.0),
            Param("sigma_a", "rgb", [0.0, 0.0, 0.0], "absorption coefficient in the coating",
                  unit="1/um", lo=0.0, hi=10.0),
            spectral_fresnel.param(dielectric_only=True),
        )),
        Param("base", "material", {"model": "lambert", "albedo": [0.5, 0.1, 0.1]},
              "the material under the coating (any non-layered model)"),
    ),
    source="Weidlich & Wilkie 2007 (layered micro-facet surfaces); Walter et al. 2007 eq. 20; "
           "Heitz 2014 eq. 99; Bouguer's law",
)


def _base(p):
    from viewer import brdf

    return brdf.get(p.base.model)


def refract_in(w, eta):
    """w refracted into the layer through the mean surface, pointing up (z > 0): Snell's law
    in vector form for the normal +z. Incident from outside, so no total internal reflection."""
    xy = w[:, :2] / eta
    z = np.sqrt(np.maximum(0.0, 1.0 - np.sum(xy * xy, axis=-1)))
    return np.concatenate([xy, z[:, None]], axis=-1)


def refract_out(w, eta):
    """A direction inside the layer (z > 0) refracted out; ok = False under total internal
    reflection."""
    xy = w[:, :2] * eta
    s2 = np.sum(xy * xy, axis=-1)
    ok = s2 < 1.0
    z = np.sqrt(np.maximum(0.0, 1.0 - s2))
    return np.concatenate([xy, z[:, None]], axis=-1), ok


def _dist(p):
    return Distribution("ggx", p.coating.alpha, p.coating.alpha)


def eval_coat(p, wi, wo):
    ci, co = wi[:, 2], wo[:, 2]
    ok = (ci > 0) & (co > 0)
    h = normalize(wi + wo)
    d = _dist(p)
    # Walter et al. 2007 eq. 20 with the dielectric F (Fresnel at the microfacet)
    F = fresnel_dielectric(np.clip(np.sum(wi * h, axis=-1), 0.0, 1.0), p.coating.ior)
    val = F * ratio_capped(d.G2(wi, wo, h) * d.D(h), 4.0 * np.where(ok, ci * co, 1.0))
    return np.where(ok, val, 0.0)


def _through(p, wi, wo):
    """(wi', wo', factor (N,3)) of the base term: T_i T_o a / eta^2."""
    eta = p.coating.ior
    wi_t = refract_in(wi, eta)
    wo_t = refract_in(wo, eta)
    Ti = fresnel_dielectric_transmittance(np.clip(wi[:, 2], 0.0, 1.0), eta)
    To = fresnel_dielectric_transmittance(np.clip(wo[:, 2], 0.0, 1.0), eta)
    # Bouguer absorption along both refracted paths (cos_t >= sqrt(1 - 1/eta^2) > 0 unless eta = 1
    # at grazing; guarded)
    path = 1.0 / np.maximum(wi_t[:, 2], 1e-12) + 1.0 / np.maximum(wo_t[:, 2], 1e-12)
    a = np.exp(-p.coating.sigma_a[None, :] * p.coating.thickness * path[:, None])
    return wi_t, wo_t, (Ti * To / (eta * eta))[:, None] * a


def eval(p, wi, wo):
    ok = (wi[:, 2] > 0) & (wo[:, 2] > 0)
    f = np.repeat(eval_coat(p, wi, wo)[:, None], 3, axis=1)
    # (a delta base evaluates to 0 here; it is reached through ``sample`` only)
    wi_t, wo_t, k = _through(p, wi, wo)
    f = f + k * _base(p).module.eval(p.base, wi_t, wo_t)
    return np.where(ok[:, None], f, 0.0)


def _p_coat(p, wo):
    return fresnel_dielectric(np.clip(wo[:, 2], 0.0, 1.0), p.coating.ior)


def _pdf_coat(p, wi, wo):
    h = normalize(wi + wo)
    oh = np.sum(wo * h, axis=-1)
    ok = (wi[:, 2] > 0) & (wo[:, 2] > 0) & (oh > 0)
    return np.where(ok, _dist(p).D_visible(wo, h) / (4.0 * np.where(ok, oh, 1.0)), 0.0)


def _pdf_base(p, wi, wo):
    eta = p.coating.ior
    wi_t = refract_in(wi, eta)
    wo_t = refract_in(wo, eta)
    pb = _base(p).module.pdf(p.base, wi_t, wo_t)
    # solid-angle Jacobian of refraction: dw' / dw = cos_i / (eta^2 cos_i')
    jac = np.maximum(wi[:, 2], 0.0) / (eta * eta * np.maximum(wi_t[:, 2], 1e-300))
    return pb * jac


def pdf(p, wi, wo):
    ok = (wi[:, 2] > 0) & (wo[:, 2] > 0)
    pc = _p_coat(p, wo)
    out = pc * _pdf_coat(p, wi, wo) + (1.0 - pc) * _pdf_base(p, wi, wo)
    return np.where(ok, out, 0.0)


def sample(p, wo, u):
    n = wo.shape[0]
    up = wo[:, 2] > 0
    wo_s = np.where(up[:, None], wo, np.array([0.0, 0.0, 1.0]))
    pc = _p_coat(p, wo_s)
    uc, u0 = split_uniform(u[:, 0])
    uu = np.stack([u0, u[:, 1]], axis=-1)
    coat = uc < pc
    wi = np.zeros((n, 3))
    if np.any(coat):
        m = _dist(p).sample_m(wo_s[coat], uu[coat])
        wi[coat] = reflect(wo_s[coat], m)
    base = _base(p)
    eta = p.coating.ior
    ok_b = np.ones(n, dtype=bool)
    w_delta = None
    if np.any(~coat):
        sel = ~coat
        wo_t = refract_in(wo_s[sel], eta)
        wi_t, w_b, pdf_b = base.module.sample(p.base, wo_t, uu[sel])
        wi_out, ok_out = refract_out(wi_t, eta)
        wi[sel] = wi_out
        ok_b[sel] = ok_out & (pdf_b > 0) & (wi_t[:, 2] > 0)
        if _base_is_delta(p):
            # discrete base lobe: throughput T_i T_o a w_b (the eta^2 factors cancel for a delta
            # lobe: radiance times eta^2 going in, divided by eta^2 going out)
            _, _, k = _through(p, wi_out, wo_s[sel])
            w_delta = (sel, k * eta * eta * w_b / np.maximum(1.0 - pc[sel], 1e-300)[:, None],
                       (1.0 - pc[sel]) * pdf_b)
    pdf_ = pdf(p, wi, wo)
    ok = up & (wi[:, 2] > 0) & ok_b
    if w_delta is not None:
        sel, wd, pd = w_delta
        pdf_[sel] = pd
    ok &= pdf_ > 0
    f = eval(p, wi, wo)
    weight = f * (wi[:, 2] / np.where(ok, pdf_, 1.0))[:, None]
    if w_delta is not None:
        sel, wd, pd = w_delta
        weight[sel] = wd
    weight = np.where(ok[:, None], weight, 0.0)
    return wi, weight, np.where(ok, pdf_, 0.0)


def _base_is_delta(p):
    spec = _base(p).spec
    return spec.delta and not (spec.name == "dielectric" and p.base.get("alpha", 0.0) > 0)


def ibl_split(p):
    """Image-based lighting proxy: the coating alone (a black base) and the coating's alpha."""
    from viewer import brdf

    return p.replace(base=brdf.get("lambert").params(albedo=[0.0, 0.0, 0.0])), float(p.coating["alpha"])


def splits_u(p):
    """The sample splits u[:, 0] into the coat-or-base choice and the direction
    (``split_uniform``); the GLSL twin takes those as u.z and u.x (viewer.brdf.glsl.glsl_u)."""
    return True
