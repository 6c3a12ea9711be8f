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

// ---------------------------------------------------------------------------------------------
// Thin-film interference, twin of fresnel_thin_film (viewer/brdf/fresnel.py) and of
// viewer/brdf/thin_film.py. Complex numbers are vec2 (re, im).
vec2 tf_cmul(vec2 a, vec2 b) { return vec2(a.x * b.x - a.y * b.y, a.x * b.y + a.y * b.x); }
vec2 tf_cdiv(vec2 a, vec2 b) {
    float d = dot(b, b);
    return d > 0.0 ? vec2(a.x * b.x + a.y * b.y, a.y * b.x - a.x * b.y) / d : vec2(-1.0, 0.0);
}

// Unpolarized R of a film (real index n1, thickness d_nm) on a base n2 = (eta, k), from index 1,
// at one wavelength: the Airy sum r = (r01 + r12 e^{i phi}) / (1 + r01 r12 e^{i phi}),
// phi = 4 pi d w1 / lambda, w_j = n_j cos_j = sqrt(n_j^2 - sin_0^2) (Born & Wolf sec. 7.6.1),
// s: r_ij = (w_i - w_j) / (w_i + w_j), p: r_ij = (n_j^2 w_i - n_i^2 w_j) / (n_j^2 w_i + n_i^2 w_j).
float fresnel_thin_film(float cos_i, float lambda_nm, float n1, float d_nm, vec2 n2) {
    float c = clamp(cos_i, 0.0, 1.0);
    float s2 = 1.0 - c * c;
    vec2 w0 = vec2(c, 0.0);
    vec2 n1sq = vec2(n1 * n1, 0.0);
    vec2 n2sq = tf_cmul(n2, n2);
    vec2 w1 = complex_sqrt(n1sq - vec2(s2, 0.0));
    vec2 w2 = complex_sqrt(n2sq - vec2(s2, 0.0));
    vec2 ph = (4.0 * PI * d_nm / lambda_nm) * w1;           // i phi = i (ph.x + i ph.y)
    vec2 e = exp(-ph.y) * vec2(cos(ph.x), sin(ph.x));
    vec2 r01s = tf_cdiv(w0 - w1, w0 + w1);
    vec2 r12s = tf_cdiv(w1 - w2, w1 + w2);
    vec2 r01p = tf_cdiv(n1sq.x * w0 - w1, n1sq.x * w0 + w1);
    vec2 r12p = tf_cdiv(tf_cmul(n2sq, w1) - n1sq.x * w2, tf_cmul(n2sq, w1) + n1sq.x * w2);
    vec2 ns = r01s + tf_cmul(r12s, e), ds = vec2(1.0, 0.0) + tf_cmul(r01s, tf_cmul(r12s, e));
    vec2 np = r01p + tf_cmul(r12p, e), dp = vec2(1.0, 0.0) + tf_cmul(r01p, tf_cmul(r12p, e));
    float Rs = dot(ds, ds) > 0.0 ? min(dot(ns, ns) / dot(ds, ds), 1.0) : 1.0;
    float Rp = dot(dp, dp) > 0.0 ? min(dot(np, np) / dot(dp, dp), 1.0) : 1.0;
    return 0.5 * (Rs + Rp);
}

