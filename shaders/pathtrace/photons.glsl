// The caustic photon map's density estimate (the PHOTONS variant of passes/pathtrace.frag,
// included there after the BRDF dispatch and the BVH): at a vertex that is not a pure delta
// surface the reflected radiance of the caustic photons within radius r,
//   L = sum_p f(x, wo, wi_p) Phi_p / (pi r^2),   wi_p = -(the photon's direction of travel),
// over photons whose normal is compatible with the vertex's (dot > PHOTON_NORMAL_COS) and whose
// direction passes the rasterizer's light test there (as next-event estimation's). The photons
// of this pass lie in a uniform hash grid built on the CPU (viewer.reference_common.caustics):
// cell c = floor((x - u_grid_lo) / u_grid_cell) lives in slot hash(c) mod u_grid_slots, whose
// texel of u_grid_table holds (first photon, photon count) of the photons sorted by slot in
// u_gph_pos (xyz position), u_gph_dir (direction of travel), u_gph_pow (power), u_gph_nrm.
uniform sampler2D u_grid_table;
uniform sampler2D u_gph_pos;
uniform sampler2D u_gph_dir;
uniform sampler2D u_gph_pow;
uniform sampler2D u_gph_nrm;
uniform vec3 u_grid_lo;
uniform float u_grid_cell;
uniform int u_grid_slots;
uniform float u_ph_r2;        // this pass's radius squared
uniform int u_ph_stored;      // photons stored this pass (0: nothing to gather)

#ifndef PHOTON_NORMAL_COS
#define PHOTON_NORMAL_COS 0.9
#endif

ivec2 ph_texel(int i) { return ivec2(i & 4095, i >> 12); }

int grid_slot(ivec3 c) {
    // Teschner et al. 2003, "Optimized Spatial Hashing for Collision Detection of Deformable Objects"
    uint h = (uint(c.x) * 73856093u) ^ (uint(c.y) * 19349663u) ^ (uint(c.z) * 83492791u);
    return int(h % uint(u_grid_slots));
}

vec3 photon_gather(vec3 p, vec3 n, vec3 ng, vec3 tx, vec3 ty, bool trans, int model, int moff, vec3 wo_l) {
    if (u_ph_stored <= 0) return vec3(0.0);
    float r = sqrt(u_ph_r2);
    ivec3 c0 = ivec3(floor((p - r - u_grid_lo) / u_grid_cell));
    ivec3 c1 = ivec3(floor((p + r - u_grid_lo) / u_grid_cell));
    c1 = min(c1, c0 + 2);     // the cell is at least r wide: at most 3 per axis
    vec3 sum = vec3(0.0);
    int seen[27];             // slots already visited: two cells that share a slot count once
    int n_seen = 0;
    for (int z = c0.z; z <= c1.z; ++z)
    for (int y = c0.y; y <= c1.y; ++y)
    for (int x = c0.x; x <= c1.x; ++x) {
        int slot = grid_slot(ivec3(x, y, z));
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
            if (dot(texelFetch(u_gph_nrm, t, 0).xyz, n) <= PHOTON_NORMAL_COS) continue;
            vec3 wi = -texelFetch(u_gph_dir, t, 0).xyz;
            vec3 wl = vec3(dot(wi, tx), dot(wi, ty), dot(wi, n));
            float g = dot(ng, wi);
            if (!(trans ? wl.z * g > 0.0 : (wl.z > 0.0 && g > 0.0))) continue;
            sum += clean(brdf_eval(model, moff, wl, wo_l)) * texelFetch(u_gph_pow, t, 0).rgb;
        }
    }
    return sum * (1.0 / (PI * u_ph_r2));
}
