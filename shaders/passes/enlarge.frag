#version 410 core
// An image resampled to the target's size with bilinear interpolation between its texel centres,
// clamped at the borders: the output pixel p lies at (p + 1/2) u_ratio - 1/2 in the source's texel
// centres, u_ratio the source's texels per output pixel on each axis. A preview enlarged s times
// has u_ratio = 1 / s (viewer.gl.raytrace.upscale, the same weights, here on the GPU); the view
// drawn at another size (a compare view's half) has u_ratio = its size / the target's.
uniform sampler2D u_src;   // read by texelFetch: the driver's filtering plays no part
uniform vec2 u_ratio;
out vec4 color;
void main() {
    ivec2 size = textureSize(u_src, 0);
    vec2 x = gl_FragCoord.xy * u_ratio - 0.5;   // gl_FragCoord is at the pixel's centre
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