// The 32 wavelengths of viewer/brdf/thin_film.py and their RGB weights W_k (from
// viewer.spectral.to_rgb: RGB = sum_k R(lambda_k) W_k; tests compare these numbers with it).
const float TF_NM[32] = float[32](386.2500, 398.7500, 411.2500, 423.7500, 436.2500, 448.7500, 461.2500, 473.7500, 486.2500, 498.7500, 511.2500, 523.7500, 536.2500, 548.7500, 561.2500, 573.7500, 586.2500, 598.7500, 611.2500, 623.7500, 636.2500, 648.7500, 661.2500, 673.7500, 686.2500, 698.7500, 711.2500, 723.7500, 736.2500, 748.7500, 761.2500, 773.7500);
const vec3 TF_W[32] = vec3[32](
    vec3(0.000233612522, -0.000199366995, 0.00139682996),
    vec3(0.00112569362, -0.000974766106, 0.00686270013),
    vec3(0.00519994313, -0.00458857857, 0.0326667941),
    vec3(0.0159218873, -0.014506674, 0.107123471),
    vec3(0.0252389841, -0.0246465589, 0.20076026),
    vec3(0.0203942422, -0.0245649365, 0.252235212),
    vec3(-0.000694791408, -0.0110357395, 0.2346972),
    vec3(-0.0284647124, 0.0133264442, 0.158083576),
    vec3(-0.0523117822, 0.0412068601, 0.0794585171),
    vec3(-0.0772998005, 0.0763128581, 0.0330183708),
    vec3(-0.104954508, 0.124673711, 0.00664136426),
    vec3(-0.110249571, 0.168309885, -0.0101973152),
    vec3(-0.0797660093, 0.186072556, -0.0179362869),
    vec3(-0.0212242902, 0.177395564, -0.0204373337),
    vec3(0.0556694831, 0.147925298, -0.0191989504),
    vec3(0.140784612, 0.106275056, -0.0159593186),
    vec3(0.211987073, 0.0597074273, -0.0116488818),
    vec3(0.255641611, 0.0205978446, -0.00769127554),
    vec3(0.254871505, -0.0032594984, -0.00473616703),
    vec3(0.202705835, -0.0118571198, -0.00262280188),
    vec3(0.135068612, -0.0111651631, -0.00134431592),
    vec3(0.0785977793, -0.00753797425, -0.000653056819),
    vec3(0.0402858215, -0.00413437147, -0.000301054696),
    vec3(0.0185990457, -0.00196711569, -0.000131669037),
    vec3(0.00754728787, -0.000812607934, -5.16269737e-05),
    vec3(0.00297200043, -0.000322617753, -2.00005247e-05),
    vec3(0.00127874057, -0.000138953046, -8.58757928e-06),
    vec3(0.00049592502, -5.38891804e-05, -3.33046189e-06),
    vec3(0.000221167328, -2.4032921e-05, -1.48528351e-06),
    vec3(8.24288194e-05, -8.95704382e-06, -5.53563451e-07),
    vec3(2.78113687e-05, -3.02209404e-06, -1.86771544e-07),
    vec3(1.43634343e-05, -1.56078799e-06, -9.64598569e-08));

// The base's (eta, k) at lambda from RGB values at 650 / 550 / 450 nm, linear, held beyond.
vec2 tf_base(float lambda_nm, vec3 eta, vec3 k) {
    float t = clamp((lambda_nm - 450.0) / 100.0, 0.0, 2.0);
    if (t < 1.0) return mix(vec2(eta.b, k.b), vec2(eta.g, k.g), t);
    return mix(vec2(eta.g, k.g), vec2(eta.r, k.r), t - 1.0);
}

// RGB reflectance of a film (n1, d_nm) on a base (eta, k per RGB channel) from index 1, as
// integrated; d_nm <= 0 gives the loop no iterations. The loop is compiled in only where THIN_FILM is
// defined (programs of materials with a film: viewer.gl.brdf_glsl.program_defines): inlined at
// every Fresnel call of every sampler, it multiplies software GL's compile time (an all-model
// program went from 6 s to more than 10 minutes).
vec3 thin_film_sum(float cos_i, float n1, float d_nm, vec3 eta, vec3 k) {
    vec3 rgb = vec3(0.0);
#ifdef THIN_FILM
    int n = d_nm > 0.0 ? 32 : 0;
    for (int i = 0; i < n; ++i)
        rgb += fresnel_thin_film(cos_i, TF_NM[i], n1, d_nm, tf_base(TF_NM[i], eta, k)) * TF_W[i];
#endif
    return rgb;
}

// On a dielectric base: clipped to [0, 1] (1 - R is its transmittance).
vec3 thin_film_rgb(float cos_i, float n1, float d_nm, vec3 eta, vec3 k) {
    return clamp(thin_film_sum(cos_i, n1, d_nm, eta, k), 0.0, 1.0);
}

// On a conductor: kept as integrated (linear RGB may exceed 1 outside the gamut), clipped at 0.
vec3 thin_film_conductor_rgb(float cos_i, float n1, float d_nm, vec3 eta, vec3 k) {
    return max(thin_film_sum(cos_i, n1, d_nm, eta, k), vec3(0.0));
}

// The film on a dielectric interface seen from the side with relative index eta (eta < 1:
// from inside; the film is on the outside face): R at the outside angle, 1 beyond the critical
// angle (a lossless stack reflects alike from both sides). Twin of dielectric_reflectance_rgb.
vec3 thin_film_dielectric_rgb(float cos_i, float eta, float n1, float d_nm) {
    float c = clamp(cos_i, 0.0, 1.0);
    float ior = eta < 1.0 ? 1.0 / eta : eta;
    float s2 = eta < 1.0 ? (1.0 - c * c) * ior * ior : 1.0 - c * c;
    if (s2 >= 1.0) return vec3(1.0);
    return thin_film_rgb(sqrt(1.0 - s2), n1, d_nm, vec3(ior), vec3(0.0));
}
