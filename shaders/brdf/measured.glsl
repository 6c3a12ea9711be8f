// Measured isotropic BRDF (Matusik et al. 2003, the MERL BRDF database), twin of
// viewer/brdf/measured.py and viewer/brdf/merl.py: Rusinkiewicz (1998) half / difference angles,
// the MERL index mapping (theta_h: sqrt, theta_d: linear, phi_d: folded into [0, pi) by
// reciprocity), trilinear interpolation on the index grid done here with texelFetch (eight texels,
// float32 weights) so that it is the numpy lookup exactly, not the hardware's filter precision.
// The table is a 3D RGB float texture u_measured (x = phi_d 180, y = theta_d 90, z = theta_h 90),
// bound by the renderer only in programs compiled with MEASURED_TEXTURE; without it (programs
// built for every model) the model evaluates to 0 and never samples.
// With MEASURED_ANISO the table is an MIT anisotropic one (viewer/brdf/mit_aniso.py): x = phi_in,
// y = phi_diff, z = theta_in n_to + theta_out, and the sampler's data in the last layer.
#include "common/sampling.glsl"

#if defined(MEASURED_TEXTURE) && defined(MEASURED_ANISO)
uniform sampler3D u_measured;
vec3 measured_texel(int h, int d, int p) { return vec3(0.0); }
// the sampler's data, the last layer's row 0: the theta_h CDF at x = 0..89, the cosine weight at
// 90, the dimensions (n_ti, n_to, n_pd, n_pi) at 91..94
float measured_aux(int i) { return texelFetch(u_measured, ivec3(i, 0, textureSize(u_measured, 0).z - 1), 0).r; }
#elif defined(MEASURED_TEXTURE)
uniform sampler3D u_measured;
vec3 measured_texel(int h, int d, int p) { return texelFetch(u_measured, ivec3(p, d, h), 0).rgb; }
// the sampler's data, layer z = 90: the CDF of the 90 theta_h bins at x = 0..89, the cosine weight at 90
float measured_aux(int i) { return texelFetch(u_measured, ivec3(i, 0, 90), 0).r; }
#else
vec3 measured_texel(int h, int d, int p) { return vec3(0.0); }
float measured_aux(int i) { return 0.0; }
#endif

const float MEASURED_HALF_PI = 1.57079632679489661923;

// (theta_h, theta_d, phi_d) of a direction pair; theta from atan(length(xy), z), accurate in
// float32 near the normal where acos is not.
vec3 measured_half_diff(vec3 wi, vec3 wo) {
    vec3 h = normalize(wi + wo);
    float th = atan(length(h.xy), h.z);
    float ph = atan(h.y, h.x);
    float c = cos(ph), s = sin(ph);
    float x = c * wi.x + s * wi.y;
    float y = -s * wi.x + c * wi.y;
    float ct = cos(th), st = sin(th);
    float dx = ct * x - st * wi.z;
    float dz = st * x + ct * wi.z;
    float td = atan(length(vec2(dx, y)), dz);
    float pd = atan(y, dx);
    if (pd < 0.0) pd += PI;
    return vec3(th, td, pd);
}

