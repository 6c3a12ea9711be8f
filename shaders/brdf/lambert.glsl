// Lambert 1760: f = rho_d / pi (lecture: "The BRDF of perfectly diffuse materials").
vec3 lambert_eval(lambert_params p, vec3 wi, vec3 wo) {
    if (wi.z <= 0.0 || wo.z <= 0.0) return vec3(0.0);
    return p.albedo * INV_PI;
}

// ---- sampling twin of viewer/brdf/lambert.py: cosine-weighted (common/sampling.glsl)
#include "common/sampling.glsl"

float lambert_pdf(lambert_params p, vec3 wi, vec3 wo) {
    return wo.z > 0.0 ? cosine_hemisphere_pdf(wi) : 0.0;
}

vec3 lambert_sample(lambert_params p, vec3 wo, vec3 u, out vec3 wi, out float pdf, out uint lobe) {
    lobe = LOBE_REFLECTION | LOBE_DIFFUSE;  // lambert.lobes (viewer/brdf/lambert.py)
    wi = sample_cosine_hemisphere(u.xy);
    pdf = lambert_pdf(p, wi, wo);
    // f cos / pdf = (albedo / pi) cos / (cos / pi) = albedo
    return pdf > 0.0 ? p.albedo : vec3(0.0);
}
