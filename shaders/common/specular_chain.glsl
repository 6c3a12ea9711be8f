// Specular chains traced through the scene's triangles ([render] raytrace = true): compiled into
// the forward program of mirrors and smooth glass only (the RAYTRACE variant; software GL pays
// for untaken branches). Included by passes/forward.frag after its uniforms and after every
// other include (the light and environment uniforms, shadow maps, IBL and the BRDF dispatch
// with MAT_TEXTURE, so brdf_eval reads any material of the scene from u_mat_tex).
//
// From the camera's hit the chain follows delta lobes only: a mirror reflects with its Fresnel
// (conductor, dielectric or none); smooth glass splits into the reflected ray with weight
// R = fresnel_dielectric (exact, both polarizations) and the refracted one with 1 - R times the
// radiance factor 1 / eta^2 (eta the relative index seen from the incoming ray; entering and
// leaving cancel); past the critical angle refract() is empty and R = 1 (total internal
// reflection). A segment that ends on the inside of an absorbing dielectric is attenuated by
// exp(-sigma_a t) over its true length t (Bouguer; objects closed and not nested, as the
// reference assumes). Where a chain meets a surface that is not a delta lobe, that surface is
// shaded the rasterizer's way (point / directional lights with shadow maps, split-sum IBL from
// the material's albedo tables); where it leaves the scene it takes the environment.
// A vertex past u_rt_depth scattering events (the camera's hit counts as one) is not scattered
// again: at a mirror or glass the chain ends in the environment along its ray (times eta^2 where
// it leaves glass), a surface of any other kind is shaded (the reference's max_depth adds
// nothing there; the environment is the better guess for the light a longer chain would find).
// Branches are kept on a small stack, the heavier one followed first;
// a branch lighter than RT_MIN_WEIGHT or with no room on the stack ends in the environment
// along its direction.
//
// Material rows of u_mat_tex (viewer/gl/raytrace.py): texels 0..63 the u_mat block (at float
// offset 256 row), 64.. the albedo table, 96.. its specular part, 128.. the transmitted part,
// 160 = (model index, specular alpha, the material's lobes (LOBE_* flags: all delta = a mirror,
// or smooth glass where they transmit; else shaded), transmits),
// 161 = (sigma_a, 0), 162 = (eta per colour channel, mirror Fresnel MIRROR_FRESNEL_CONDUCTOR /
// _DIELECTRIC / _NONE), 163 = (mirror k, mirror dielectric ior), 164 = a smooth glass's thin film
// (film ior, thickness at the bottom, at the top or -1, 1 where there is a film), 165 = the world
// y range over which its thickness varies.
//
// A thin film on smooth glass (a soap bubble: ior 1 with a water film) splits a ray at each face
// with the film's RGB reflectance R (thin_film_dielectric_rgb, the BRDF's own; 1 past the critical
// angle) and transmits 1 - R, refracted by the glass's index (for ior 1 straight on), as the
// dielectric's sampler and the reference do; each face of a shell does this.
#include "generated/constants.glsl"
#include "common/lobes.glsl"
#include "common/albedo_table.glsl"
#include "common/bvh.glsl"
#include "common/fresnel.glsl"

uniform int u_rt_row;            // this object's material row
uniform int u_rt_depth;          // most scattering events along a chain (camera hit included)
uniform int u_rt_max_segments;   // most rays traced per pixel

const int RT_STACK = 8;
const float RT_MIN_WEIGHT = 1e-3;
// RT_T_ALBEDO, _SPEC, _TRANS, _INFO, _SIGMA, _ETA, _K: where a row's parts start (generated/constants.glsl)

const float RT_MIN_COS = 1e-3;  // the least cosine between a ray and the normal it scatters at

vec4 rt_texel(int row, int x) { return texelFetch(u_mat_tex, ivec2(x, row), 0); }

// d (unit) on the side of the plane with normal ng that ng points to: mirrored through the plane
// when it lies on the other side, lifted to at least RT_MIN_COS above it
vec3 rt_above(vec3 d, vec3 ng) {
    float c = dot(d, ng);
    if (c >= RT_MIN_COS) return d;
    d -= 2.0 * min(c, 0.0) * ng;
    return normalize(d + max(RT_MIN_COS - dot(d, ng), 0.0) * ng);
}

vec3 rt_table(int row, int base, float cos_o) {
    int k0, k1;
    float fx;
    albedo_lerp(cos_o, k0, k1, fx);
    return mix(rt_texel(row, base + k0).rgb, rt_texel(row, base + k1).rgb, fx);
}

