// Shared constants and small helpers. Included once per program by the loader.
const float PI = 3.14159265358979323846;
const float INV_PI = 0.31830988618379067154;
const float TWO_PI = 6.28318530717958647692;

float saturate(float x) { return clamp(x, 0.0, 1.0); }
vec3 saturate(vec3 x) { return clamp(x, 0.0, 1.0); }
float sqr(float x) { return x * x; }
float luminance(vec3 c) { return dot(c, vec3(0.2126, 0.7152, 0.0722)); } // Rec.709 weights

// BRDF values are capped at F_MAX = e^80 (about 5.5e34), as in the numpy twins
// (viewer/brdf/sampling.py): at grazing angles 1 / (4 cos_i cos_o) outgrows float32, and an inf
// becomes NaN at the next multiplication by 0. (Lafortune's lobe clamp is the same e^80.)
const float F_MAX = 5.5406223843935098e34;

// a / b for a >= 0, capped at F_MAX without overflowing: 0 where a <= 0, F_MAX where a > 0
// and b <= 0 (both cosines underflowed) or a / b would exceed it.
float ratio_capped(float a, float b) {
    if (a <= 0.0) return 0.0;
    return (b > 0.0 && a < F_MAX * b) ? a / b : F_MAX;
}

// normalize(v) that survives float32 underflow: dot(v, v) underflows to 0 below |v| ~ 1e-19,
// e.g. the half vector of two grazing directions facing each other (wi + wo = (0, 0, 2e-30)),
// where normalize gives NaN; v is scaled by its largest component first. The zero vector
// (wi = -wo) stays zero, as numpy's viewer.brdf.sampling.normalize leaves it.
vec3 normalize_safe(vec3 v) {
    float m = max(max(abs(v.x), abs(v.y)), abs(v.z));
    if (m == 0.0) return vec3(0.0);
    v /= m;
    return v * inversesqrt(dot(v, v));
}

// log(1 - x) for x < 1. Near 0 (sharp lobes: x = 1 - cos tiny) the series keeps full
// relative precision, where rounding 1 - x first would cost n ulps in cos^n (6e-4 relative at
// n = 10000 in float32). -(x + x^2/2 + ... + x^12/12) for |x| < 0.2 (the first dropped term is
// < 1e-9 relative); the series diverges for x <= -1 (Lafortune's L = 1 - |C o wo|^2 < 0 when |C| > 1).
float log1m(float x) {
    if (abs(x) < 0.2) {
        float s = 1.0 / 12.0;
        s = 1.0 / 11.0 + x * s; s = 1.0 / 10.0 + x * s; s = 1.0 / 9.0 + x * s;
        s = 1.0 / 8.0 + x * s;  s = 1.0 / 7.0 + x * s;  s = 1.0 / 6.0 + x * s;
        s = 1.0 / 5.0 + x * s;  s = 1.0 / 4.0 + x * s;  s = 1.0 / 3.0 + x * s;
        s = 1.0 / 2.0 + x * s;  s = 1.0 + x * s;
        return -x * s;
    }
    return log(1.0 - x);
}

// (1 - x)^n for x in [0, 1], 0 at x >= 1 (no log(0), no pow(0, 0)).
float pow_one_minus(float x, float n) {
    if (x >= 1.0) return 0.0;
    return exp(n * log1m(x));
}
