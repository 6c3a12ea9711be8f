// A ray's hit in the path tracer's shading conventions (the module docstring of
// viewer/pathtracer/integrator.py; passes/pathtrace.frag computes the same inline): the point,
// the interpolated shading normal flipped to the ray's side on opaque surfaces, the geometric
// normal on the shading normal's side, the tangent frame of forward.frag, the material and the
// ray offset eps. Included after brdf/dispatch.glsl and common/bvh.glsl by passes that read
// u_mat_info (the photon pass).
#include "generated/constants.glsl"
struct Surface {
    vec3 p;
    vec3 n;        // shading normal (flipped toward the ray on opaque surfaces)
    vec3 ng;       // geometric normal on n's side
    vec3 ng_raw;   // the triangle's winding normal
    vec3 tx;
    vec3 ty;
    int mi;        // material index
    int model;
    int moff;      // float offset of its parameters in u_mat_tex
    uint lobes;
    bool trans;
    float eps;     // ray offset EPS_REL (1 + max|p|)
};

Surface surface_at(BvhHit h, vec3 d) {
    Surface s;
    int k = h.tri;
    vec3 v0 = bvh_vertex(k, 0), v1 = bvh_vertex(k, 1), v2 = bvh_vertex(k, 2);
    float bw = 1.0 - h.uv.x - h.uv.y;
    s.p = bw * v0 + h.uv.x * v1 + h.uv.y * v2;
    vec3 ngc = cross(v1 - v0, v2 - v0);
    float lng = length(ngc);
    s.ng_raw = lng > 0.0 ? ngc / lng : vec3(0.0);
    vec3 n = bw * bvh_vertex_normal(k, 0) + h.uv.x * bvh_vertex_normal(k, 1) + h.uv.y * bvh_vertex_normal(k, 2);
    float ln = length(n);
    n = ln > 1e-30 ? n / ln : s.ng_raw;
    vec4 tan = bw * bvh_vertex_tangent(k, 0) + h.uv.x * bvh_vertex_tangent(k, 1) + h.uv.y * bvh_vertex_tangent(k, 2);
    s.mi = bvh_material(k);
    vec4 info = u_mat_info[2 * s.mi];
    s.model = int(info.x + 0.5);
    s.moff = int(info.y + 0.5);
    s.lobes = uint(info.z + 0.5);
    s.trans = info.w > 0.5;
    if (dot(d, s.ng_raw) > 0.0 && !s.trans) n = -n;
    s.n = n;
    s.ng = dot(s.ng_raw, n) < 0.0 ? -s.ng_raw : s.ng_raw;
    vec3 tx = tan.xyz - n * dot(n, tan.xyz);
    float l2 = dot(tx, tx);
    if (l2 > 1e-12) tx *= inversesqrt(l2);
    else tx = normalize(cross(n, abs(n.x) < 0.9 ? vec3(1.0, 0.0, 0.0) : vec3(0.0, 1.0, 0.0)));
    s.tx = tx;
    s.ty = cross(n, tx) * (tan.w < 0.0 ? -1.0 : 1.0);
    s.eps = EPS_REL * (1.0 + max(max(abs(s.p.x), abs(s.p.y)), abs(s.p.z)));
    return s;
}

vec3 surface_local(Surface s, vec3 w) { return vec3(dot(w, s.tx), dot(w, s.ty), dot(w, s.n)); }
vec3 surface_world(Surface s, vec3 wl) { return wl.x * s.tx + wl.y * s.ty + wl.z * s.n; }

// The rasterizer's light test for a world direction w (local wl): shading and geometric cosine
// on one side (both positive on a surface that does not transmit).
bool surface_valid(Surface s, vec3 wl, vec3 w) {
    float g = dot(s.ng, w);
    return s.trans ? wl.z * g > 0.0 : (wl.z > 0.0 && g > 0.0);
}

// A ray leaving s along w starts eps off the surface on the side w leaves.
vec3 surface_offset(Surface s, vec3 w) { return s.p + s.eps * (dot(s.ng, w) < 0.0 ? -1.0 : 1.0) * s.ng; }
