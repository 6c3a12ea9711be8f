#version 410 core
// A preview enlarged u_scale times with bilinear interpolation between its texel centres,
// clamped at the borders: the output pixel p lies at (p + 1/2) / s - 1/2 in the preview's texel
// centres (viewer.gl.raytrace.upscale, the same weights, here on the GPU).
uniform sampler2D u_src;   // read by texelFetch: the driver's filtering plays no part
uniform int u_scale;
out vec4 color;
void main() {
    ivec2 size = textureSize(u_src, 0);
    vec2 x = (gl_FragCoord.xy) / float(u_scale) - 0.5;   // gl_FragCoord is at the pixel's centre
    vec2 i0 = floor(x);
    vec2 f = x - i0;
    ivec2 a = clamp(ivec2(i0), ivec2(0), size - 1);
    ivec2 b = clamp(ivec2(i0) + 1, ivec2(0), size - 1);
    vec4 c00 = texelFetch(u_src, ivec2(a.x, a.y), 0);
    vec4 c10 = texelFetch(u_src, ivec2(b.x, a.y), 0);
    vec4 c01 = texelFetch(u_src, ivec2(a.x, b.y), 0);
    vec4 c11 = texelFetch(u_src, ivec2(b.x, b.y), 0);
    vec4 lo = c00 + (c10 - c00) * f.x;
    vec4 hi = c01 + (c11 - c01) * f.x;
    color = lo + (hi - lo) * f.y;
}
