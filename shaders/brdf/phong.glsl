// Modified Phong, energy-normalized (Lafortune & Willems 1994, "Using the modified Phong
// reflectance model for physically based rendering", eqs. 1-3):
//   f = kd / pi + ks (n + 2) / (2 pi) cos^n(alpha_r),  alpha_r = angle(wi, mirror of wo).
// Twin of viewer/brdf/phong.py.

// Lafortune & Willems 1994, eq. 3: (n + 2) / (2 pi) cos^n(alpha_r), with
// 1 - cos(alpha_r) = |wi - r|^2 / 2 (exact where wi ~ r, the peak).
float phong_lobe_normalized(vec3 wi, vec3 wo, float n) {
    vec3 d = wi - vec3(-wo.x, -wo.y, wo.z);
    return (n + 2.0) / (2.0 * PI) * pow_one_minus(0.5 * dot(d, d), n);
}

vec3 phong_eval(phong_params p, vec3 wi, vec3 wo) {
    if (wi.z <= 0.0 || wo.z <= 0.0) return vec3(0.0);
    return p.kd * INV_PI + p.ks * phong_lobe_normalized(wi, wo, p.shininess);
}
