#version 410 core
// Forward shading: every material goes through brdf_eval (the one include point of the BRDFs,
// generated from the registry), lit by point and directional lights with shadow maps.
#include "generated/constants.glsl"
#include "common/math.glsl"
#include "common/albedo_table.glsl"
#include "common/colour.glsl"
#include "common/rng.glsl"
#include "brdf/dispatch.glsl"
#include "common/shadow.glsl"
#include "common/ibl.glsl"

in vec3 v_position;
in vec3 v_normal;
in vec4 v_tangent;
flat in vec3 v_geometric_normal;  // from forward.geom

uniform int u_model_id;        // registry index of this object's material model
uniform vec2 u_film_y;         // the object's lowest and highest world y (a thin film over height)
uniform vec3 u_camera_pos;
uniform int u_num_lights;
uniform int u_light_type[MAX_LIGHTS];    // LIGHT_POINT or LIGHT_DIRECTIONAL
uniform vec3 u_light_pos[MAX_LIGHTS];    // point: position; directional: direction the light travels
uniform vec3 u_light_value[MAX_LIGHTS];  // point: intensity I [W/sr]; directional: irradiance E [W/m^2]
uniform int u_env_on;                    // any environment light (constant or map), IBL not "off"
uniform vec3 u_env_constant;             // the constant environment's radiance (ENV_CONSTANT)
uniform int u_ibl_mode;                  // IBL_MODE_SPLIT_SUM, _FIS (filtered importance sampling), _BRUTE_FORCE
uniform float u_ibl_alpha;               // the lobe width of the material's specular part (ibl_split)
uniform int u_ibl_delta;                 // the material has only delta lobes (mirror, smooth glass)
uniform int u_frame_index;               // brute force: a new sample set each frame
uniform int u_ms_on;                     // multiple-scattering compensation (Fdez-Aguera 2019)
uniform vec3 u_ms_f0;                    // the specular lobe's normal-incidence reflectance
uniform float u_ms_ess[ALBEDO_TABLE];    // E_ss: that lobe's single-scattering albedo with F = 1
uniform float u_ms_eavg;                 // E_avg: its hemispherical average (viewer/ms_compensation.py e_avg)
uniform int u_view_mode;                 // VIEW_MODE_SHADED, _F, _D, _G, _N_L, _F_COS, _SHADOW
uniform vec3 u_albedo[ALBEDO_TABLE];     // directional albedo at cos(theta_o) = (k + 0.5) / ALBEDO_TABLE
uniform vec3 u_albedo_t[ALBEDO_TABLE];   // its transmitted part (wi below the surface)
uniform vec3 u_albedo_s[ALBEDO_TABLE];   // the reflected albedo of the specular part alone
uniform int u_transmit_on;
uniform vec3 u_sigma_a;                  // absorption inside a transmissive material [1/m]
uniform float u_ior;
uniform sampler2D u_thickness;           // distance to the nearest back face (0 = none)
#if defined(RAYTRACE) || defined(ENV_OCCLUSION)
// mirrors and smooth glass trace their specular chains (common/specular_chain.glsl), and with
// ENV_OCCLUSION every surface its environment's occlusion: every
// material comes from u_mat_tex (MAT_TEXTURE), this object's at float offset u_mat_base
uniform int u_mat_base;
#define MAT_BASE u_mat_base
#else
#define MAT_BASE 0
#endif

#ifdef SSR
// Screen-space reflections (viewer/gl/ssr.py): the radiance (with the specular environment term,
// as without SSR), that term's weight rho_s and lobe width, and the geometry the SSR pass traces
// against.
layout(location = 0) out vec4 frag_color;
layout(location = 1) out vec4 frag_spec;   // rho_s, alpha of the specular part
layout(location = 2) out vec4 frag_geom;   // world shading normal, linear view depth
uniform mat4 u_view;
const bool SSR_ON = true;
#elif defined(THIN_SHELL)
// A thin shell (a dielectric of ior 1) over the opaque frame, with dual-source blending
// (GL_ONE, GL_SRC1_COLOR; viewer/gl/renderer.py _draw_shells): the destination becomes
// destination x frag_transmit + frag_color. Light crosses the shell without bending, so what
// lies behind it is the frame already drawn there, not an environment lookup.
layout(location = 0, index = 0) out vec4 frag_color;
layout(location = 0, index = 1) out vec4 frag_transmit;
const bool SSR_ON = false;
#else
out vec4 frag_color;
const bool SSR_ON = false;
#endif