// the environment as the rest of the forward pass sees it (nothing when it does not light)
#ifdef ENV_LIGHT
#ifdef ENV_CONSTANT
vec3 rt_env(vec3 d) { return u_env_on != 0 ? u_env_constant : vec3(0.0); }
vec3 rt_irradiance(vec3 n) { return u_env_on != 0 ? PI * u_env_constant : vec3(0.0); }
vec3 rt_prefiltered(vec3 r, float a) { return u_env_on != 0 ? u_env_constant : vec3(0.0); }
#else
vec3 rt_env(vec3 d) { return u_env_on != 0 ? env_radiance(d) : vec3(0.0); }
vec3 rt_irradiance(vec3 n) { return u_env_on != 0 ? env_irradiance(n) : vec3(0.0); }
vec3 rt_prefiltered(vec3 r, float a) { return u_env_on != 0 ? env_prefiltered(r, a) : vec3(0.0); }
#endif
#else
vec3 rt_env(vec3 d) { return vec3(0.0); }
vec3 rt_irradiance(vec3 n) { return vec3(0.0); }
vec3 rt_prefiltered(vec3 r, float a) { return vec3(0.0); }
#endif

#ifdef ENV_OCCLUSION
vec3 rt_occluded_irradiance(vec3 p, vec3 n, vec3 ng, int rays);  // below
const int AO_RAYS = 16;       // rays per point the camera sees (a new rotation of the set per pixel and frame)
const int AO_RAYS_CHAIN = 4;  // per point a traced chain meets
#endif

// A surface that is not a delta lobe, shaded as the forward pass shades it: the lights through
// brdf_eval with shadow maps, the environment by the split sum of its albedo tables (with
// ENV_OCCLUSION its diffuse part's irradiance traced for occlusion).
vec3 rt_shade(int row, vec3 p, vec3 n, vec3 ng, vec4 tangent, vec3 wo_w) {
    vec3 t = tangent.xyz - n * dot(n, tangent.xyz);
    t = dot(t, t) > 1e-12 ? normalize(t) : normalize(abs(n.x) < 0.9 ? cross(n, vec3(1, 0, 0)) : cross(n, vec3(0, 1, 0)));
    vec3 b = cross(n, t) * (tangent.w < 0.0 ? -1.0 : 1.0);
    mat3 to_local = transpose(mat3(t, b, n));
    vec3 wo = to_local * wo_w;
    vec4 info = rt_texel(row, RT_T_INFO);
    int model = int(info.x + 0.5);
    int o = row * MAT_FLOATS;  // the row's u_mat block (MAT_TEXTURE)
    vec3 radiance = vec3(0.0);
    for (int i = 0; i < MAX_LIGHTS; ++i) {
        if (i >= u_num_lights) break;
        bool is_point = u_light_type[i] == LIGHT_POINT;
        vec3 wi_w;
        vec3 e;
        if (is_point) {
            vec3 d = u_light_pos[i] - p;
            float r2 = max(dot(d, d), 1e-12);
            wi_w = d * inversesqrt(r2);
            e = u_light_value[i] / r2;
        } else {
            wi_w = -normalize(u_light_pos[i]);
            e = u_light_value[i];
        }
        vec3 wi = to_local * wi_w;
        if (wi.z <= 0.0 || dot(ng, wi_w) <= 0.0) continue;
#ifdef GLASS_SHADOW
        vec3 vis = info.w > 0.5 ? vec3(shadow_visibility(i, is_point, u_light_pos[i], p, ng, dot(ng, wi_w)))
                                : shadow_transmittance(i, is_point, u_light_pos[i], p, ng, dot(ng, wi_w));
#else
        float vis = shadow_visibility(i, is_point, u_light_pos[i], p, ng, dot(ng, wi_w));
#endif
        radiance += brdf_eval(model, o, wi, wo) * e * wi.z * vis;
    }
    if (wo.z > 0.0) {
        vec3 rho = rt_table(row, RT_T_ALBEDO, wo.z);
        vec3 rho_s = min(rt_table(row, RT_T_SPEC, wo.z), rho);
#ifdef ENV_OCCLUSION
        radiance += (rho - rho_s) * rt_occluded_irradiance(p, n, ng, AO_RAYS_CHAIN) * INV_PI
                  + rho_s * rt_prefiltered(reflect(-wo_w, n), info.y);
#else
        radiance += (rho - rho_s) * rt_irradiance(n) * INV_PI + rho_s * rt_prefiltered(reflect(-wo_w, n), info.y);
#endif
        if (info.w > 0.5) {  // rough glass: the environment straight through (no chain behind it)
            float ior = rt_texel(row, RT_T_ETA).x;
            radiance += rt_table(row, RT_T_TRANS, wo.z) * ior * ior * rt_prefiltered(-wo_w, info.y);
        }
    }
    return radiance;
}

