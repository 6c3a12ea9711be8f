// Ray queries against the scene's BVH in float textures (OpenGL 4.1: texelFetch only).
// Layout: viewer/pathtracer/bvh_flat.py; upload and binding: viewer/gl/scene_textures.py.
//
//   bool bvh_closest(vec3 o, vec3 d, float tmin, float tmax, out BvhHit hit);
//   bool bvh_occluded(vec3 o, vec3 d, float tmin, float tmax);
//
// A hit lies at o + t d with tmin < t < tmax (d need not be unit) and at
// (1 - u - v) v0 + u v1 + v v2 of triangle hit.tri, an index into the *reordered* triangles
// (bvh_prim(k) gives the scene geometry's index, bvh_material(k) its material). The closest-hit
// query visits the nearer child first and skips a stacked node whose entry lies beyond the hit
// found so far; the any-hit query stops at the first hit.
//
// Box test: slabs with the exit distance enlarged by 1 + 2 gamma(3) of float32 (Ize 2013,
// "Robust BVH Ray Traversal", JCGT 2(2)), so rounding never culls a box the ray touches; a zero
// direction component is replaced by +-1e-30 (no division by zero, whose result GLSL leaves
// undefined). Triangle test: the watertight test of Woop, Benthin and Wald 2013 (JCGT 2(1)), as
// in the CPU numba kernel, in float32 (no 64-bit fallback for exactly-zero edge
// functions: that costs at most a hit exactly on an edge, which the neighbour then takes).

uniform sampler2D u_bvh_nodes;    // 2 texels per node
uniform sampler2D u_bvh_tris;     // 3 texels per triangle: (v0, prim) (v1, material) (v2, object)
uniform sampler2D u_tri_shading;  // 6 texels per triangle: n0 n1 n2 (w 0), t0 t1 t2 (w sign)
uniform int u_bvh_n_tris;         // 0: an empty scene (every ray misses)

// BVH_STACK (generated/constants.glsl) is bvh_flat.STACK_SIZE
#include "generated/constants.glsl"
const float BVH_INF = 3.0e38;
const float BVH_BOX_PAD = 1.0 + 2.0 * (3.0 * 5.9604645e-8 / (1.0 - 3.0 * 5.9604645e-8));

// texel i of a texture TEX_WIDTH = 4096 wide (bvh_flat.TEX_WIDTH)
ivec2 bvh_texel(int i) { return ivec2(i & 4095, i >> 12); }

vec3 bvh_vertex(int k, int c) { return texelFetch(u_bvh_tris, bvh_texel(3 * k + c), 0).xyz; }
int bvh_prim(int k) { return floatBitsToInt(texelFetch(u_bvh_tris, bvh_texel(3 * k), 0).w); }
int bvh_material(int k) { return floatBitsToInt(texelFetch(u_bvh_tris, bvh_texel(3 * k + 1), 0).w); }
int bvh_object(int k) { return floatBitsToInt(texelFetch(u_bvh_tris, bvh_texel(3 * k + 2), 0).w); }
vec3 bvh_vertex_normal(int k, int c) { return texelFetch(u_tri_shading, bvh_texel(6 * k + c), 0).xyz; }
vec4 bvh_vertex_tangent(int k, int c) { return texelFetch(u_tri_shading, bvh_texel(6 * k + 3 + c), 0); }

struct BvhHit {
    float t;
    int tri;      // reordered triangle index, -1 on a miss
    vec2 uv;      // barycentrics of v1 and v2
};

struct BvhRay {
    vec3 o;
    vec3 inv;     // 1 / d (zero components replaced)
    ivec3 k;      // Woop's kx, ky, kz
    vec3 S;       // shear constants Sx, Sy, Sz
};

BvhRay bvh_ray(vec3 o, vec3 d) {
    BvhRay r;
    r.o = o;
    vec3 dd = vec3(abs(d.x) > 1e-30 ? d.x : (d.x < 0.0 ? -1e-30 : 1e-30),
                   abs(d.y) > 1e-30 ? d.y : (d.y < 0.0 ? -1e-30 : 1e-30),
                   abs(d.z) > 1e-30 ? d.z : (d.z < 0.0 ? -1e-30 : 1e-30));
    r.inv = 1.0 / dd;
    // kz = the dimension where |d| is largest; kx, ky follow cyclically, swapped when d[kz] < 0
    vec3 ad = abs(d);
    int kz = (ad.x > ad.y && ad.x > ad.z) ? 0 : (ad.y > ad.z ? 1 : 2);
    int kx = kz == 2 ? 0 : kz + 1;
    int ky = kx == 2 ? 0 : kx + 1;
    if (d[kz] < 0.0) { int s = kx; kx = ky; ky = s; }
    r.k = ivec3(kx, ky, kz);
    r.S = vec3(d[kx] / d[kz], d[ky] / d[kz], 1.0 / d[kz]);
    return r;
}