#if defined(RAYTRACE) || defined(ENV_OCCLUSION)
#include "common/specular_chain.glsl"
#endif

// Light i at p: the direction to it (world) and its irradiance at normal incidence.
void light_incident(int i, vec3 p, out vec3 wi_w, out vec3 e) {
    if (u_light_type[i] == LIGHT_POINT) {
        vec3 d = u_light_pos[i] - p;
        float r2 = max(dot(d, d), 1e-12);
        wi_w = d * inversesqrt(r2);
        e = u_light_value[i] / r2;            // I / r^2 (docs/conventions.md)
    } else {
        wi_w = -normalize(u_light_pos[i]);
        e = u_light_value[i];
    }
}

#ifdef THIN_SHELL
// The ground a shell's reflections meet (viewer/scene/ground.py): the scene's floor, a
// horizontal rectangle of Lambert albedo u_ground_albedo. The environment map has no floor (the
// studio map is dark below the horizon), so a face's reflected ray going down meets this plane
// first and sees the floor's radiance where it lands, shaded as the floor itself is (the lights
// with their shadow maps, the environment's irradiance from above); elsewhere the environment.
uniform int u_ground_on;
uniform vec3 u_ground_origin;      // its centre (world)
uniform vec4 u_ground_to_local;    // the rows of the 2 x 2 map world (dx, dz) -> the plane's [-1, 1]^2
uniform vec3 u_ground_albedo;
bool shell_ground_hit(vec3 p, vec3 r, out vec3 q) {
    q = p;
    if (u_ground_on == 0 || r.y >= 0.0 || p.y <= u_ground_origin.y) return false;
    q = p + r * ((u_ground_origin.y - p.y) / r.y);
    vec2 d = q.xz - u_ground_origin.xz;
    vec2 u = vec2(dot(u_ground_to_local.xy, d), dot(u_ground_to_local.zw, d));
    return all(lessThanEqual(abs(u), vec2(1.0)));
}

// The ground's radiance at q from the lights (its environment part is added where the
// environment lights the scene): albedo / pi times the irradiance, with the shadow maps.
vec3 shell_ground_lights(vec3 q) {
    const vec3 up = vec3(0.0, 1.0, 0.0);
    vec3 sum = vec3(0.0);
    for (int i = 0; i < MAX_LIGHTS; ++i) {
        if (i >= u_num_lights) break;
        vec3 wi_w, e;
        light_incident(i, q, wi_w, e);
        float c = wi_w.y;
        if (c <= 0.0) continue;
        bool is_point = u_light_type[i] == LIGHT_POINT;
#ifdef GLASS_SHADOW
        vec3 vis = shadow_transmittance(i, is_point, u_light_pos[i], q, up, c);
#else
        float vis = shadow_visibility(i, is_point, u_light_pos[i], q, up, c);
#endif
        sum += e * c * vis;
    }
    return u_ground_albedo * INV_PI * sum;
}
#endif

