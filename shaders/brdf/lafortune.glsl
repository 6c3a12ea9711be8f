// Lafortune, Foo, Torrance & Greenberg 1997, "Non-linear approximation of reflectance functions",
// Sec. 3: f = kd / pi + sum_j max(0, Cx wi.x wo.x + Cy wi.y wo.y + Cz wi.z wo.z)^n_j.
// lobes[j] = (cx, cy, cz, n). Twin of viewer/brdf/lafortune.py.

// One generalized cosine lobe: with v = C o wo, (v . wi)^n = |v|^n cos^n(angle(wi, v)); evaluated as
// exp(n (log|v| + log(1 - x))), x = |wi - v/|v||^2 / 2, so a sharp lobe keeps its precision, n = 0 never
// meets pow(0, 0), and values are clamped at e^80 (far outside energy conservation) instead of overflowing.
// log|v| = log(1 - L) / 2 with L = 1 - |v|^2 = sum_k wo_k^2 (1 - C_k)(1 + C_k) (wo unit): no cancellation
// when |C| ~ 1, where one rounding of |v|^2 would cost n ulps.
float lafortune_lobe(vec4 lobe, vec3 wi, vec3 wo) {
    vec3 v = lobe.xyz * wo;
    float len = length(v);
    if (len <= 0.0) return 0.0;
    float L = dot(wo * wo, (1.0 - lobe.xyz) * (1.0 + lobe.xyz));
    // the L form where |v| is near 1; the plain log|v| where |v| is small (L ~ 1 would cancel there)
    float log_len = L <= 0.5 ? 0.5 * log1m(L) : log(len);
    vec3 d = wi - v / len;
    float x = 0.5 * dot(d, d);
    if (x >= 1.0) return 0.0;
    return exp(min(lobe.w * (log_len + log1m(x)), 80.0));
}

vec3 lafortune_eval(lafortune_params p, vec3 wi, vec3 wo) {
    if (wi.z <= 0.0 || wo.z <= 0.0) return vec3(0.0);
    float spec = 0.0;
    for (int j = 0; j < 4; ++j) {
        if (j >= p.lobes_count) break;
        spec += lafortune_lobe(p.lobes[j], wi, wo);
    }
    return p.kd * INV_PI + vec3(spec);
}
