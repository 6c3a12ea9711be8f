// Microfacet BRDF f = F G D / (4 cos_i cos_o) (lecture; Torrance & Sparrow 1967, Blinn 1977,
// Cook & Torrance 1981, Walter et al. 2007 eq. 20) plus the optional diffuse base
// kd / pi (1 - F(cos_i)) (1 - F(cos_o)). Twin of viewer/brdf/microfacet.py.
// Choice ids: MICROFACET_<PARAM>_<CHOICE> of generated/constants.glsl (from the spec).
#include "generated/constants.glsl"
#include "common/fresnel.glsl"
#include "common/microfacet.glsl"
#include "common/spectral.glsl"

vec3 microfacet_fresnel(microfacet_params p, float cos_i) {
    // a thin film on the dielectric or conductor (common/fresnel.glsl; Schlick has none)
    if (p.thin_film.thickness_nm > 0.0 && p.fresnel != MICROFACET_FRESNEL_SCHLICK) {
        // a tabulated base: its own n, k at the film's wavelengths (after its RGB table)
        if (p.spectral > MICROFACET_SPECTRAL_NONE)
            return thin_film_spectral_rgb(cos_i, p.thin_film.ior, p.thin_film.thickness_nm, p.spectral_offset);
        return p.fresnel == MICROFACET_FRESNEL_CONDUCTOR ? thin_film_conductor_rgb(cos_i, p.thin_film.ior, p.thin_film.thickness_nm, p.eta, p.k)
                              : thin_film_rgb(cos_i, p.thin_film.ior, p.thin_film.thickness_nm, vec3(p.ior), vec3(0.0));
    }
    if (p.spectral > MICROFACET_SPECTRAL_NONE) return spectral_fresnel(p.spectral_offset, cos_i);
    if (p.fresnel == MICROFACET_FRESNEL_DIELECTRIC) return vec3(fresnel_dielectric(clamp(cos_i, 0.0, 1.0), p.ior));
    if (p.fresnel == MICROFACET_FRESNEL_CONDUCTOR) return fresnel_conductor(cos_i, p.eta, p.k);
    return fresnel_schlick(cos_i, p.f0);
}

float microfacet_G(microfacet_params p, vec3 wi, vec3 wo, vec3 h) {
    if (p.shadowing == MICROFACET_SHADOWING_V_CAVITY) return G_v_cavity(wi, wo, h);
    float lam_i = mf_lambda(p.distribution, wi, p.alpha_x, p.alpha_y);
    float lam_o = mf_lambda(p.distribution, wo, p.alpha_x, p.alpha_y);
    // blinn_phong borrows Beckmann's Lambda (Walter 2007 sec. 5.2); the V-cavity cap (Heitz 2014
    // sec. 4.3) is blended in only where the albedo would exceed 1; see microfacet_dist.py
    if (p.distribution == MICROFACET_DISTRIBUTION_BLINN_PHONG) return G_blinn_smith(p.alpha_x, lam_i, lam_o, wi, wo, h);
    return smith_g2_height_correlated(lam_i, lam_o, wi, wo, h);
}

// (F averaged over RGB, D, G) for the term views; zero below the surface.
vec3 microfacet_terms(microfacet_params p, vec3 wi, vec3 wo) {
    if (wi.z <= 0.0 || wo.z <= 0.0) return vec3(0.0);
    vec3 h = normalize_safe(wi + wo);
    vec3 F = microfacet_fresnel(p, dot(wi, h));
    float D = mf_D(p.distribution, h, p.alpha_x, p.alpha_y);
    return vec3((F.r + F.g + F.b) / 3.0, D, microfacet_G(p, wi, wo, h));
}

vec3 microfacet_eval(microfacet_params p, vec3 wi, vec3 wo) {
    if (wi.z <= 0.0 || wo.z <= 0.0) return vec3(0.0);
    float den = 4.0 * wi.z * wo.z;  // may underflow at grazing angles: ratio_capped caps at F_MAX
    vec3 h = normalize_safe(wi + wo);
    vec3 F = microfacet_fresnel(p, dot(wi, h));
    float D = mf_D(p.distribution, h, p.alpha_x, p.alpha_y);
    float G = microfacet_G(p, wi, wo, h);
    vec3 f = F * ratio_capped(D * G, den);
    if (any(greaterThan(p.kd, vec3(0.0)))) {
        vec3 Fi = microfacet_fresnel(p, wi.z);
        vec3 Fo = microfacet_fresnel(p, wo.z);
        f += p.kd * INV_PI * max(1.0 - Fi, vec3(0.0)) * max(1.0 - Fo, vec3(0.0));
    }
    return f;
}

// ---- sampling twin of viewer/brdf/microfacet.py: visible normals (GGX, Beckmann) or D cos
// (blinn_phong) for the specular lobe, cosine for the diffuse base, the diffuse lobe chosen with
// P_d = mean(kd (1 - F(cos_o))) / (mean(kd (1 - F(cos_o))) + mean(F(cos_o))).
#include "common/sampling.glsl"

float microfacet_p_diffuse(microfacet_params p, vec3 wo) {
    if (!any(greaterThan(p.kd, vec3(0.0)))) return 0.0;
    vec3 Fo = microfacet_fresnel(p, wo.z);
    float wd = dot(p.kd * max(1.0 - Fo, vec3(0.0)), vec3(1.0 / 3.0));
    float ws = dot(Fo, vec3(1.0 / 3.0));
    float tot = wd + ws;
    return tot > 0.0 ? wd / tot : 0.0;
}

float microfacet_pdf(microfacet_params p, vec3 wi, vec3 wo) {
    if (wi.z <= 0.0 || wo.z <= 0.0) return 0.0;
    float pd = microfacet_p_diffuse(p, wo);
    vec3 h = normalize_safe(wi + wo);
    float oh = dot(wo, h);
    // reflection Jacobian dm / dwi = 1 / (4 |wo.m|) (Walter et al. 2007, eq. 14)
    float spec = oh > 0.0 ? mf_pdf_m(p.distribution, wo, h, p.alpha_x, p.alpha_y) / (4.0 * oh) : 0.0;
    return (1.0 - pd) * spec + pd * wi.z * INV_PI;
}

vec3 microfacet_sample(microfacet_params p, vec3 wo, vec3 u, out vec3 wi, out float pdf, out uint lobe) {
    lobe = LOBE_REFLECTION | LOBE_GLOSSY | (any(greaterThan(p.kd, vec3(0.0))) ? LOBE_DIFFUSE : LOBE_NONE);  // microfacet.lobes (viewer/brdf/microfacet.py)
    bool up = wo.z > 0.0;
    vec3 wo_s = up ? wo : vec3(0.0, 0.0, 1.0);
    float pd = microfacet_p_diffuse(p, wo_s);
    bool choose_d = u.x < pd;
    float u0 = choose_d ? u.x / (pd > 0.0 ? pd : 1.0) : (u.x - pd) / (pd < 1.0 ? 1.0 - pd : 1.0);
    vec2 uu = vec2(clamp(u0, 0.0, ONE_MINUS_EPS), u.y);
    wi = choose_d ? sample_cosine_hemisphere(uu)
                  : reflect_about(wo_s, mf_sample_m(p.distribution, wo_s, uu, p.alpha_x, p.alpha_y));
    pdf = microfacet_pdf(p, wi, wo);
    if (!up || wi.z <= 0.0) pdf = 0.0;
    return sample_weight(microfacet_eval(p, wi, wo), wi.z, pdf);
}
