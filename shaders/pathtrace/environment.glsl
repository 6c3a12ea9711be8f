// The environment light of the GPU path tracer: the same strategies as the CPU engine
// (viewer/reference_common/envmap.py). ENV_MODE_BLACK, ENV_MODE_CONSTANT (cosine hemisphere about the
// shading normal; uniform sphere on transmissive surfaces), ENV_MODE_MAP: lat-long map importance sampled by
// luminance x sin(theta) (pbrt-v3 14.2.4): a row from the marginal CDF, a column from the row's
// conditional CDF, then a uniform point in the texel; p(omega) = p(u, v) / (2 pi^2 sin theta).
#include "generated/constants.glsl"
#include "common/latlong.glsl"
#ifndef ENV_MODE
#define ENV_MODE ENV_MODE_BLACK
#endif
uniform vec3 u_env_constant;
uniform sampler2D u_env_map;      // rgb = radiance (intensity applied), a = texel probability * W * H
uniform sampler2D u_env_row_cdf;  // (H + 1) x 1 texels, r channel
uniform sampler2D u_env_col_cdf;  // (W + 1) x H texels, r channel
uniform mat3 u_env_to_map;        // world -> map rotation (mat3 columns as numpy rows: see engine)
uniform ivec2 u_env_size;         // (W, H)
const float INV_4PI = 0.07957747154594767;

ivec2 env_texel(vec2 uv) {
    int W = u_env_size.x, H = u_env_size.y;
    int col = int(floor(uv.x * float(W)));
    col = ((col % W) + W) % W;
    int row = clamp(int(floor(uv.y * float(H))), 0, H - 1);
    return ivec2(col, row);
}

vec3 env_eval(vec3 d) {
#if ENV_MODE == ENV_MODE_CONSTANT
    return u_env_constant;
#elif ENV_MODE == ENV_MODE_MAP
    return texelFetch(u_env_map, env_texel(env_dir_to_uv(u_env_to_map * d)), 0).rgb;
#else
    return vec3(0.0);
#endif
}

// Malley's method with the concentric map (Shirley and Chiu 1997), as viewer/brdf/sampling.py
vec3 cosine_hemisphere(vec2 u) {
    float a = 2.0 * u.x - 1.0, b = 2.0 * u.y - 1.0;
    if (a == 0.0 && b == 0.0) return vec3(0.0, 0.0, 1.0);
    float r, phi;
    if (abs(a) > abs(b)) { r = a; phi = (PI / 4.0) * (b / a); }
    else { r = b; phi = PI / 2.0 - (PI / 4.0) * (a / b); }
    float x = r * cos(phi), y = r * sin(phi);
    return vec3(x, y, sqrt(max(0.0, 1.0 - x * x - y * y)));
}

// Duff et al. 2017, "Building an Orthonormal Basis, Revisited"
void onb(vec3 n, out vec3 t, out vec3 b) {
    float s = n.z >= 0.0 ? 1.0 : -1.0;
    float a = -1.0 / (s + n.z);
    float c = n.x * n.y * a;
    t = vec3(1.0 + s * n.x * n.x * a, s * c, -s * n.x);
    b = vec3(c, s + n.y * n.y * a, -n.y);
}

// the row (or column) j with cdf[j] <= x < cdf[j + 1], j in [0, n - 1] (binary search)
int env_search_row(float x) {
    int lo = 0, hi = u_env_size.y;   // invariant: cdf[lo] <= x (cdf[0] = 0), answer < hi
    while (hi - lo > 1) {
        int mid = (lo + hi) >> 1;
        if (texelFetch(u_env_row_cdf, ivec2(mid, 0), 0).r <= x) lo = mid; else hi = mid;
    }
    return lo;
}
int env_search_col(int row, float x) {
    int lo = 0, hi = u_env_size.x;   // the largest j with cdf[j] < x (numpy: (cdf < x).sum() - 1)
    while (hi - lo > 1) {
        int mid = (lo + hi) >> 1;
        if (texelFetch(u_env_col_cdf, ivec2(mid, row), 0).r < x) lo = mid; else hi = mid;
    }
    return lo;
}

float env_map_pdf_uv(vec2 uv, ivec2 tx) {
    float st = sin(PI * clamp(uv.y, 0.0, 1.0));
    float p_uv = texelFetch(u_env_map, tx, 0).a;
    return st > 0.0 ? p_uv / (2.0 * PI * PI * st) : 0.0;
}

// a direction for next-event estimation: returns its radiance, sets wi and the solid-angle pdf
vec3 env_sample(vec2 u, vec3 n, bool two_sided, out vec3 wi, out float pdf) {
#if ENV_MODE == ENV_MODE_CONSTANT
    if (two_sided) {
        float z = 1.0 - 2.0 * u.x;
        float r = sqrt(max(0.0, 1.0 - z * z));
        float phi = TWO_PI * u.y;
        wi = vec3(r * cos(phi), r * sin(phi), z);
        pdf = INV_4PI;
    } else {
        vec3 l = cosine_hemisphere(u);
        vec3 t, b;
        onb(n, t, b);
        wi = l.x * t + l.y * b + l.z * n;
        pdf = l.z * INV_PI;
    }
    return u_env_constant;
#elif ENV_MODE == ENV_MODE_MAP
    int W = u_env_size.x, H = u_env_size.y;
    int row = env_search_row(u.y);
    float lo = texelFetch(u_env_row_cdf, ivec2(row, 0), 0).r;
    float hi = texelFetch(u_env_row_cdf, ivec2(row + 1, 0), 0).r;
    float fv = clamp((u.y - lo) / (hi > lo ? hi - lo : 1.0), 0.0, 0.99999994);
    int col = env_search_col(row, u.x);
    float clo = texelFetch(u_env_col_cdf, ivec2(col, row), 0).r;
    float chi = texelFetch(u_env_col_cdf, ivec2(col + 1, row), 0).r;
    float fu = clamp((u.x - clo) / (chi > clo ? chi - clo : 1.0), 0.0, 0.99999994);
    vec2 uv = vec2((float(col) + fu) / float(W), (float(row) + fv) / float(H));
    // map -> world: the transpose of the rotation
    wi = transpose(u_env_to_map) * env_uv_to_dir(uv);
    vec4 texel = texelFetch(u_env_map, ivec2(col, row), 0);
    float st = sin(PI * uv.y);
    pdf = st > 0.0 ? texel.a / (2.0 * PI * PI * st) : 0.0;
    return texel.rgb;
#else
    wi = n;
    pdf = 0.0;
    return vec3(0.0);
#endif
}

// the solid-angle density with which env_sample picks the world direction d
float env_pdf(vec3 d, vec3 n, bool two_sided) {
#if ENV_MODE == ENV_MODE_CONSTANT
    return two_sided ? INV_4PI : max(dot(d, n), 0.0) * INV_PI;
#elif ENV_MODE == ENV_MODE_MAP
    vec2 uv = env_dir_to_uv(u_env_to_map * d);
    return env_map_pdf_uv(uv, env_texel(uv));
#else
    return 0.0;
#endif
}
