// The caustic photon map's density estimate (the PHOTONS variant of passes/pathtrace.frag,
// included there after the BRDF dispatch and the BVH): at a vertex that is not a pure delta
// surface the reflected radiance of the caustic photons within radius r,
//   L = sum_p f(x, wo, wi_p) Phi_p / (pi r^2),   wi_p = -(the photon's direction of travel),
// over photons whose normal is compatible with the vertex's geometric one (|dot| >= PHOTON_NORMAL_COS) and whose
// direction passes the rasterizer's light test there (as next-event estimation's). The photons
// of this pass lie in the uniform hash grid of viewer.reference_common.caustics (PhotonGrid):
// cell c = floor(x / u_grid_cell) lives in bucket hash(c) & (u_grid_slots - 1), whose texel of
// u_grid_table holds (first photon, photon count) of the photons sorted by bucket in u_gph_pos
// (position), u_gph_dir (direction of travel), u_gph_pow (power) and u_gph_nrm (normal); a
// lookup visits the 27 cells around p's (the cell is r wide), each bucket once.
// Included by passes/pathtrace.frag before pathtrace/spectral.glsl.
#include "generated/constants.glsl"
uniform sampler2D u_grid_table;
uniform sampler2D u_gph_pos;
uniform sampler2D u_gph_dir;
uniform sampler2D u_gph_pow;
uniform sampler2D u_gph_nrm;
uniform float u_grid_cell;    // the cell size: this pass's radius
uniform int u_grid_slots;     // buckets (a power of two)
uniform float u_ph_r2;        // this pass's radius squared
uniform int u_ph_stored;      // photons stored this pass (0: nothing to gather)

ivec2 ph_texel(int i) { return ivec2(i & 4095, i >> 12); }

// the bucket of cell c: caustics.hash_cells (Teschner et al. 2003) in uint arithmetic (int to uint
// keeps the bits, as numpy's int64 to uint32 wraps)
int grid_slot(ivec3 c) {
    uint h = (uint(c.x) * PHOTON_HASH_P1) ^ (uint(c.y) * PHOTON_HASH_P2) ^ (uint(c.z) * PHOTON_HASH_P3);
    return int(h & uint(u_grid_slots - 1));
}

// What the per-photon term needs of the vertex: the material's model and parameter offset, wo in
// the local frame; SPECTRAL: spec = (category, parameter set, set at lambda_3) and hmask, as
// spec_eval takes them; PHOTON_WAVELENGTHS: ms = the material's u_mat_spec (category, _, offset
// of the per-bin sets, floats per set). A variant's unused fields cost nothing.
struct PhotonVertex { int model; int moff; vec3 wo_l; ivec3 spec; vec4 hmask; vec4 ms; };

// photon_term(v, wl, power): one photon's share of the sum (before the kernel's 1 / (pi r^2)),
// wl its incoming direction in the vertex's local frame, power as stored. One variant a program.
#if defined(PHOTON_WAVELENGTHS)
// Photons of one wavelength each (power = (spectral flux, bin, 0)): f(lambda_p) Phi(lambda_p) times
// W(lambda_p) (row 1 of u_spec_tab) as RGB; f of a non-spectral material upsampled at the bin, of a
// spectral one with its set at the bin.
uniform sampler2D u_spec_tab;
#define PhotonSum vec3
vec3 photon_term(PhotonVertex v, vec3 wl, vec3 power) {
    bool rgb_mat = v.ms.x < 0.5;
    int b = int(power.y + 0.5);
    vec3 f = clean(brdf_eval(v.model, rgb_mat ? v.moff : int(v.ms.z + 0.5) + b * int(v.ms.w + 0.5), wl, v.wo_l));
    float fb = rgb_mat ? dot(texelFetch(u_spec_tab, ivec2(b, 0), 0).rgb, f) : f.x;
    return (fb * power.x) * texelFetch(u_spec_tab, ivec2(b, 1), 0).rgb;
}
#elif defined(SPECTRAL)
// RGB power upsampled, f at the path's four wavelengths: the spectral estimator's evaluation
// (pathtrace/spectral.glsl, included after this file)
vec4 spec_eval(int cat, int model, int o_s, int o_3, vec4 hmask, vec3 wi, vec3 wo);
vec4 spec_up(vec3 rgb);
#define PhotonSum vec4
vec4 photon_term(PhotonVertex v, vec3 wl, vec3 power) {
    return spec_eval(v.spec.x, v.model, v.spec.y, v.spec.z, v.hmask, wl, v.wo_l) * spec_up(power);
}
#else
#define PhotonSum vec3
vec3 photon_term(PhotonVertex v, vec3 wl, vec3 power) {
    return clean(brdf_eval(v.model, v.moff, wl, v.wo_l)) * power;
}
#endif

