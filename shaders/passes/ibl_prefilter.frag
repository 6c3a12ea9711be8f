#version 410 core
// GGX prefiltering of the lat-long map (viewer/gl/ibl.py): all levels alpha_1 .. alpha_{n-1} in
// one draw, stacked as bands of u_layer_size texels (band b = level b + 1, bottom first).
//
// Karis 2013 ("Real Shading in Unreal Engine 4"), split-sum first factor with n = v = r:
// half vectors h are drawn from D(h) (n.h) (Walter et al. 2007 eqs. 35-36; with v = n this is
// also Heitz 2018's visible-normal density, since D_v(h) = G1(v) (v.h) D(h) / (n.v) = D(h) (n.h)
// there), l = reflect(-v, h), and the estimate is sum L(l) (n.l) / sum (n.l). Its limit is
//     P(r) = integral L(l) D(h) max(0, r.l) dl / integral D(h) max(0, r.l) dl,  h = (r + l)/|r + l|,
// the integral the tests compare with. pdf(l) = D(h) (n.h) / (4 v.h) = D(h) / 4.
// Every radiance lookup is filtered (Colbert & Krivanek 2007, env_fis_lod_map): a tiny bright
// source is read from the mip level whose texels match the sample's solid angle, so it is
// spread over the lobe instead of hitting a few texels as fireflies.
// The sample set is the same Hammersley set for every texel: its error varies smoothly across
// the map (no per-texel noise).
#include "generated/constants.glsl"
#include "common/math.glsl"
#include "common/ibl.glsl"

uniform vec2 u_layer_size;               // (w, h) of one level
uniform int u_samples[IBL_MAX_LEVELS];    // samples per texel of each level
uniform float u_fis_bias;                 // Colbert & Krivanek's +1; below -50: no filtering (tests)
out vec4 frag_color;

vec2 hammersley(uint i, uint n) {
    return vec2((float(i) + 0.5) / float(n), float(bitfieldReverse(i)) * 2.3283064365386963e-10);
}

void main() {
    int band = int(gl_FragCoord.y / u_layer_size.y);
    int level = band + 1;
    float alpha = u_env_alphas[level];
    int n = u_samples[level];
    vec2 uv = vec2(gl_FragCoord.x, gl_FragCoord.y - float(band) * u_layer_size.y) / u_layer_size;
    vec3 N = env_uv_to_dir(uv);
    // orthonormal basis around N: Duff et al. 2017, "Building an Orthonormal Basis, Revisited"
    float sgn = N.z >= 0.0 ? 1.0 : -1.0;
    float a = -1.0 / (sgn + N.z);
    float b = N.x * N.y * a;
    vec3 T = vec3(1.0 + sgn * N.x * N.x * a, sgn * b, -sgn * N.x);
    vec3 B = vec3(b, sgn + N.y * N.y * a, -N.y);
    float a2 = alpha * alpha;
    vec3 sum = vec3(0.0);
    float wsum = 0.0;
    // With v = n, l = reflect(-n, h) is above the surface only for theta_h < 45 degrees, i.e.
    // cos^2(theta_h) > 1/2, i.e. xi < 1 / (1 + alpha^2) below: draw xi from that range only (at
    // alpha = 1 half of the plain samples would be wasted) and raise the pdf by the same factor.
    float xi_max = 1.0 / (1.0 + a2);
    for (int i = 0; i < n; ++i) {
        vec2 xi = hammersley(uint(i), uint(n));
        xi.x *= xi_max;
        // GGX: cos^2(theta_h) = (1 - xi) / (1 + (alpha^2 - 1) xi)   (Walter et al. 2007 eq. 35)
        float c2 = (1.0 - xi.x) / (1.0 + (a2 - 1.0) * xi.x);
        float nol = 2.0 * c2 - 1.0;   // n.l = cos(2 theta_h) with v = n
        if (nol <= 0.0) continue;
        float ct = sqrt(c2);
        float st = sqrt(max(0.0, 1.0 - c2));
        float phi = TWO_PI * xi.y;
        vec3 h = (T * cos(phi) + B * sin(phi)) * st + N * ct;
        vec3 l = 2.0 * ct * h - N;
        float q = c2 * (a2 - 1.0) + 1.0;
        float D = a2 / (PI * q * q);
        float pdf = 0.25 * D / xi_max;
        float lod = clamp(env_fis_lod_raw(pdf, n, l) + u_fis_bias, 0.0, u_env_max_lod);
        sum += env_map_lod(l, lod) * nol;
        wsum += nol;
    }
    frag_color = vec4(sum / max(wsum, 1e-30), 1.0);
}
