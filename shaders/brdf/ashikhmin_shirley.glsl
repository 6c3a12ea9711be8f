// Ashikhmin & Shirley 2000, "An Anisotropic Phong BRDF Model", JGT 5(2).
// Specular eq. 4 with Schlick's Fresnel on rs, diffuse eq. 5; nu along the tangent x, nv along y.
// Twin of viewer/brdf/ashikhmin_shirley.py.

float ashikhmin_shirley_pow5(float x) { float x2 = x * x; return x2 * x2 * x; }

// Schlick 1994: F0 + (1 - F0)(1 - cos)^5 (the F of Ashikhmin & Shirley 2000, eq. 4).
vec3 F_Schlick_AS(vec3 f0, float cos_theta) {
    return f0 + (1.0 - f0) * ashikhmin_shirley_pow5(1.0 - saturate(cos_theta));
}

// Ashikhmin & Shirley 2000, eq. 8 (without 1 / (4 k.h)): sqrt((nu+1)(nv+1)) / (2 pi) (n.h)^e,
// e = nu cos^2 phi_h + nv sin^2 phi_h = (nu h.x^2 + nv h.y^2) / (1 - h.z^2), replaced by nu at h = n
// where (n.h)^e = 1 anyway; 1 - n.h = (h.x^2 + h.y^2) / (1 + h.z) avoids the cancellation.
float D_AshikhminShirley(vec3 h, float nu, float nv) {
    if (h.z <= 0.0) return 0.0;
    float t2 = h.x * h.x + h.y * h.y;
    float e = t2 > 0.0 ? (nu * h.x * h.x + nv * h.y * h.y) / t2 : nu;
    float x = t2 / (1.0 + h.z);
    if (x >= 1.0) return 0.0;
    return sqrt((nu + 1.0) * (nv + 1.0)) / (2.0 * PI) * exp(e * log1m(x));
}

// Ashikhmin & Shirley 2000, eq. 4: D / (4 (h.k) max(n.k1, n.k2)) F(k.h).
vec3 ashikhmin_shirley_specular(ashikhmin_shirley_params p, vec3 wi, vec3 wo) {
    vec3 h = normalize_safe(wi + wo);
    float hk = dot(h, wo);
    float den = 4.0 * hk * max(wi.z, wo.z);
    if (den <= 0.0) return vec3(0.0);
    return ratio_capped(D_AshikhminShirley(h, p.nu, p.nv), den) * F_Schlick_AS(p.rs, hk);
}

// Ashikhmin & Shirley 2000, eq. 5: 28 rd / (23 pi) (1 - rs)(1 - (1 - n.k1/2)^5)(1 - (1 - n.k2/2)^5).
vec3 ashikhmin_shirley_diffuse(ashikhmin_shirley_params p, vec3 wi, vec3 wo) {
    float a = 1.0 - ashikhmin_shirley_pow5(1.0 - 0.5 * wi.z);
    float b = 1.0 - ashikhmin_shirley_pow5(1.0 - 0.5 * wo.z);
    return (28.0 / (23.0 * PI)) * p.rd * (1.0 - p.rs) * (a * b);
}

vec3 ashikhmin_shirley_eval(ashikhmin_shirley_params p, vec3 wi, vec3 wo) {
    if (wi.z <= 0.0 || wo.z <= 0.0) return vec3(0.0);
    return ashikhmin_shirley_diffuse(p, wi, wo) + ashikhmin_shirley_specular(p, wi, wo);
}

// Term views: (F averaged over RGB, D, -1); the model has no shadowing term G ("not applicable").
vec3 ashikhmin_shirley_terms(ashikhmin_shirley_params p, vec3 wi, vec3 wo) {
    vec3 h = normalize_safe(wi + wo);
    vec3 F = F_Schlick_AS(p.rs, dot(h, wo));
    return vec3((F.r + F.g + F.b) / 3.0, D_AshikhminShirley(h, p.nu, p.nv), -1.0);
}

// ---- sampling twin of viewer/brdf/ashikhmin_shirley.py: cosine for the diffuse term, the
// paper's half-vector distribution (eqs. 9-10) for the specular term, pdf eq. 8; picked in
// proportion to luminance(rd)(1 - luminance(rs)) vs. the Schlick reflectance at wo.
#include "common/sampling.glsl"

float ashikhmin_shirley_specular_probability(ashikhmin_shirley_params p, vec3 wo) {
    float ls = luminance(p.rs);
    float ws = ls + (1.0 - ls) * ashikhmin_shirley_pow5(1.0 - saturate(wo.z));
    float wd = luminance(p.rd) * (1.0 - ls);
    float tot = ws + wd;
    return tot > 0.0 ? ws / tot : 0.5;
}

float ashikhmin_shirley_pdf_ps(ashikhmin_shirley_params p, vec3 wi, vec3 wo, float ps) {
    if (wi.z <= 0.0 || wo.z <= 0.0) return 0.0;
    vec3 h = normalize_safe(wi + wo);
    float hk = dot(h, wo);
    float spec = hk > 0.0 ? D_AshikhminShirley(h, p.nu, p.nv) / (4.0 * hk) : 0.0;
    return ps * spec + (1.0 - ps) * cosine_hemisphere_pdf(wi);
}

float ashikhmin_shirley_pdf(ashikhmin_shirley_params p, vec3 wi, vec3 wo) {
    return ashikhmin_shirley_pdf_ps(p, wi, wo, ashikhmin_shirley_specular_probability(p, wo));
}

// Ashikhmin & Shirley 2000, eqs. 9-10: u.x picks the quadrant and phi in it (atan2 form of
// atan(sqrt((nu+1)/(nv+1)) tan(pi u / 2))), cos theta_h = (1 - u.y)^(1 / (e + 1)).
vec3 ashikhmin_shirley_half_vector(vec2 u, float nu, float nv) {
    float q = floor(4.0 * u.x);
    float v = 4.0 * u.x - q;
    float a = sqrt((nu + 1.0) / (nv + 1.0));
    float phi = atan(a * sin(0.5 * PI * v), cos(0.5 * PI * v));
    phi = q == 0.0 ? phi : (q == 1.0 ? PI - phi : (q == 2.0 ? PI + phi : TWO_PI - phi));
    float c = cos(phi), s = sin(phi);
    float e = nu * c * c + nv * s * s;
    float t = log(1.0 - u.y) / (e + 1.0);
    float cos_t = exp(t);
    float sin_t = sqrt(max(0.0, one_minus_exp(2.0 * t)));
    return vec3(sin_t * c, sin_t * s, cos_t);
}

vec3 ashikhmin_shirley_sample(ashikhmin_shirley_params p, vec3 wo, vec3 u, out vec3 wi, out float pdf, out uint lobe) {
    lobe = LOBE_REFLECTION | LOBE_DIFFUSE | LOBE_GLOSSY;  // ashikhmin_shirley.lobes (viewer/brdf/ashikhmin_shirley.py)
    float ps = ashikhmin_shirley_specular_probability(p, wo);
    float u0 = u.x;
    int k = pick_lobe2(ps, u0);
    vec2 uu = vec2(u0, u.y);
    wi = normalize_safe(k == 0 ? reflect_about(wo, ashikhmin_shirley_half_vector(uu, p.nu, p.nv))
                               : sample_cosine_hemisphere(uu));
    pdf = ashikhmin_shirley_pdf_ps(p, wi, wo, ps);
    return sample_weight(ashikhmin_shirley_eval(p, wi, wo), wi.z, pdf);
}
