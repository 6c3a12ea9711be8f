// Shared constants and small helpers. Included once per program by the loader.
const float PI = 3.14159265358979323846;
const float INV_PI = 0.31830988618379067154;
const float TWO_PI = 6.28318530717958647692;

float saturate(float x) { return clamp(x, 0.0, 1.0); }
vec3 saturate(vec3 x) { return clamp(x, 0.0, 1.0); }
float sqr(float x) { return x * x; }
float luminance(vec3 c) { return dot(c, vec3(0.2126, 0.7152, 0.0722)); } // Rec.709 weights

// log(1 - x) for x in [0, 1). Near 0 (sharp lobes: x = 1 - cos tiny) the series keeps full
// relative precision, where rounding 1 - x first would cost n ulps in cos^n (6e-4 relative at
// n = 10000 in float32). -(x + x^2/2 + ... + x^12/12); the first dropped term is < 1e-9 relative.
float log1m(float x) {
    if (x < 0.2) {
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
