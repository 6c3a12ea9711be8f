// Shared sampling helpers, the GLSL twin of viewer/brdf/sampling.py and of the sampling half of
// viewer/brdf/microfacet_dist.py (shading frame, z = normal). Used by the <name>_sample and
// <name>_pdf functions of the BRDF families; u components are uniforms in [0, 1).
#include "generated/constants.glsl"
#include "common/math.glsl"
#include "common/microfacet.glsl"

const float ONE_MINUS_EPS = 0.99999994;  // the largest float32 below 1 (numpy: nextafter(1, 0))

// 1 - exp(x) for x <= 0 with relative accuracy near 0 (-expm1(x)): the sin^2 of a direction
// sampled as cos = exp(t) with t ~ -1e-8 (sharp lobes), where 1 - cos^2 would round to 0.
float one_minus_exp(float x) {
    if (x > -0.125) {
        // -(x + x^2/2! + ... + x^7/7!); the first dropped term is < 1e-9 relative
        float s = 1.0 / 5040.0;
        s = 1.0 / 720.0 + x * s; s = 1.0 / 120.0 + x * s; s = 1.0 / 24.0 + x * s;
        s = 1.0 / 6.0 + x * s;   s = 0.5 + x * s;         s = 1.0 + x * s;
        return -x * s;
    }
    return 1.0 - exp(x);
}

// Malley's method: the concentric map of Shirley & Chiu 1997 lifted to the hemisphere.
// pdf = cos(theta) / pi.
vec3 sample_cosine_hemisphere(vec2 u) {
    float a = 2.0 * u.x - 1.0;
    float b = 2.0 * u.y - 1.0;
    float r, phi;
    if (a == 0.0 && b == 0.0) {
        r = 0.0;
        phi = 0.0;
    } else if (abs(a) > abs(b)) {
        r = a;
        phi = (PI / 4.0) * (b / a);
    } else {
        r = b;
        phi = (PI / 2.0) - (PI / 4.0) * (a / b);
    }
    float x = r * cos(phi);
    float y = r * sin(phi);
    return vec3(x, y, sqrt(max(0.0, 1.0 - x * x - y * y)));
}

float cosine_hemisphere_pdf(vec3 w) { return max(w.z, 0.0) * INV_PI; }

// Directions around +z with pdf (n + 1) / (2 pi) cos^n (Lafortune & Willems 1994, Sec. 4):
// cos = u.x^(1 / (n + 1)) = exp(t), t = log(u.x) / (n + 1); sin^2 = 1 - exp(2 t) (no cancellation).
vec3 sample_power_cosine(vec2 u, float n) {
    float t = log(u.x) / (n + 1.0);  // u.x = 0: t = -inf, cos = 0
    float cos_t = exp(t);
    float sin_t = sqrt(max(0.0, one_minus_exp(2.0 * t)));
    float phi = TWO_PI * u.y;
    return vec3(sin_t * cos(phi), sin_t * sin(phi), cos_t);
}

// Orthonormal basis (x, y) around the unit vector z (Duff et al. 2017, branchless ONB).
void frame_from_z(vec3 z, out vec3 x, out vec3 y) {
    float sgn = z.z >= 0.0 ? 1.0 : -1.0;
    float a = -1.0 / (sgn + z.z);
    float b = z.x * z.y * a;
    x = vec3(1.0 + sgn * z.x * z.x * a, sgn * b, -sgn * z.x);
    y = vec3(b, sgn + z.y * z.y * a, -z.y);
}

// A direction given in the frame whose z is ``axis`` rotated to the shading frame.
vec3 to_world(vec3 local, vec3 axis) {
    vec3 x, y;
    frame_from_z(axis, x, y);
    return local.x * x + local.y * y + local.z * axis;
}

// Reflect w about the unit vector m: 2 (w.m) m - w.
vec3 reflect_about(vec3 w, vec3 m) { return 2.0 * dot(w, m) * m - w; }

// The chosen interval of a two-lobe choice: lobe 0 with probability p0 when u < p0; u rescaled
// into [0, 1) within the interval (viewer.brdf.sampling.pick_lobe for two lobes).
int pick_lobe2(float p0, inout float u) {
    if (u < p0) {
        u = p0 > 0.0 ? u / p0 : 0.0;
        u = clamp(u, 0.0, ONE_MINUS_EPS);
        return 0;
    }
    float w = 1.0 - p0;
    u = w > 0.0 ? (u - p0) / w : 0.0;
    u = clamp(u, 0.0, ONE_MINUS_EPS);
    return 1;
}

