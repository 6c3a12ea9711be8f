#version 410 core
// SSR mode: fills the three forward-pass attachments behind the scene. Colour: the environment
// along the view ray (the map, or the constant); specular weight and geometry: 0 (no surface).
#include "common/math.glsl"
#include "common/ibl.glsl"
uniform mat4 u_inv_view_proj;
uniform vec3 u_camera_pos;
uniform int u_use_map;
uniform vec3 u_constant;
in vec2 v_uv;
layout(location = 0) out vec4 frag_color;
layout(location = 1) out vec4 frag_spec;
layout(location = 2) out vec4 frag_geom;
void main() {
    vec4 far = u_inv_view_proj * vec4(v_uv * 2.0 - 1.0, 1.0, 1.0);
    vec3 dir = normalize(far.xyz / far.w - u_camera_pos);
    frag_color = vec4(u_use_map != 0 ? env_radiance(dir) : u_constant, 1.0);
    frag_spec = vec4(0.0);
    frag_geom = vec4(0.0);
}