vec3 measured_lookup(vec3 a) {
    // between the bins' centres (viewer/brdf/merl.py lookup): index coordinates minus 1/2
    float ch = clamp(sqrt(clamp(a.x, 0.0, MEASURED_HALF_PI) / MEASURED_HALF_PI) * 90.0 - 0.5, 0.0, 89.0);
    float cd = clamp(clamp(a.y, 0.0, MEASURED_HALF_PI) / MEASURED_HALF_PI * 90.0 - 0.5, 0.0, 89.0);
    float cp = a.z / PI * 180.0 - 0.5;
    if (cp < 0.0) cp += 180.0;
    int h0 = min(int(floor(ch)), 88);
    int d0 = min(int(floor(cd)), 88);
    float fp = floor(cp);
    int p0 = int(fp) % 180;
    if (p0 < 0) p0 += 180;
    int p1 = (p0 + 1) % 180;
    float th = ch - float(h0), td = cd - float(d0), tp = cp - fp;
    vec3 v00 = mix(measured_texel(h0, d0, p0), measured_texel(h0, d0, p1), tp);
    vec3 v01 = mix(measured_texel(h0, d0 + 1, p0), measured_texel(h0, d0 + 1, p1), tp);
    vec3 v10 = mix(measured_texel(h0 + 1, d0, p0), measured_texel(h0 + 1, d0, p1), tp);
    vec3 v11 = mix(measured_texel(h0 + 1, d0 + 1, p0), measured_texel(h0 + 1, d0 + 1, p1), tp);
    return mix(mix(v00, v01, td), mix(v10, v11, td), th);
}

#if defined(MEASURED_TEXTURE) && defined(MEASURED_ANISO)
// azimuth of the reversed direction, [0, 2 pi) (the MIT convention; 0 on the normal)
float measured_azimuth(vec3 w) {
    float phi = dot(w.xy, w.xy) > 0.0 ? atan(-w.y, -w.x) : 0.0;
    return phi < 0.0 ? phi + TWO_PI : phi;
}

// lower index, upper index and weight of one axis: clamped (theta) or periodic (phi)
void measured_axis(float c, int n, bool periodic, out int i0, out int i1, out float t) {
    if (periodic) {
        c = mod(c, float(n));
        float f = floor(c);
        i0 = int(f) % n;
        i1 = (i0 + 1) % n;
        t = c - f;
    } else {
        c = clamp(c, 0.0, float(n - 1));
        i0 = int(floor(c));
        i1 = min(i0 + 1, n - 1);
        t = c - float(i0);
    }
}

vec3 measured_aniso_lookup(vec3 wi, vec3 wo) {
    int nti = int(measured_aux(91) + 0.5), nto = int(measured_aux(92) + 0.5);
    int npd = int(measured_aux(93) + 0.5), npi = int(measured_aux(94) + 0.5);
    float ti = atan(length(wi.xy), wi.z), to = atan(length(wo.xy), wo.z);
    float pi_ = measured_azimuth(wi);
    float pd = measured_azimuth(wo) - pi_;
    if (pd < 0.0) pd += TWO_PI;
    int a0, a1, b0, b1, c0, c1, d0, d1;
    float ta, tb, tc, td;
    measured_axis(ti / MEASURED_HALF_PI * float(nti) - 0.5, nti, false, a0, a1, ta);
    measured_axis(to / MEASURED_HALF_PI * float(nto) - 0.5, nto, false, b0, b1, tb);
    measured_axis(pd / TWO_PI * float(npd) - 0.5, npd, true, c0, c1, tc);
    measured_axis(pi_ / TWO_PI * float(npi) - 0.5, npi, true, d0, d1, td);
    vec3 acc = vec3(0.0);
    for (int k = 0; k < 8; ++k) {
        int ia = (k & 4) != 0 ? a1 : a0, ib = (k & 2) != 0 ? b1 : b0, ic = (k & 1) != 0 ? c1 : c0;
        float w = ((k & 4) != 0 ? ta : 1.0 - ta) * ((k & 2) != 0 ? tb : 1.0 - tb) * ((k & 1) != 0 ? tc : 1.0 - tc);
        int z = ia * nto + ib;
        vec3 v = mix(texelFetch(u_measured, ivec3(d0, ic, z), 0).rgb, texelFetch(u_measured, ivec3(d1, ic, z), 0).rgb, td);
        acc += w * v;
    }
    return acc;
}
#endif

vec3 measured_eval(measured_params p, vec3 wi, vec3 wo) {
    if (wi.z <= 0.0 || wo.z <= 0.0) return vec3(0.0);
#if defined(MEASURED_TEXTURE) && defined(MEASURED_ANISO)
    return p.scale * measured_aniso_lookup(wi, wo);
#else
    return p.scale * measured_lookup(measured_half_diff(wi, wo));
#endif
}

