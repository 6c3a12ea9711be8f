// Modified Phong, energy-normalized (Lafortune & Willems 1994, "Using the modified Phong
// reflectance model for physically based rendering", eqs. 1-3):
//   f = kd / pi + ks (n + 2) / (2 pi) cos^n(alpha_r),  alpha_r = angle(wi, mirror of wo).
// Twin of viewer/brdf/phong.py.

// Lafortune & Willems 1994, eq. 3: (n + 2) / (2 pi) cos^n(alpha_r), with
// 1 - cos(alpha_r) = |wi - r|^2 / 2 (exact where wi ~ r, the peak).
float phong_lobe_normalized(vec3 wi, vec3 wo, float n) {
    vec3 d = wi - vec3(-wo.x, -wo.y, wo.z);
    return (n + 2.0) / (2.0 * PI) * pow_one_minus(0.5 * dot(d, d), n);
}

vec3 phong_eval(phong_params p, vec3 wi, vec3 wo) {
    if (wi.z <= 0.0 || wo.z <= 0.0) return vec3(0.0);
    return p.kd * INV_PI + p.ks * phong_lobe_normalized(wi, wo, p.shininess);
}

// ---- sampling twin of viewer/brdf/phong.py: cosine for kd, the cos^n lobe about the mirror
// direction for ks, picked with the lobes' share of the albedo luminance (common/sampling.glsl).
#include "common/sampling.glsl"

float phong_specular_probability(phong_params p) {
    float ld = luminance(p.kd), ls = luminance(p.ks);
    return ld + ls <= 0.0 ? 0.5 : ls / (ld + ls);
}

float phong_pdf_ps(phong_params p, vec3 wi, vec3 wo, float ps) {
    if (wi.z <= 0.0 || wo.z <= 0.0) return 0.0;
    float n = p.shininess;
    vec3 d = wi - vec3(-wo.x, -wo.y, wo.z);
    float lobe = (n + 1.0) / (2.0 * PI) * pow_one_minus(0.5 * dot(d, d), n);
    return ps * lobe + (1.0 - ps) * cosine_hemisphere_pdf(wi);
}

float phong_pdf(phong_params p, vec3 wi, vec3 wo) {
    return phong_pdf_ps(p, wi, wo, phong_specular_probability(p));
}

vec3 phong_sample(phong_params p, vec3 wo, vec3 u, out vec3 wi, out float pdf, out uint lobe) {
    lobe = LOBE_REFLECTION | LOBE_DIFFUSE | LOBE_GLOSSY;  // phong.lobes (viewer/brdf/phong.py)
    float ps = phong_specular_probability(p);
    float u0 = u.x;
    int k = pick_lobe2(ps, u0);
    vec2 uu = vec2(u0, u.y);
    wi = k == 0 ? to_world(sample_power_cosine(uu, p.shininess), vec3(-wo.x, -wo.y, wo.z))
                : sample_cosine_hemisphere(uu);
    pdf = phong_pdf_ps(p, wi, wo, ps);
    return sample_weight(phong_eval(p, wi, wo), wi.z, pdf);
}