// entry distance of node m's box within (tmin, tmax), BVH_INF when missed
float bvh_box(int m, BvhRay r, float tmin, float tmax) {
    vec3 lo = texelFetch(u_bvh_nodes, bvh_texel(2 * m), 0).xyz;
    vec3 hi = texelFetch(u_bvh_nodes, bvh_texel(2 * m + 1), 0).xyz;
    vec3 t0 = (lo - r.o) * r.inv;
    vec3 t1 = (hi - r.o) * r.inv;
    vec3 tn = min(t0, t1);
    vec3 tf = max(t0, t1) * BVH_BOX_PAD;
    float enter = max(max(tn.x, tn.y), max(tn.z, tmin));
    float leave = min(min(tf.x, tf.y), min(tf.z, tmax));
    return enter <= leave ? enter : BVH_INF;
}

// Woop et al. 2013: t and (u, v) of triangle k if hit within (tmin, tmax)
bool bvh_triangle(int k, BvhRay r, float tmin, float tmax, out float t, out vec2 uv) {
    vec3 a = bvh_vertex(k, 0) - r.o;
    vec3 b = bvh_vertex(k, 1) - r.o;
    vec3 c = bvh_vertex(k, 2) - r.o;
    a = vec3(a[r.k.x], a[r.k.y], a[r.k.z]);
    b = vec3(b[r.k.x], b[r.k.y], b[r.k.z]);
    c = vec3(c[r.k.x], c[r.k.y], c[r.k.z]);
    float Ax = a.x - r.S.x * a.z, Ay = a.y - r.S.y * a.z;
    float Bx = b.x - r.S.x * b.z, By = b.y - r.S.y * b.z;
    float Cx = c.x - r.S.x * c.z, Cy = c.y - r.S.y * c.z;
    float U = Cx * By - Cy * Bx;
    float V = Ax * Cy - Ay * Cx;
    float W = Bx * Ay - By * Ax;
    t = 0.0;
    uv = vec2(0.0);
    if ((U < 0.0 || V < 0.0 || W < 0.0) && (U > 0.0 || V > 0.0 || W > 0.0)) return false;
    float det = U + V + W;
    if (det == 0.0) return false;
    float T = U * (r.S.z * a.z) + V * (r.S.z * b.z) + W * (r.S.z * c.z);
    t = T / det;
    if (!(t > tmin && t < tmax)) return false;
    uv = vec2(V, W) / det;
    return true;
}

// the shared traversal: closest hit (any_hit false) or the first hit found (true)
bool bvh_trace(vec3 o, vec3 d, float tmin, float tmax, bool any_hit, out BvhHit hit) {
    hit.t = BVH_INF;
    hit.tri = -1;
    hit.uv = vec2(0.0);
    if (u_bvh_n_tris == 0 || !(tmax > tmin)) return false;
    BvhRay r = bvh_ray(o, d);
    if (bvh_box(0, r, tmin, tmax) == BVH_INF) return false;
    int stack_node[BVH_STACK];
    float stack_t[BVH_STACK];
    int sp = 0;
    int node = 0;
    float best = tmax;
    bool have = true;
    while (have) {
        vec4 a = texelFetch(u_bvh_nodes, bvh_texel(2 * node), 0);
        int cnt = floatBitsToInt(texelFetch(u_bvh_nodes, bvh_texel(2 * node + 1), 0).w);
        int first = floatBitsToInt(a.w);
        int next = -1;
        if (cnt > 0) {
            for (int k = first; k < first + cnt; ++k) {
                float t;
                vec2 uv;
                if (bvh_triangle(k, r, tmin, best, t, uv)) {
                    best = t;
                    hit.t = t;
                    hit.tri = k;
                    hit.uv = uv;
                    if (any_hit) return true;
                }
            }
        } else {
            float t0 = bvh_box(first, r, tmin, best);
            float t1 = bvh_box(first + 1, r, tmin, best);
            if (t0 < BVH_INF && t1 < BVH_INF) {
                bool near0 = t0 <= t1;
                stack_node[sp] = near0 ? first + 1 : first;
                stack_t[sp] = near0 ? t1 : t0;
                ++sp;
                next = near0 ? first : first + 1;
            } else if (t0 < BVH_INF) {
                next = first;
            } else if (t1 < BVH_INF) {
                next = first + 1;
            }
        }
        if (next >= 0) {
            node = next;
            continue;
        }
        have = false;
        while (sp > 0) {
            --sp;
            if (stack_t[sp] < best) {   // else it was entered beyond the closest hit found since
                node = stack_node[sp];
                have = true;
                break;
            }
        }
    }
    return hit.tri >= 0;
}

bool bvh_closest(vec3 o, vec3 d, float tmin, float tmax, out BvhHit hit) {
    return bvh_trace(o, d, tmin, tmax, false, hit);
}

bool bvh_occluded(vec3 o, vec3 d, float tmin, float tmax) {
    BvhHit h;
    return bvh_trace(o, d, tmin, tmax, true, h);
}
