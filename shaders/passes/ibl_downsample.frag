#version 410 core
// One level of the lat-long mip chain from the level above (viewer/gl/ibl.py): each destination
// texel is the solid-angle weighted mean of the source texels under its footprint (a box filter
// on the sphere, exact for any sizes, odd ones included). A texel's weight is its overlap in u
// times the solid angle of its overlap in v: integral over [v_a, v_b] of sin(pi v) pi dv
// = cos(pi v_a) - cos(pi v_b) = 2 sin(pi (v_a + v_b) / 2) sin(pi (v_b - v_a) / 2)
// (the product form keeps float32 precision near the poles).
#include "common/math.glsl"

uniform sampler2D u_src;
uniform int u_src_level;
uniform vec2 u_src_size;
uniform vec2 u_dst_size;
out vec4 frag_color;

void main() {
    vec2 p = floor(gl_FragCoord.xy);
    vec2 lo = p * u_src_size / u_dst_size;
    vec2 hi = (p + 1.0) * u_src_size / u_dst_size;
    vec3 sum = vec3(0.0);
    float wsum = 0.0;
    for (int y = int(floor(lo.y)); y < int(ceil(hi.y)); ++y) {
        float ya = max(lo.y, float(y)) / u_src_size.y;
        float yb = min(hi.y, float(y + 1)) / u_src_size.y;
        float wy = 2.0 * sin(0.5 * PI * (ya + yb)) * sin(0.5 * PI * (yb - ya));
        for (int x = int(floor(lo.x)); x < int(ceil(hi.x)); ++x) {
            float wx = min(hi.x, float(x + 1)) - max(lo.x, float(x));
            float w = wx * wy;
            sum += w * texelFetch(u_src, ivec2(x, y), u_src_level).rgb;
            wsum += w;
        }
    }
    frag_color = vec4(sum / max(wsum, 1e-30), 1.0);
}
