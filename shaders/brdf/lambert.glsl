// Lambert 1760: f = rho_d / pi (lecture: "The BRDF of perfectly diffuse materials").
vec3 lambert_eval(lambert_params p, vec3 wi, vec3 wo) {
    if (wi.z <= 0.0 || wo.z <= 0.0) return vec3(0.0);
    return p.albedo * INV_PI;
}
