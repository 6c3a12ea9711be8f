// Microfacet distributions and masking-shadowing, the GLSL twin of viewer/brdf/microfacet_dist.py.
// Shading frame: normal +z, tangent +x; alpha_x along +x (Walter et al. 2007 alpha).
// Distribution ids: MICROFACET_DISTRIBUTION_* of generated/constants.glsl (the spec's choice order).
#include "generated/constants.glsl"
#include "common/math.glsl"

// mx^2/ax^2 + my^2/ay^2 (the anisotropic tan^2 term times cos^2; Heitz 2014 eqs. 82, 85)
float mf_ellipse(vec3 m, float ax, float ay) {
    float x = m.x / ax;
    float y = m.y / ay;
    return x * x + y * y;
}

// alpha^2 tan^2(theta) of w, generalized to anisotropy (Heitz 2014 eq. 80 with eq. 87's alpha_o).
// Capped so that grazing directions give a huge, finite Lambda (G -> 0) instead of inf / inf.
float mf_slope_sq(vec3 w, float ax, float ay) {
    float wz2 = w.z * w.z;
    float num = ax * ax * w.x * w.x + ay * ay * w.y * w.y;
    if (wz2 <= 0.0) return 1e30;
    return min(num / wz2, 1e30);
}

// Trowbridge & Reitz 1975 / Walter et al. 2007 eq. 33, anisotropic (Heitz 2014 eq. 85):
// D(m) = 1 / (pi ax ay (mx^2/ax^2 + my^2/ay^2 + mz^2)^2).
float D_ggx(vec3 m, float ax, float ay) {
    if (m.z <= 0.0) return 0.0;
    float t = mf_ellipse(m, ax, ay) + m.z * m.z;
    return 1.0 / (PI * ax * ay * t * t);
}

// Heitz 2014 eq. 86: Lambda = (-1 + sqrt(1 + s)) / 2, s = alpha^2 tan^2, written as
// s / (2 (1 + sqrt(1 + s))) so that small s does not cancel in float32.
float lambda_ggx(vec3 w, float ax, float ay) {
    float s = mf_slope_sq(w, ax, ay);
    return s / (2.0 * (1.0 + sqrt(1.0 + s)));
}

// Beckmann & Spizzichino 1963; Walter et al. 2007 eq. 25, anisotropic (Heitz 2014 eq. 83):
// D(m) = exp(-(mx^2/ax^2 + my^2/ay^2) / mz^2) / (pi ax ay mz^4).
float D_beckmann(vec3 m, float ax, float ay) {
    if (m.z <= 0.0) return 0.0;
    float mz2 = m.z * m.z;
    float e = mf_ellipse(m, ax, ay) / mz2;
    // exp(-80) ~ 2e-35: beyond it D is negligible, and near-horizontal m would give 0 / 0.
    if (e > 80.0) return 0.0;
    return exp(-e) / (PI * ax * ay * mz2 * mz2);
}

// erfc(x) for x >= 0 with fractional error < 1.2e-7 everywhere: the Chebyshev fit of
// Press et al., Numerical Recipes in C, 2nd ed., sec. 6.2 (function erfcc).
float mf_erfc(float x) {
    float t = 1.0 / (1.0 + 0.5 * x);
    float poly = -1.26551223 + t * (1.00002368 + t * (0.37409196 + t * (0.09678418 +
                 t * (-0.18628806 + t * (0.27886807 + t * (-1.13520398 + t * (1.48851587 +
                 t * (-0.82215223 + t * 0.17087277))))))));
    return t * exp(-x * x + poly);
}

// Heitz 2014 eq. 80 (Walter et al. 2007 eq. 27 before its rational fit), a = 1 / (alpha tan):
// Lambda = (erf(a) - 1) / 2 + exp(-a^2) / (2 a sqrt(pi)) = (exp(-a^2) / (a sqrt(pi)) - erfc(a)) / 2.
float lambda_beckmann(vec3 w, float ax, float ay) {
    float s = mf_slope_sq(w, ax, ay);
    if (s <= 0.0) return 0.0;
    float a = inversesqrt(s);
    if (a > 9.0) return 0.0;  // erfc(9) ~ 4e-37: Lambda is below float32 resolution of 1 + Lambda
    float lam = 0.5 * (exp(-a * a) / (a * 1.7724538509055159) - mf_erfc(a));
    return max(lam, 0.0);
}

// Walter et al. 2007 sec. 5.2: the Phong exponent of a Beckmann alpha, n = 2 / alpha^2 - 2.
float blinn_exponent(float alpha) {
    return max(2.0 / (alpha * alpha) - 2.0, 0.0);
}

