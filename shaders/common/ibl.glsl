// Image-based lighting lookups (GLSL 4.10). The textures and uniforms are made and bound by
// viewer/gl/ibl.py (IBL.bind); see its docstring for how each was built.
//
// Every public function takes WORLD-space directions; the environment rotation is applied here:
// u_env_rot = R_y(-rotation_deg) takes a world direction to the map's own frame, so
// L(d) = map(R_y(-rotation_deg) d) (docs/conventions.md, viewer/environment/latlong.py).
// Lat-long orientation: u = 0.5 + atan2(d.x, -d.z) / (2 pi), v = acos(d.y) / pi; the maps are
// uploaded with row 0 (the zenith) first, so the texture coordinate t equals v.
//
//   vec3  env_radiance(vec3 dir)                 the map itself (background, delta reflections)
//   vec3  env_radiance_lod(vec3 dir, float lod)  from the lat-long mip chain (solid-angle box)
//   vec3  env_irradiance(vec3 n)                 E(n) from SH9 (Ramamoorthi & Hanrahan 2001)
//   vec3  env_prefiltered(vec3 r, float alpha)   GGX-prefiltered radiance (split-sum 1st factor)
//   vec2  env_dfg(float n_dot_v, float alpha)    (A, B): E_ss = F0 A + B (Karis 2013)
//   float env_fis_lod(float pdf, int n_samples)  Colbert & Krivanek 2007 source mip level
#include "generated/constants.glsl"
#include "common/math.glsl"
#include "common/latlong.glsl"

uniform sampler2D u_env_map;               // lat-long radiance, full mip chain
uniform sampler2DArray u_env_prefiltered;  // layer k - 1 holds alpha = u_env_alphas[k], k >= 1
uniform sampler2D u_env_dfg;               // s = alpha, t = NoV; rg = (A, B)
uniform vec3 u_env_sh[9];                  // raw SH coefficients L_lm of the map (map frame)
uniform mat3 u_env_rot;                    // world -> map frame: R_y(-rotation_deg)
uniform float u_env_alphas[IBL_MAX_LEVELS];  // the prefiltered alphas; [0] = 0 = the map itself
uniform int u_env_num_levels;              // how many of u_env_alphas are used (>= 2)
uniform vec2 u_env_size;                   // (W, H) of level 0 of u_env_map
uniform float u_env_max_lod;               // last mip level of u_env_map

// ------------------------------------------------------------------ map-frame helpers
// env_dir_to_uv, env_uv_to_dir: common/latlong.glsl

// Radiance of the map's mip chain for a map-frame direction. textureLod everywhere: implicit
// derivatives would jump at the u = 0/1 seam and pick a wrong level along it.
vec3 env_map_lod(vec3 d_map, float lod) {
    return textureLod(u_env_map, env_dir_to_uv(d_map), lod).rgb;
}

// Colbert & Krivanek 2007 ("GPU-Based Importance Sampling", GPU Gems 3 ch. 20, eqs. 12-13):
// a sample of solid-angle density pdf, one of N, stands for Omega_s = 1 / (N pdf) steradians;
// read it from the level whose texels cover that: lod = 0.5 log2(Omega_s / Omega_p) + 1, where
// Omega_p is the solid angle of one level-0 texel and +1 is their bias toward the blurrier level
// (it trades a little extra blur for less noise). Omega_p here is the texel solid angle at the
// sample's latitude, (2 pi / W)(pi / H) sin(theta), floored at the pole row's.
float env_fis_lod_raw(float pdf, int n_samples, vec3 d_map) {   // without the +1 bias and clamp
    float st = sqrt(max(0.0, 1.0 - d_map.y * d_map.y / max(dot(d_map, d_map), 1e-30)));
    st = max(st, 0.5 * PI / u_env_size.y);
    float omega_p = (TWO_PI / u_env_size.x) * (PI / u_env_size.y) * st;
    float omega_s = 1.0 / max(float(n_samples) * pdf, 1e-30);
    return 0.5 * log2(omega_s / omega_p);
}

float env_fis_lod_map(float pdf, int n_samples, vec3 d_map) {
    return clamp(env_fis_lod_raw(pdf, n_samples, d_map) + 1.0, 0.0, u_env_max_lod);
}

// ------------------------------------------------------------------ public functions

vec3 env_radiance(vec3 dir) {
    return env_map_lod(u_env_rot * dir, 0.0);
}

vec3 env_radiance_lod(vec3 dir, float lod) {
    return env_map_lod(u_env_rot * dir, lod);
}

