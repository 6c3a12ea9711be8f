// The SPECTRAL variant of the GPU path tracer: the CPU engine's hero-wavelength estimator
// (viewer/pathtracer/spectral.py; Wilkie et al. 2014, "Hero Wavelength Spectral Sampling")
// term for term. Included by passes/pathtrace.frag only when SPECTRAL is defined, after its
// helpers (clean, power_heuristic, mul_sat, add_sat, max3, any_pos) and uniforms.
//
// Wavelengths: 420 bins of 1 nm (360-779 nm). A path carries four, bins lam_j = c + 105 j
// (c uniform in 0..104), and a hero j_h uniform in 0..3; its sample is
//     RGB = (420 / 4) sum_j W(lam_j) L(lam_j)
// with W the bins' CIE RGB weights (row 1 of u_spec_tab). RGB quantities (model values and
// weights of non-spectral materials, light intensities, the environment, Bouguer
// transmittances exp(-sigma_a t)) become spectra through the Mallett & Yuksel (2019) basis
// (row 0 of u_spec_tab): spectrum(x)(lam) = sum_c x_c b_c(lam), i.e. g_B * x below.
//
// Materials by category (u_mat_spec[m].x, as the CPU's SpectralIntegrator sorts them):
//   0 RGB: evaluated with its RGB parameters, the value upsampled;
//   1 table (a spectral metal, `spectral = "NAME"` on microfacet or mirror): two calls of the
//     model with the parameters of viewer.pathtracer.spectral.params_at, one at
//     (lam_0, lam_1, lam_2) as its three channels (packed for each c at u_mat_spec.y + c stride)
//     and one at lam_3 (channel 0; packed for each bin l at u_mat_spec.z + l stride); sampling
//     draws with the first and weights lam_3 by its value over the same pdf (a delta lobe: the
//     second set sampled with the same numbers);
//   2 hero (a dispersive dielectric or layered coating, or a spectral material with a delta
//     base): one call at the hero's wavelength (channel 0); every sampled bounce terminates the
//     other three wavelengths and the hero carries 4x (pbrt-v4's TerminateSecondary), and until
//     then a hero-only next-event estimate counts 4x.
// The parameter sets are packed by viewer/gpupt/spectral.py with params_at itself, so each
// substitution (n, k of the table for eta, k; n(lam) for ior; upsampled RGB parameters) is
// the CPU engine's by construction.
//
// The estimator's options are trace_path's compile-time variants (STRATEGY, BALANCE_HEURISTIC
// through mis_weight, NO_ROULETTE), as the CPU spectral estimator runs the RGB one's steps.

#include "generated/constants.glsl"

// SPEC_STRIDE: bins between a path's wavelengths (420 / 4), SPEC_N_BINS, SPEC_HERO: a hero-only
// estimate stands for the four wavelengths (the header's, from viewer/reference_common/wavelengths.py)

#ifndef PHOTON_WAVELENGTHS   // (declared by pathtrace/photons.glsl then)
uniform sampler2D u_spec_tab;      // 420 x 2 texels: row 0 rgb = basis b_r, b_g, b_b at bin l; row 1 rgb = W(l)
#endif
// per material: (category 0 rgb / 1 table / 2 hero, float offset of the 105 parameter sets at
// (c, c + 105, c + 210), float offset of the 420 sets at (l, l, l), floats per set)
uniform vec4 u_mat_spec[MAX_MATERIALS];

mat3x4 g_B;   // the basis at the path's four wavelengths: column c = b_c(lam_0..3)

vec4 spec_up(vec3 rgb) { return g_B * rgb; }
vec4 clean4(vec4 x) { return vec4(clean(x.x), clean(x.y), clean(x.z), clean(x.w)); }
float max4(vec4 v) { return max(max(v.x, v.y), max(v.z, v.w)); }
bool any_pos4(vec4 v) { return v.x > 0.0 || v.y > 0.0 || v.z > 0.0 || v.w > 0.0; }
vec4 mul_sat4(vec4 a, vec4 b) { return min(min(a, vec4(F_MAX)) * min(b, vec4(F_MAX)), vec4(F_MAX)); }
vec4 add_sat4(vec4 a, vec4 b) { return min(a + b, vec4(F_MAX)); }

// f at the four wavelengths (the CPU's _eval4): o_s the set sampling uses, o_3 the set at lam_3.
// Every call site of the dispatch inlines every model of the program (compile time on software
// GL), so the two sets of a table material go through one call in a loop that is not unrolled.
vec4 spec_eval(int cat, int model, int o_s, int o_3, vec4 hmask, vec3 wi, vec3 wo) {
    vec4 f4 = vec4(0.0);
    int n_sets = cat == 1 ? 2 : 1;
    for (int s = 0; s < n_sets; ++s) {
        vec3 f = clean(brdf_eval(model, s == 0 ? o_s : o_3, wi, wo));
        if (s == 0) f4 = cat == 0 ? spec_up(f) : (cat == 2 ? f.x * hmask : vec4(f, 0.0));
        else f4.w = f.x;
    }
    return f4;
}

