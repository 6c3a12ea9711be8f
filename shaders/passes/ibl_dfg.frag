#version 410 core
// The split-sum DFG table on the GPU, in the convention of viewer/environment/dfg.py:
// pixel (x = j, y = i) holds (A, B) at NoV = (i + 0.5) / N, alpha = (j + 0.5) / N, so the
// texture read back row by row is table[i, j, :] and GLSL samples it as vec2(alpha, NoV).
// A = integral (f / F)(1 - Fc) cos dwi, B = integral (f / F) Fc cos dwi, Fc = (1 - v.h)^5
// (Karis 2013), GGX with height-correlated Smith G2. Visible-normal sampling (Heitz 2018,
// "Sampling the GGX Distribution of Visible Normals", JCGT 7(4)) gives the weight
// f cos / pdf = F G2 / G1(wo) = F (1 + Lambda_o) / (1 + Lambda_o + Lambda_i) (Heitz 2014 eq. 99).
// The quadrature points (u0, u1) and weights come from dfg.vndf_quadrature (a rim-graded
// Gauss-Legendre x midpoint rule, uploaded as a float texture) so that the GPU table and the
// numpy table integrate with the same rule; everything else is evaluated here.
#include "common/math.glsl"
#include "common/microfacet.glsl"

uniform sampler2D u_quad;   // texel k (row-major in a u_quad_width-wide texture): (u0, u1, weight)
uniform int u_quad_count;
uniform int u_quad_width;
uniform float u_size;
out vec4 frag_color;

// Heitz 2018 listing 1 (isotropic alpha here): stretch, sample the projected hemisphere, unstretch.
vec3 sample_vndf(vec3 wo, vec2 u, float alpha) {
    vec3 vh = normalize(vec3(alpha * wo.x, alpha * wo.y, wo.z));
    float lensq = vh.x * vh.x + vh.y * vh.y;
    vec3 t1 = lensq > 0.0 ? vec3(-vh.y, vh.x, 0.0) * inversesqrt(lensq) : vec3(1.0, 0.0, 0.0);
    vec3 t2 = cross(vh, t1);
    float r = sqrt(u.x);
    float phi = TWO_PI * u.y;
    float p1 = r * cos(phi);
    float p2 = r * sin(phi);
    float s = 0.5 * (1.0 + vh.z);
    p2 = (1.0 - s) * sqrt(max(0.0, 1.0 - p1 * p1)) + s * p2;
    vec3 nh = p1 * t1 + p2 * t2 + sqrt(max(0.0, 1.0 - p1 * p1 - p2 * p2)) * vh;
    return normalize(vec3(alpha * nh.x, alpha * nh.y, max(1e-7, nh.z)));
}

void main() {
    float nov = gl_FragCoord.y / u_size;   // (i + 0.5) / N
    float alpha = gl_FragCoord.x / u_size; // (j + 0.5) / N
    vec3 wo = vec3(sqrt(max(0.0, 1.0 - nov * nov)), 0.0, nov);
    float lam_o = lambda_ggx(wo, alpha, alpha);
    float A = 0.0;
    float B = 0.0;
    for (int k = 0; k < u_quad_count; ++k) {
        vec3 q = texelFetch(u_quad, ivec2(k % u_quad_width, k / u_quad_width), 0).xyz;
        vec3 m = sample_vndf(wo, q.xy, alpha);
        float vom = dot(wo, m);
        vec3 wi = 2.0 * vom * m - wo;
        if (wi.z <= 0.0 || vom <= 0.0) continue;
        float lam_i = lambda_ggx(wi, alpha, alpha);
        float w = (1.0 + lam_o) / (1.0 + lam_o + lam_i);
        float fc = pow(1.0 - clamp(vom, 0.0, 1.0), 5.0);
        A += q.z * w * (1.0 - fc);
        B += q.z * w * fc;
    }
    frag_color = vec4(A, B, 0.0, 1.0);
}