#ifdef IBL_SAMPLED
// Environment light by importance sampling the material's own BRDF (brdf_eval) with a proxy
// density: a GGX lobe of the material's alpha about the normal (reflected half vectors, Walter
// et al. 2007 eq. 35-36) mixed with a cosine lobe in proportion to rho_s : rho_d. Unbiased for
// any model (the cosine part covers the hemisphere). filtered: the environment is looked up at
// the Colbert-Krivanek 2007 mip level of each sample's pdf (FIS); otherwise at full resolution
// (brute force, averaged over frames by the renderer).
// A .brdf file material (u_ibl_own) draws its directions from its own sampler instead
// (brdf_sample, with the exact pdf of what it draws), and in split-sum mode its constant part
// u_env_floor (the largest constant under its f) is taken out of the sampled integrand and lit by
// the irradiance, as a built-in diffuse lobe is (a control variate: c E(n) + the integral of
// (f - c) cos L; any c keeps it unbiased, and a Lambertian file then has nothing left to sample).
// Each frame's pixel gets new sample sets (frame); the window and render_arrays average frames.
const int IBL_SAMPLES = 16;
uniform int u_ibl_own;
uniform vec3 u_env_floor;
uniform int u_fis_samples;  // the samples a pixel's estimate averages (16 x the frames averaged): the filter's N
vec3 ibl_sampled(vec3 wo, mat3 from_local, vec3 rho, vec3 rho_s, float alpha, bool filtered, int frame) {
    float ls = luminance(rho_s), lt = luminance(rho);
    float p_spec = lt > 0.0 ? clamp(ls / lt, 0.1, 0.9) : 0.5;
    float a = max(alpha, 0.02);
    float a2 = a * a;
    vec2 cp = vec2(pixel_hash(uvec2(gl_FragCoord.xy), uint(frame)), pixel_hash(uvec2(gl_FragCoord.yx) + 7u, uint(frame)));
    float cz = pixel_hash(uvec2(gl_FragCoord.xy) + 13u, uint(frame) + 101u);
    vec3 sum = vec3(0.0);
    for (int k = 0; k < IBL_SAMPLES; ++k) {
        float u0 = (float(k) + 0.5) / float(IBL_SAMPLES);
        float u1 = fract(float(k) * 0.6180339887498949);  // golden-ratio sequence
        u0 = fract(u0 + cp.x);
        u1 = fract(u1 + cp.y);
        vec3 wi;
        if (u_ibl_own != 0) {
            float pdf_own;
            uint lobe_own;
            vec3 w = brdf_sample(u_model_id, 0, wo, vec3(u0, u1, fract(float(k) * 0.7548776662466927 + cz)), wi, pdf_own, lobe_own);
            if (!(pdf_own > 0.0) || wi.z <= 0.0) continue;
            vec3 dir_own = from_local * wi;
            vec3 L_own = filtered ? env_radiance_lod(dir_own, env_fis_lod(pdf_own, max(u_fis_samples, IBL_SAMPLES))) : env_radiance(dir_own);
            sum += (w - u_env_floor * (wi.z / pdf_own)) * L_own;  // (f - c) cos / pdf
            continue;
        }
        if (u0 < p_spec) {
            float v = u0 / p_spec;
            float phi = TWO_PI * u1;
            float cos2 = (1.0 - v) / (1.0 + (a2 - 1.0) * v);  // GGX: tan^2 theta_h = a^2 v / (1 - v)
            float ch = sqrt(cos2), sh = sqrt(max(0.0, 1.0 - cos2));
            vec3 h = vec3(sh * cos(phi), sh * sin(phi), ch);
            wi = reflect(-wo, h);
        } else {
            float v = (u0 - p_spec) / (1.0 - p_spec);
            float r = sqrt(v), phi = TWO_PI * u1;
            wi = vec3(r * cos(phi), r * sin(phi), sqrt(max(0.0, 1.0 - v)));
        }
        if (wi.z <= 0.0) continue;
        vec3 h = normalize(wi + wo);
        float d_h = a2 / (PI * sqr(h.z * h.z * (a2 - 1.0) + 1.0));
        float pdf = p_spec * d_h * h.z / (4.0 * max(dot(wo, h), 1e-6)) + (1.0 - p_spec) * wi.z * INV_PI;
        if (pdf <= 0.0) continue;
        vec3 dir = from_local * wi;
        vec3 L = filtered ? env_radiance_lod(dir, env_fis_lod(pdf, IBL_SAMPLES)) : env_radiance(dir);
        sum += brdf_eval(u_model_id, 0, wi, wo) * wi.z / pdf * L;
    }
    return sum / float(IBL_SAMPLES);
}

#endif

// E_ss(cos) from the table u_ms_ess at cos = (k + 0.5) / ALBEDO_TABLE (linear, held at the ends).
float ms_ess_at(float c) {
    float x = clamp(c, 0.0, 1.0) * float(ALBEDO_TABLE) - 0.5;
    int k0 = clamp(int(floor(x)), 0, ALBEDO_TABLE - 1);
    int k1 = min(k0 + 1, ALBEDO_TABLE - 1);
    return mix(u_ms_ess[k0], u_ms_ess[k1], clamp(x - float(k0), 0.0, 1.0));
}

