// Dielectric interface, twin of viewer/brdf/dielectric.py. alpha = 0 is smooth glass: two delta
// lobes, so eval is 0 (the rasterizer handles reflection/refraction itself). alpha > 0: rough
// GGX interface after Walter et al. 2007 (eq. 20 reflection, eq. 21 transmission, eq. 16 the
// generalized half vector), height-correlated Smith G (Heitz 2014: eq. 99 reflection, the Beta
// function B(1 + Lambda_o, 1 + Lambda_i) of sec. 5.3 refraction), with pbrt-v4's
// radiance-mode 1 / eta^2 on transmission. wi may be below the surface (transmission).
// sigma_a is applied by the path tracer along the path inside, not here.
#include "generated/constants.glsl"
#include "common/fresnel.glsl"
#include "common/microfacet.glsl"

// Float only (32-bit throughout: Apple's OpenGL 4.1 on Apple silicon has no fp64). The care needed:
// T = 1 - R is ill-conditioned near total internal reflection. The textbook route,
// cos_t = sqrt(1 - (1 - cos_i^2) / eta^2), subtracts two numbers of size ~eta^2 whose difference
// cos_t^2 is tiny there: an absolute rounding error of ~1e-7 in cos_i^2 becomes a relative error
// of 1e-7 / cos_t^2 in cos_t (percents within 1e-3 rad of the critical angle). For a transmission
// pair the facet normal m is the generalized half vector, and Snell's law holds at m by
// construction: the refracted cosine IS |wi . m|, which float computes with an absolute error of
// ~1e-7, i.e. a relative error of only 1e-7 / cos_t. So T takes both cosines as they are:
// T = 1 - (r_s^2 + r_p^2) / 2 written as 4 eta cos_i cos_t / (cos_i + eta cos_t)^2 (s) and
// 4 eta cos_i cos_t / (eta cos_i + cos_t)^2 (p), sums of positive terms without cancellation.
float dielectric_transmittance_cos(float cos_i, float cos_t, float eta) {
    float num = 4.0 * eta * cos_i * cos_t;
    float ds = cos_i + eta * cos_t;
    float dp = eta * cos_i + cos_t;
    float Ts = ds > 0.0 ? num / (ds * ds) : 0.0;
    float Tp = dp > 0.0 ? num / (dp * dp) : 0.0;
    return 0.5 * (Ts + Tp);
}

vec3 dielectric_eval(dielectric_params p, vec3 wi, vec3 wo) {
    if (p.alpha <= 0.0) return vec3(0.0);
    // work in the frame where wo is up; eta is the relative index seen from wo
    float s = wo.z < 0.0 ? -1.0 : 1.0;
    float eta = s > 0.0 ? p.ior : 1.0 / p.ior;
    wo.z *= s;
    wi.z *= s;
    float co = wo.z, ci = wi.z;
    if (co <= 0.0 || ci == 0.0) return vec3(0.0);
    bool refl = ci > 0.0;
    float etap = refl ? 1.0 : eta;
    // generalized half vector (Walter et al. 2007 eq. 16). |h| >= |1 - eta| for transmission, so
    // h is well away from 0 except for ior = 1, where refraction goes straight on anyway.
    vec3 h = wi * etap + wo;
    float hlen2 = dot(h, h);
    if (hlen2 <= 0.0) return vec3(0.0);
    vec3 wm = h * inversesqrt(hlen2);
    if (wm.z < 0.0) wm = -wm;
    float imd = dot(wi, wm), omd = dot(wo, wm);
    if (imd * ci <= 0.0 || omd * co <= 0.0) return vec3(0.0);
    float D = D_ggx(wm, p.alpha, p.alpha);
    float lam_i = lambda_ggx(wi, p.alpha, p.alpha), lam_o = lambda_ggx(wo, p.alpha, p.alpha);
    // Heitz 2014: eq. 99 for reflection, the Beta-function form (sec. 5.3) for refraction
    float G = refl ? smith_g2_height_correlated(lam_i, lam_o, wi, wo, wm)
                   : smith_g2_height_correlated_transmission(lam_i, lam_o, wi, wo, wm);
    float aci = abs(ci);
    float om_c = clamp(omd, 0.0, 1.0);
    // values capped at F_MAX (common/math.glsl): 1 / (|cos_i| cos_o) outgrows float32 at grazing angles
    bool film = p.thin_film.thickness_nm > 0.0;  // a thin film: RGB R and T = 1 - R
    vec3 Rf = film ? thin_film_dielectric_rgb(om_c, eta, p.thin_film.ior, p.thin_film.thickness_nm) : vec3(0.0);
    if (refl) {
        float rc = ratio_capped(G * D, 4.0 * aci * co);
        return film ? Rf * rc : vec3(fresnel_dielectric(om_c, eta) * rc);
    }
    // eq. 21 with (eta_i (i.m) + eta_o (o.m))^2 = |h|^2 / etap^2, then radiance's 1 / etap^2.
    float r = ratio_capped(G * D, aci * co);
    if (film) {
        // T = 1 - R of the film at the outside cosine, which for a transmission pair is a facet
        // cosine (Snell's law holds at m): |wi.m| when wo is inside, |wo.m| when outside; no
        // ill-conditioned sqrt(1 - sin^2) near the critical angle (see above)
        float c_out = eta < 1.0 ? min(abs(imd), 1.0) : om_c;
        float ior_f = eta < 1.0 ? 1.0 / eta : eta;
        vec3 Tf = 1.0 - thin_film_rgb(c_out, p.thin_film.ior, p.thin_film.thickness_nm, vec3(ior_f), vec3(0.0));
        vec3 t3 = min(Tf * (abs(imd) * abs(omd) / hlen2), vec3(F_MAX));
        return min(t3 * r, vec3(F_MAX));
    }
    // T from the two facet cosines (see dielectric_transmittance_cos): cos_t = |wi . m|.
    float T = dielectric_transmittance_cos(om_c, min(abs(imd), 1.0), eta);
    // |i.m| |o.m| / |h|^2 <= 1 / (1 - eta)^2 is finite; the product is formed in this order so
    // that no intermediate leaves the float range
    float t = min(T * (abs(imd) * abs(omd) / hlen2), F_MAX);
    return vec3(t <= 1.0 || r < F_MAX / t ? t * r : F_MAX);
}