struct RtRay { vec3 o; vec3 d; vec3 w; int depth; };

// The delta scattering at p of a ray travelling along d (unit) into a surface with shading
// normal n and winding (outward) normal ng_w: up to two rays leaving, weights w * (R, T).
// channel: the colour channel whose index of refraction bends the rays (dispersion).
int rt_interface(int row, uint lobes, vec3 p, vec3 d, vec3 n, vec3 ng_w, vec3 w, int depth, int channel,
                 out RtRay a, out RtRay b) {
    bool entering = dot(ng_w, d) < 0.0;
    vec3 ngf = entering ? ng_w : -ng_w;           // faces the incoming ray
    vec3 nf = dot(n, ngf) < 0.0 ? -n : n;
    // At a silhouette the interpolated normal can turn away from a ray that meets the triangle
    // itself from the front (and under MSAA the pixel centre lies past the triangle's edge, with
    // the normal extrapolated further): its mirror direction then points into the surface, where
    // the chain bounced on between the faces until its depth ran out (dotted black rims). The
    // normal is bent toward the ray just enough to face it, and a reflected (refracted) ray left
    // below (above) the triangle's plane is mirrored through that plane.
    float c_n = dot(-d, nf);
    if (c_n < RT_MIN_COS) nf = normalize(nf + (RT_MIN_COS - c_n) * (-d));
    float cos_i = clamp(dot(-d, nf), 0.0, 1.0);
    float eps = EPS_REL * (1.0 + max(max(abs(p.x), abs(p.y)), abs(p.z)));
    a.o = p + eps * ngf;
    a.d = rt_above(reflect(d, nf), ngf);
    a.depth = depth;
    b.depth = depth;
    b.w = vec3(0.0);
    b.o = p;
    b.d = d;
    vec4 eta4 = rt_texel(row, RT_T_ETA);
    if (!lobe_transmits(lobes)) {  // a mirror
        int fr = int(eta4.w + 0.5);
        vec4 k4 = rt_texel(row, RT_T_K);
        vec3 R = fr == MIRROR_FRESNEL_CONDUCTOR ? fresnel_conductor(cos_i, eta4.xyz, k4.xyz)
                         : (fr == MIRROR_FRESNEL_DIELECTRIC ? vec3(fresnel_dielectric(cos_i, k4.w)) : vec3(1.0));
        a.w = w * R;
        return 1;
    }
    float eta = eta4[channel];
    float eta_rel = entering ? eta : 1.0 / eta;   // n_t / n_i seen from the incoming ray
    vec3 dt = refract(d, nf, 1.0 / eta_rel);
    if (dot(dt, dt) == 0.0) {                     // total internal reflection
        a.w = w;
        return 1;
    }
    b.o = p - eps * ngf;
    b.d = -rt_above(-normalize(dt), ngf);
    vec4 film = rt_texel(row, RT_T_FILM);
    if (film.w > 0.5) {  // a thin film: RGB R, T = 1 - R (thickness_top_nm: linear in height)
        vec2 fy = rt_texel(row, RT_T_FILM_Y).xy;
        float h = fy.y > fy.x ? clamp((p.y - fy.x) / (fy.y - fy.x), 0.0, 1.0) : 0.0;
        float d_nm = film.z >= 0.0 ? mix(film.y, film.z, h) : film.y;
        vec3 Rf = thin_film_dielectric_rgb(cos_i, eta_rel, film.x, d_nm);
        a.w = w * Rf;
        b.w = w * (1.0 - Rf) / (eta_rel * eta_rel);
        return 2;
    }
    float F = fresnel_dielectric(cos_i, eta_rel);
    float T = fresnel_dielectric_transmittance(cos_i, eta_rel);
    a.w = w * F;
    b.w = w * (T / (eta_rel * eta_rel));
    return 2;
}

float rt_max(vec3 v) { return max(v.x, max(v.y, v.z)); }


