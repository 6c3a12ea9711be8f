#version 410 core
// One pass of the GPU reference path tracer: for every pixel of the row band [u_row0, u_row1),
// u_spp_pass more camera samples added to the running sums (ping-pong: read the previous sums,
// write prev + new); pixels outside the band copy theirs.
//
// The estimator is the CPU engine's (viewer/pathtracer/integrator.py) term for term: camera box
// filter; next-event estimation of point and directional lights (delta lights, no MIS); the
// environment reached by one of three strategies: MIS (sampled by env_sample and reached by BSDF
// sampling, combined by the power heuristic, Veach 1997, eq. 9.13, beta 2, or the balance
// heuristic, eq. 9.10), BSDF sampling only (weight 1) or light sampling only (an escaping BSDF
// ray adds nothing); delta lobes skip NEE and MIS and take the full environment under every
// strategy, as camera rays do; max_depth scattering events; Russian roulette from the 4th event
// on (survival clamp(max(throughput), 0.05, 0.95)) unless NO_ROULETTE; Bouguer exp(-sigma_a t) inside dielectrics. Shading: the
// rasterizer's interpolated normals, back faces flipped for opaque surfaces, light counted where
// both the shading and the geometric cosine are positive (either sign on transmissive surfaces).
// Rays start at p + EPS_REL (1 + max|p|) n_g on the side they leave.
//
// Defines (compile-time variants): ENV_MODE (environment.glsl), N_LIGHTS, and the
// estimator's options: STRATEGY (STRATEGY_MIS, default; _BSDF sampling only; _LIGHT sampling only),
// BALANCE_HEURISTIC (MIS weights by the balance heuristic instead of the power one),
// NO_ROULETTE (every path to max_depth). llvmpipe runs branches a uniform disables, so these
// are variants, compiled only for the options in use.
#include "generated/constants.glsl"
#include "brdf/dispatch.glsl"
#include "common/bvh.glsl"
#include "common/rng.glsl"
#include "pathtrace/environment.glsl"

#ifndef N_LIGHTS
#define N_LIGHTS 0
#endif
#ifndef STRATEGY
#define STRATEGY STRATEGY_MIS
#endif

uniform sampler2D u_prev_sum;     // rgb = sum of radiance, a = number of samples
uniform sampler2D u_prev_sq;      // rgb = sum of squared radiance, a = bad values met
uniform int u_row0;
uniform int u_row1;
uniform int u_spp_pass;
uniform uint u_seed;
uniform int u_max_depth;
uniform ivec2 u_size;
uniform vec3 u_cam_pos;
uniform vec3 u_cam_forward;
uniform vec3 u_cam_right;
uniform vec3 u_cam_up;
uniform float u_tan_half_y;
// per material: (model, float offset into the material texture, its lobes (LOBE_* flags, as a float),
// transmissive), then (sigma_a, 0)
uniform vec4 u_mat_info[2 * MAX_MATERIALS];
#if N_LIGHTS > 0
uniform vec4 u_light_a[N_LIGHTS];   // xyz = position (point) or unit direction of travel; w = 0 point, 1 directional
uniform vec3 u_light_v[N_LIGHTS];   // intensity (point) or irradiance (directional)
#endif

layout(location = 0) out vec4 out_sum;
layout(location = 1) out vec4 out_sq;

float g_bad = 0.0;   // model outputs that were NaN, infinite or negative (a non-zero count is a bug)

float clean(float x) {
    if (isnan(x) || isinf(x) || x < 0.0) { g_bad += 1.0; return 0.0; }
    return x;
}
vec3 clean(vec3 x) { return vec3(clean(x.x), clean(x.y), clean(x.z)); }

// power heuristic a^2 / (a^2 + b^2) without overflowing float32
float power_heuristic(float a, float b) {
    if (!(a > 0.0)) return 0.0;
    if (!(b > 0.0)) return 1.0;
    if (a >= b) { float r = b / a; return 1.0 / (1.0 + r * r); }
    float r = a / b;
    return r * r / (1.0 + r * r);
}

