#version 410 core
// Forward shading: every material goes through brdf_eval (the one include point of the BRDFs,
// generated from the registry), lit by point and directional lights with shadow maps.
#include "common/math.glsl"
#include "brdf/dispatch.glsl"
#include "common/shadow.glsl"

// With MSAA, shade at every sample (GLSL 4.00 'sample' inputs) so a pixel is the average over
// its square (CONTRACT section 1, box filter) rather than the value at its centre; defined by
// the renderer when sample shading is on.
#ifdef SAMPLE_SHADING
sample in vec3 v_position;
sample in vec3 v_normal;
sample in vec4 v_tangent;
#else
in vec3 v_position;
in vec3 v_normal;
in vec4 v_tangent;
#endif
flat in vec3 v_geometric_normal;  // from forward.geom

uniform int u_model_id;        // registry index of this object's material model
uniform vec3 u_camera_pos;
uniform int u_num_lights;
uniform int u_light_type[MAX_LIGHTS];    // 0 point, 1 directional
uniform vec3 u_light_pos[MAX_LIGHTS];    // point: position; directional: direction the light travels
uniform vec3 u_light_value[MAX_LIGHTS];  // point: intensity I [W/sr]; directional: irradiance E [W/m^2]
uniform vec3 u_env_constant;             // constant environment radiance
uniform int u_env_on;
uniform int u_view_mode;                 // 0 shaded, 1 F, 2 D, 3 G, 4 N.L, 5 f cos, 6 shadow
const int ALBEDO_TABLE = 32;             // keep equal to viewer.brdf.albedo.TABLE_SIZE
uniform vec3 u_albedo[ALBEDO_TABLE];     // directional albedo at cos(theta_o) = (k + 0.5) / 32
uniform vec3 u_albedo_t[ALBEDO_TABLE];   // its transmitted part (wi below the surface)
uniform int u_transmit_on;
uniform vec3 u_sigma_a;                  // absorption inside a transmissive material [1/m]
uniform float u_ior;
uniform sampler2D u_thickness;           // distance to the nearest back face (0 = none)

out vec4 frag_color;

// A false-colour ramp for term views (dark blue -> cyan -> yellow -> red), t in [0, 1].
vec3 false_colour(float t) {
    t = clamp(t, 0.0, 1.0);
    vec3 a = mix(vec3(0.05, 0.05, 0.35), vec3(0.0, 0.8, 0.9), smoothstep(0.0, 0.35, t));
    vec3 b = mix(a, vec3(1.0, 0.9, 0.1), smoothstep(0.35, 0.7, t));
    return mix(b, vec3(0.9, 0.1, 0.05), smoothstep(0.7, 1.0, t));
}

void main() {
    vec3 ng = v_geometric_normal;
    vec3 n = normalize(v_normal);
    vec3 wo_w = normalize(u_camera_pos - v_position);
    // Two-sided surfaces: shade the side the viewer sees.
    if (!gl_FrontFacing) n = -n;
    if (dot(ng, n) < 0.0) ng = -ng;
    // Shading frame: x = tangent (anisotropy axis), z = normal (CONTRACT section 1).
    vec3 t = v_tangent.xyz - n * dot(n, v_tangent.xyz);
    t = dot(t, t) > 1e-12 ? normalize(t) : normalize(abs(n.x) < 0.9 ? cross(n, vec3(1, 0, 0)) : cross(n, vec3(0, 1, 0)));
    vec3 b = cross(n, t) * (v_tangent.w < 0.0 ? -1.0 : 1.0);
    mat3 to_local = transpose(mat3(t, b, n));
    vec3 wo = to_local * wo_w;

    vec3 radiance = vec3(0.0);
    vec3 first_terms = vec3(-1.0);
    float first_ndotl = 0.0;
    float first_visibility = 0.0;
    vec3 first_fcos = vec3(0.0);
    for (int i = 0; i < MAX_LIGHTS; ++i) {
        if (i >= u_num_lights) break;
        bool is_point = u_light_type[i] == 0;
        vec3 wi_w;
        vec3 e;  // irradiance at normal incidence from this light
        if (is_point) {
            vec3 d = u_light_pos[i] - v_position;
            float r2 = max(dot(d, d), 1e-12);
            wi_w = d * inversesqrt(r2);
            e = u_light_value[i] / r2;            // I / r^2 (CONTRACT section 1)
        } else {
            wi_w = -normalize(u_light_pos[i]);
            e = u_light_value[i];
        }
        vec3 wi = to_local * wi_w;
        float cos_i = wi.z;
        vec3 f = brdf_eval(u_model_id, 0, wi, wo);
        if (i == 0) {
            first_terms = brdf_terms(u_model_id, 0, wi, wo);
            first_ndotl = max(cos_i, 0.0);
            first_fcos = f * max(cos_i, 0.0);
        }
        if (cos_i <= 0.0 || dot(ng, wi_w) <= 0.0) continue;
        float vis = shadow_visibility(i, is_point, u_light_pos[i], v_position, ng, dot(ng, wi_w));
        if (i == 0) first_visibility = vis;
        radiance += f * e * cos_i * vis;
    }
    if (u_env_on != 0 && any(greaterThan(u_env_constant, vec3(0.0)))) {
        // Constant environment: L_o = L_env * rho(wo), the directional albedo, tabulated per
        // material over cos(theta_o) by viewer/brdf/albedo.py with the model's own sampler.
        // No occlusion (environment maps and proper IBL come with the environment work).
        float x = clamp(wo.z, 0.0, 1.0) * float(ALBEDO_TABLE) - 0.5;
        int k0 = clamp(int(floor(x)), 0, ALBEDO_TABLE - 1);
        int k1 = min(k0 + 1, ALBEDO_TABLE - 1);
        float fx = clamp(x - float(k0), 0.0, 1.0);
        vec3 rho = mix(u_albedo[k0], u_albedo[k1], fx);
        if (u_transmit_on != 0) {
            // Glass: light refracted in crosses the object and leaves through the back. The
            // rasterizer's approximation: one straight traversal of length d = back - front
            // along the view ray with Bouguer attenuation exp(-sigma_a d), the radiance factor
            // ior^2 of leaving the denser medium, no exit Fresnel or internal bounces.
            float front = length(v_position - u_camera_pos);
            float back = texelFetch(u_thickness, ivec2(gl_FragCoord.xy), 0).r;
            float d = (any(greaterThan(u_sigma_a, vec3(0.0))) && back > front) ? back - front : 0.0;
            vec3 rho_t = mix(u_albedo_t[k0], u_albedo_t[k1], fx) * u_ior * u_ior;
            rho += rho_t * exp(-u_sigma_a * d);
        }
        radiance += u_env_constant * (wo.z > 0.0 ? rho : vec3(0.0));
    }
    if (u_view_mode == 0) {
        frag_color = vec4(radiance, 1.0);
    } else if (u_view_mode <= 3) {
        float v = first_terms[u_view_mode - 1];
        // F in [0,1]; D and G shown on a log-ish scale so peaks and tails are both visible
        float t = u_view_mode == 2 ? log(1.0 + max(v, 0.0)) / log(1.0 + 100.0) : v;
        frag_color = vec4(v < 0.0 ? vec3(0.25) : false_colour(t), 1.0);
    } else if (u_view_mode == 4) {
        frag_color = vec4(false_colour(first_ndotl), 1.0);
    } else if (u_view_mode == 5) {
        frag_color = vec4(first_fcos, 1.0);
    } else {
        frag_color = vec4(vec3(first_visibility), 1.0);  // light 0 visibility (shadow map)
    }
}
