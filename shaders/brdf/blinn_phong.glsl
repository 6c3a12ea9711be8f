// Blinn-Phong, energy-normalized: f = kd / pi + ks N(n) (n . h)^n (Blinn 1977), with the exact
// normalization of Giesen 2009 ("Derivation of Phong and Blinn-Phong BRDF normalization factors"):
// N(n) = (n + 2)(n + 4) / (8 pi (2^(-n/2) + n)); the lobe's albedo is ks at normal incidence, less
// elsewhere. (Real-Time Rendering's (n + 8) / (8 pi) overshoots by up to 7.5 %.)
// Twin of viewer/brdf/blinn_phong.py.

// Giesen 2009: the exact Blinn-Phong normalization.
float blinn_phong_normalization_giesen(float n) {
    return (n + 2.0) * (n + 4.0) / (8.0 * PI * (exp2(-0.5 * n) + n));
}

// Blinn 1977: cos^n(theta_h), with 1 - h.z = (h.x^2 + h.y^2) / (1 + h.z) (no cancellation near the normal).
float blinn_phong_lobe(vec3 wi, vec3 wo, float n) {
    vec3 h = normalize_safe(wi + wo);
    if (h.z <= 0.0) return 0.0;
    float x = (h.x * h.x + h.y * h.y) / (1.0 + h.z);
    if (x >= 1.0) return 0.0;
    return exp(n * log1m(x));
}

vec3 blinn_phong_eval(blinn_phong_params p, vec3 wi, vec3 wo) {
    if (wi.z <= 0.0 || wo.z <= 0.0) return vec3(0.0);
    float n = p.shininess;
    return p.kd * INV_PI + p.ks * (blinn_phong_normalization_giesen(n) * blinn_phong_lobe(wi, wo, n));
}

// ---- sampling twin of viewer/brdf/blinn_phong.py: cosine for kd; h from the cos^n lobe about
// the normal, wi = reflect(wo, h), pdf = p(h) / (4 wo.h) (Walter et al. 2007 eq. 14).
#include "common/sampling.glsl"

float blinn_phong_specular_probability(blinn_phong_params p) {
    float ld = luminance(p.kd), ls = luminance(p.ks);
    return ld + ls <= 0.0 ? 0.5 : ls / (ld + ls);
}

float blinn_phong_pdf_ps(blinn_phong_params p, vec3 wi, vec3 wo, float ps) {
    if (wi.z <= 0.0 || wo.z <= 0.0) return 0.0;
    float n = p.shininess;
    vec3 h = normalize_safe(wi + wo);
    float cos_oh = dot(wo, h);
    float ph = (n + 1.0) / (2.0 * PI) * blinn_phong_lobe(wi, wo, n);
    float spec = cos_oh > 0.0 ? ph / (4.0 * cos_oh) : 0.0;
    return ps * spec + (1.0 - ps) * cosine_hemisphere_pdf(wi);
}

float blinn_phong_pdf(blinn_phong_params p, vec3 wi, vec3 wo) {
    return blinn_phong_pdf_ps(p, wi, wo, blinn_phong_specular_probability(p));
}

vec3 blinn_phong_sample(blinn_phong_params p, vec3 wo, vec3 u, out vec3 wi, out float pdf, out uint lobe) {
    lobe = LOBE_REFLECTION | LOBE_DIFFUSE | LOBE_GLOSSY;  // blinn_phong.lobes (viewer/brdf/blinn_phong.py)
    float ps = blinn_phong_specular_probability(p);
    float u0 = u.x;
    int k = pick_lobe2(ps, u0);
    vec2 uu = vec2(u0, u.y);
    wi = normalize_safe(k == 0 ? reflect_about(wo, sample_power_cosine(uu, p.shininess))
                               : sample_cosine_hemisphere(uu));
    pdf = blinn_phong_pdf_ps(p, wi, wo, ps);
    return sample_weight(blinn_phong_eval(p, wi, wo), wi.z, pdf);
}