// balance heuristic a / (a + b) without overflowing float32
float balance_heuristic(float a, float b) {
    if (!(a > 0.0)) return 0.0;
    if (!(b > 0.0)) return 1.0;
    if (a >= b) return 1.0 / (1.0 + b / a);
    float r = a / b;
    return r / (1.0 + r);
}

#ifdef BALANCE_HEURISTIC
#define mis_weight balance_heuristic
#else
#define mis_weight power_heuristic
#endif

float max3(vec3 v) { return max(max(v.x, v.y), v.z); }
bool any_pos(vec3 v) { return v.x > 0.0 || v.y > 0.0 || v.z > 0.0; }

// float32 range guards. A model value is capped at F_MAX = e^80 (common/math.glsl), but a path's
// throughput is a product of such values and overflows float32 (the CPU engine carries float64 and
// saturates only its output): products and sums of radiance saturate at F_MAX instead, so inf * 0
// never makes a NaN. Both operands are finite and non-negative here, and nothing below F_MAX changes.
vec3 mul_sat(vec3 a, vec3 b) { return min(min(a, vec3(F_MAX)) * min(b, vec3(F_MAX)), vec3(F_MAX)); }
vec3 add_sat(vec3 a, vec3 b) { return min(a + b, vec3(F_MAX)); }


// PHOTONS (a define): the `photon` integrator, path tracing plus a progressive caustic photon
// map. A caustic path (its light end reached from its last non-delta vertex through one or more
// delta vertices) is the photon map's alone: every vertex that is not a pure delta surface adds
// the photons' density estimate (pathtrace/photons.glsl), and the path tracer drops light
// reached by a delta sample after a vertex that sampled a non-delta lobe.
#ifdef PHOTONS
#include "pathtrace/photons.glsl"
#endif

// SPECTRAL (a define): the hero-wavelength estimator of pathtrace/spectral.glsl replaces trace_path
// in main (the RGB program is unchanged without it)
#ifdef SPECTRAL
#include "pathtrace/spectral.glsl"
#endif

