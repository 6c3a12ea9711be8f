// Layered BRDF (Weidlich & Wilkie 2007), twin of viewer/brdf/layered.py:
//   f = f_coat(wi, wo) + T(cos_i) T(cos_o) a f_base(wi', wo') / eta^2
// f_coat: GGX reflection with dielectric F and height-correlated Smith G (Walter 2007 eq. 20,
// Heitz 2014 eq. 99); wi', wo': refracted into the layer, pointing up; T = 1 - E (the coat's albedo) at the
// macro-surface angles; a = exp(-sigma_a thickness (1/cos_ti' + 1/cos_to')) (Bouguer);
// 1 / eta^2: the radiance leaving the layer is the radiance inside over eta^2 (L / n^2 invariant).
// The coat-base interreflections after the first bounce, for every non-delta base, from the base's
// tables computed on the CPU (layered.py base_bounce_tables: E_b, A_b, rho_K).
// A thin film on the coating (p.coating.thin_film): the coat's F becomes the film's RGB R over the
// coat's ior, its albedo E + R_film - F (exact for a smooth coat). R_film
// is a table over cos computed once per material on the CPU (viewer/brdf/layered.py film_table,
// in the derived block after the albedo table, a film flag and K): no wavelength loop here, so a coat film
// compiles as fast as none. Only under COAT_FILM (viewer/gl/brdf_glsl.py program_defines).
// The base is any non-layered material, evaluated through the generated brdf_eval_base().
#include "generated/constants.glsl"
#include "common/fresnel.glsl"
#include "common/microfacet.glsl"

// w refracted into the layer through the mean surface (normal +z), pointing up.
vec3 layered_refract_in(vec3 w, float eta) {
    vec2 xy = w.xy / eta;
    return vec3(xy, sqrt(max(0.0, 1.0 - dot(xy, xy))));
}

#ifdef COAT_FILM
// the film table's first entry, R at grazing incidence: 1 with a film, 0 without
bool layered_has_film(layered_params p) { return p.derived[LAYERED_COAT_TABLE] > 0.5; }

// The film's RGB R at cos, from the table at cos = (k / (N - 1))^2: linear in sqrt(cos).
vec3 layered_film_table(layered_params p, float c) {
    float x = sqrt(clamp(c, 0.0, 1.0)) * float(LAYERED_FILM_TABLE - 1);
    int i = min(int(floor(x)), LAYERED_FILM_TABLE - 2);
    int o = p.derived_at + LAYERED_COAT_TABLE + 3 * i;  // from the material block itself
    vec3 r0 = vec3(mat_f(o), mat_f(o + 1), mat_f(o + 2));
    vec3 r1 = vec3(mat_f(o + 3), mat_f(o + 4), mat_f(o + 5));
    return mix(r0, r1, x - float(i));
}
#endif

// The coat surface's reflectance at cos (from outside): dielectric F, or the thin film's RGB R.
vec3 layered_coat_fresnel(layered_params p, float c) {
    c = clamp(c, 0.0, 1.0);
#ifdef COAT_FILM
    if (layered_has_film(p)) return layered_film_table(p, c);
#endif
    return vec3(fresnel_dielectric(c, p.coating.ior));
}

vec3 layered_coat(layered_params p, vec3 wi, vec3 wo) {
    vec3 h = normalize_safe(wi + wo);
    float a = p.coating.alpha;
    vec3 F = layered_coat_fresnel(p, dot(wi, h));
    float G = smith_g2_height_correlated(lambda_ggx(wi, a, a), lambda_ggx(wo, a, a), wi, wo, h);
    return F * ratio_capped(G * D_ggx(h, a, a), 4.0 * wi.z * wo.z);
}

// E(cos), the coat's own directional albedo, from the 24-entry table at cos = k / 23 that
// viewer/brdf/layered.py (coat_albedo_table) puts in the material block; linear interpolation.
float layered_coat_albedo(layered_params p, float c) {
    float x = clamp(c, 0.0, 1.0) * float(LAYERED_COAT_TABLE - 1);
    int i = min(int(floor(x)), LAYERED_COAT_TABLE - 2);
    return mix(p.derived[i], p.derived[i + 1], x - float(i));
}

