// The lat-long mapping of environment maps (docs/conventions.md), the one GLSL definition: the
// rasterizer's IBL (common/ibl.glsl) and the GPU reference engine's environment light
// (pathtrace/environment.glsl) both include it; viewer/environment/latlong.py is its numpy twin
// (dir_to_uv, uv_to_dir; tests/test_environment.py compares them on the GPU).
// u = 0.5 + atan2(d.x, -d.z) / (2 pi), v = acos(d.y) / pi; v = 0 at the zenith (row 0).
#include "common/math.glsl"

// (u, v) of a map-frame direction (need not be unit length). atan(0, 0) is undefined in GLSL,
// so the poles get u = 0.5 (any u is the same point there).
vec2 env_dir_to_uv(vec3 d) {
    vec3 n = d / max(length(d), 1e-30);
    float x = n.x;
    float z = -n.z;
    float u = (abs(x) + abs(z) > 0.0) ? 0.5 + atan(x, z) * (0.5 * INV_PI) : 0.5;
    float v = acos(clamp(n.y, -1.0, 1.0)) * INV_PI;
    return vec2(u, v);
}

// Unit map-frame direction of (u, v): phi = 2 pi (u - 0.5), theta = pi v.
vec3 env_uv_to_dir(vec2 uv) {
    float phi = TWO_PI * (uv.x - 0.5);
    float theta = PI * uv.y;
    float st = sin(theta);
    return vec3(st * sin(phi), cos(theta), -st * cos(phi));
}
