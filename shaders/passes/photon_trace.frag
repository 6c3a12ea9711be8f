#version 410 core
// The photon pass of the `photon` integrator (viewer/gpupt/photons.py), the CPU engine's photon
// tracing (viewer/pathtracer/photons.py) step for step: one photon per fragment of a target
// TEX_WIDTH texels wide. A photon's state comes from four float textures: (origin, its index),
// (direction of travel, delta vertices passed), (power, random numbers drawn), (sigma_a of the
// medium it is in); a new photon is the CPU's emission (viewer.reference_common.caustics.
// emit_photons) with the rest zero. It is traced over the scene's BVH: inside an absorbing
// dielectric each segment is attenuated by exp(-sigma_a t) (Bouguer); at a material with a
// smooth lobe a photon that has passed a delta vertex is stored (out_pos = (position, 1),
// out_dir = its direction of travel, out_power, out_normal = the winding normal: the gather's
// normal test takes |dot|); at a material with a delta lobe the material's sampler
// (brdf_sample) draws the next direction and the photon goes on only where it drew a delta
// lobe, its power times the sample's weight; Russian roulette from the PHOTON_RR_START-th
// delta vertex on (survival max(weight) clamped to [RR_MIN, RR_MAX], survivors divided by it);
// at most PHOTON_MAX_BOUNCES delta vertices. A material with both (a coat over a mirror) stores
// and sends on: one fragment writes one stored photon, so there the fragment ends and writes
// the photon's new state (out_state*, w of the first = 1), which the host traces in the next
// round (until no photon goes on).
//
// Random numbers: a hash of (the photon's index, pass, seed), one block of four per scattering
// (xyz the sampler's, w roulette's), the count carried across rounds.
//
// PHOTON_WAVELENGTHS (a define; viewer.reference_common.caustics.spectral_photons): a photon
// carries one wavelength bin, its state2 = (spectral flux, bin, 0, random blocks): a non-spectral
// material's RGB weight and the Bouguer transmittance are upsampled at the bin (row 0 of
// u_spec_tab), a spectral material samples with its parameter set at the bin (u_mat_spec.z + bin
// stride, channel 0: n(lambda) for a dispersive dielectric), as the CPU engine's PhotonSpectra;
// it is stored as (spectral flux, bin, 0).
//
// Radiance and flux: a delta sampler's weight is the radiance-mode one (refraction scales by
// 1 / eta^2 of the side the radiance arrives on); a photon that enters and leaves a closed
// dielectric takes eta^2 and 1 / eta^2, which cancel, and photons are stored only outside
// dielectrics (objects are closed and not nested), so the weights carry flux unchanged.
#include "generated/constants.glsl"
#include "brdf/dispatch.glsl"
#include "common/bvh.glsl"
#include "common/rng.glsl"

uniform vec4 u_mat_info[2 * MAX_MATERIALS];
#include "pathtrace/surface.glsl"

#ifdef PHOTON_WAVELENGTHS
uniform sampler2D u_spec_tab;      // row 0: the upsampling basis at each bin (pathtrace/spectral.glsl)
uniform vec4 u_mat_spec[MAX_MATERIALS];
float ph_up(vec3 rgb, int b) { return dot(texelFetch(u_spec_tab, ivec2(b, 0), 0).rgb, rgb); }
#endif

uniform sampler2D u_ph_state0;   // xyz origin, w the photon's index
uniform sampler2D u_ph_state1;   // xyz unit direction of travel, w delta vertices passed
uniform sampler2D u_ph_state2;   // rgb power, w random blocks drawn
uniform sampler2D u_ph_state3;   // rgb sigma_a of the medium it is in
uniform int u_ph_count;
uniform int u_ph_width;
uniform uint u_seed;
uniform uint u_pass;

layout(location = 0) out vec4 out_pos;
layout(location = 1) out vec4 out_dir;
layout(location = 2) out vec4 out_power;
layout(location = 3) out vec4 out_normal;
layout(location = 4) out vec4 out_state0;   // (origin, 1 = goes on)
layout(location = 5) out vec4 out_state1;
layout(location = 6) out vec4 out_state2;
layout(location = 7) out vec4 out_state3;   // (sigma_a, its index)

bool finite_pos(vec3 v) {
    return !(any(isnan(v)) || any(isinf(v))) && v.x >= 0.0 && v.y >= 0.0 && v.z >= 0.0;
}