// the sampled weight at the four wavelengths (the CPU's _sample4); wi, pdf, lobe from the set o_s. A
// table material weights lam_3 by its value at the same direction over the same pdf, or, a delta
// lobe (a mirror: the same direction at every wavelength), by the set o_3 sampled with the same
// numbers (one call site in a loop, as spec_eval).
vec4 spec_sample(int cat, uint lobes, int model, int o_s, int o_3, vec4 hmask, vec3 wo, vec3 u,
                 out vec3 wi, out float pdf, out uint lobe) {
    vec4 w4 = vec4(0.0);
    wi = vec3(0.0, 0.0, 1.0);
    pdf = 0.0;
    lobe = LOBE_NONE;
    int n_sets = cat == 1 && lobe_is_delta(lobes) ? 2 : 1;
    for (int s = 0; s < n_sets; ++s) {
        vec3 wi_s;
        float pdf_s;
        uint lobe_s;
        vec3 w = clean(brdf_sample(model, s == 0 ? o_s : o_3, wo, u, wi_s, pdf_s, lobe_s));
        if (s == 0) {
            wi = wi_s;
            pdf = pdf_s;
            lobe = lobe_s;
            w4 = cat == 0 ? spec_up(w) : (cat == 2 ? w.x * hmask : vec4(w, 0.0));
        } else {
            w4.w = w.x;
        }
    }
    if (cat == 1 && !lobe_is_delta(lobes)) {
        float f3 = clean(brdf_eval(model, o_3, wi, wo)).x;
        w4.w = pdf > 0.0 ? f3 * abs(wi.z) / pdf : 0.0;
    }
    return w4;
}

vec3 trace_spectral(vec3 o, vec3 d, vec2 lam_u, inout Rng rng) {
    int c = min(int(lam_u.x * float(SPEC_STRIDE)), SPEC_STRIDE - 1);
    int hero = min(int(lam_u.y * 4.0), 3);
    ivec4 lam = ivec4(c, c + SPEC_STRIDE, c + 2 * SPEC_STRIDE, c + 3 * SPEC_STRIDE);
    int lam_h = lam[hero];
    vec4 hmask = vec4(equal(ivec4(0, 1, 2, 3), ivec4(hero)));
    vec3 b0 = texelFetch(u_spec_tab, ivec2(lam.x, 0), 0).rgb, b1 = texelFetch(u_spec_tab, ivec2(lam.y, 0), 0).rgb;
    vec3 b2 = texelFetch(u_spec_tab, ivec2(lam.z, 0), 0).rgb, b3 = texelFetch(u_spec_tab, ivec2(lam.w, 0), 0).rgb;
    g_B = mat3x4(vec4(b0.x, b1.x, b2.x, b3.x), vec4(b0.y, b1.y, b2.y, b3.y), vec4(b0.z, b1.z, b2.z, b3.z));

    vec4 L = vec4(0.0);
    vec3 photon_rgb = vec3(0.0);   // PHOTON_WAVELENGTHS: the photons' RGB
    vec4 T = vec4(1.0);
    bool solo = false;          // the secondaries are terminated: T holds the hero alone
    vec3 sigma = vec3(0.0);
    float prev_pdf = 0.0, prev_lpdf = 0.0;
    bool prev_delta = true;     // camera rays count as delta: the full environment
#ifdef PHOTONS
    bool seen_nd = false;       // some vertex so far sampled a non-delta lobe
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
            L = add_sat4(L, mul_sat4(T, spec_up(env_eval(d)) * w));
#endif
            break;
        }
        if (depth > u_max_depth) break;
        if (any_pos(sigma)) T = mul_sat4(T, spec_up(exp(-sigma * h.t)));
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
        vec4 ms = u_mat_spec[mi];
        int cat = int(ms.x + 0.5);
        int stride = int(ms.w + 0.5);
        int o_s = cat == 0 ? moff : (cat == 1 ? int(ms.y + 0.5) + c * stride : int(ms.z + 0.5) + lam_h * stride);
        int o_3 = int(ms.z + 0.5) + lam.w * stride;
        // a hero-only estimate stands for the four wavelengths unless the path is already reduced
        // to its hero (its throughput holds the 4x)
        float share = cat == 2 && !solo ? SPEC_HERO : 1.0;
        if (dot(d, ng_raw) > 0.0 && !trans) n = -n;
        vec3 ng = dot(ng_raw, n) < 0.0 ? -ng_raw : ng_raw;
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
#if defined(PHOTONS) && defined(PHOTON_WAVELENGTHS)
            // photons of their own wavelengths: RGB beside the path's, times the path's mean
            // throughput over its wavelengths (a hero-only path: its hero's)
            photon_rgb += dot(T, vec4(0.25)) * photon_gather_rgb(p, n, ng, tx, ty, trans, model, moff, wo_l, ms);
