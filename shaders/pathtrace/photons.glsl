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

// the photons' estimate at p; ng: the geometric normal there (the normal test), the rest as for
// next-event estimation
vec3 photon_gather(vec3 p, vec3 n, vec3 ng, vec3 tx, vec3 ty, bool trans, int model, int moff, vec3 wo_l) {
    if (u_ph_stored <= 0) return vec3(0.0);
    ivec3 base = ivec3(floor(p / u_grid_cell));
    vec3 sum = vec3(0.0);
    int seen[27];             // buckets already visited: two cells that share one count once
    int n_seen = 0;
    for (int z = -1; z <= 1; ++z)
    for (int y = -1; y <= 1; ++y)
    for (int x = -1; x <= 1; ++x) {
        int slot = grid_slot(base + ivec3(x, y, z));
        bool dup = false;
        for (int k = 0; k < n_seen; ++k) dup = dup || seen[k] == slot;
        if (dup) continue;
        seen[n_seen++] = slot;
        vec2 sc = texelFetch(u_grid_table, ph_texel(slot), 0).xy;
        int first = int(sc.x + 0.5), count = int(sc.y + 0.5);
        for (int j = first; j < first + count; ++j) {
            ivec2 t = ph_texel(j);
            vec3 q = texelFetch(u_gph_pos, t, 0).xyz - p;
            if (dot(q, q) >= u_ph_r2) continue;
            if (abs(dot(texelFetch(u_gph_nrm, t, 0).xyz, ng)) < PHOTON_NORMAL_COS) continue;
            vec3 wi = -texelFetch(u_gph_dir, t, 0).xyz;
            vec3 wl = vec3(dot(wi, tx), dot(wi, ty), dot(wi, n));
            float g = dot(ng, wi);
            if (!(trans ? wl.z * g > 0.0 : (wl.z > 0.0 && g > 0.0))) continue;
            sum += clean(brdf_eval(model, moff, wl, wo_l)) * texelFetch(u_gph_pow, t, 0).rgb;
        }
    }
    return sum * (1.0 / (PI * u_ph_r2));
}
