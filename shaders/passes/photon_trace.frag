#version 410 core
// The photon pass of the `photon` integrator (viewer/gpupt/photons.py): one photon per fragment
// of a target PHOTON_WIDTH texels wide. Photon i (texel (i % width, i / width)) starts at the
// origin, direction and power emitted for it on the CPU (viewer.reference_common.caustics.
// emit_photons, uploaded as float textures) and is traced over the scene's BVH only while it
// meets delta surfaces (materials whose every lobe is a delta lobe: mirrors, smooth glass,
// smooth conductors), each scattering drawn by the material's own sampler (brdf_sample) and
// its power multiplied by the sample's weight; inside an absorbing dielectric each segment is
// attenuated by exp(-sigma_a t) (Bouguer). At the first hit on any other surface the photon is
// stored when it passed at least one delta vertex (else it is dropped): out_pos = (position,
// 1), out_dir = its direction of travel, out_power = its power, out_normal = the geometric
// normal there (the gather's normal test takes |dot|). A photon that escapes, dies, or passes
// PHOTON_MAX_BOUNCES delta vertices without meeting such a surface is not stored (out_pos.w = 0).
//
// Radiance and flux: a delta sampler's weight is the radiance-mode one (refraction scales by
// 1 / eta^2 of the side the radiance arrives on); a photon that enters and leaves a closed
// dielectric takes eta^2 and 1 / eta^2, which cancel, and photons are stored only outside
// dielectrics (a delta surface stores nothing), so the weights carry flux unchanged.
#include "generated/constants.glsl"
#include "brdf/dispatch.glsl"
#include "common/bvh.glsl"
#include "common/rng.glsl"

uniform vec4 u_mat_info[2 * MAX_MATERIALS];
#include "pathtrace/surface.glsl"

uniform sampler2D u_ph_origin;   // xyz origin
uniform sampler2D u_ph_dir;      // xyz unit direction of travel
uniform sampler2D u_ph_power;    // rgb power
uniform int u_ph_count;
uniform int u_ph_width;
uniform uint u_seed;
uniform uint u_pass;

layout(location = 0) out vec4 out_pos;
layout(location = 1) out vec4 out_dir;
layout(location = 2) out vec4 out_power;
layout(location = 3) out vec4 out_normal;

bool finite_pos(vec3 v) {
    return !(any(isnan(v)) || any(isinf(v))) && v.x >= 0.0 && v.y >= 0.0 && v.z >= 0.0;
}

void main() {
    ivec2 px = ivec2(gl_FragCoord.xy);
    out_pos = vec4(0.0);
    out_dir = vec4(0.0);
    out_power = vec4(0.0);
    out_normal = vec4(0.0);
    int i = px.y * u_ph_width + px.x;
    if (i >= u_ph_count) return;
    vec3 o = texelFetch(u_ph_origin, px, 0).xyz;
    vec3 d = texelFetch(u_ph_dir, px, 0).xyz;
    vec3 P = texelFetch(u_ph_power, px, 0).rgb;
    // the photon's numbers: a hash of (texel, pass, seed), apart from every camera sample's
    Rng rng = rng_init(px, u_pass, u_seed ^ 0x5bd1e995u);
    vec3 sigma = vec3(0.0);
    int n_delta = 0;
    for (int depth = 0; depth <= PHOTON_MAX_BOUNCES; ++depth) {
        BvhHit h;
        if (!bvh_closest(o, d, 0.0, BVH_INF, h)) return;
        if (sigma.x > 0.0 || sigma.y > 0.0 || sigma.z > 0.0) P *= exp(-sigma * h.t);
        Surface s = surface_at(h, d);
        if (!lobe_is_delta(s.lobes)) {
            if (n_delta > 0 && finite_pos(P) && (P.x > 0.0 || P.y > 0.0 || P.z > 0.0)) {
                out_pos = vec4(s.p, 1.0);
                out_dir = vec4(d, 0.0);
                out_power = vec4(P, 0.0);
                out_normal = vec4(s.ng, 0.0);
            }
            return;
        }
        if (depth == PHOTON_MAX_BOUNCES) return;   // out of delta vertices
        vec4 r = rng_next4(rng);
        vec3 wo_l = surface_local(s, -d);
        vec3 wi_l;
        float pdf;
        uint lobe;
        vec3 w = brdf_sample(s.model, s.moff, wo_l, r.xyz, wi_l, pdf, lobe);
        if (!(pdf > 0.0) || !finite_pos(w) || any(isnan(wi_l)) || any(isinf(wi_l))) return;
        vec3 wi = surface_world(s, wi_l);
        if (!surface_valid(s, wi_l, wi)) return;
        P *= w;
        if (!(P.x > 0.0 || P.y > 0.0 || P.z > 0.0)) return;
        ++n_delta;
        if (s.trans) sigma = dot(s.ng_raw, wi) < 0.0 ? u_mat_info[2 * s.mi + 1].xyz : vec3(0.0);
        o = surface_offset(s, wi);
        d = wi;
    }
}
