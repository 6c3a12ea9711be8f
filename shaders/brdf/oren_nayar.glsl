// Oren & Nayar 1994, "Generalization of Lambert's Reflectance Model" (SIGGRAPH '94).
// variant 0 = full: Sec. 4 functional approximation, direct term L1 (C1, C2, C3) plus the
// interreflection term L2; variant 1 = qualitative: Sec. 5, A + B max(0, cos dphi) sin(alpha) tan(beta).
// sigma in degrees; sigma = 0 gives Lambert exactly. Twin of viewer/brdf/oren_nayar.py.
#include "generated/constants.glsl"

// Oren & Nayar 1994, Sec. 5: A = 1 - 0.5 s^2 / (s^2 + 0.33), B = 0.45 s^2 / (s^2 + 0.09).
float oren_nayar_qualitative(float s2, float cos_dphi, float sin_alpha, float tan_beta) {
    float A = 1.0 - 0.5 * s2 / (s2 + 0.33);
    float B = 0.45 * s2 / (s2 + 0.09);
    return A + B * max(0.0, cos_dphi) * sin_alpha * tan_beta;
}

// Oren & Nayar 1994, Sec. 4 (bracket of L1): C1 + cos(dphi) C2 tan(beta) + (1 - |cos dphi|) C3 tan((alpha + beta)/2).
// Near grazing, sin(alpha) - (2 beta/pi)^3 cancels: evaluated as (1 - t)(1 + t + t^2) - cos^2(alpha)/(1 + sin(alpha))
// with 1 - t = elevation(beta) 2/pi; tan((alpha + beta)/2) = (sin a + sin b)/(cos a + cos b) avoids tan near its
// pole. Clamped at 0: near grazing with cos(dphi) < 0 the approximation can dip slightly below zero.
float oren_nayar_L1(float s2, float cos_dphi, float alpha, float beta, vec2 sc_alpha, vec2 sc_beta, float elev_beta) {
    float C1 = 1.0 - 0.5 * s2 / (s2 + 0.33);
    float b = 0.45 * s2 / (s2 + 0.09);
    float t = 2.0 * beta / PI;
    float one_minus_t = 2.0 * elev_beta / PI;
    float sin_a_minus_t3 = one_minus_t * (1.0 + t + t * t) - sc_alpha.y * sc_alpha.y / (1.0 + sc_alpha.x);
    float C2 = b * (cos_dphi >= 0.0 ? sc_alpha.x : sin_a_minus_t3);
    float g = 4.0 * alpha * beta / (PI * PI);
    float C3 = 0.125 * s2 / (s2 + 0.09) * g * g;
    float tan_beta = sc_beta.x / max(sc_beta.y, 1e-12);
    float tan_half_sum = (sc_alpha.x + sc_beta.x) / max(sc_alpha.y + sc_beta.y, 1e-12);
    float L1 = C1 + cos_dphi * C2 * tan_beta + (1.0 - abs(cos_dphi)) * C3 * tan_half_sum;
    return max(L1, 0.0);
}

// Oren & Nayar 1994, Sec. 4 interreflections (bracket of L2, times rho^2 / pi):
// 0.17 s^2 / (s^2 + 0.13) (1 - cos(dphi) (2 beta / pi)^2).
float oren_nayar_L2(float s2, float cos_dphi, float beta) {
    float t = 2.0 * beta / PI;
    return 0.17 * s2 / (s2 + 0.13) * (1.0 - cos_dphi * t * t);
}

vec3 oren_nayar_eval(oren_nayar_params p, vec3 wi, vec3 wo) {
    if (wi.z <= 0.0 || wo.z <= 0.0) return vec3(0.0);
    float s = radians(p.sigma);
    float s2 = s * s;
    // cos(phi_i - phi_o) from the tangential parts; 0 on the normal (then beta = 0 and it does not matter)
    // angles from the vectors (sin theta = |w.xy|, theta = atan(|w.xy|, w.z)): no acos, whose float32
    // versions lose digits near the normal
    float si = length(wi.xy);
    float so = length(wo.xy);
    // cos(phi_i - phi_o) from the tangential parts; 0 on the normal (then beta = 0 and it does not matter)
    float den = si * so;
    float cos_dphi = den > 1e-30 ? clamp(dot(wi.xy, wo.xy) / den, -1.0, 1.0) : 0.0;
    float ci = max(wi.z, 0.0);
    float co = max(wo.z, 0.0);
    float theta_i = atan(si, ci);
    float theta_o = atan(so, co);
    bool i_larger = theta_i >= theta_o;
    float alpha = i_larger ? theta_i : theta_o;
    float beta = i_larger ? theta_o : theta_i;
    vec2 sc_alpha = i_larger ? vec2(si, ci) : vec2(so, co);  // (sin, cos)
    vec2 sc_beta = i_larger ? vec2(so, co) : vec2(si, ci);
    // pi/2 - beta, the elevation of the direction nearer the normal (accurate near grazing)
    float elev_beta = atan(sc_beta.y, sc_beta.x);
    if (p.variant == OREN_NAYAR_VARIANT_QUALITATIVE) {
        float tan_beta = sc_beta.x / max(sc_beta.y, 1e-12);
        return p.albedo * INV_PI * oren_nayar_qualitative(s2, cos_dphi, sc_alpha.x, tan_beta);
    }
    return p.albedo * INV_PI * oren_nayar_L1(s2, cos_dphi, alpha, beta, sc_alpha, sc_beta, elev_beta)
         + p.albedo * p.albedo * INV_PI * oren_nayar_L2(s2, cos_dphi, beta);
}

// ---- sampling twin of viewer/brdf/oren_nayar.py: cosine-weighted (common/sampling.glsl)
#include "common/sampling.glsl"

float oren_nayar_pdf(oren_nayar_params p, vec3 wi, vec3 wo) {
    return wo.z > 0.0 ? cosine_hemisphere_pdf(wi) : 0.0;
}

vec3 oren_nayar_sample(oren_nayar_params p, vec3 wo, vec3 u, out vec3 wi, out float pdf, out uint lobe) {
    lobe = LOBE_REFLECTION | LOBE_DIFFUSE;  // oren_nayar.lobes (viewer/brdf/oren_nayar.py)
    wi = sample_cosine_hemisphere(u.xy);
    pdf = oren_nayar_pdf(p, wi, wo);
    // f cos / (cos / pi) = pi f
    return pdf > 0.0 ? PI * oren_nayar_eval(p, wi, wo) : vec3(0.0);
}
