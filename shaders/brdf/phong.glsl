// Modified Phong, energy-normalized (Lafortune & Willems 1994, "Using the modified Phong
// reflectance model for physically based rendering", eqs. 1-3):
//   f = kd / pi + ks (n + 2) / (2 pi) cos^n(alpha_r),  alpha_r = angle(wi, mirror of wo).
// Twin of viewer/brdf/phong.py.

// log(1 - x) for x in [0, 1). Near 0 (sharp lobes, x = 1 - cos tiny) the series keeps full precision,
// where rounding 1 - x first would cost n ulps in cos^n (6e-4 relative at n = 10000 in float32).
float phong_log1m(float x) {
    if (x < 0.2) {
        // -(x + x^2/2 + ... + x^12/12); the first dropped term is < 1e-9 relative
        float s = 1.0 / 12.0;
        s = 1.0 / 11.0 + x * s; s = 1.0 / 10.0 + x * s; s = 1.0 / 9.0 + x * s;
        s = 1.0 / 8.0 + x * s;  s = 1.0 / 7.0 + x * s;  s = 1.0 / 6.0 + x * s;
        s = 1.0 / 5.0 + x * s;  s = 1.0 / 4.0 + x * s;  s = 1.0 / 3.0 + x * s;
        s = 1.0 / 2.0 + x * s;  s = 1.0 + x * s;
        return -x * s;
    }
    return log(1.0 - x);
}

// (1 - x)^n for x in [0, 1], 0 at x >= 1 (no log(0), no pow(0, 0)).
float phong_pow_one_minus(float x, float n) {
    if (x >= 1.0) return 0.0;
    return exp(n * phong_log1m(x));
}

// Lafortune & Willems 1994, eq. 3: (n + 2) / (2 pi) cos^n(alpha_r), with
// 1 - cos(alpha_r) = |wi - r|^2 / 2 (exact where wi ~ r, the peak).
float phong_lobe_normalized(vec3 wi, vec3 wo, float n) {
    vec3 d = wi - vec3(-wo.x, -wo.y, wo.z);
    return (n + 2.0) / (2.0 * PI) * phong_pow_one_minus(0.5 * dot(d, d), n);
}

vec3 phong_eval(phong_params p, vec3 wi, vec3 wo) {
    if (wi.z <= 0.0 || wo.z <= 0.0) return vec3(0.0);
    return p.kd * INV_PI + p.ks * phong_lobe_normalized(wi, wo, p.shininess);
}