// ---- sampling twin of viewer/brdf/dielectric.py. Smooth (alpha = 0): reflect when u.x < R
// (pdf R, weight 1), else refract (pdf T = 1 - R, weight 1 / eta^2); eval and pdf are 0 as
// functions. Rough: GGX visible normals for wo (u.x, u.y), then reflect when u.z < F(wo.m), else
// refract (numpy draws that choice and u.x from one uniform: split_uniform(u[:, 0]) = (u.z, u.x)).
// lobe: DELTA (smooth) or GLOSSY, on the branch's side (numpy: the side wi went to).
// Transmitted directions have wi.z of the other sign than wo.z. All in float32.
#include "common/sampling.glsl"

// A thin film's RGB reflectance averaged over the channels: the probability of the reflection
// branch (the numpy twin chooses with the same mean; the weight carries R / mean R).
float dielectric_film_mean_r(dielectric_params p, float cos_o, float eta) {
    vec3 R = thin_film_dielectric_rgb(cos_o, eta, p.thin_film.ior, p.thin_film.thickness_nm);
    return (R.x + R.y + R.z) / 3.0;
}

// Refract w (pointing away, on the side m points to) through the facet m, eta = n_t / n_i (Snell's
// law in vector form); ok = false under total internal reflection.
vec3 dielectric_refract(vec3 w, vec3 m, float eta, out bool ok) {
    float cos_i = dot(w, m);
    float sin2_t = max(0.0, 1.0 - cos_i * cos_i) / (eta * eta);
    ok = sin2_t < 1.0;
    float cos_t = sqrt(max(0.0, 1.0 - sin2_t));
    return -w / eta + (cos_i / eta - cos_t) * m;
}