// E per channel: with a thin film on the coating E + R_film - F, clipped (coat_albedo_rgb).
vec3 layered_coat_albedo_rgb(layered_params p, float c) {
    vec3 E = vec3(layered_coat_albedo(p, c));
#ifdef COAT_FILM
    if (layered_has_film(p))
        E = clamp(E + layered_film_table(p, c) - fresnel_dielectric(clamp(c, 0.0, 1.0), p.coating.ior), 0.0, 1.0);
#endif
    return E;
}

// The base's interreflection tables (viewer/brdf/layered.py base_bounce_tables), after the film's
// in the material block: E_b (which = 0) or A_b (which = 1) at the outside cosine c, linear in
// sqrt(c).
vec3 layered_base_table(layered_params p, int which, float c) {
    float x = sqrt(clamp(c, 0.0, 1.0)) * float(LAYERED_BASE_TABLE - 1);
    int i = min(int(floor(x)), LAYERED_BASE_TABLE - 2);
    int o = p.derived_at + LAYERED_BASE_TABLES_AT + which * 3 * LAYERED_BASE_TABLE + 3 * i;
    vec3 r0 = vec3(mat_f(o), mat_f(o + 1), mat_f(o + 2));
    vec3 r1 = vec3(mat_f(o + 3), mat_f(o + 4), mat_f(o + 5));
    return mix(r0, r1, x - float(i));
}

// The orders after the first of the coat-base interreflections (base_interreflections):
// (A_b(mu_i) E_b(mu_o) + E_b(mu_i) A_b(mu_o)) / (2 pi (1 - rho_K)); for a Lambert base the
// geometric series 1 / (1 - rho K) of its albedo, zero for a delta base.
vec3 layered_base_interreflections(layered_params p, vec3 wi, vec3 wo) {
    int o = p.derived_at + LAYERED_BASE_TABLES_AT + 6 * LAYERED_BASE_TABLE;
    vec3 rk = vec3(mat_f(o), mat_f(o + 1), mat_f(o + 2));
    vec3 num = layered_base_table(p, 1, wi.z) * layered_base_table(p, 0, wo.z)
             + layered_base_table(p, 0, wi.z) * layered_base_table(p, 1, wo.z);
    return num / (2.0 * PI * max(1.0 - rk, vec3(1e-6)));
}

vec3 layered_eval(layered_params p, vec3 wi, vec3 wo) {
    if (wi.z <= 0.0 || wo.z <= 0.0) return vec3(0.0);
    if (wi.z * wo.z <= 0.0) return vec3(0.0);  // both cosines underflowed
    float eta = p.coating.ior;
    vec3 f = layered_coat(p, wi, wo);
    vec3 wi_t = layered_refract_in(wi, eta);
    vec3 wo_t = layered_refract_in(wo, eta);
    // T = 1 - E: what the (rough) coat does not reflect enters the layer
    vec3 Ti = 1.0 - layered_coat_albedo_rgb(p, wi.z);
    vec3 To = 1.0 - layered_coat_albedo_rgb(p, wo.z);
    float path = 1.0 / max(wi_t.z, 1e-12) + 1.0 / max(wo_t.z, 1e-12);
    vec3 absorb = exp(-p.coating.sigma_a * (p.coating.thickness * path));
    vec3 fb = brdf_eval_base(p.base_model, p.base_offset, wi_t, wo_t)
            + layered_base_interreflections(p, wi, wo);
    f += (Ti * To / (eta * eta)) * absorb * fb;
    return f;
}

// ---- sampling twin of viewer/brdf/layered.py: the coat lobe (GGX visible normals) with
// probability P_c = F(cos_o), else the base's own sample with wo' (refracted in), the result
// refracted out; pdf converted by the solid-angle Jacobian cos_i / (eta^2 cos_i'). The choice
// is u.z (numpy: split_uniform(u[:, 0]) = (u.z, u.x)); the base gets (u.x, u.y, (u.z - P_c) /
// (1 - P_c)). A delta base is a discrete lobe: pdf (1 - P_c) pdf_base, weight its throughput.
// The base goes through the generated brdf_sample_base / brdf_pdf_base; its lobe's kind is the
// sample's (a DELTA base lobe is discrete), reflected.
#include "common/sampling.glsl"

// A direction inside the layer (z > 0) refracted out; ok = false under total internal reflection.
vec3 layered_refract_out(vec3 w, float eta, out bool ok) {
    vec2 xy = w.xy * eta;
    float s2 = dot(xy, xy);
    ok = s2 < 1.0;
    return vec3(xy, sqrt(max(0.0, 1.0 - s2)));
}