// The walk over the photons near p: sum_p photon_term over the 27 cells around p's cell (each
// bucket once: two cells that share a bucket count once, found by hashing the earlier cells again,
// which costs less on software GL than an array of the buckets seen) and the photons of each
// bucket within r whose normal passes the test against ng (the geometric normal at p) and whose
// direction passes the rasterizer's light test there (as next-event estimation's).
PhotonSum photon_walk(vec3 p, vec3 n, vec3 ng, vec3 tx, vec3 ty, bool trans, PhotonVertex v) {
    PhotonSum sum = PhotonSum(0.0);
    if (u_ph_stored <= 0) return sum;
    ivec3 base = ivec3(floor(p / u_grid_cell)) - 1;
    for (int cell = 0; cell < 27; ++cell) {
        int slot = grid_slot(base + ivec3(cell % 3, (cell / 3) % 3, cell / 9));
        bool dup = false;
        for (int k = 0; k < cell; ++k) dup = dup || grid_slot(base + ivec3(k % 3, (k / 3) % 3, k / 9)) == slot;
        if (dup) continue;
        vec2 sc = texelFetch(u_grid_table, ph_texel(slot), 0).xy;
        int first = int(sc.x + 0.5), end = first + int(sc.y + 0.5);
        for (int j = first; j < end; ++j) {
            ivec2 t = ph_texel(j);
            vec3 q = texelFetch(u_gph_pos, t, 0).xyz - p;
            if (dot(q, q) >= u_ph_r2) continue;
            if (abs(dot(texelFetch(u_gph_nrm, t, 0).xyz, ng)) < PHOTON_NORMAL_COS) continue;
            vec3 wi = -texelFetch(u_gph_dir, t, 0).xyz;
            vec3 wl = vec3(dot(wi, tx), dot(wi, ty), dot(wi, n));
            float g = dot(ng, wi);
            if (!(trans ? wl.z * g > 0.0 : (wl.z > 0.0 && g > 0.0))) continue;
            sum += photon_term(v, wl, texelFetch(u_gph_pow, t, 0).rgb);
        }
    }
    return sum;
}

#ifdef PHOTON_WAVELENGTHS
// The photons' estimate as RGB: sum_p f(lambda_p) Phi(lambda_p) / (pi r^2) times SPEC_N_BINS
// W(lambda_p), the one-sample estimate of sum_lambda W L for a bin of probability 1 / SPEC_N_BINS.
// The CPU engine's CausticMap gather with wavelengths; the caller multiplies by the path's mean
// throughput.
vec3 photon_gather_rgb(vec3 p, vec3 n, vec3 ng, vec3 tx, vec3 ty, bool trans, int model, int moff, vec3 wo_l,
                       vec4 ms) {
    return photon_walk(p, n, ng, tx, ty, trans, PhotonVertex(model, moff, wo_l, ivec3(0), vec4(0.0), ms))
           * (float(SPEC_N_BINS) / (PI * u_ph_r2));
}
#else
// The photons' estimate at p: sum_p f(wo, wi_p) Phi_p / (pi r^2). RGB: f from brdf_eval; SPECTRAL:
// f at the path's four wavelengths (spec_eval with spec = (category, parameter set, set at
// lambda_3) and hmask) times the upsampled RGB power.
PhotonSum photon_gather(vec3 p, vec3 n, vec3 ng, vec3 tx, vec3 ty, bool trans, int model, int moff, vec3 wo_l,
                        ivec3 spec, vec4 hmask) {
    return photon_walk(p, n, ng, tx, ty, trans, PhotonVertex(model, moff, wo_l, spec, hmask, vec4(0.0)))
           * (1.0 / (PI * u_ph_r2));
}
#endif
