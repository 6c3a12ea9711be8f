#version 410 core
// One level of the SSR pass's hierarchical depth (Hi-Z) pyramid (viewer/gl/ssr.py; the idea is
// Uludag 2014, "Hi-Z Screen-Space Cone-Traced Reflections", GPU Pro 5, here on the linear view
// depth with the minimum = the closest surface).
//
// u_level == 0: the linear view depth of the G-buffer (u_src = the resolved normal/depth target;
// depth / coverage where coverage > 0.5 like ssr.frag's scene_depth, else EMPTY_DEPTH, larger than any
// ray depth, so that "no surface" never stops a ray).
// u_level > 0: the minimum over the 2x2 texels of level u_level - 1 of u_src (the mipmapped
// pyramid), whose size is u_src_size; a level is floor(src / 2) texels (at least 1), so when the
// source has an odd width or height the last column / row of the output also covers its extra
// column / row.
uniform sampler2D u_src;
uniform int u_level;
uniform ivec2 u_src_size;

out vec4 frag_color;

#include "generated/constants.glsl"

void main() {
    ivec2 p = ivec2(gl_FragCoord.xy);
    if (u_level == 0) {
        vec4 g = texelFetch(u_src, p, 0);
        float cov = length(g.xyz);
        frag_color = vec4(cov > 0.5 ? g.w / cov : EMPTY_DEPTH, 0.0, 0.0, 1.0);
        return;
    }
    int lod = u_level - 1;
    ivec2 dst_size = max(u_src_size / 2, ivec2(1));
    ivec2 lo = 2 * p;
    // the last column / row takes everything up to the source's end (1, 2 or 3 texels)
    ivec2 hi = lo + 1;
    if (p.x == dst_size.x - 1) hi.x = u_src_size.x - 1;
    if (p.y == dst_size.y - 1) hi.y = u_src_size.y - 1;
    hi = min(hi, u_src_size - 1);
    float z = EMPTY_DEPTH;
    for (int y = lo.y; y <= hi.y; ++y)
        for (int x = lo.x; x <= hi.x; ++x)
            z = min(z, texelFetch(u_src, ivec2(x, y), lod).r);
    frag_color = vec4(z, 0.0, 0.0, 1.0);
}
