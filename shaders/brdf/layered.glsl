// Layered BRDF (Weidlich & Wilkie 2007), twin of viewer/brdf/layered.py:
//   f = f_coat(wi, wo) + T(cos_i) T(cos_o) a f_base(wi', wo') / eta^2
// f_coat: GGX reflection with dielectric F and height-correlated Smith G (Walter 2007 eq. 20,
// Heitz 2014 eq. 99); wi', wo': refracted into the layer, pointing up; T = 1 - E (the coat's albedo) at the
// macro-surface angles; a = exp(-sigma_a thickness (1/cos_ti' + 1/cos_to')) (Bouguer);
// 1 / eta^2: the radiance leaving the layer is the radiance inside over eta^2 (L / n^2 invariant).
// Lambert base: times 1 / (1 - rho K), the coat-base interreflections (layered_internal_reflectance).
// The base is any non-layered material, evaluated through the generated brdf_eval_base().
#include "generated/constants.glsl"
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

// ---- sampling twin of viewer/brdf/layered.py: the coat lobe (GGX visible normals) with
// probability P_c = F(cos_o), else the base's own sample with wo' (refracted in), the result
// refracted out; pdf converted by the solid-angle Jacobian cos_i / (eta^2 cos_i'). The choice
// is u.z (numpy: split_uniform(u[:, 0]) = (u.z, u.x)); the base gets (u.x, u.y, (u.z - P_c) /
// (1 - P_c)). A delta base is a discrete lobe: pdf (1 - P_c) pdf_base, weight its throughput.
// The base goes through the generated brdf_sample_base / brdf_pdf_base / brdf_is_delta_base.
#include "common/sampling.glsl"

// A direction inside the layer (z > 0) refracted out; ok = false under total internal reflection.
vec3 layered_refract_out(vec3 w, float eta, out bool ok) {
    vec2 xy = w.xy * eta;
    float s2 = dot(xy, xy);
    ok = s2 < 1.0;
    return vec3(xy, sqrt(max(0.0, 1.0 - s2)));
}

float layered_pdf(layered_params p, vec3 wi, vec3 wo) {
    if (wi.z <= 0.0 || wo.z <= 0.0) return 0.0;
    float eta = p.coating.ior;
    float a = p.coating.alpha;
    float pc = fresnel_dielectric(clamp(wo.z, 0.0, 1.0), eta);
    vec3 h = normalize_safe(wi + wo);
    float oh = dot(wo, h);
    float coat = oh > 0.0 ? mf_D_visible(MICROFACET_DISTRIBUTION_GGX, wo, h, a, a) / (4.0 * oh) : 0.0;
    vec3 wi_t = layered_refract_in(wi, eta);
    vec3 wo_t = layered_refract_in(wo, eta);
    float pb = brdf_pdf_base(p.base_model, p.base_offset, wi_t, wo_t);
    // solid-angle Jacobian of refraction: dw' / dw = cos_i / (eta^2 cos_i')
    float jac = wi.z / (eta * eta * max(wi_t.z, 1.17549435e-38));
    return pc * coat + (1.0 - pc) * pb * jac;
}

vec3 layered_sample(layered_params p, vec3 wo, vec3 u, out vec3 wi, out float pdf) {
    bool up = wo.z > 0.0;
    vec3 wo_s = up ? wo : vec3(0.0, 0.0, 1.0);
    float eta = p.coating.ior;
    float a = p.coating.alpha;
    float pc = fresnel_dielectric(clamp(wo_s.z, 0.0, 1.0), eta);
    bool coat = u.z < pc;
    if (coat) {
        wi = reflect_about(wo_s, sample_vndf_ggx(wo_s, u.xy, a, a));
        pdf = (up && wi.z > 0.0) ? layered_pdf(p, wi, wo) : 0.0;
        return sample_weight(layered_eval(p, wi, wo), wi.z, pdf);
    }
    vec3 wo_t = layered_refract_in(wo_s, eta);
    float uz = clamp((u.z - pc) / max(1.0 - pc, 1.17549435e-38), 0.0, ONE_MINUS_EPS);
    vec3 wi_t;
    float pdf_b;
    vec3 w_b = brdf_sample_base(p.base_model, p.base_offset, wo_t, vec3(u.xy, uz), wi_t, pdf_b);
    bool ok_out;
    wi = layered_refract_out(wi_t, eta, ok_out);
    bool ok = up && wi.z > 0.0 && ok_out && pdf_b > 0.0 && wi_t.z > 0.0;
    if (!ok) { pdf = 0.0; return vec3(0.0); }
    if (brdf_is_delta_base(p.base_model, p.base_offset)) {
        // discrete base lobe: throughput T_i T_o a w_b (the eta^2 into and out of the layer cancel)
        vec3 wi_in = layered_refract_in(wi, eta);
        float Ti = fresnel_dielectric_transmittance(min(wi.z, 1.0), eta);
        float To = fresnel_dielectric_transmittance(min(wo_s.z, 1.0), eta);
        float path = 1.0 / max(wi_in.z, 1e-12) + 1.0 / max(wo_t.z, 1e-12);
        vec3 absorb = exp(-p.coating.sigma_a * (p.coating.thickness * path));
        pdf = (1.0 - pc) * pdf_b;
        if (!(pdf > 0.0)) { pdf = 0.0; return vec3(0.0); }
        return Ti * To * absorb * w_b / max(1.0 - pc, 1.17549435e-38);
    }
    pdf = layered_pdf(p, wi, wo);
    return sample_weight(layered_eval(p, wi, wo), wi.z, pdf);
}
