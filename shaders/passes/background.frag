#version 410 core
// The environment behind the scene: the radiance arriving along each pixel's view ray.
#include "common/math.glsl"
#include "common/ibl.glsl"
uniform mat4 u_inv_view_proj;
uniform vec3 u_camera_pos;
in vec2 v_uv;
out vec4 frag_color;
void main() {
    vec4 far = u_inv_view_proj * vec4(v_uv * 2.0 - 1.0, 1.0, 1.0);
    vec3 dir = normalize(far.xyz / far.w - u_camera_pos);
    frag_color = vec4(env_radiance(dir), 1.0);
}