// Colbert & Krivanek 2007 with the MEAN texel solid angle Omega_p = 4 pi / (W H) (no direction
// given); env_fis_lod(pdf, n, dir) uses the texel solid angle at dir's latitude, as the
// prefiltering pass does.
float env_fis_lod(float pdf, int n_samples) {
    float omega_p = 4.0 * PI / (u_env_size.x * u_env_size.y);
    float omega_s = 1.0 / max(float(n_samples) * pdf, 1e-30);
    return clamp(0.5 * log2(omega_s / omega_p) + 1.0, 0.0, u_env_max_lod);
}

float env_fis_lod(float pdf, int n_samples, vec3 dir) {
    return env_fis_lod_map(pdf, n_samples, u_env_rot * dir);
}

// Irradiance E(n) = sum_lm A_l L_lm Y_lm(n), Ramamoorthi & Hanrahan 2001 eqs. 3, 7-8, 12-13,
// A_0 = pi, A_1 = 2 pi / 3, A_2 = pi / 4; the basis in the order and with the (x, y, z) of
// viewer/environment/sh.py. A Lambertian surface reflects albedo / pi * E. Order-2 SH ring
// (Gibbs) behind small bright sources and can dip below 0 there: E is clamped at 0.
vec3 env_irradiance(vec3 n) {
    vec3 d = u_env_rot * n;
    d /= max(length(d), 1e-30);
    float x = d.x, y = d.y, z = d.z;
    const float C0 = 0.28209479177387814;   // 1 / (2 sqrt(pi))
    const float C1 = 0.48860251190291992;   // sqrt(3 / 4pi)
    const float C2 = 1.09254843059207907;   // sqrt(15 / 4pi)
    const float C20 = 0.31539156525252005;  // sqrt(5 / 16pi)
    const float C22 = 0.54627421529603953;  // sqrt(15 / 16pi)
    const float A0 = PI;
    const float A1 = 2.0 * PI / 3.0;
    const float A2 = PI / 4.0;
    vec3 e = A0 * C0 * u_env_sh[0];
    e += A1 * C1 * (y * u_env_sh[1] + z * u_env_sh[2] + x * u_env_sh[3]);
    e += A2 * (C2 * (x * y * u_env_sh[4] + y * z * u_env_sh[5] + x * z * u_env_sh[7])
               + C20 * (3.0 * z * z - 1.0) * u_env_sh[6]
               + C22 * (x * x - y * y) * u_env_sh[8]);
    return max(e, vec3(0.0));
}

// GGX-prefiltered radiance for reflection direction r and GGX alpha (Walter et al. 2007's alpha,
// not perceptual roughness): linear interpolation in alpha between the two stored levels around
// alpha, exactly the list IBL.ALPHAS (u_env_alphas). Level 0 (alpha = 0) is the map itself at
// full resolution; alpha above the last level is clamped to it.
vec3 env_prefiltered(vec3 r, float alpha) {
    int n = max(u_env_num_levels, 2);
    float a = clamp(alpha, 0.0, u_env_alphas[n - 1]);
    int k = 0;
    for (int i = 1; i < IBL_MAX_LEVELS - 1; ++i) {
        if (i < n - 1 && a >= u_env_alphas[i]) k = i;
    }
    float a0 = u_env_alphas[k];
    float a1 = u_env_alphas[k + 1];
    float t = clamp((a - a0) / max(a1 - a0, 1e-12), 0.0, 1.0);
    vec2 uv = env_dir_to_uv(u_env_rot * r);
    vec3 c1 = textureLod(u_env_prefiltered, vec3(uv, float(k)), 0.0).rgb;
    if (t >= 1.0) return c1;
    vec3 c0 = (k == 0) ? textureLod(u_env_map, uv, 0.0).rgb
                       : textureLod(u_env_prefiltered, vec3(uv, float(k - 1)), 0.0).rgb;
    if (t <= 0.0) return c0;
    return mix(c0, c1, t);
}

// The split-sum DFG term (Karis 2013) of GGX with height-correlated Smith G2, in the convention
// of viewer/environment/dfg.py: the texture's s axis is alpha, its t axis NoV, r = A (scale on
// F0), g = B (bias): E_ss = F0 * A + B. Use F0 here, not F(v.h).
vec2 env_dfg(float n_dot_v, float alpha) {
    return texture(u_env_dfg, vec2(clamp(alpha, 0.0, 1.0), clamp(n_dot_v, 0.0, 1.0))).rg;
}