// The rough interface's pdf: visible normals times the Jacobians (Walter et al. 2007 eq. 14:
// 1 / (4 |o.m|); eq. 17 with the half vector's length: |i.m| etap^2 / |h|^2) times the
// probability of the branch, F or T = 1 - F.
float dielectric_pdf(dielectric_params p, vec3 wi, vec3 wo) {
    if (p.alpha <= 0.0) return 0.0;
    float s = wo.z < 0.0 ? -1.0 : 1.0;
    float eta = s > 0.0 ? p.ior : 1.0 / p.ior;
    wo.z *= s;
    wi.z *= s;
    float co = wo.z, ci = wi.z;
    if (co <= 0.0 || ci == 0.0) return 0.0;
    bool refl = ci > 0.0;
    float etap = refl ? 1.0 : eta;
    vec3 h = wi * etap + wo;
    float hlen2 = dot(h, h);
    if (hlen2 <= 0.0) return 0.0;
    vec3 wm = h * inversesqrt(hlen2);
    if (wm.z < 0.0) wm = -wm;
    float im = dot(wi, wm), om = dot(wo, wm);
    if (im * ci <= 0.0 || om * co <= 0.0) return 0.0;
    float pm = mf_D_visible(MICROFACET_DISTRIBUTION_GGX, wo, wm, p.alpha, p.alpha);
    float oc = clamp(om, 0.0, 1.0);
    if (p.thin_film.thickness_nm > 0.0) {  // the sampler's branch probabilities: mean R, 1 - mean R
        float R = dielectric_film_mean_r(p, oc, eta);
        return refl ? pm / (4.0 * abs(om)) * R : pm * abs(im) * etap * etap / hlen2 * (1.0 - R);
    }
    if (refl) return pm / (4.0 * abs(om)) * fresnel_dielectric(oc, eta);
    return pm * abs(im) * etap * etap / hlen2 * fresnel_dielectric_transmittance(oc, eta);
}

vec3 dielectric_sample(dielectric_params p, vec3 wo, vec3 u, out vec3 wi, out float pdf, out uint lobe) {
    float s = wo.z < 0.0 ? -1.0 : 1.0;
    float eta = s > 0.0 ? p.ior : 1.0 / p.ior;
    vec3 wo_u = vec3(wo.xy, s * wo.z);
    bool ok_t;
    if (p.alpha <= 0.0) {
        float co = wo_u.z;
        bool film = p.thin_film.thickness_nm > 0.0;
        vec3 R3 = film ? thin_film_dielectric_rgb(clamp(co, 0.0, 1.0), eta, p.thin_film.ior, p.thin_film.thickness_nm)
                       : vec3(fresnel_dielectric(co, eta));
        float R = (R3.x + R3.y + R3.z) / 3.0;
        float T = 1.0 - R;
        bool choose_r = u.x < R;
        vec3 wt = dielectric_refract(wo_u, vec3(0.0, 0.0, 1.0), eta, ok_t);
        vec3 wi_u = choose_r ? vec3(-wo_u.x, -wo_u.y, wo_u.z) : wt;
        wi = vec3(wi_u.xy, s * wi_u.z);
        lobe = LOBE_DELTA | (choose_r ? LOBE_REFLECTION : LOBE_TRANSMISSION);
        pdf = choose_r ? R : T;
        bool ok = co > 0.0 && (choose_r || ok_t) && pdf > 0.0;
        if (!ok) pdf = 0.0;
        // throughput f cos / pdf: 1 for reflection, 1 / eta^2 for transmission (radiance mode);
        // with a film R is RGB and the branch was chosen with its mean: R / mean R, (1 - R) / T
        if (!ok) return vec3(0.0);
        if (!film) return vec3(choose_r ? 1.0 : 1.0 / (eta * eta));
        return choose_r ? R3 / R : (1.0 - R3) / (T * eta * eta);
    }
    bool up = wo_u.z > 0.0;
    vec3 wo_s = up ? wo_u : vec3(0.0, 0.0, 1.0);
    vec3 m = sample_vndf_ggx(wo_s, u.xy, p.alpha, p.alpha);
    float om = dot(wo_s, m);
    float F = p.thin_film.thickness_nm > 0.0 ? dielectric_film_mean_r(p, clamp(om, 0.0, 1.0), eta)
                                             : fresnel_dielectric(clamp(om, 0.0, 1.0), eta);
    bool choose_r = u.z < F;
    vec3 wt = dielectric_refract(wo_s, m, eta, ok_t);
    vec3 wi_u = choose_r ? reflect_about(wo_s, m) : normalize_safe(wt);
    bool ok = up && (choose_r ? wi_u.z > 0.0 : (ok_t && wi_u.z < 0.0));
    wi = vec3(wi_u.xy, s * wi_u.z);
    lobe = LOBE_GLOSSY | (choose_r ? LOBE_REFLECTION : LOBE_TRANSMISSION);
    pdf = ok ? dielectric_pdf(p, wi, wo) : 0.0;
    return sample_weight(dielectric_eval(p, wi, wo), abs(wi.z), pdf);
}