// log(1 + x) with relative accuracy near x = 0, where GLSL's log (absolute error bounds only)
// is not enough: for |x| < 1/4 the series log1p(x) = 2 atanh(z) = 2 (z + z^3/3 + z^5/5 + ...),
// z = x / (2 + x) (|z| < 1/7, so 7 terms reach float32 precision); log(1 + x) otherwise.
float mf_log1p(float x) {
    if (abs(x) >= 0.25) return log(1.0 + x);
    float z = x / (2.0 + x);
    float z2 = z * z;
    float s = 1.0 / 13.0;
    s = 1.0 / 11.0 + z2 * s;
    s = 1.0 / 9.0 + z2 * s;
    s = 1.0 / 7.0 + z2 * s;
    s = 1.0 / 5.0 + z2 * s;
    s = 1.0 / 3.0 + z2 * s;
    s = 1.0 + z2 * s;
    return 2.0 * z * s;
}

// Blinn 1977, normalized as in Walter et al. 2007 eq. 30: D = (n + 2) / (2 pi) cos^n(theta_m).
// cos^n = exp(n/2 log(1 - sin^2)): n reaches 2e8 at alpha = 1e-4, so log(cos) must keep its
// relative accuracy near cos = 1; sin^2 = mx^2 + my^2 does, log(m.z) would not (float32).
float D_blinn_phong(vec3 m, float alpha) {
    if (m.z <= 0.0) return 0.0;
    float n = blinn_exponent(alpha);
    // n = 0 (alpha = 1): cos^0 = 1 even at m.z -> 0, where the log form would give 0 * -inf
    if (n <= 0.0) return INV_PI;
    float sin2 = min(m.x * m.x + m.y * m.y, 1.0);
    return (n + 2.0) * (0.5 * INV_PI) * exp(0.5 * n * mf_log1p(-sin2));
}

float mf_D(int dist, vec3 m, float ax, float ay) {
    if (dist == MICROFACET_DISTRIBUTION_BECKMANN) return D_beckmann(m, ax, ay);
    if (dist == MICROFACET_DISTRIBUTION_GGX) return D_ggx(m, ax, ay);
    return D_blinn_phong(m, ax);
}

// Smith Lambda of a distribution; blinn_phong borrows Beckmann's (Walter et al. 2007 sec. 5.2).
float mf_lambda(int dist, vec3 w, float ax, float ay) {
    if (dist == MICROFACET_DISTRIBUTION_GGX) return lambda_ggx(w, ax, ay);
    if (dist == MICROFACET_DISTRIBUTION_BLINN_PHONG) return lambda_beckmann(w, ax, ax);
    return lambda_beckmann(w, ax, ay);
}

// Smith masking with the local side test, Heitz 2014 eq. 43: chi+((w.m)(w.n)) / (1 + Lambda).
float smith_g1(float lam, vec3 w, vec3 m) {
    return dot(w, m) * w.z > 0.0 ? 1.0 / (1.0 + lam) : 0.0;
}

// Height-correlated Smith masking-shadowing, Heitz 2014 eq. 99:
// G2 = chi+(wi.m) chi+(wo.m) / (1 + Lambda(wi) + Lambda(wo)).
float smith_g2_height_correlated(float lam_i, float lam_o, vec3 wi, vec3 wo, vec3 m) {
    if (dot(wi, m) * wi.z <= 0.0 || dot(wo, m) * wo.z <= 0.0) return 0.0;
    return 1.0 / (1.0 + lam_i + lam_o);
}

// V-cavity geometric attenuation, Blinn 1977 / Cook & Torrance 1981:
// G = min(1, 2 (n.m)(n.wo) / (wo.m), 2 (n.m)(n.wi) / (wi.m)).
float G_v_cavity(vec3 wi, vec3 wo, vec3 m) {
    float om = dot(wo, m);
    float im = dot(wi, m);
    if (om <= 0.0 || im <= 0.0 || m.z <= 0.0) return 0.0;
    float g = min(1.0, min(2.0 * m.z * wo.z / om, 2.0 * m.z * wi.z / im));
    return max(g, 0.0);
}

