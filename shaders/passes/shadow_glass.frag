#version 410 core
// Glass in the shadow pass: each face of a transmissive object in front of the nearest opaque
// caster (depth-tested against the opaque shadow map, no depth write) adds its optical depth
// tau = -ln T to the light's tile (additive blending into an RGBA16F atlas cleared to 0); the
// forward pass multiplies the light by exp(-tau) (common/shadow.glsl). What a face adds:
//
// - Fresnel: -ln(1 - R(theta)) at the angle between the light's ray and the face, seen from
//   outside (1 - R is the same from either side of an interface at corresponding angles, Stokes
//   relations: so an exit face seen at the outside angle gives the exit's transmittance), RGB
//   1 - R of a thin film where the material has one.
// - Bouguer absorption sigma_a d over the path d inside, by the object's shape (u_shape):
//   SHAPE_SPHERE (the built-in sphere, uniform scale) and SHAPE_BOX (the built-in cube, any
//   scale and turn): the face the light enters through adds everything, the refracted ray's
//   exact length through the analytic shape (a sphere's chord 2 R cos(theta_t), a box's exit
//   along the refracted direction) and the exit's Fresnel at the refracted ray's inside angle
//   (0 past the critical angle: total internal reflection sends the direct light elsewhere);
//   its exit face adds nothing. SHAPE_CLOSED (any other closed mesh): the straight chord along
//   the light's ray, the entry face adding -sigma_a z and the exit face +sigma_a z (z measured
//   along the ray from the object's centre, so the sum is the chord, exact at normal incidence).
//   SHAPE_OPEN (the plane): no inside, Fresnel alone.
// Left out: the caustic (light focused or spread by the refraction: the straight-line texel
// gets the light), multiple internal reflections (the slab's light bounced twice inside adds
// R^2 T^2 a^3 of the direct T^2 a, under 0.3% for n = 1.5), the lateral shift of the exit point.
#include "common/fresnel.glsl"

in vec3 v_world;
in vec3 v_normal;

uniform int u_point;          // 1: a point light at u_light, 0: directional travelling along u_light
uniform vec3 u_light;
uniform float u_ior;
uniform vec3 u_sigma_a;       // absorption inside [1/m]
uniform int u_shape;          // SHAPE_* below
uniform vec3 u_center;        // the object's translate (its mesh's centre)
uniform float u_radius;       // a sphere's radius
uniform mat4 u_world_to_local;
uniform vec4 u_film;          // thin film: (ior, thickness at the bottom, at the top or -1, 1 when on)
uniform vec2 u_film_y;        // the world y range its thickness varies over

const int SHAPE_CLOSED = 0;
const int SHAPE_SPHERE = 1;
const int SHAPE_BOX = 2;
const int SHAPE_OPEN = 3;

out vec4 tau_out;

// 1 - R of an interface at cosine c, seen from the side where the relative index is eta
vec3 interface_t(float c, float eta, float y) {
    if (u_film.w > 0.5) {
        float h = u_film_y.y > u_film_y.x ? clamp((y - u_film_y.x) / (u_film_y.y - u_film_y.x), 0.0, 1.0) : 0.0;
        float d_nm = u_film.z >= 0.0 ? mix(u_film.y, u_film.z, h) : u_film.y;
        return 1.0 - thin_film_dielectric_rgb(c, eta, u_film.x, d_nm);
    }
    return vec3(fresnel_dielectric_transmittance(c, eta));
}

// the distance along direction l from o (one axis) to the box's face ahead, [-1, 1]
float exit_t(float l, float o) { return l > 1e-12 ? (1.0 - o) / l : (l < -1e-12 ? (-1.0 - o) / l : 3.0e38); }

vec3 optical_depth(vec3 t) { return -log(max(t, vec3(1e-30))); }

void main() {
    vec3 d = u_point == 1 ? normalize(v_world - u_light) : normalize(u_light);  // the light's travel
    vec3 n = normalize(v_normal);
    float c = dot(n, d);
    bool entry = c < 0.0;          // outward normals: the face turned to the light
    bool absorbs = any(greaterThan(u_sigma_a, vec3(0.0)));
    vec3 tau = vec3(0.0);
    if (u_shape == SHAPE_SPHERE) {
        if (!entry) discard;
        vec3 na = normalize(v_world - u_center);          // the analytic sphere's normal
        float ci = clamp(-dot(na, d), 0.0, 1.0);
        float st2 = (1.0 - ci * ci) / (u_ior * u_ior);
        float ct = sqrt(max(0.0, 1.0 - st2));
        vec3 t = interface_t(ci, u_ior, v_world.y);
        // the exit: inside angle theta_t, whose transmittance equals the entry's (Stokes)
        tau = 2.0 * optical_depth(t) + (absorbs ? u_sigma_a * (2.0 * u_radius * ct) : vec3(0.0));
    } else if (u_shape == SHAPE_BOX) {
        if (!entry) discard;
        float ci = clamp(-c, 0.0, 1.0);
        vec3 t_in = interface_t(ci, u_ior, v_world.y);
        vec3 r = refract(d, n, 1.0 / u_ior);
        // the refracted ray through the box [-1, 1]^3 in the object's frame: its exit
        vec3 o = (u_world_to_local * vec4(v_world, 1.0)).xyz;
        vec3 l = mat3(u_world_to_local) * r;
        vec3 s3 = vec3(exit_t(l.x, o.x), exit_t(l.y, o.y), exit_t(l.z, o.z));
        float s = min(s3.x, min(s3.y, s3.z));
        int axis = s == s3.x ? 0 : (s == s3.y ? 1 : 2);
        vec3 nl = vec3(0.0);
        nl[axis] = l[axis] > 0.0 ? 1.0 : -1.0;
        vec3 n_exit = normalize(transpose(mat3(u_world_to_local)) * nl);
        vec3 p_exit = v_world + r * s;                     // r is unit: s is the world length
        vec3 t_out = interface_t(clamp(dot(r, n_exit), 0.0, 1.0), 1.0 / u_ior, p_exit.y);
        tau = optical_depth(t_in) + optical_depth(t_out) + u_sigma_a * max(s, 0.0);
    } else {
        tau = optical_depth(interface_t(abs(c), u_ior, v_world.y));
        if (u_shape == SHAPE_CLOSED && absorbs) {
            float z = u_point == 1 ? length(v_world - u_light) - length(u_center - u_light) : dot(v_world - u_center, d);
            tau += u_sigma_a * (entry ? -z : z);
        }
    }
    tau_out = vec4(tau, 0.0);
}
