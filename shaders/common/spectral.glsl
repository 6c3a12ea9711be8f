// The RGB Fresnel table of a spectral material (twin of viewer/brdf/spectral_fresnel.py):
// SPECTRAL_TABLE_N RGB samples at cos theta_j = (j / (N - 1))^2, stored in u_mat from float
// offset o (r, g, b per sample), interpolated linearly in sqrt(cos theta).
// Needs mat_f() (brdf/dispatch.glsl defines it before including the family files).
#include "generated/constants.glsl"

vec3 spectral_fresnel(int o, float cos_i) {
    float x = sqrt(clamp(cos_i, 0.0, 1.0)) * float(SPECTRAL_TABLE_N - 1);
    int i = min(int(floor(x)), SPECTRAL_TABLE_N - 2);
    float f = x - float(i);
    int a = o + 3 * i;
    vec3 r0 = vec3(mat_f(a), mat_f(a + 1), mat_f(a + 2));
    vec3 r1 = vec3(mat_f(a + 3), mat_f(a + 4), mat_f(a + 5));
    return r0 * (1.0 - f) + r1 * f;
}

// A thin film (n1, d_nm) on a tabulated base, from index 1: the base's own n, k at the film's 32
// wavelengths, stored after its RGB table (viewer/brdf/thin_film.py packed_base); as integrated,
// clipped at 0 (twin of reflectance_rgb with spectral_name). Needs common/fresnel.glsl.
vec3 thin_film_spectral_rgb(float cos_i, float n1, float d_nm, int o) {
    vec3 rgb = vec3(0.0);
#ifdef THIN_FILM
    int b = o + 3 * SPECTRAL_TABLE_N;
    int n = d_nm > 0.0 ? 32 : 0;
    for (int i = 0; i < n; ++i)
        rgb += fresnel_thin_film(cos_i, TF_NM[i], n1, d_nm, vec2(mat_f(b + 2 * i), mat_f(b + 2 * i + 1))) * TF_W[i];
#endif
    return max(rgb, vec3(0.0));
}
