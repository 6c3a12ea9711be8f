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

// The photons near p, one per call of photon_next: an iterator over the 27 cells around p's
// (each bucket once: two cells that share one count once) and the photons of each bucket within
// r whose normal passes the test against ng (the geometric normal at p) and whose direction
// passes the rasterizer's light test there (as next-event estimation's).
struct PhotonIter {
    ivec3 base;      // p's cell
    int cell;        // the next of the 27 cells
    int j, end;      // the photons of the current bucket still to visit
    int seen[27];    // buckets visited
    int n_seen;
};

PhotonIter photon_iter(vec3 p) {
    PhotonIter it;
    it.base = ivec3(floor(p / u_grid_cell));
    it.cell = 0;
    it.j = 0;
    it.end = u_ph_stored > 0 ? 0 : -1;   // -1: nothing to visit
    it.n_seen = 0;
    return it;
}

// the next photon: its direction wl toward where it came from (local frame tx, ty, n) and power
bool photon_next(inout PhotonIter it, vec3 p, vec3 n, vec3 ng, vec3 tx, vec3 ty, bool trans,
                 out vec3 wl, out vec3 power) {
    wl = vec3(0.0, 0.0, 1.0);
    power = vec3(0.0);
    if (it.end < 0) return false;
    for (int guard = 0; guard < 1 << 30; ++guard) {
        if (it.j >= it.end) {                       // the next bucket not yet visited
            if (it.cell >= 27) return false;
            ivec3 c = it.base + ivec3(it.cell % 3, (it.cell / 3) % 3, it.cell / 9) - 1;
            ++it.cell;
            int slot = grid_slot(c);
            bool dup = false;
            for (int k = 0; k < it.n_seen; ++k) dup = dup || it.seen[k] == slot;
            if (dup) continue;
            it.seen[it.n_seen++] = slot;
            vec2 sc = texelFetch(u_grid_table, ph_texel(slot), 0).xy;
            it.j = int(sc.x + 0.5);
            it.end = it.j + int(sc.y + 0.5);
            continue;
        }
        ivec2 t = ph_texel(it.j++);
        vec3 q = texelFetch(u_gph_pos, t, 0).xyz - p;
        if (dot(q, q) >= u_ph_r2) continue;
        if (abs(dot(texelFetch(u_gph_nrm, t, 0).xyz, ng)) < PHOTON_NORMAL_COS) continue;
        vec3 wi = -texelFetch(u_gph_dir, t, 0).xyz;
        wl = vec3(dot(wi, tx), dot(wi, ty), dot(wi, n));
        float g = dot(ng, wi);
        if (!(trans ? wl.z * g > 0.0 : (wl.z > 0.0 && g > 0.0))) continue;
        power = texelFetch(u_gph_pow, t, 0).rgb;
        return true;
    }
    return false;
}

// the photons' estimate at p (RGB): sum_p f Phi_p / (pi r^2)
vec3 photon_gather(vec3 p, vec3 n, vec3 ng, vec3 tx, vec3 ty, bool trans, int model, int moff, vec3 wo_l) {
    PhotonIter it = photon_iter(p);
    vec3 wl, power, sum = vec3(0.0);
    while (photon_next(it, p, n, ng, tx, ty, trans, wl, power))
        sum += clean(brdf_eval(model, moff, wl, wo_l)) * power;
    return sum * (1.0 / (PI * u_ph_r2));
}
