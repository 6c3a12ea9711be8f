// Colour encoding for display: exposure, optional tone mapping, sRGB.
// The piecewise sRGB transfer function (IEC 61966-2-1), not a 2.2 gamma (docs/conventions.md).
#include "generated/constants.glsl"
vec3 srgb_encode(vec3 c) {
    c = max(c, vec3(0.0));
    vec3 lo = 12.92 * c;
    vec3 hi = 1.055 * pow(c, vec3(1.0 / 2.4)) - 0.055;
    return mix(lo, hi, step(vec3(0.0031308), c));
}

// Reinhard et al. 2002, simple global operator L / (1 + L).
vec3 tonemap_reinhard(vec3 c) { return c / (1.0 + c); }

// Narkowicz 2015, "ACES Filmic Tone Mapping Curve" (a fit of the ACES RRT+ODT).
vec3 tonemap_aces(vec3 c) {
    const float a = 2.51, b = 0.03, cc = 2.43, d = 0.59, e = 0.14;
    return clamp((c * (a * c + b)) / (c * (cc * c + d) + e), 0.0, 1.0);
}

// Hable 2010, "Filmic Tonemapping for Real-time Rendering" (Uncharted 2), white point 11.2.
vec3 hable_curve(vec3 x) {
    const float A = 0.15, B = 0.50, C = 0.10, D = 0.20, E = 0.02, F = 0.30;
    return ((x * (A * x + C * B) + D * E) / (x * (A * x + B) + D * F)) - E / F;
}
vec3 tonemap_filmic(vec3 c) {
    return hable_curve(2.0 * c) / hable_curve(vec3(11.2));
}

// A false-colour ramp for term views (dark blue -> cyan -> yellow -> red), t in [0, 1].
vec3 false_colour(float t) {
    t = clamp(t, 0.0, 1.0);
    vec3 a = mix(vec3(0.05, 0.05, 0.35), vec3(0.0, 0.8, 0.9), smoothstep(0.0, 0.35, t));
    vec3 b = mix(a, vec3(1.0, 0.9, 0.1), smoothstep(0.35, 0.7, t));
    return mix(b, vec3(0.9, 0.1, 0.05), smoothstep(0.7, 1.0, t));
}

// A term view's value v as a position on that ramp (viewer/term_scales.py's scales, generated):
// t = log(1 + k v) / log(1 + k v_max), or v / v_max for k = 0; negative v counts as 0.
float term_t(float v, float k, float vmax) {
    v = max(v, 0.0);
    return clamp(k > 0.0 ? log(1.0 + k * v) / log(1.0 + k * vmax) : v / vmax, 0.0, 1.0);
}

// mode: TONEMAP_NONE, _REINHARD, _ACES or _FILMIC (generated/constants.glsl)
vec3 tonemap(vec3 c, int mode) {
    if (mode == TONEMAP_REINHARD) return tonemap_reinhard(c);
    if (mode == TONEMAP_ACES) return tonemap_aces(c);
    if (mode == TONEMAP_FILMIC) return tonemap_filmic(c);
    return c;
}