// Smooth glass: the chain refracts through it (delta lobes that transmit).
bool rt_glass(uint lobes) { return lobe_is_delta(lobes) && lobe_transmits(lobes); }

#ifdef ENV_OCCLUSION
// Environment occlusion (traced frames, the ENV_OCCLUSION variant): the irradiance of a diffuse
// part is pi/N times the radiance along N cosine-distributed rays about n, traced in the BVH.
// A ray that leaves the scene, directly or after mirror and smooth-glass bounces (the heavier
// branch followed with its Fresnel weight and Bouguer absorption, the lighter one taken as
// leaving), counts as seeing the sky, and all such rays together take their share of the
// unoccluded irradiance E(n) (spherical harmonics or pi L): E(n) times the visible fraction,
// exact for a constant environment; with a map the hidden directions are taken to be as bright
// as the hemisphere's average (no noise from looking the map up per ray). A ray that meets a
// diffuse (not delta) surface takes that surface's radiance as the raster has it without
// occlusion (rt_occluder: its lights with shadow maps, its whole albedo under the unoccluded
// irradiance): one bounce of interreflection, where the reference has them all. A surface
// seen through a chain gets AO_RAYS_CHAIN rays (a glass ball's pixel meets the floor along
// several branches, each with its own set).
const int AO_SEGMENTS = 4;   // delta bounces followed along a ray before it counts as leaving

vec3 rt_occluder(int row, vec3 p, vec3 n, vec3 ng, vec3 wo_w) {
    vec3 t = normalize(abs(n.x) < 0.9 ? cross(n, vec3(1, 0, 0)) : cross(n, vec3(0, 1, 0)));
    mat3 to_local = transpose(mat3(t, cross(n, t), n));
    vec3 wo = to_local * wo_w;
    if (wo.z <= 0.0) return vec3(0.0);
    int model = int(rt_texel(row, RT_T_INFO).x + 0.5);
    int o = row * MAT_FLOATS;
    vec3 radiance = vec3(0.0);
    for (int i = 0; i < MAX_LIGHTS; ++i) {
        if (i >= u_num_lights) break;
        bool is_point = u_light_type[i] == LIGHT_POINT;
        vec3 d = is_point ? u_light_pos[i] - p : -u_light_pos[i];
        float r2 = max(dot(d, d), 1e-12);
        vec3 wi_w = is_point ? d * inversesqrt(r2) : normalize(d);
        vec3 e = is_point ? u_light_value[i] / r2 : u_light_value[i];
        vec3 wi = to_local * wi_w;
        if (wi.z <= 0.0 || dot(ng, wi_w) <= 0.0) continue;
        float vis = shadow_visibility(i, is_point, u_light_pos[i], p, ng, dot(ng, wi_w));
        radiance += brdf_eval(model, o, wi, wo) * e * wi.z * vis;
    }
    return radiance + rt_table(row, RT_T_ALBEDO, wo.z) * rt_irradiance(n) * INV_PI;
}