// weight = f cos / pdf of a sampled direction (viewer.brdf.sampling.sample_weight): a sample
// with pdf <= 0, or a weight beyond float32's range, fails (weight = pdf = 0).
vec3 sample_weight(vec3 f, float cos_i, inout float pdf) {
    if (!(pdf > 0.0)) { pdf = 0.0; return vec3(0.0); }
    vec3 w = f * (cos_i / pdf);
    if (!all(lessThan(abs(w), vec3(3.0e38)))) { pdf = 0.0; return vec3(0.0); }
    return w;
}

// ---------------------------------------------------------------- microfacet normals

// Heitz & d'Eon 2014 eq. 2: D_w(m) = G1(w, m) max(0, w.m) D(m) / (w.n), for w.z > 0 (the density
// of the visible-normal samplers below).
float mf_D_visible(int dist, vec3 w, vec3 m, float ax, float ay) {
    if (w.z <= 0.0) return 0.0;
    float g1 = smith_g1(mf_lambda(dist, w, ax, ay), w, m);
    return g1 * max(0.0, dot(w, m)) * mf_D(dist, m, ax, ay) / w.z;
}

// Density (per solid angle of m) of mf_sample_m: visible normals for beckmann / ggx, D cos for
// blinn_phong (Distribution.pdf_m).
float mf_pdf_m(int dist, vec3 wo, vec3 m, float ax, float ay) {
    if (dist == MICROFACET_DISTRIBUTION_BLINN_PHONG) return D_blinn_phong(m, ax) * max(m.z, 0.0);
    return mf_D_visible(dist, wo, m, ax, ay);
}

// GGX visible normals, Heitz 2018, "Sampling the GGX Distribution of Visible Normals", JCGT 7(4),
// listing 1: stretch wo to alpha = 1, sample the projected hemisphere, unstretch. wo.z > 0.
vec3 sample_vndf_ggx(vec3 wo, vec2 u, float ax, float ay) {
    vec3 vh = normalize(vec3(ax * wo.x, ay * wo.y, wo.z));
    float lensq = vh.x * vh.x + vh.y * vh.y;
    vec3 t1 = lensq > 0.0 ? vec3(-vh.y, vh.x, 0.0) * inversesqrt(lensq) : vec3(1.0, 0.0, 0.0);
    vec3 t2 = cross(vh, t1);
    float r = sqrt(u.x);
    float phi = TWO_PI * u.y;
    float p1 = r * cos(phi);
    float p2 = r * sin(phi);
    float s = 0.5 * (1.0 + vh.z);
    p2 = (1.0 - s) * sqrt(max(0.0, 1.0 - p1 * p1)) + s * p2;
    vec3 nh = p1 * t1 + p2 * t2 + sqrt(max(0.0, 1.0 - p1 * p1 - p2 * p2)) * vh;
    return normalize(vec3(ax * nh.x, ay * nh.y, max(1e-12, nh.z)));
}

// erf^-1(x) for |x| < 1 in single precision: Giles 2010, "Approximating the erfinv function"
// (GPU Computing Gems Jade, ch. 10), the single-precision polynomials (relative error ~ 4e-7).
float mf_erfinv(float x) {
    float w = -log((1.0 - x) * (1.0 + x));
    float p;
    if (w < 5.0) {
        w = w - 2.5;
        p = 2.81022636e-08;
        p = 3.43273939e-07 + p * w;  p = -3.5233877e-06 + p * w;
        p = -4.39150654e-06 + p * w; p = 0.00021858087 + p * w;
        p = -0.00125372503 + p * w;  p = -0.00417768164 + p * w;
        p = 0.246640727 + p * w;     p = 1.50140941 + p * w;
    } else {
        w = sqrt(w) - 3.0;
        p = -0.000200214257;
        p = 0.000100950558 + p * w;  p = 0.00134934322 + p * w;
        p = -0.00367342844 + p * w;  p = 0.00573950773 + p * w;
        p = -0.0076224613 + p * w;   p = 0.00943887047 + p * w;
        p = 1.00167406 + p * w;      p = 2.83297682 + p * w;
    }
    return p * x;
}