// ---- sampling twin: cosine + tabulated half-vector mixture; measured_aux(90) = cosine weight,
// measured_aux(i) = the CDF of the 90 theta_h bins (edges ((i / 90)^2) pi / 2)
float measured_edge(int i) { float u = float(i) / 90.0; return u * u * MEASURED_HALF_PI; }

// 1 - cos(edge i) without cancellation
float measured_one_minus_cos(int i) { float s = sin(0.5 * measured_edge(i)); return 2.0 * s * s; }

float measured_h_pdf(measured_params p, vec3 h) {
    if (h.z <= 0.0) return 0.0;
    float th = atan(length(h.xy), h.z);
    int i = clamp(int(floor(sqrt(clamp(th, 0.0, MEASURED_HALF_PI) / MEASURED_HALF_PI) * 90.0)), 0, 89);
    float lo = i > 0 ? measured_aux(i - 1) : 0.0;
    float mass = measured_aux(i) - lo;
    // solid angle of the bin: 2 pi (cos a - cos b) = 4 pi sin((a + b) / 2) sin((b - a) / 2)
    float a = measured_edge(i), b = measured_edge(i + 1);
    float d_omega = 4.0 * PI * sin(0.5 * (a + b)) * sin(0.5 * (b - a));
    return mass / d_omega;
}

float measured_pdf(measured_params p, vec3 wi, vec3 wo) {
    if (wi.z <= 0.0 || wo.z <= 0.0) return 0.0;
    vec3 h = normalize(wi + wo);
    float cos_oh = dot(wo, h);
    float ph = cos_oh > 0.0 ? measured_h_pdf(p, h) / (4.0 * cos_oh) : 0.0;
    float w = measured_aux(90);
    return w * cosine_hemisphere_pdf(wi) + (1.0 - w) * ph;
}

vec3 measured_sample(measured_params p, vec3 wo, vec3 u, out vec3 wi, out float pdf, out uint lobe) {
    lobe = LOBE_REFLECTION | LOBE_GLOSSY;  // the lobes the measured model declares (viewer/brdf/measured.py)
    float w = measured_aux(90);
    bool use_cos = u.x < w;
    float uc = min(use_cos ? u.x / w : (u.x - w) / (1.0 - w), ONE_MINUS_EPS);
    if (use_cos) {
        wi = sample_cosine_hemisphere(vec2(uc, u.y));
    } else {
        // the theta_h bin by its CDF (binary search over the 90 entries), then uniform in solid angle
        int lo_i = 0, hi_i = 89;
        for (int k = 0; k < 7; ++k) {
            if (lo_i >= hi_i) break;
            int mid = (lo_i + hi_i) / 2;
            if (uc >= measured_aux(mid)) lo_i = mid + 1; else hi_i = mid;
        }
        int i = min(lo_i, 89);
        float lo = i > 0 ? measured_aux(i - 1) : 0.0;
        float width = measured_aux(i) - lo;
        float t = clamp(width > 0.0 ? (uc - lo) / width : 0.0, 0.0, 1.0);
        float a = measured_one_minus_cos(i), b = measured_one_minus_cos(i + 1);
        float x = a + t * (b - a);
        float sin_t = sqrt(max(x * (2.0 - x), 0.0));
        float phi = TWO_PI * u.y;
        vec3 h = vec3(sin_t * cos(phi), sin_t * sin(phi), 1.0 - x);
        wi = 2.0 * dot(wo, h) * h - wo;
    }
    pdf = measured_pdf(p, wi, wo);
    if (pdf <= 0.0) { pdf = 0.0; return vec3(0.0); }
    vec3 f = measured_eval(p, wi, wo);
    return f * wi.z / pdf;
}