// Kulla & Conty 2017's multiple-scattering lobe for point and directional lights (twin of
// viewer/ms_compensation.py kulla_conty_eval): (1 - E_ss(mu_i)) (1 - E_ss(mu_o)) / (pi (1 - E_avg)) times
// F_avg^2 E_avg / (1 - F_avg (1 - E_avg)); its albedo is the energy single scattering loses.
vec3 ms_kulla_conty(float cos_i, float cos_o) {
    if (!any(greaterThan(u_ms_f0, vec3(0.0)))) return vec3(0.0);  // no specular lobe
    vec3 f_avg = u_ms_f0 + (1.0 - u_ms_f0) / 21.0;
    vec3 f_add = f_avg * f_avg * u_ms_eavg / (1.0 - f_avg * (1.0 - u_ms_eavg));
    float lobe = (1.0 - ms_ess_at(cos_i)) * (1.0 - ms_ess_at(cos_o)) / (PI * max(1.0 - u_ms_eavg, 1e-6));
    return lobe * f_add;
}

void main() {
    // relative height on the object, for a thin film whose thickness varies with it
    brdf_film_height = u_film_y.y > u_film_y.x ? clamp((v_position.y - u_film_y.x) / (u_film_y.y - u_film_y.x), 0.0, 1.0) : 0.0;
    vec3 ng = v_geometric_normal;
    vec3 n = normalize(v_normal);
    vec3 wo_w = normalize(u_camera_pos - v_position);
    // Two-sided surfaces: shade the side the viewer sees.
    if (!gl_FrontFacing) n = -n;
    if (dot(ng, n) < 0.0) ng = -ng;
#ifndef THIN_SHELL
    // Mirrors and smooth glass: at the silhouette the interpolated normal turns away from the
    // viewer on some pixels (wo.z <= 0), which then reflected nothing, a dotted black rim; the
    // normal is bent toward the viewer just enough to face it (grazing: R near 1 of the horizon).
    if (u_ibl_delta != 0 && dot(n, wo_w) < 1e-3) n = normalize(n + (1e-3 - dot(n, wo_w)) * wo_w);
#endif
    // Shading frame: x = tangent (anisotropy axis), z = normal (docs/conventions.md).
    vec3 t = v_tangent.xyz - n * dot(n, v_tangent.xyz);
    t = dot(t, t) > 1e-12 ? normalize(t) : normalize(abs(n.x) < 0.9 ? cross(n, vec3(1, 0, 0)) : cross(n, vec3(0, 1, 0)));
    vec3 b = cross(n, t) * (v_tangent.w < 0.0 ? -1.0 : 1.0);
    mat3 to_local = transpose(mat3(t, b, n));
    vec3 wo = to_local * wo_w;

    vec3 radiance = vec3(0.0);
#ifdef THIN_SHELL
    // where this face's reflected ray lands on the ground, and the ground's radiance there
    vec3 ground_q;
    bool on_ground = shell_ground_hit(v_position, reflect(-wo_w, n), ground_q);
#ifdef ENV_LIGHT
    // the environment term below replaces its lookup by the ground in its split-sum path only (a
    // rough shell's sampled one, fis or brute force, sees the environment below the horizon)
    on_ground = on_ground && (u_env_on == 0 || u_ibl_delta != 0 || u_ibl_mode == IBL_MODE_SPLIT_SUM);
#endif
    vec3 ground_l = on_ground ? shell_ground_lights(ground_q) : vec3(0.0);
    // a smooth shell (delta lobes only) reflects R at this point and lets 1 - R through, R from
    // the model's own sampler (its reflection branch, taken at u.x = 0, weighs R / P with P the
    // branch's probability, its pdf): the film's thickness at this height, which the albedo
    // tables, made without a position, do not follow (a bubble thinner at its top)
    vec3 shell_r = vec3(-1.0);  // < 0: a rough shell, from the tables
    if (u_ibl_delta != 0 && wo.z > 0.0) {
        vec3 wi_s;
        float pdf_s;
        uint lobe_s;
        vec3 w_s = brdf_sample(u_model_id, MAT_BASE, wo, vec3(0.0, 0.5, 0.5), wi_s, pdf_s, lobe_s);
        shell_r = (lobe_s & LOBE_REFLECTION) != 0u && pdf_s > 0.0 ? clamp(w_s * pdf_s, 0.0, 1.0) : vec3(0.0);
    }
#else
    const bool on_ground = false;
#endif
    vec3 first_terms = vec3(-1.0);
    float first_ndotl = 0.0;
    float first_visibility = 0.0;
    vec3 first_fcos = vec3(0.0);
    for (int i = 0; i < MAX_LIGHTS; ++i) {
        if (i >= u_num_lights) break;
        bool is_point = u_light_type[i] == LIGHT_POINT;
        vec3 wi_w;
        vec3 e;  // irradiance at normal incidence from this light
        light_incident(i, v_position, wi_w, e);
        vec3 wi = to_local * wi_w;
        float cos_i = wi.z;
        vec3 f = brdf_eval(u_model_id, MAT_BASE, wi, wo);
        if (i == 0) {
            first_terms = brdf_terms(u_model_id, MAT_BASE, wi, wo);
            first_ndotl = max(cos_i, 0.0);
            first_fcos = f * max(cos_i, 0.0);
        }
        if (cos_i <= 0.0 || dot(ng, wi_w) <= 0.0) continue;
#ifdef GLASS_SHADOW
        // glass casters let their transmittance through (common/shadow.glsl); a transmissive
        // surface (rough glass) takes the opaque casters' shadow alone: the glass atlas holds its
        // own optical depth, which would darken the light it reflects
        vec3 vis = u_transmit_on != 0 ? vec3(shadow_visibility(i, is_point, u_light_pos[i], v_position, ng, dot(ng, wi_w)))
                                      : shadow_transmittance(i, is_point, u_light_pos[i], v_position, ng, dot(ng, wi_w));
        if (i == 0) first_visibility = luminance(vis);
#else
        float vis = shadow_visibility(i, is_point, u_light_pos[i], v_position, ng, dot(ng, wi_w));
        if (i == 0) first_visibility = vis;
#endif
        vec3 f_ms = u_ms_on != 0 ? ms_kulla_conty(cos_i, wo.z) : vec3(0.0);
        radiance += (f + f_ms) * e * cos_i * vis;
    }
#ifdef ENV_LIGHT  // compiled in only where the environment lights the scene (see IBL_SAMPLED)
#ifdef ENV_CONSTANT
    // a constant environment L: irradiance pi L and prefiltered radiance L at every alpha (what
    // the SH and prefiltered lookups return for it, without their cost)
    #define ENV_IRRADIANCE(n) (PI * u_env_constant)
    #define ENV_PREFILTERED(r, a) (u_env_constant)
#else
    #define ENV_IRRADIANCE(n) env_irradiance(n)
    #define ENV_PREFILTERED(r, a) env_prefiltered(r, a)
#endif
#ifdef RAYTRACE
    if (false) {  // mirrors and smooth glass: the traced chain below replaces the lookups
#else
    if (u_env_on != 0) {
#endif
#ifdef THIN_SHELL
        if (on_ground) ground_l += u_ground_albedo * ENV_IRRADIANCE(vec3(0.0, 1.0, 0.0)) * INV_PI;
#endif
        // Environment light. Tables (viewer/brdf/albedo.py, the model's own sampler) give the
        // directional albedo rho(wo), its specular part rho_s (the model's ibl_split hook) and the
        // transmitted part; rho_d = rho - rho_s is treated as diffuse.
        int k0, k1;
        float fx;
        albedo_lerp(wo.z, k0, k1, fx);
        vec3 rho = mix(u_albedo[k0], u_albedo[k1], fx);
        vec3 rho_s = min(mix(u_albedo_s[k0], u_albedo_s[k1], fx), rho);
#ifdef THIN_SHELL
        if (shell_r.x >= 0.0) rho = rho_s = shell_r;  // its R at this height (above)
#endif
        vec3 rho_d = rho - rho_s;
        vec3 r_w = reflect(-wo_w, n);
        if (wo.z > 0.0) {
            if (u_ibl_mode == IBL_MODE_SPLIT_SUM || u_ibl_delta != 0 || SSR_ON) {
                // Split sum (Karis 2013): the lobe integral of the environment is the prefiltered
                // environment around the mirror direction times the lobe's albedo; the diffuse
                // part sees the irradiance (order-2 spherical harmonics). Exact for a constant
                // environment; no occlusion.
                // (with SSR the pass replaces the specular term where its ray hits the scene)
#ifdef ENV_OCCLUSION
                // traced mode: the diffuse part's irradiance with the scene's occlusion traced in
                // the BVH (common/specular_chain.glsl rt_occluded_irradiance)
                radiance += rho_d * rt_occluded_irradiance(v_position, n, ng, AO_RAYS) * INV_PI
                          + rho_s * ENV_PREFILTERED(r_w, u_ibl_alpha);
#else
                // (a shell's reflection that lands on the ground takes the ground's radiance, below)
                radiance += rho_d * ENV_IRRADIANCE(n) * INV_PI
                          + (on_ground ? vec3(0.0) : rho_s * ENV_PREFILTERED(r_w, u_ibl_alpha));
#endif
                if (u_ms_on != 0 && u_ibl_delta == 0) {
                    // Fdez-Aguera 2019, sec. 3-4: single scattering loses E_ms = 1 - E_ss of the
                    // energy; bounces return the geometric series F_ms = FssEss F_avg /
                    // (1 - E_ms F_avg), spread like a diffuse lobe. E_ss is the lobe's own
                    // albedo with F = 1 (table u_ms_ess, viewer/ms_compensation.py: any D, not only
                    // GGX), FssEss its albedo with its own Fresnel (the table rho_s).
                    float e_ms = clamp(1.0 - mix(u_ms_ess[k0], u_ms_ess[k1], fx), 0.0, 1.0);
                    vec3 f_avg = u_ms_f0 + (1.0 - u_ms_f0) / 21.0;
                    vec3 f_ms = rho_s * f_avg / (1.0 - e_ms * f_avg);
                    radiance += f_ms * e_ms * ENV_IRRADIANCE(n) * INV_PI;
                }
            } else {
#ifdef IBL_SAMPLED
                // only compiled into programs for the fis / brute_force modes: software GL pays
                // for an untaken loop of BRDF evaluations (measured: +65% frame time)
                radiance += ibl_sampled(wo, transpose(to_local), rho, rho_s, u_ibl_alpha,
                                        u_ibl_mode == IBL_MODE_FIS, u_frame_index)
                          + u_env_floor * ENV_IRRADIANCE(n);  // a file's constant part (split sum)
#endif
            }
        }
#ifndef THIN_SHELL  // a shell's transmission is the blend with the frame behind it (below)
        if (u_transmit_on != 0 && wo.z > 0.0) {
            // Glass: light refracted in crosses the object and leaves through the back. The
            // rasterizer's approximation: one straight traversal of length d = back - front
            // along the view ray with Bouguer attenuation exp(-sigma_a d), the radiance factor
            // ior^2 of leaving the denser medium, no exit Fresnel or internal bounces; the
            // environment is looked up along the ray refracted at the entry surface and bent
            // again by an exit surface taken parallel to the entry one mirrored through the
            // centre (exact for a sphere's central ray, and the straight line for a slab).
            float front = length(v_position - u_camera_pos);
            float back = texelFetch(u_thickness, ivec2(gl_FragCoord.xy), 0).r;
            float d = (any(greaterThan(u_sigma_a, vec3(0.0))) && back > front) ? back - front : 0.0;
            vec3 rho_t = mix(u_albedo_t[k0], u_albedo_t[k1], fx) * u_ior * u_ior;
            vec3 t_in = refract(-wo_w, n, 1.0 / u_ior);
            // a sphere's outward normal where the chord along t_in leaves: n - 2 (n.t) t
            vec3 n_out = reflect(n, t_in);
            vec3 t_out = refract(t_in, -n_out, u_ior);
            if (dot(t_out, t_out) == 0.0) t_out = reflect(t_in, -n_out);  // total internal reflection
            radiance += rho_t * exp(-u_sigma_a * d) * ENV_PREFILTERED(normalize(t_out), u_ibl_alpha);
        }
#endif
    }
#endif  // ENV_LIGHT
#ifdef SSR
    {
        // the same table lookup as the environment block, also when the environment is off
        // (reflections of the lit scene need the weight all the same)
        int k0, k1;
        float fx;
        albedo_lerp(wo.z, k0, k1, fx);
        vec3 rho = mix(u_albedo[k0], u_albedo[k1], fx);
        vec3 rho_s = wo.z > 0.0 ? min(mix(u_albedo_s[k0], u_albedo_s[k1], fx), rho) : vec3(0.0);
#ifdef RAYTRACE
        rho_s = vec3(0.0);  // the traced chain has the reflections already
#endif
        frag_spec = vec4(rho_s, u_ibl_alpha);
        frag_geom = vec4(n, -(u_view * vec4(v_position, 1.0)).z);
    }
#endif
#ifdef RAYTRACE
    radiance += rt_specular(v_position, wo_w, n, v_geometric_normal);
#endif
#ifdef THIN_SHELL
    // the fraction of the light behind the face that it lets through: its transmitted albedo
    // at this angle (air on both sides: no ior^2 factor), with Bouguer absorption over the
    // straight path to the far side where the inside absorbs; opaque in the term views
    vec3 shell_t = vec3(0.0);
    if (u_view_mode == VIEW_MODE_SHADED && wo.z <= 0.0) {
        // the interpolated normal turned away at the silhouette: nothing reflected, let the
        // light behind through rather than draw a black rim of samples
        radiance = vec3(0.0);
        shell_t = vec3(1.0);
    } else if (u_view_mode == VIEW_MODE_SHADED) {
        int k0, k1;
        float fx;
        albedo_lerp(wo.z, k0, k1, fx);
        float front = length(v_position - u_camera_pos);
        float back = texelFetch(u_thickness, ivec2(gl_FragCoord.xy), 0).r;
        float d = (gl_FrontFacing && any(greaterThan(u_sigma_a, vec3(0.0))) && back > front) ? back - front : 0.0;
        vec3 r_s = min(mix(u_albedo_s[k0], u_albedo_s[k1], fx), mix(u_albedo[k0], u_albedo[k1], fx));
        vec3 t_s = clamp(mix(u_albedo_t[k0], u_albedo_t[k1], fx), 0.0, 1.0);
        if (shell_r.x >= 0.0) {  // smooth: R at this height, and a lossless interface's T = 1 - R
            r_s = shell_r;
            t_s = 1.0 - shell_r;
        }
        shell_t = t_s * exp(-u_sigma_a * d);
        // its reflection of the ground (shell_ground_hit): R times the floor's radiance
        if (on_ground) radiance += r_s * ground_l;
    }
    frag_transmit = vec4(shell_t, 1.0);
#endif
    if (u_view_mode == VIEW_MODE_SHADED) {
        frag_color = vec4(radiance, 1.0);
    } else if (u_view_mode <= VIEW_MODE_G) {  // F, D, G in the order brdf_terms returns them
        float v = first_terms[u_view_mode - VIEW_MODE_F];
        // F and G linear in [0,1]; D on a log scale so peaks and tails are both visible (the
        // scales, generated from viewer/term_scales.py, which draws the colour bars)
        float t = u_view_mode == VIEW_MODE_D ? term_t(v, TERM_D_K, TERM_D_MAX)
                : u_view_mode == VIEW_MODE_F ? term_t(v, TERM_F_K, TERM_F_MAX) : term_t(v, TERM_G_K, TERM_G_MAX);
        frag_color = vec4(v < 0.0 ? vec3(TERM_NOT_APPLICABLE) : false_colour(t), 1.0);
    } else if (u_view_mode == VIEW_MODE_N_L) {
        frag_color = vec4(false_colour(term_t(first_ndotl, TERM_N_L_K, TERM_N_L_MAX)), 1.0);
    } else if (u_view_mode == VIEW_MODE_F_COS) {
        // f cos theta_i of the first light: its luminance, on a log scale
        float v = luminance(first_fcos);
        frag_color = vec4(false_colour(term_t(v, TERM_F_COS_K, TERM_F_COS_MAX)), 1.0);
    } else {
        frag_color = vec4(vec3(first_visibility), 1.0);  // light 0 visibility (shadow map)
    }
}