// Blinn-Phong distribution + Smith: the V-cavity cap blended in only where Beckmann's borrowed
// Lambda would let the albedo exceed 1 (grazing cos, alpha >= 0.2); table t(alpha, cos) with
// alpha = 0, 0.1, .., 1 (rows), cos = 0, 0.025, .., 0.3 (columns), bilinear. Twin of
// BLINN_SMITH_CAP / G_blinn_smith in viewer/brdf/microfacet_dist.py, which says how it is made.
const float MF_BLINN_CAP[143] = float[143](
    0.0000, 0.0000, 0.0000, 0.0000, 0.0000, 0.0000, 0.0000, 0.0000, 0.0000, 0.0000, 0.0000, 0.0000, 0.0000,
    0.0000, 0.0000, 0.0000, 0.0000, 0.0000, 0.0000, 0.0000, 0.0000, 0.0000, 0.0000, 0.0000, 0.0000, 0.0000,
    0.0409, 0.0000, 0.0000, 0.0000, 0.0000, 0.0000, 0.0000, 0.0000, 0.0000, 0.0000, 0.0000, 0.0000, 0.0000,
    0.1015, 0.0458, 0.0000, 0.0000, 0.0000, 0.0000, 0.0000, 0.0000, 0.0000, 0.0000, 0.0000, 0.0000, 0.0000,
    0.1781, 0.1381, 0.0891, 0.0328, 0.0000, 0.0000, 0.0000, 0.0000, 0.0000, 0.0000, 0.0000, 0.0000, 0.0000,
    0.2673, 0.2360, 0.1987, 0.1573, 0.1109, 0.0582, 0.0000, 0.0000, 0.0000, 0.0000, 0.0000, 0.0000, 0.0000,
    0.3644, 0.3378, 0.3065, 0.2722, 0.2344, 0.1923, 0.1450, 0.0914, 0.0304, 0.0000, 0.0000, 0.0000, 0.0000,
    0.4646, 0.4393, 0.4094, 0.3766, 0.3404, 0.3001, 0.2550, 0.2042, 0.1465, 0.0807, 0.0054, 0.0000, 0.0000,
    0.5633, 0.5353, 0.5021, 0.4654, 0.4247, 0.3792, 0.3281, 0.2704, 0.2050, 0.1305, 0.0453, 0.0000, 0.0000,
    0.6565, 0.6204, 0.5790, 0.5336, 0.4833, 0.4269, 0.3635, 0.2919, 0.2105, 0.1179, 0.0121, 0.0000, 0.0000,
    0.7403, 0.6901, 0.6369, 0.5794, 0.5156, 0.4440, 0.3631, 0.2714, 0.1670, 0.0480, 0.0000, 0.0000, 0.0000);

float mf_blinn_cap_weight(float alpha, float c) {
    float fa = clamp(alpha / 0.1, 0.0, 10.0);
    float fm = clamp(abs(c) / 0.025, 0.0, 12.0);
    int ia = min(int(floor(fa)), 9);
    int im = min(int(floor(fm)), 11);
    float ta = fa - float(ia), tm = fm - float(im);
    int k = ia * 13 + im;
    return mix(mix(MF_BLINN_CAP[k], MF_BLINN_CAP[k + 1], tm),
               mix(MF_BLINN_CAP[k + 13], MF_BLINN_CAP[k + 14], tm), ta);
}

float G_blinn_smith(float alpha, float lam_i, float lam_o, vec3 wi, vec3 wo, vec3 m) {
    float g = smith_g2_height_correlated(lam_i, lam_o, wi, wo, m);
    float gc = min(g, G_v_cavity(wi, wo, m));
    float t = max(mf_blinn_cap_weight(alpha, wi.z), mf_blinn_cap_weight(alpha, wo.z));
    return g - t * (g - gc);
}

// Height-correlated Smith masking-shadowing for refraction (wo above, wi below the surface),
// Heitz 2014 sec. 5.3: the points at height h visible from wo and, from below, from wi give
// G2 = integral_0^1 C^Lambda(wo) (1 - C)^Lambda(wi) dC = B(1 + Lambda(wo), 1 + Lambda(wi)) with
// the Beta function B (C: the height distribution's CDF). Computed in the log domain: both
// arguments shifted to >= 8 with B(x, y) = B(x + 1, y) (x + y) / x, then Stirling's series for
// ln Gamma written with ratios (ln(x / (x + y)) by log1p), so that nothing cancels in float32
// however large Lambda is. Twin of smith_g2_height_correlated_transmission in microfacet_dist.py.
float mf_beta_1p(float a, float b) {
    float x = 1.0 + a, y = 1.0 + b;
    float lf = 0.0;
    for (int k = 0; k < 7; ++k) {
        if (x < 8.0) { lf += log((x + y) / x); x += 1.0; }
    }
    for (int k = 0; k < 7; ++k) {
        if (y < 8.0) { lf += log((x + y) / y); y += 1.0; }
    }
    float s = x + y;
    // ln(x / s) and ln(y / s): log1p of the small ratio when the other one is near 1
    float lxs = y < 0.25 * s ? mf_log1p(-y / s) : log(x / s);
    float lys = x < 0.25 * s ? mf_log1p(-x / s) : log(y / s);
    float lb = (x - 0.5) * lxs + (y - 0.5) * lys - 0.5 * log(s)
             + 0.91893853320467274;  // 0.5 ln(2 pi)
    // Stirling's corrections 1/(12 z) - 1/(360 z^3) of ln Gamma(x) + ln Gamma(y) - ln Gamma(s)
    lb += (1.0 / 12.0) * (1.0 / x + 1.0 / y - 1.0 / s)
        - (1.0 / 360.0) * (1.0 / (x * x * x) + 1.0 / (y * y * y) - 1.0 / (s * s * s));
    return exp(lb + lf);
}

float smith_g2_height_correlated_transmission(float lam_i, float lam_o, vec3 wi, vec3 wo, vec3 m) {
    if (dot(wi, m) * wi.z <= 0.0 || dot(wo, m) * wo.z <= 0.0) return 0.0;
    return mf_beta_1p(lam_o, lam_i);
}
