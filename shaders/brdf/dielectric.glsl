// Dielectric interface, twin of viewer/brdf/dielectric.py. alpha = 0 is smooth glass: two delta
// lobes, so eval is 0 (the rasterizer handles reflection/refraction itself). alpha > 0: rough
// GGX interface after Walter et al. 2007 (eq. 20 reflection, eq. 21 transmission, eq. 16 the
// generalized half vector), height-correlated Smith G (Heitz 2014 eq. 99), with pbrt-v4's
// radiance-mode 1 / eta^2 on transmission. wi may be below the surface (transmission).
// sigma_a is applied by the path tracer along the path inside, not here.
#include "common/fresnel.glsl"
#include "common/microfacet.glsl"

// Float only (no double: Apple's OpenGL 4.1 on Apple silicon has no fp64). The care needed:
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
    float G = smith_g2_height_correlated(lambda_ggx(wi, p.alpha, p.alpha),
                                         lambda_ggx(wo, p.alpha, p.alpha), wi, wo, wm);
    float aci = abs(ci);
    float om_c = clamp(omd, 0.0, 1.0);
    // values capped at F_MAX (common/math.glsl): 1 / (|cos_i| cos_o) outgrows float32 at grazing angles
    if (refl) return vec3(fresnel_dielectric(om_c, eta) * ratio_capped(G * D, 4.0 * aci * co));
    // eq. 21 with (eta_i (i.m) + eta_o (o.m))^2 = |h|^2 / etap^2, then radiance's 1 / etap^2.
    // T from the two facet cosines (see dielectric_transmittance_cos): cos_t = |wi . m|.
    float T = dielectric_transmittance_cos(om_c, min(abs(imd), 1.0), eta);
    // |i.m| |o.m| / |h|^2 <= 1 / (1 - eta)^2 is finite; the product is formed in this order so
    // that no intermediate leaves the float range
    float t = min(T * (abs(imd) * abs(omd) / hlen2), F_MAX);
    float r = ratio_capped(G * D, aci * co);
    return vec3(t <= 1.0 || r < F_MAX / t ? t * r : F_MAX);
}
