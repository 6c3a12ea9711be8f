// Layered BRDF (Weidlich & Wilkie 2007), twin of viewer/brdf/layered.py:
//   f = f_coat(wi, wo) + T(cos_i) T(cos_o) a f_base(wi', wo') / eta^2
// f_coat: GGX reflection with dielectric F and height-correlated Smith G (Walter 2007 eq. 20,
// Heitz 2014 eq. 99); wi', wo': refracted into the layer, pointing up; T = 1 - F at the
// macro-surface angles; a = exp(-sigma_a thickness (1/cos_ti' + 1/cos_to')) (Bouguer);
// 1 / eta^2: radiance scaling into and out of the layer with the solid-angle compression.
// The base is any non-layered material, evaluated through the generated brdf_eval_base().
#include "common/fresnel.glsl"
#include "common/microfacet.glsl"

// w refracted into the layer through the mean surface (normal +z), pointing up.
vec3 layered_refract_in(vec3 w, float eta) {
    vec2 xy = w.xy / eta;
    return vec3(xy, sqrt(max(0.0, 1.0 - dot(xy, xy))));
}

float layered_coat(layered_params p, vec3 wi, vec3 wo) {
    vec3 h = normalize_safe(wi + wo);
    float a = p.coating.alpha;
    float F = fresnel_dielectric(clamp(dot(wi, h), 0.0, 1.0), p.coating.ior);
    float G = smith_g2_height_correlated(lambda_ggx(wi, a, a), lambda_ggx(wo, a, a), wi, wo, h);
    return F * ratio_capped(G * D_ggx(h, a, a), 4.0 * wi.z * wo.z);
}

vec3 layered_eval(layered_params p, vec3 wi, vec3 wo) {
    if (wi.z <= 0.0 || wo.z <= 0.0) return vec3(0.0);
    if (wi.z * wo.z <= 0.0) return vec3(0.0);  // both cosines underflowed
    float eta = p.coating.ior;
    vec3 f = vec3(layered_coat(p, wi, wo));
    vec3 wi_t = layered_refract_in(wi, eta);
    vec3 wo_t = layered_refract_in(wo, eta);
    float Ti = fresnel_dielectric_transmittance(min(wi.z, 1.0), eta);
    float To = fresnel_dielectric_transmittance(min(wo.z, 1.0), eta);
    float path = 1.0 / max(wi_t.z, 1e-12) + 1.0 / max(wo_t.z, 1e-12);
    vec3 absorb = exp(-p.coating.sigma_a * (p.coating.thickness * path));
    f += (Ti * To / (eta * eta)) * absorb * brdf_eval_base(p.base_model, p.base_offset, wi_t, wo_t);
    return f;
}