float layered_pdf(layered_params p, vec3 wi, vec3 wo) {
    if (wi.z <= 0.0 || wo.z <= 0.0) return 0.0;
    float eta = p.coating.ior;
    float a = p.coating.alpha;
    float pc = fresnel_dielectric(clamp(wo.z, 0.0, 1.0), eta);
    vec3 h = normalize_safe(wi + wo);
    float oh = dot(wo, h);
    float coat = oh > 0.0 ? mf_D_visible(MICROFACET_DISTRIBUTION_GGX, wo, h, a, a) / (4.0 * oh) : 0.0;
    vec3 wi_t = layered_refract_in(wi, eta);
    vec3 wo_t = layered_refract_in(wo, eta);
    float pb = brdf_pdf_base(p.base_model, p.base_offset, wi_t, wo_t);
    // solid-angle Jacobian of refraction: dw' / dw = cos_i / (eta^2 cos_i')
    float jac = wi.z / (eta * eta * max(wi_t.z, 1.17549435e-38));
    return pc * coat + (1.0 - pc) * pb * jac;
}

vec3 layered_sample(layered_params p, vec3 wo, vec3 u, out vec3 wi, out float pdf, out uint lobe) {
    bool up = wo.z > 0.0;
    vec3 wo_s = up ? wo : vec3(0.0, 0.0, 1.0);
    float eta = p.coating.ior;
    float a = p.coating.alpha;
    float pc = fresnel_dielectric(clamp(wo_s.z, 0.0, 1.0), eta);
    bool coat = u.z < pc;
    lobe = LOBE_REFLECTION | LOBE_GLOSSY;
    if (coat) {
        wi = reflect_about(wo_s, sample_vndf_ggx(wo_s, u.xy, a, a));
        pdf = (up && wi.z > 0.0) ? layered_pdf(p, wi, wo) : 0.0;
        return sample_weight(layered_eval(p, wi, wo), wi.z, pdf);
    }
    vec3 wo_t = layered_refract_in(wo_s, eta);
    float uz = clamp((u.z - pc) / max(1.0 - pc, 1.17549435e-38), 0.0, ONE_MINUS_EPS);
    vec3 wi_t;
    float pdf_b;
    uint lobe_b;
    vec3 w_b = brdf_sample_base(p.base_model, p.base_offset, wo_t, vec3(u.xy, uz), wi_t, pdf_b, lobe_b);
    lobe = (lobe_b & LOBE_KINDS) | LOBE_REFLECTION;
    bool ok_out;
    wi = layered_refract_out(wi_t, eta, ok_out);
    bool ok = up && wi.z > 0.0 && ok_out && pdf_b > 0.0 && wi_t.z > 0.0;
    if (!ok) { pdf = 0.0; return vec3(0.0); }
    if (lobe_has_delta(lobe_b)) {
        // discrete base lobe: throughput T_i T_o a w_b (the eta^2 into and out of the layer cancel)
        vec3 wi_in = layered_refract_in(wi, eta);
        vec3 Ti = vec3(fresnel_dielectric_transmittance(min(wi.z, 1.0), eta));
        vec3 To = vec3(fresnel_dielectric_transmittance(min(wo_s.z, 1.0), eta));
#ifdef COAT_FILM
        if (layered_has_film(p)) {  // the film's change of R at the macro angles
            Ti = clamp(Ti - layered_film_table(p, wi.z) + fresnel_dielectric(min(wi.z, 1.0), eta), 0.0, 1.0);
            To = clamp(To - layered_film_table(p, wo_s.z) + fresnel_dielectric(min(wo_s.z, 1.0), eta), 0.0, 1.0);
        }
#endif
        float path = 1.0 / max(wi_in.z, 1e-12) + 1.0 / max(wo_t.z, 1e-12);
        vec3 absorb = exp(-p.coating.sigma_a * (p.coating.thickness * path));
        pdf = (1.0 - pc) * pdf_b;
        if (!(pdf > 0.0)) { pdf = 0.0; return vec3(0.0); }
        return Ti * To * absorb * w_b / max(1.0 - pc, 1.17549435e-38);
    }
    pdf = layered_pdf(p, wi, wo);
    return sample_weight(layered_eval(p, wi, wo), wi.z, pdf);
}
