// Dielectric interface, twin of viewer/brdf/dielectric.py. alpha = 0 is smooth glass: two delta
// lobes, so eval is 0 (the rasterizer handles reflection/refraction itself). alpha > 0: rough
// GGX interface after Walter et al. 2007 (eq. 20 reflection, eq. 21 transmission, eq. 16 the
// generalized half vector), height-correlated Smith G (Heitz 2014 eq. 99), with pbrt-v4's
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
    float G = smith_g2_height_correlated(lambda_ggx(wi, p.alpha, p.alpha),
                                         lambda_ggx(wo, p.alpha, p.alpha), wi, wo, wm);
    float aci = abs(ci);
    double om_c = clamp(omd, 0.0LF, 1.0LF);
    // values capped at F_MAX (common/math.glsl): 1 / (|cos_i| cos_o) outgrows float32 at grazing angles
    if (refl) return vec3(fresnel_dielectric(float(om_c), float(eta)) * ratio_capped(G * D, 4.0 * aci * co));
    // eq. 21 with (eta_i (i.m) + eta_o (o.m))^2 = |h|^2 / etap^2, then radiance's 1 / etap^2
    double T = dielectric_transmittance_d(om_c, eta);
    float t = float(min(T * abs(imd) * abs(omd) / hlen2, double(F_MAX)));
    float r = ratio_capped(G * D, aci * co);
    return vec3(t <= 1.0 || r < F_MAX / t ? t * r : F_MAX);
}

// ---- sampling twin of viewer/brdf/dielectric.py. Smooth (alpha = 0): reflect when u.x < R
// (pdf R, weight 1), else refract (pdf T = 1 - R, weight 1 / eta^2); eval and pdf are 0 as
// functions. Rough: GGX visible normals for wo (u.x, u.y), then reflect when u.z < F(wo.m), else
// refract (numpy draws that choice and u.x from one uniform: split_uniform(u[:, 0]) = (u.z, u.x)).
// Transmitted directions have wi.z of the other sign than wo.z. All in float32.
#include "common/sampling.glsl"

bool dielectric_is_delta(dielectric_params p) { return p.alpha <= 0.0; }

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
    float pm = mf_D_visible(1, wo, wm, p.alpha, p.alpha);
    float oc = clamp(om, 0.0, 1.0);
    if (refl) return pm / (4.0 * abs(om)) * fresnel_dielectric(oc, eta);
    return pm * abs(im) * etap * etap / hlen2 * fresnel_dielectric_transmittance(oc, eta);
}

vec3 dielectric_sample(dielectric_params p, vec3 wo, vec3 u, out vec3 wi, out float pdf) {
    float s = wo.z < 0.0 ? -1.0 : 1.0;
    float eta = s > 0.0 ? p.ior : 1.0 / p.ior;
    vec3 wo_u = vec3(wo.xy, s * wo.z);
    bool ok_t;
    if (p.alpha <= 0.0) {
        float co = wo_u.z;
        float R = fresnel_dielectric(co, eta);
        float T = 1.0 - R;
        bool choose_r = u.x < R;
        vec3 wt = dielectric_refract(wo_u, vec3(0.0, 0.0, 1.0), eta, ok_t);
        vec3 wi_u = choose_r ? vec3(-wo_u.x, -wo_u.y, wo_u.z) : wt;
        wi = vec3(wi_u.xy, s * wi_u.z);
        pdf = choose_r ? R : T;
        bool ok = co > 0.0 && (choose_r || ok_t) && pdf > 0.0;
        if (!ok) pdf = 0.0;
        // throughput f cos / pdf: 1 for reflection, 1 / eta^2 for transmission (radiance mode)
        return ok ? vec3(choose_r ? 1.0 : 1.0 / (eta * eta)) : vec3(0.0);
    }
    bool up = wo_u.z > 0.0;
    vec3 wo_s = up ? wo_u : vec3(0.0, 0.0, 1.0);
    vec3 m = sample_vndf_ggx(wo_s, u.xy, p.alpha, p.alpha);
    float om = dot(wo_s, m);
    float F = fresnel_dielectric(clamp(om, 0.0, 1.0), eta);
    bool choose_r = u.z < F;
    vec3 wt = dielectric_refract(wo_s, m, eta, ok_t);
    vec3 wi_u = choose_r ? reflect_about(wo_s, m) : normalize_safe(wt);
    bool ok = up && (choose_r ? wi_u.z > 0.0 : (ok_t && wi_u.z < 0.0));
    wi = vec3(wi_u.xy, s * wi_u.z);
    pdf = ok ? dielectric_pdf(p, wi, wo) : 0.0;
    return sample_weight(dielectric_eval(p, wi, wo), abs(wi.z), pdf);
}
