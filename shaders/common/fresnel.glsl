// Fresnel reflectance, the GLSL twin of viewer/brdf/fresnel.py.
// Lecture (Frisvad, "BRDF, Fresnel Reflectance, and Absorption"):
//   r_perp = (n_i cos_i - n_t cos_t) / (n_i cos_i + n_t cos_t)
//   r_par  = (n_t cos_i - n_i cos_t) / (n_t cos_i + n_i cos_t),  R = (|r_perp|^2 + |r_par|^2) / 2
// eta = n_t / n_i; cos_i < 0 means the light comes from the other side (media swapped).
#include "common/math.glsl"

// (Rs, Rp) of a dielectric interface; total internal reflection gives (1, 1).
vec2 fresnel_dielectric_polarized(float cos_i, float eta) {
    if (cos_i < 0.0) { eta = 1.0 / eta; cos_i = -cos_i; }
    cos_i = min(cos_i, 1.0);
    // Snell: sin_t^2 = sin_i^2 / eta^2 (lecture, "Total internal reflection")
    float sin2_t = max(0.0, 1.0 - cos_i * cos_i) / (eta * eta);
    if (sin2_t >= 1.0) return vec2(1.0);
    float cos_t = sqrt(1.0 - sin2_t);
    float den_s = cos_i + eta * cos_t;
    float den_p = eta * cos_i + cos_t;
    // den == 0 only at grazing incidence with eta == 1: take the limit R = 1 (as numpy does).
    float rs = den_s > 0.0 ? (cos_i - eta * cos_t) / den_s : 1.0;
    float rp = den_p > 0.0 ? (eta * cos_i - cos_t) / den_p : 1.0;
    return vec2(rs * rs, rp * rp);
}

float fresnel_dielectric(float cos_i, float eta) {
    vec2 r = fresnel_dielectric_polarized(cos_i, eta);
    return 0.5 * (r.x + r.y);
}

// T = 1 - R without the cancellation of 1 - R near total internal reflection:
// 1 - r_perp^2 = 4 eta cos_i cos_t / (cos_i + eta cos_t)^2, 1 - r_par^2 = 4 eta cos_i cos_t / (eta cos_i + cos_t)^2.
float fresnel_dielectric_transmittance(float cos_i, float eta) {
    if (cos_i < 0.0) { eta = 1.0 / eta; cos_i = -cos_i; }
    cos_i = min(cos_i, 1.0);
    float sin2_t = max(0.0, 1.0 - cos_i * cos_i) / (eta * eta);
    if (sin2_t >= 1.0) return 0.0;
    float cos_t = sqrt(1.0 - sin2_t);
    float num = 4.0 * eta * cos_i * cos_t;
    float ds = cos_i + eta * cos_t;
    float dp = eta * cos_i + cos_t;
    float Ts = ds > 0.0 ? num / (ds * ds) : 0.0;
    float Tp = dp > 0.0 ? num / (dp * dp) : 0.0;
    return 0.5 * (Ts + Tp);
}

// Principal square root of a complex number (x + i y), written without cancellation:
// the larger of the two parts comes from sqrt((|z| + |x|) / 2), the other from y / (2 t).
vec2 complex_sqrt(vec2 z) {
    float r = length(z);
    if (z.x >= 0.0) {
        float t = sqrt(0.5 * (r + z.x));
        return vec2(t, t > 0.0 ? z.y / (2.0 * t) : 0.0);
    }
    float t = sqrt(0.5 * (r - z.x));
    return vec2(abs(z.y) / (2.0 * t), z.y >= 0.0 ? t : -t);
}

// (Rs, Rp) of a conductor n_t = eta + i k seen from index 1 (Born & Wolf sec. 14.2), with
// w = n_t cos_t = sqrt(n_t^2 - sin_i^2):
//   r_perp = (cos_i - w) / (cos_i + w),  r_par = (n_t^2 cos_i - w) / (n_t^2 cos_i + w).
// |a - b|^2 / |a + b|^2 needs no complex division.
vec2 fresnel_conductor_polarized(float cos_i, float eta, float k) {
    float c = clamp(cos_i, 0.0, 1.0);
    vec2 n2 = vec2(eta * eta - k * k, 2.0 * eta * k);
    vec2 w = complex_sqrt(n2 - vec2(1.0 - c * c, 0.0));
    vec2 a = n2 * c;
    float den_s = (c + w.x) * (c + w.x) + w.y * w.y;
    float den_p = (a.x + w.x) * (a.x + w.x) + (a.y + w.y) * (a.y + w.y);
    float Rs = den_s > 0.0 ? ((c - w.x) * (c - w.x) + w.y * w.y) / den_s : 1.0;
    float Rp = den_p > 0.0 ? ((a.x - w.x) * (a.x - w.x) + (a.y - w.y) * (a.y - w.y)) / den_p : 1.0;
    return min(vec2(Rs, Rp), vec2(1.0));
}

float fresnel_conductor(float cos_i, float eta, float k) {
    vec2 r = fresnel_conductor_polarized(cos_i, eta, k);
    return 0.5 * (r.x + r.y);
}

vec3 fresnel_conductor(float cos_i, vec3 eta, vec3 k) {
    return vec3(fresnel_conductor(cos_i, eta.r, k.r),
                fresnel_conductor(cos_i, eta.g, k.g),
                fresnel_conductor(cos_i, eta.b, k.b));
}

// Schlick 1994, "An Inexpensive BRDF Model for Physically-based Rendering", eq. 15.
vec3 fresnel_schlick(float cos_i, vec3 f0) {
    float m = 1.0 - clamp(cos_i, 0.0, 1.0);
    float m2 = m * m;
    return f0 + (1.0 - f0) * (m2 * m2 * m);
}
