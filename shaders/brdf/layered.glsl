// Layered BRDF (Weidlich & Wilkie 2007), twin of viewer/brdf/layered.py:
//   f = f_coat(wi, wo) + T(cos_i) T(cos_o) a f_base(wi', wo') / eta^2
// f_coat: GGX reflection with dielectric F and height-correlated Smith G (Walter 2007 eq. 20,
// Heitz 2014 eq. 99); wi', wo': refracted into the layer, pointing up; T = 1 - E (the coat's albedo) at the
// macro-surface angles; a = exp(-sigma_a thickness (1/cos_ti' + 1/cos_to')) (Bouguer);
// 1 / eta^2: the radiance leaving the layer is the radiance inside over eta^2 (L / n^2 invariant).
// Lambert base: times 1 / (1 - rho K), the coat-base interreflections (layered_internal_reflectance).
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

// 16-point Gauss-Legendre on [0, 1], the numbers of GL16_X / GL16_W in viewer/brdf/layered.py
const float LAYERED_GL_X[16] = float[16](0.0052995325, 0.0277124885, 0.0671843988, 0.122297796, 0.191061878, 0.270991611, 0.359198225, 0.452493745, 0.547506255, 0.640801775, 0.729008389, 0.808938122, 0.877702204, 0.932815601, 0.972287512, 0.994700467);
const float LAYERED_GL_W[16] = float[16](0.0135762297, 0.031126762, 0.0475792558, 0.0623144856, 0.0747979944, 0.0845782597, 0.0913017075, 0.0947253052, 0.0947253052, 0.0913017075, 0.0845782597, 0.0747979944, 0.0623144856, 0.0475792558, 0.031126762, 0.0135762297);

// E(cos), the coat's own directional albedo, from the 24-entry table at cos = k / 23 that
// viewer/brdf/layered.py (coat_albedo_table) puts in the material block; linear interpolation.
float layered_coat_albedo(layered_params p, float c) {
    float x = clamp(c, 0.0, 1.0) * 23.0;
    int i = min(int(floor(x)), 22);
    return mix(p.derived[i], p.derived[i + 1], x - float(i));
}

// K = integral_0^1 F_int(mu) exp(-2 tau / mu) 2 mu dmu, the coat's internal diffuse reflectance
// with absorption up and down (tau = sigma_a thickness): the total-internal-reflection cone
// mu < mu_c, then the transmitting cone in the outside cosine mu' (F_int(mu) ~ E(mu'),
// 2 mu dmu = 2 mu' dmu' / eta^2). Twin of internal_reflectance in layered.py.
vec3 layered_internal_reflectance(layered_params p) {
    float eta = p.coating.ior;
    vec3 tau = p.coating.sigma_a * p.coating.thickness;
    float mu_c = sqrt(max(0.0, 1.0 - 1.0 / (eta * eta)));
    vec3 K = vec3(0.0);
    for (int k = 0; k < 16; ++k) {
        float mu = mu_c * LAYERED_GL_X[k];
        K += (LAYERED_GL_W[k] * mu_c * 2.0 * mu) * exp(-2.0 * tau / max(mu, 1e-30));
        float mo = LAYERED_GL_X[k];
        float mu_in = sqrt(1.0 - (1.0 - mo * mo) / (eta * eta));
        K += (LAYERED_GL_W[k] * layered_coat_albedo(p, mo) * 2.0 * mo / (eta * eta)) * exp(-2.0 * tau / mu_in);
    }
    return K;
}

vec3 layered_eval(layered_params p, vec3 wi, vec3 wo) {
    if (wi.z <= 0.0 || wo.z <= 0.0) return vec3(0.0);
    if (wi.z * wo.z <= 0.0) return vec3(0.0);  // both cosines underflowed
    float eta = p.coating.ior;
    vec3 f = vec3(layered_coat(p, wi, wo));
    vec3 wi_t = layered_refract_in(wi, eta);
    vec3 wo_t = layered_refract_in(wo, eta);
    // T = 1 - E: what the (rough) coat does not reflect enters the layer
    float Ti = 1.0 - layered_coat_albedo(p, wi.z);
    float To = 1.0 - layered_coat_albedo(p, wo.z);
    float path = 1.0 / max(wi_t.z, 1e-12) + 1.0 / max(wo_t.z, 1e-12);
    vec3 absorb = exp(-p.coating.sigma_a * (p.coating.thickness * path));
    vec3 fb = brdf_eval_base(p.base_model, p.base_offset, wi_t, wo_t);
    if (p.base_model == BRDF_MODEL_LAMBERT) {
        // Lambert base: f_base = rho / pi; the interreflections' geometric series 1 / (1 - rho K)
        vec3 K = layered_internal_reflectance(p);
        fb /= max(1.0 - PI * fb * K, vec3(1e-6));
    }
    f += (Ti * To / (eta * eta)) * absorb * fb;
    return f;
}