vec3 trace_path(vec3 o, vec3 d, inout Rng rng) {
    vec3 L = vec3(0.0);
    vec3 T = vec3(1.0);
    vec3 sigma = vec3(0.0);
    float prev_pdf = 0.0, prev_lpdf = 0.0;
    bool prev_delta = true;    // camera rays count as delta: the full environment
#ifdef PHOTONS
    bool seen_nd = false;      // some vertex so far sampled a non-delta lobe
#endif
    for (int depth = 1; depth <= u_max_depth + 1; ++depth) {
        BvhHit h;
        if (!bvh_closest(o, d, 0.0, BVH_INF, h)) {
#if ENV_MODE != ENV_MODE_BLACK
#if STRATEGY == STRATEGY_MIS
            float w = prev_delta ? 1.0 : mis_weight(prev_pdf, prev_lpdf);
#elif STRATEGY == STRATEGY_BSDF
            float w = 1.0;
#else
            float w = prev_delta ? 1.0 : 0.0;   // light sampling only: NEE reached it
#endif
#ifdef PHOTONS
            if (prev_delta && seen_nd) w = 0.0;   // a caustic path: the photon map's
#endif
            L = add_sat(L, mul_sat(T, env_eval(d) * w));
#endif
            break;
        }
        if (depth > u_max_depth) break;
        if (any_pos(sigma)) T *= exp(-sigma * h.t);
        vec4 r0 = rng_next4(rng);   // bsdf u (xyz), roulette (w)
        vec4 r1 = rng_next4(rng);   // environment u (xy)
        int k = h.tri;
        vec3 v0 = bvh_vertex(k, 0), v1 = bvh_vertex(k, 1), v2 = bvh_vertex(k, 2);
        float bw = 1.0 - h.uv.x - h.uv.y;
        vec3 p = bw * v0 + h.uv.x * v1 + h.uv.y * v2;
        vec3 ngc = cross(v1 - v0, v2 - v0);
        float lng = length(ngc);
        vec3 ng_raw = lng > 0.0 ? ngc / lng : vec3(0.0);
        vec3 n = bw * bvh_vertex_normal(k, 0) + h.uv.x * bvh_vertex_normal(k, 1) + h.uv.y * bvh_vertex_normal(k, 2);
        float ln = length(n);
        n = ln > 1e-30 ? n / ln : ng_raw;
        vec4 tan = bw * bvh_vertex_tangent(k, 0) + h.uv.x * bvh_vertex_tangent(k, 1) + h.uv.y * bvh_vertex_tangent(k, 2);
        int mi = bvh_material(k);
        vec4 info = u_mat_info[2 * mi];
        int model = int(info.x + 0.5);
        int moff = int(info.y + 0.5);
        uint lobes = uint(info.z + 0.5);
        bool trans = info.w > 0.5;
        if (dot(d, ng_raw) > 0.0 && !trans) n = -n;
        vec3 ng = dot(ng_raw, n) < 0.0 ? -ng_raw : ng_raw;
        // shading frame as forward.frag: t = tangent minus its normal part, b = cross(n, t) sign(w)
        vec3 tx = tan.xyz - n * dot(n, tan.xyz);
        float l2 = dot(tx, tx);
        if (l2 > 1e-12) tx *= inversesqrt(l2);
        else tx = normalize(cross(n, abs(n.x) < 0.9 ? vec3(1.0, 0.0, 0.0) : vec3(0.0, 1.0, 0.0)));
        vec3 ty = cross(n, tx) * (tan.w < 0.0 ? -1.0 : 1.0);
        vec3 wo = -d;
        vec3 wo_l = vec3(dot(wo, tx), dot(wo, ty), dot(wo, n));
        float eps = EPS_REL * (1.0 + max3(abs(p)));

        // ---- next-event estimation (not for pure delta lobes)
        if (!lobe_is_delta(lobes)) {
#if defined(PHOTONS) && !defined(SPECTRAL)
            L = add_sat(L, mul_sat(T, photon_gather(p, n, ng, tx, ty, trans, model, moff, wo_l, ivec3(0), vec4(0.0))));
#endif
#if N_LIGHTS > 0
            for (int j = 0; j < N_LIGHTS; ++j) {
                vec3 wi, val;
                float tmax;
                if (u_light_a[j].w < 0.5) {
                    vec3 dv = u_light_a[j].xyz - p;
                    float r2 = max(dot(dv, dv), 1e-30);
                    float r = sqrt(r2);
                    wi = dv / r;
                    val = u_light_v[j] / r2;
                    tmax = r - eps;
                } else {
                    wi = -u_light_a[j].xyz;
                    val = u_light_v[j];
                    tmax = BVH_INF;
                }
                vec3 wl = vec3(dot(wi, tx), dot(wi, ty), dot(wi, n));
                float g = dot(ng, wi);
                bool ok = trans ? wl.z * g > 0.0 : (wl.z > 0.0 && g > 0.0);
                if (!ok) continue;
                vec3 c = mul_sat(T, clean(brdf_eval(model, moff, wl, wo_l)) * (abs(wl.z) * val));
                if (!any_pos(c)) continue;
                vec3 so = p + eps * (g < 0.0 ? -1.0 : 1.0) * ng;
                if (!bvh_occluded(so, wi, 0.0, tmax)) L = add_sat(L, c);
            }
#endif
#if ENV_MODE != ENV_MODE_BLACK && STRATEGY != STRATEGY_BSDF
            {
                vec3 wi;
                float pe;
                vec3 ev = env_sample(r1.xy, n, trans, wi, pe);
                pe = clean(pe);
                vec3 wl = vec3(dot(wi, tx), dot(wi, ty), dot(wi, n));
                float g = dot(ng, wi);
                bool ok = (trans ? wl.z * g > 0.0 : (wl.z > 0.0 && g > 0.0)) && pe > 0.0;
                if (ok) {
                    vec3 f = clean(brdf_eval(model, moff, wl, wo_l));
#if STRATEGY == STRATEGY_MIS
                    float pb = clean(brdf_pdf(model, moff, wl, wo_l));
                    vec3 c = mul_sat(T, mul_sat(f, abs(wl.z) * ev * (mis_weight(pe, pb) / pe)));
#else
                    vec3 c = mul_sat(T, mul_sat(f, abs(wl.z) * ev * (1.0 / pe)));
#endif
                    if (any_pos(c)) {
                        vec3 so = p + eps * (g < 0.0 ? -1.0 : 1.0) * ng;
                        if (!bvh_occluded(so, wi, 0.0, BVH_INF)) L = add_sat(L, c);
                    }
                }
            }
#endif
        }

        // ---- BSDF sampling
        vec3 wi_l;
        float pdf_s;
        uint lobe;
        vec3 wgt = clean(brdf_sample(model, moff, wo_l, r0.xyz, wi_l, pdf_s, lobe));
        pdf_s = clean(pdf_s);
        if (any(isnan(wi_l)) || any(isinf(wi_l))) { g_bad += 1.0; wi_l = vec3(0.0, 0.0, 1.0); wgt = vec3(0.0); }
        bool disc = lobe_has_delta(lobe);  // drawn discretely: no MIS, the full environment next
        vec3 wi_w = wi_l.x * tx + wi_l.y * ty + wi_l.z * n;
        float gw = dot(ng, wi_w);
        bool ok = (trans ? wi_l.z * gw > 0.0 : (wi_l.z > 0.0 && gw > 0.0)) && pdf_s > 0.0 && any_pos(wgt);
        vec3 Tn = ok ? mul_sat(T, wgt) : vec3(0.0);
#if ENV_MODE != ENV_MODE_BLACK && STRATEGY == STRATEGY_MIS
        prev_lpdf = disc ? 0.0 : env_pdf(wi_w, n, trans);
#endif
        prev_pdf = pdf_s;
        prev_delta = disc;
#ifdef PHOTONS
        seen_nd = seen_nd || !disc;
#endif
        if (trans) sigma = dot(ng_raw, wi_w) < 0.0 ? u_mat_info[2 * mi + 1].xyz : vec3(0.0);
        bool alive = any_pos(Tn);
#ifndef NO_ROULETTE
        if (depth >= RR_START_DEPTH) {
            float q = clamp(max3(Tn), RR_MIN, RR_MAX);
            alive = alive && r0.w < q;
            Tn /= q;
        }
#endif
        if (!alive) break;
        T = Tn;
        o = p + eps * (gw < 0.0 ? -1.0 : 1.0) * ng;
        d = wi_w;
    }
    if (any(isnan(L)) || any(isinf(L)) || L.x < 0.0 || L.y < 0.0 || L.z < 0.0) {
        g_bad += 1.0;
        L = vec3(0.0);
    }
    return L;
}