vec3 rt_occluded_irradiance(vec3 p, vec3 n, vec3 ng, int rays) {
    vec3 e_open = rt_irradiance(n);
    if (!any(greaterThan(e_open, vec3(0.0)))) return e_open;
    vec3 t = normalize(abs(n.x) < 0.9 ? cross(n, vec3(1, 0, 0)) : cross(n, vec3(0, 1, 0)));
    vec3 b = cross(n, t);
    float cx = pixel_hash(uvec2(gl_FragCoord.xy) + 977u, uint(u_frame_index) + 5u);
    float cy = pixel_hash(uvec2(gl_FragCoord.yx) + 311u, uint(u_frame_index) + 17u);
    float eps = EPS_REL * (1.0 + max(max(abs(p.x), abs(p.y)), abs(p.z)));
    vec3 sky = vec3(0.0);    // the weights of the rays that leave the scene
    vec3 occ = vec3(0.0);    // the radiance of the diffuse surfaces the others meet
    for (int k = 0; k < rays; ++k) {
        float u0 = fract((float(k) + 0.5) / float(rays) + cx);
        float u1 = fract(float(k) * 0.6180339887498949 + cy);
        float r = sqrt(u0), phi = TWO_PI * u1;
        RtRay ray;
        ray.o = p + eps * ng;
        ray.d = rt_above(normalize(t * (r * cos(phi)) + b * (r * sin(phi)) + n * sqrt(max(0.0, 1.0 - u0))), ng);
        ray.w = vec3(1.0);
        ray.depth = 0;
        for (int s = 0; s < AO_SEGMENTS; ++s) {
            BvhHit h;
            if (!bvh_closest(ray.o, ray.d, 0.0, BVH_INF, h)) {
                sky += ray.w;
                break;
            }
            vec3 v0 = bvh_vertex(h.tri, 0), v1 = bvh_vertex(h.tri, 1), v2 = bvh_vertex(h.tri, 2);
            float bu = h.uv.x, bv = h.uv.y, bw = 1.0 - bu - bv;
            vec3 hp = bw * v0 + bu * v1 + bv * v2;
            vec3 hg = cross(v1 - v0, v2 - v0);
            hg = dot(hg, hg) > 0.0 ? normalize(hg) : -ray.d;
            vec3 hn = bw * bvh_vertex_normal(h.tri, 0) + bu * bvh_vertex_normal(h.tri, 1) + bv * bvh_vertex_normal(h.tri, 2);
            hn = dot(hn, hn) > 0.0 ? normalize(hn) : hg;
            int row = bvh_material(h.tri);
            uint hlobes = uint(rt_texel(row, RT_T_INFO).z + 0.5);
            bool entering = dot(hg, ray.d) < 0.0;
            if (rt_glass(hlobes) && !entering) ray.w *= exp(-rt_texel(row, RT_T_SIGMA).xyz * h.t);  // Bouguer
            if (!lobe_is_delta(hlobes)) {
                vec3 ngs = entering ? hg : -hg;
                occ += ray.w * rt_occluder(row, hp, dot(hn, ngs) < 0.0 ? -hn : hn, ngs, -ray.d);
                break;
            }
            if (s == AO_SEGMENTS - 1) {   // out of bounces: taken as leaving
                sky += ray.w;
                break;
            }
            RtRay ra, rb;
            int m = rt_interface(row, hlobes, hp, ray.d, hn, hg, ray.w, 0, 0, ra, rb);
            if (m == 2 && rt_max(rb.w) > rt_max(ra.w)) { RtRay q = ra; ra = rb; rb = q; }
            if (m == 2) sky += rb.w;      // the lighter branch: taken as leaving
            ray = ra;
        }
    }
    return sky * (e_open / float(rays)) + occ * (PI / float(rays));
}
#endif

// The radiance arriving along the rays the camera's hit (row, lobes) scatters into.
vec3 rt_chain(uint lobes, vec3 p, vec3 d, vec3 n, vec3 ng_w, int channel) {
    RtRay stack[RT_STACK];
    RtRay a, b;
    int sp = 0;
    vec3 total = vec3(0.0);
    int m = rt_interface(u_rt_row, lobes, p, d, n, ng_w, vec3(1.0), 1, channel, a, b);
    // the lighter branch below the heavier, which is popped first
    bool swap = m == 2 && rt_max(b.w) < rt_max(a.w);
    if (m == 2) stack[sp++] = swap ? b : a;
    stack[sp++] = (m == 2 && !swap) ? b : a;
    int segments = 0;
    while (sp > 0) {
        RtRay r = stack[--sp];
        if (segments >= u_rt_max_segments) {      // out of budget: the environment beyond
            total += r.w * rt_env(r.d);
            continue;
        }
        ++segments;
        BvhHit h;
        if (!bvh_closest(r.o, r.d, 0.0, BVH_INF, h)) {
            total += r.w * rt_env(r.d);
            continue;
        }
        vec3 v0 = bvh_vertex(h.tri, 0), v1 = bvh_vertex(h.tri, 1), v2 = bvh_vertex(h.tri, 2);
        float bu = h.uv.x, bv = h.uv.y, bw = 1.0 - bu - bv;
        vec3 hp = bw * v0 + bu * v1 + bv * v2;
        vec3 ng = cross(v1 - v0, v2 - v0);
        ng = dot(ng, ng) > 0.0 ? normalize(ng) : -r.d;
        vec3 hn = bw * bvh_vertex_normal(h.tri, 0) + bu * bvh_vertex_normal(h.tri, 1) + bv * bvh_vertex_normal(h.tri, 2);
        hn = dot(hn, hn) > 0.0 ? normalize(hn) : ng;
        int row = bvh_material(h.tri);
        vec4 info = rt_texel(row, RT_T_INFO);
        uint hlobes = uint(info.z + 0.5);
        bool entering = dot(ng, r.d) < 0.0;
        if (rt_glass(hlobes) && !entering) r.w *= exp(-rt_texel(row, RT_T_SIGMA).xyz * h.t);  // Bouguer
        // Out of depth at a mirror or glass: the environment along the ray stands for the light
        // a longer chain would find (black before: dotted rims where grazing chains bounced
        // inside glass, black spots in a glass shader ball's groove), where the reference's
        // max_depth adds nothing; a ray leaving glass there gets the exit's radiance factor
        // eta^2 (its Fresnel left out). A surface that is not a delta lobe is shaded as at any
        // depth below (it scatters no further ray).
        if (r.depth + 1 > u_rt_depth && lobe_is_delta(hlobes)) {
            float e = (rt_glass(hlobes) && !entering) ? rt_texel(row, RT_T_ETA)[channel] : 1.0;
            total += r.w * (e * e) * rt_env(r.d);
            continue;
        }
        if (!lobe_is_delta(hlobes)) {
            // two-sided as in the forward pass: the side the ray arrives on
            vec3 ngs = entering ? ng : -ng;
            vec3 ns = dot(hn, ngs) < 0.0 ? -hn : hn;
            vec4 tg = bw * bvh_vertex_tangent(h.tri, 0) + bu * bvh_vertex_tangent(h.tri, 1) + bv * bvh_vertex_tangent(h.tri, 2);
            tg.w = bvh_vertex_tangent(h.tri, 0).w;
            total += r.w * rt_shade(row, hp, ns, ngs, tg, -r.d);
            continue;
        }
        m = rt_interface(row, hlobes, hp, r.d, hn, ng, r.w, r.depth + 1, channel, a, b);
        if (m == 2 && rt_max(b.w) > rt_max(a.w)) { RtRay s = a; a = b; b = s; }  // a: the heavier
        if (m == 2 && rt_max(b.w) > 0.0) {
            if (rt_max(b.w) >= RT_MIN_WEIGHT && sp < RT_STACK - 1) stack[sp++] = b;
            else total += b.w * rt_env(b.d);
        }
        if (rt_max(a.w) > 0.0) stack[sp++] = a;
    }
    return total;
}