// 1 + erf(x) = erfc(-x) for any x, accurate in both tails.
float mf_one_plus_erf(float x) {
    return x <= 0.0 ? mf_erfc(-x) : 2.0 - mf_erfc(x);
}

// The x slope of visible alpha = 1 Beckmann facets for cot(theta) = mu (Heitz & d'Eon 2014,
// sec. 4): the CDF C(x) = mu (1 + erf x) / 2 + exp(-x^2) / (2 sqrt pi) inverted at u C(hi) by
// safeguarded Newton steps, as viewer/brdf/microfacet_dist.py does (float32 converges in a few).
float mf_beckmann_slope_x(float mu, float u) {
    mu = min(mu, 1e8);
    float lo = -7.0;
    float hi = min(mu, 7.0);
    float c_hi = 0.5 * mu * mf_one_plus_erf(hi) + exp(-hi * hi) * (0.5 / 1.7724538509055159);
    float target = u * c_hi;
    float x = clamp(mf_erfinv(clamp(2.0 * u - 1.0, -ONE_MINUS_EPS, ONE_MINUS_EPS)), lo, hi);
    for (int i = 0; i < 24; ++i) {
        float c = 0.5 * mu * mf_one_plus_erf(x) + exp(-x * x) * (0.5 / 1.7724538509055159) - target;
        if (c < 0.0) lo = x; else hi = x;
        float q = max(mu - x, 0.0) * exp(-x * x) / 1.7724538509055159;
        float xn = x - c / q;
        if (!(xn > lo && xn < hi)) xn = 0.5 * (lo + hi);  // also catches q = 0 (inf / NaN)
        bool done = abs(xn - x) <= 1e-6 * (1.0 + abs(x));
        x = xn;
        if (done) break;
    }
    return x;
}

// Beckmann visible normals (Heitz & d'Eon 2014, algorithm 1): stretch, sample the slopes in the
// frame where wo has azimuth 0, rotate back, unstretch, m = normalize(-x, -y, 1). wo.z > 0.
vec3 sample_vndf_beckmann(vec3 wo, vec2 u, float ax, float ay) {
    vec3 w = normalize(vec3(ax * wo.x, ay * wo.y, wo.z));
    float sin_t = length(w.xy);
    float mu = sin_t > 0.0 ? w.z / sin_t : 1e30;
    float cos_p = sin_t > 0.0 ? w.x / sin_t : 1.0;
    float sin_p = sin_t > 0.0 ? w.y / sin_t : 0.0;
    float x = mf_beckmann_slope_x(mu, u.x);
    float y = mf_erfinv(clamp(2.0 * u.y - 1.0, -ONE_MINUS_EPS, ONE_MINUS_EPS));
    float sx = (cos_p * x - sin_p * y) * ax;
    float sy = (sin_p * x + cos_p * y) * ay;
    return normalize(vec3(-sx, -sy, 1.0));
}

// m with density D(m) cos(theta_m) for the Phong distribution (Walter et al. 2007 eqs. 35, 36):
// cos = u.x^(1 / (n + 2)), phi = 2 pi u.y; sin^2 from one_minus_exp (n reaches 2e8 at alpha = 1e-4).
vec3 sample_blinn_phong_m(vec2 u, float alpha) {
    float n = blinn_exponent(alpha);
    float t = log(max(u.x, 1.17549435e-38)) / (n + 2.0);
    float cos_t = exp(t);
    float sin_t = sqrt(max(0.0, one_minus_exp(2.0 * t)));
    float phi = TWO_PI * u.y;
    return vec3(sin_t * cos(phi), sin_t * sin(phi), cos_t);
}

// A microfacet normal for the upper-hemisphere direction wo (Distribution.sample_m).
vec3 mf_sample_m(int dist, vec3 wo, vec2 u, float ax, float ay) {
    if (dist == MICROFACET_DISTRIBUTION_GGX) return sample_vndf_ggx(wo, u, ax, ay);
    if (dist == MICROFACET_DISTRIBUTION_BECKMANN) return sample_vndf_beckmann(wo, u, ax, ay);
    return sample_blinn_phong_m(u, ax);
}