#elif defined(PHOTONS)
            // the caustic photons (RGB power upsampled, the hero-only share as next-event's)
            L = add_sat4(L, mul_sat4(T, photon_gather(p, n, ng, tx, ty, trans, model, moff, wo_l,
                                                      ivec3(cat, o_s, o_3), hmask) * share));
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
                vec4 f = spec_eval(cat, model, o_s, o_3, hmask, wl, wo_l);
                vec4 cc = mul_sat4(T, mul_sat4(f, (abs(wl.z) * share) * spec_up(val)));
                if (!any_pos4(cc)) continue;
                vec3 so = p + eps * (g < 0.0 ? -1.0 : 1.0) * ng;
                if (!bvh_occluded(so, wi, 0.0, tmax)) L = add_sat4(L, cc);
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
                    vec4 f = spec_eval(cat, model, o_s, o_3, hmask, wl, wo_l);
#if STRATEGY == STRATEGY_MIS
                    float pb = clean(brdf_pdf(model, o_s, wl, wo_l));
                    float wmis = mis_weight(pe, pb) / pe;
#else
                    float wmis = 1.0 / pe;
#endif
                    vec4 cc = mul_sat4(T, mul_sat4(f, (abs(wl.z) * share * wmis) * spec_up(ev)));
                    if (any_pos4(cc)) {
                        vec3 so = p + eps * (g < 0.0 ? -1.0 : 1.0) * ng;
                        if (!bvh_occluded(so, wi, 0.0, BVH_INF)) L = add_sat4(L, cc);
                    }
                }
            }
#endif
        }

        // ---- BSDF sampling
        vec3 wi_l;
        float pdf_s;
        uint lobe;
        vec4 wgt = spec_sample(cat, lobes, model, o_s, o_3, hmask, wo_l, r0.xyz, wi_l, pdf_s, lobe);
        pdf_s = clean(pdf_s);
        if (any(isnan(wi_l)) || any(isinf(wi_l))) { g_bad += 1.0; wi_l = vec3(0.0, 0.0, 1.0); wgt = vec4(0.0); }
        bool disc = lobe_has_delta(lobe);  // drawn discretely (the set o_s's lobe)
        vec3 wi_w = wi_l.x * tx + wi_l.y * ty + wi_l.z * n;
        float gw = dot(ng, wi_w);
        bool ok = (trans ? wi_l.z * gw > 0.0 : (wi_l.z > 0.0 && gw > 0.0)) && pdf_s > 0.0 && any_pos4(wgt);
        vec4 Tn = ok ? mul_sat4(T, wgt) : vec4(0.0);
        // a path that becomes hero-only: the model weighted the hero's channel alone; the hero
        // now carries the four wavelengths' share, the others are terminated
        if (cat == 2 && !solo) Tn = mul_sat4(Tn, vec4(SPEC_HERO));
        if (cat == 2) solo = true;
#if ENV_MODE != ENV_MODE_BLACK && STRATEGY == STRATEGY_MIS
        prev_lpdf = disc ? 0.0 : env_pdf(wi_w, n, trans);
#endif
        prev_pdf = pdf_s;
        prev_delta = disc;
#ifdef PHOTONS
        seen_nd = seen_nd || !disc;
#endif
        if (trans) sigma = dot(ng_raw, wi_w) < 0.0 ? u_mat_info[2 * mi + 1].xyz : vec3(0.0);
        bool alive = any_pos4(Tn);
#ifndef NO_ROULETTE
        if (depth >= RR_START_DEPTH) {
            float q = clamp(max4(Tn), RR_MIN, RR_MAX);
            alive = alive && r0.w < q;
            Tn /= q;
        }
#endif
        if (!alive) break;
        T = Tn;
        o = p + eps * (gw < 0.0 ? -1.0 : 1.0) * ng;
        d = wi_w;
    }
    // per wavelength, as the CPU engine: a NaN, infinite or negative radiance is counted and zeroed
    for (int j = 0; j < 4; ++j) {
        if (isnan(L[j]) || isinf(L[j]) || L[j] < 0.0) { g_bad += 1.0; L[j] = 0.0; }
    }
    // no clamp here: L <= F_MAX and |W| < 0.022 keep |RGB| below 5e35 (float32 holds 3.4e38), and a
    // clamp of the positive channels alone would turn the colour's XYZ negative
    vec3 rgb = vec3(0.0);
    for (int j = 0; j < 4; ++j) rgb += L[j] * texelFetch(u_spec_tab, ivec2(lam[j], 1), 0).rgb;
    return rgb * (SPEC_N_BINS / 4.0) + photon_rgb;
}