// The camera's hit on a mirror or smooth glass: the chain's radiance toward the camera. With
// RT_DISPERSION (a glass of the scene has one index of refraction per colour channel) each
// channel is traced on its own, from mirrors too (a dispersive glass may be seen in one).
vec3 rt_specular(vec3 p, vec3 wo_w, vec3 n, vec3 ng_w) {
    uint lobes = uint(rt_texel(u_rt_row, RT_T_INFO).z + 0.5);
    if (!lobe_is_delta(lobes)) return vec3(0.0);
    // The chain starts where the camera's ray meets the triangles, found again in the BVH: under
    // MSAA a pixel that a triangle covers only partly is shaded at the pixel centre, with its
    // attributes extrapolated past the triangle's edge, off the surface (outside a convex mesh):
    // a refracted ray started there met the neighbouring triangle from outside and entered twice
    // (speckles of wrong radiance over a glass ball, its mean 3.7% under the reference).
    {
        vec3 cam = p + wo_w * length(u_camera_pos - p);
        BvhHit h;
        if (bvh_closest(cam, -wo_w, 0.0, BVH_INF, h) && bvh_material(h.tri) == u_rt_row) {
            vec3 v0 = bvh_vertex(h.tri, 0), v1 = bvh_vertex(h.tri, 1), v2 = bvh_vertex(h.tri, 2);
            float bu = h.uv.x, bv = h.uv.y, bw = 1.0 - bu - bv;
            vec3 hp = bw * v0 + bu * v1 + bv * v2;
            if (distance(hp, p) < 0.05 * (1.0 + length(p))) {
                vec3 ng = cross(v1 - v0, v2 - v0);
                vec3 hn = bw * bvh_vertex_normal(h.tri, 0) + bu * bvh_vertex_normal(h.tri, 1)
                          + bv * bvh_vertex_normal(h.tri, 2);
                if (dot(ng, ng) > 0.0 && dot(hn, hn) > 0.0) {
                    p = hp;
                    ng_w = normalize(ng);
                    n = normalize(hn);
                }
            }
        }
    }
#ifdef RT_DISPERSION
    return vec3(rt_chain(lobes, p, -wo_w, n, ng_w, 0).r, rt_chain(lobes, p, -wo_w, n, ng_w, 1).g,
                rt_chain(lobes, p, -wo_w, n, ng_w, 2).b);
#endif
    return rt_chain(lobes, p, -wo_w, n, ng_w, 0);
}