void main() {
    ivec2 px = ivec2(gl_FragCoord.xy);      // texture row y = image row (row 0 = top)
    vec4 sum = texelFetch(u_prev_sum, px, 0);
    vec4 sq = texelFetch(u_prev_sq, px, 0);
    if (px.y < u_row0 || px.y >= u_row1) {
        out_sum = sum;
        out_sq = sq;
        return;
    }
    float W = float(u_size.x), H = float(u_size.y);
    for (int s = 0; s < u_spp_pass; ++s) {
        Rng rng = rng_init(px, uint(sum.a + 0.5), u_seed);
        vec4 cam = rng_next4(rng);
        float x = (2.0 * (float(px.x) + cam.x) / W - 1.0) * u_tan_half_y * (W / H);
        float y = (1.0 - 2.0 * (float(px.y) + cam.y) / H) * u_tan_half_y;
        vec3 d = normalize(u_cam_forward + x * u_cam_right + y * u_cam_up);
#ifdef SPECTRAL
        vec3 L = trace_spectral(u_cam_pos, d, cam.zw, rng);   // the path's wavelengths from cam.zw
#else
        vec3 L = trace_path(u_cam_pos, d, rng);
#endif
        sum = vec4(min(sum.rgb + L, vec3(3.40282347e38)), sum.a + 1.0);   // the float32 maximum
        sq.rgb += L * L;
    }
    sq.a += g_bad;
    out_sum = sum;
    out_sq = sq;
}
