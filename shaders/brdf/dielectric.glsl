// Dielectric interface, twin of viewer/brdf/dielectric.py. alpha = 0 is smooth glass: two delta
// lobes, so eval is 0 (the rasterizer handles reflection/refraction itself). alpha > 0: rough
// GGX interface after Walter et al. 2007 (eq. 20 reflection, eq. 21 transmission, eq. 16 the
// generalized half vector), height-correlated Smith G (Heitz 2014: eq. 99 reflection, the Beta
// function B(1 + Lambda_o, 1 + Lambda_i) of sec. 5.3 refraction), with pbrt-v4's
// radiance-mode 1 / eta^2 on transmission. wi may be below the surface (transmission).
// sigma_a is applied by the path tracer along the path inside, not here.
#include "common/fresnel.glsl"
#include "common/microfacet.glsl"

// T = 1 - R near total internal reflection is ill-conditioned (d T / d cos -> infinity at the
// critical angle): float32 rounding of the half vector alone moves T by percents there. The
// half vector, its cosines and T are therefore computed in double precision (GLSL 4.0+).
double dielectric_transmittance_d(double cos_i, double eta) {
    double sin2_t = max(0.0LF, 1.0LF - cos_i * cos_i) / (eta * eta);
    if (sin2_t >= 1.0LF) return 0.0LF;
    double cos_t = sqrt(1.0LF - sin2_t);
    double num = 4.0LF * eta * cos_i * cos_t;
    double ds = cos_i + eta * cos_t;
    double dp = eta * cos_i + cos_t;
    double Ts = ds > 0.0LF ? num / (ds * ds) : 0.0LF;
    double Tp = dp > 0.0LF ? num / (dp * dp) : 0.0LF;
    return 0.5LF * (Ts + Tp);
}

vec3 dielectric_eval(dielectric_params p, vec3 wi, vec3 wo) {
    if (p.alpha <= 0.0) return vec3(0.0);
    // work in the frame where wo is up; eta is the relative index seen from wo
    float s = wo.z < 0.0 ? -1.0 : 1.0;
    double eta = s > 0.0 ? double(p.ior) : 1.0LF / double(p.ior);
    wo.z *= s;
    wi.z *= s;
    float co = wo.z, ci = wi.z;
    if (co <= 0.0 || ci == 0.0) return vec3(0.0);
    bool refl = ci > 0.0;
    double etap = refl ? 1.0LF : eta;
    dvec3 h = dvec3(wi) * etap + dvec3(wo);
    double hlen2 = dot(h, h);
    if (hlen2 <= 0.0LF) return vec3(0.0);
    dvec3 wmd = h / sqrt(hlen2);
    if (wmd.z < 0.0LF) wmd = -wmd;
    double imd = dot(dvec3(wi), wmd), omd = dot(dvec3(wo), wmd);
    if (imd * double(ci) <= 0.0LF || omd * double(co) <= 0.0LF) return vec3(0.0);
    vec3 wm = vec3(wmd);
    float D = D_ggx(wm, p.alpha, p.alpha);
    float lam_i = lambda_ggx(wi, p.alpha, p.alpha), lam_o = lambda_ggx(wo, p.alpha, p.alpha);
    // Heitz 2014: eq. 99 for reflection, the Beta-function form (sec. 5.3) for refraction
    float G = refl ? smith_g2_height_correlated(lam_i, lam_o, wi, wo, wm)
                   : smith_g2_height_correlated_transmission(lam_i, lam_o, wi, wo, wm);
    float aci = abs(ci);
    double om_c = clamp(omd, 0.0LF, 1.0LF);
    // values capped at F_MAX (common/math.glsl): 1 / (|cos_i| cos_o) outgrows float32 at grazing angles
    bool film = p.thin_film.thickness_nm > 0.0;  // a thin film: RGB R and T = 1 - R
    vec3 Rf = film ? thin_film_dielectric_rgb(float(om_c), float(eta), p.thin_film.ior, p.thin_film.thickness_nm)
                   : vec3(0.0);
    if (refl) {
        float rc = ratio_capped(G * D, 4.0 * aci * co);
        return film ? Rf * rc : vec3(fresnel_dielectric(float(om_c), float(eta)) * rc);
    }
    // eq. 21 with (eta_i (i.m) + eta_o (o.m))^2 = |h|^2 / etap^2, then radiance's 1 / etap^2
    float r = ratio_capped(G * D, aci * co);
    if (film) {
        vec3 t3 = min((1.0 - Rf) * float(abs(imd) * abs(omd) / hlen2), vec3(F_MAX));
        return min(t3 * r, vec3(F_MAX));
    }
    double T = dielectric_transmittance_d(om_c, eta);
    float t = float(min(T * abs(imd) * abs(omd) / hlen2, double(F_MAX)));
    return vec3(t <= 1.0 || r < F_MAX / t ? t * r : F_MAX);
}
