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

// ---- sampling twin of viewer/brdf/lafortune.py: cosine for kd, a cos^n lobe about
// normalize(C o wo) per lobe, picked in proportion to luminance(kd) and each lobe's estimated
// albedo |v|^n 2 pi / (n + 1) max(axis.z, 0.1) (common/sampling.glsl).
#include "common/sampling.glsl"

// The lobe's peak direction normalize(C o wo) and log|C o wo| (-1e30 where it vanishes), with
// log|v| = log(1 - L) / 2, L = sum_k wo_k^2 (1 - C_k)(1 + C_k), where |v| is near 1 (lobe_axis).
vec3 lafortune_axis(vec4 lobe, vec3 wo, out float log_len) {
    vec3 w = wo / length(wo);
    vec3 v = lobe.xyz * w;
    float len = length(v);
    if (len <= 0.0) { log_len = -1e30; return vec3(0.0, 0.0, 1.0); }
    float L = dot(w * w, (1.0 - lobe.xyz) * (1.0 + lobe.xyz));
    log_len = L <= 0.5 ? 0.5 * mf_log1p(-L) : log(len);
    return v / len;
}

// Selection probabilities: [0] the cosine part, [1 + j] lobe j (rows sum to 1).
void lafortune_probabilities(lafortune_params p, vec3 wo, out float probs[5]) {
    probs[0] = luminance(p.kd);
    float total = probs[0];
    for (int j = 0; j < 4; ++j) {
        probs[j + 1] = 0.0;
        if (j >= p.lobes_count) continue;
        float log_len;
        vec3 axis = lafortune_axis(p.lobes[j], wo, log_len);
        if (log_len <= -1e30) continue;
        float n = p.lobes[j].w;
        float w = exp(min(n * log_len, 80.0)) * TWO_PI / (n + 1.0);
        probs[j + 1] = w * clamp(axis.z, 0.1, 1.0);
        total += probs[j + 1];
    }
    for (int j = 0; j < 5; ++j) probs[j] = total > 0.0 ? probs[j] / total : (j == 0 ? 1.0 : 0.0);
}

float lafortune_pdf_probs(lafortune_params p, vec3 wi, vec3 wo, float probs[5]) {
    if (wi.z <= 0.0 || wo.z <= 0.0) return 0.0;
    float val = probs[0] * cosine_hemisphere_pdf(wi);
    for (int j = 0; j < 4; ++j) {
        if (j >= p.lobes_count) break;
        float log_len;
        vec3 axis = lafortune_axis(p.lobes[j], wo, log_len);
        vec3 d = wi - axis;
        float n = p.lobes[j].w;
        val += probs[j + 1] * ((n + 1.0) / TWO_PI * pow_one_minus(0.5 * dot(d, d), n));
    }
    return val;
}

float lafortune_pdf(lafortune_params p, vec3 wi, vec3 wo) {
    float probs[5];
    lafortune_probabilities(p, wo, probs);
    return lafortune_pdf_probs(p, wi, wo, probs);
}

vec3 lafortune_sample(lafortune_params p, vec3 wo, vec3 u, out vec3 wi, out float pdf, out uint lobe) {
    lobe = LOBE_REFLECTION | LOBE_DIFFUSE | LOBE_GLOSSY;  // lafortune.lobes (viewer/brdf/lafortune.py)
    float probs[5];
    lafortune_probabilities(p, wo, probs);
    // pick_lobe: the first interval whose cumulative sum exceeds u.x (the last one closes at 1)
    int count = 1 + min(p.lobes_count, 4);
    int k = count - 1;
    float lo = 0.0, cdf = 0.0;
    for (int j = 0; j < 5; ++j) {
        if (j >= count) break;
        float c = j == count - 1 ? max(cdf + probs[j], 1.0) : cdf + probs[j];
        if (u.x < c) { k = j; lo = cdf; break; }
        cdf = c;
    }
    if (k == count - 1 && u.x >= cdf) lo = cdf;
    float width = probs[k];
    float u0 = clamp(width > 0.0 ? (u.x - lo) / width : 0.0, 0.0, ONE_MINUS_EPS);
    vec2 uu = vec2(u0, u.y);
    wi = sample_cosine_hemisphere(uu);
    for (int j = 0; j < 4; ++j) {
        if (j + 1 != k) continue;
        float log_len;
        vec3 axis = lafortune_axis(p.lobes[j], wo, log_len);
        wi = to_world(sample_power_cosine(uu, p.lobes[j].w), axis);
    }
    pdf = lafortune_pdf_probs(p, wi, wo, probs);
    // f is clamped at e^80 but the pdf is not: a huge lobe's far tail fails in sample_weight
    return sample_weight(lafortune_eval(p, wi, wo), wi.z, pdf);
}
