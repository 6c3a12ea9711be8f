// Perfect mirror (lecture: "Reflectance of perfectly specular materials"): a delta lobe, so the
// BRDF as a function is 0 everywhere; the rasterizer reflects the environment with
// mirror_reflectance() instead. Twin of viewer/brdf/mirror.py.
// fresnel: MIRROR_FRESNEL_CONDUCTOR, _DIELECTRIC or _NONE (generated/constants.glsl).
#include "generated/constants.glsl"
#include "common/fresnel.glsl"
#include "common/spectral.glsl"

vec3 mirror_reflectance(mirror_params p, float cos_o) {
    if (p.thin_film.thickness_nm > 0.0 && p.fresnel != MIRROR_FRESNEL_NONE) {
        // a tabulated base: its own n, k at the film's wavelengths (after its RGB table)
        if (p.spectral > MIRROR_SPECTRAL_NONE)
            return thin_film_spectral_rgb(cos_o, p.thin_film.ior, p.thin_film.thickness_nm, p.spectral_offset);
        return p.fresnel == MIRROR_FRESNEL_CONDUCTOR ? thin_film_conductor_rgb(cos_o, p.thin_film.ior, p.thin_film.thickness_nm, p.eta, p.k)
                              : thin_film_rgb(cos_o, p.thin_film.ior, p.thin_film.thickness_nm, vec3(p.ior), vec3(0.0));
    }
    if (p.spectral > MIRROR_SPECTRAL_NONE) return spectral_fresnel(p.spectral_offset, cos_o);
    if (p.fresnel == MIRROR_FRESNEL_CONDUCTOR) return fresnel_conductor(cos_o, p.eta, p.k);
    if (p.fresnel == MIRROR_FRESNEL_DIELECTRIC) return vec3(fresnel_dielectric(clamp(cos_o, 0.0, 1.0), p.ior));
    return vec3(1.0);
}

vec3 mirror_eval(mirror_params p, vec3 wi, vec3 wo) {
    return vec3(0.0);
}

// ---- sampling twin of viewer/brdf/mirror.py: the delta lobe. eval and pdf are 0 as functions;
// sample returns the mirror direction with pdf = 1 (the probability of the only lobe), weight F.
float mirror_pdf(mirror_params p, vec3 wi, vec3 wo) { return 0.0; }

vec3 mirror_sample(mirror_params p, vec3 wo, vec3 u, out vec3 wi, out float pdf, out uint lobe) {
    lobe = LOBE_REFLECTION | LOBE_DELTA;  // the lobes the mirror model declares (viewer/brdf/mirror.py)
    wi = vec3(-wo.x, -wo.y, wo.z);
    pdf = wo.z > 0.0 ? 1.0 : 0.0;
    return wo.z > 0.0 ? mirror_reflectance(p, wo.z) : vec3(0.0);
}