void main() {
    ivec2 px = ivec2(gl_FragCoord.xy);
    out_pos = vec4(0.0);
    out_dir = vec4(0.0);
    out_power = vec4(0.0);
    out_normal = vec4(0.0);
    out_state0 = vec4(0.0);
    out_state1 = vec4(0.0);
    out_state2 = vec4(0.0);
    out_state3 = vec4(0.0);
    int i = px.y * u_ph_width + px.x;
    if (i >= u_ph_count) return;
    vec4 s0 = texelFetch(u_ph_state0, px, 0), s1 = texelFetch(u_ph_state1, px, 0);
    vec4 s2 = texelFetch(u_ph_state2, px, 0);
    vec3 o = s0.xyz, d = s1.xyz, P = s2.rgb;
    vec3 sigma = texelFetch(u_ph_state3, px, 0).rgb;
    int index = int(s0.w + 0.5);
    int n_delta = int(s1.w + 0.5);
    // the photon's numbers: a hash of (its index, pass, seed), apart from every camera sample's
    Rng rng = rng_init(ivec2(index & 4095, index >> 12), u_pass, u_seed ^ 0x5bd1e995u);
    rng.dim = uint(s2.w + 0.5);
    for (int k = 0; k <= PHOTON_MAX_BOUNCES; ++k) {   // each round adds a delta vertex
        BvhHit h;
        if (!bvh_closest(o, d, 0.0, BVH_INF, h)) return;
#ifdef PHOTON_WAVELENGTHS
        int bin = int(P.y + 0.5);
        if (sigma.x > 0.0 || sigma.y > 0.0 || sigma.z > 0.0) P.x *= ph_up(exp(-sigma * h.t), bin);
#else
        if (sigma.x > 0.0 || sigma.y > 0.0 || sigma.z > 0.0) P *= exp(-sigma * h.t);
#endif
        Surface s = surface_at(h, d);
        bool stored = false;
        if (!lobe_is_delta(s.lobes) && n_delta > 0) {   // a smooth lobe: stored
            stored = true;
            out_pos = vec4(s.p, 1.0);
            out_dir = vec4(d, 0.0);
            out_power = vec4(P, 0.0);
            out_normal = vec4(s.ng_raw, 0.0);
        }
        if (!lobe_has_delta(s.lobes) || n_delta >= PHOTON_MAX_BOUNCES) return;
        vec4 r = rng_next4(rng);
        vec3 wo_l = surface_local(s, -d);
        vec3 wi_l;
        float pdf;
        uint lobe;
#ifdef PHOTON_WAVELENGTHS
        vec4 ms = u_mat_spec[s.mi];
        bool rgb_mat = ms.x < 0.5;
        int off = rgb_mat ? s.moff : int(ms.z + 0.5) + bin * int(ms.w + 0.5);
        vec3 w3 = brdf_sample(s.model, off, wo_l, r.xyz, wi_l, pdf, lobe);
        vec3 w = vec3(rgb_mat ? ph_up(w3, bin) : w3.x);
#else
        vec3 w = brdf_sample(s.model, s.moff, wo_l, r.xyz, wi_l, pdf, lobe);
#endif
        if (!lobe_has_delta(lobe) || !(pdf > 0.0) || !finite_pos(w) || any(isnan(wi_l)) || any(isinf(wi_l)))
            return;
        vec3 wi = surface_world(s, wi_l);
        if (!surface_valid(s, wi_l, wi) || !(w.x > 0.0 || w.y > 0.0 || w.z > 0.0)) return;
        ++n_delta;
        if (n_delta >= PHOTON_RR_START) {
            float q = clamp(max(max(w.x, w.y), w.z), RR_MIN, RR_MAX);
            if (!(r.w < q)) return;
            w /= q;
        }
#ifdef PHOTON_WAVELENGTHS
        P.x *= w.x;
#else
        P *= w;
#endif
        if (s.trans) sigma = dot(s.ng_raw, wi) < 0.0 ? u_mat_info[2 * s.mi + 1].xyz : vec3(0.0);
        o = surface_offset(s, wi);
        d = wi;
        if (stored) {   // stored here and goes on: the next round traces it further
            out_state0 = vec4(o, 1.0);
            out_state1 = vec4(d, float(n_delta));
            out_state2 = vec4(P, float(rng.dim));
            out_state3 = vec4(sigma, float(index));
            return;
        }
    }
}
