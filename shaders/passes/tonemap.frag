#version 410 core
// HDR linear radiance -> display: exposure (EV), tone mapping, sRGB encoding.
#include "common/colour.glsl"
uniform sampler2D u_hdr;
uniform float u_exposure;   // EV: radiance is scaled by 2^EV
uniform int u_tonemap;
in vec2 v_uv;
out vec4 color;
void main() {
    vec3 c = texture(u_hdr, v_uv).rgb;
    // NaN/Inf never reach the screen as garbage: show them as magenta so they are noticed
    if (any(isnan(c)) || any(isinf(c))) { color = vec4(1.0, 0.0, 1.0, 1.0); return; }
    c *= exp2(u_exposure);
    color = vec4(srgb_encode(tonemap(c, u_tonemap)), 1.0);
}
