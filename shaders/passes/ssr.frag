#version 410 core
// Screen-space reflections: the specular environment term of the forward pass, replaced by the
// scene's own radiance where the reflected ray hits something on screen.
//
// Inputs (viewer/gl/ssr.py): the forward pass's radiance without its specular environment term
// (u_color, with a mip chain), the specular weight rho_s and the lobe width alpha (u_spec), and
// the world-space shading normal with the linear view depth (u_geom; 0 where there is no
// surface). MSAA resolves average those over a pixel's samples, so a silhouette pixel holds
// coverage * value: the normal's length is the coverage and depth / coverage the surface depth.
//
// The trace is the screen-space DDA of McGuire & Mara 2014 ("Efficient GPU Screen-Space Ray
// Tracing", JCGT 3(4)): the view-space segment is projected once; x/w, y/w, z/w and 1/w are
// linear in screen space, so stepping a fixed number of pixels along the major axis gives the
// ray's depth at each step with one division; a step is a hit when the depth interval the ray
// covers over it overlaps [scene depth, scene depth + thickness]. Here a bisection between the
// last miss and the hit refines the hit point afterwards (the paper's stride-then-refine idea).
#include "common/math.glsl"
#include "common/ibl.glsl"

uniform sampler2D u_color;
uniform sampler2D u_spec;
uniform sampler2D u_geom;
uniform mat4 u_view;
uniform mat4 u_proj;
uniform vec2 u_size;          // pixels
uniform vec2 u_tan_half;      // tan(fov_x / 2), tan(fov_y / 2)
uniform float u_near;         // near plane distance (the ray is clipped there)
uniform float u_max_distance; // view-space length of the traced segment
uniform float u_thickness;    // assumed depth of every surface behind its front
uniform float u_bias;         // ray origin offset along the normal
uniform float u_stride;       // pixels per step
uniform int u_max_steps;
uniform int u_refine_steps;
uniform float u_max_roughness;
uniform float u_edge_fade;    // fraction of the screen over which hits fade out at its borders
uniform float u_max_lod;
uniform int u_env_on;
uniform int u_debug;          // 0 composite, 1 hit mask, 2 step count, 3 hit uv, 4 SSR only

in vec2 v_uv;
out vec4 frag_color;

vec3 false_colour(float t) {
    t = clamp(t, 0.0, 1.0);
    vec3 a = mix(vec3(0.05, 0.05, 0.35), vec3(0.0, 0.8, 0.9), smoothstep(0.0, 0.35, t));
    vec3 b = mix(a, vec3(1.0, 0.9, 0.1), smoothstep(0.35, 0.7, t));
    return mix(b, vec3(0.9, 0.1, 0.05), smoothstep(0.7, 1.0, t));
}

// Surface depth (positive, along -z of the view) at a pixel; 0 = no surface.
float scene_depth(ivec2 p) {
    vec4 g = texelFetch(u_geom, p, 0);
    float cov = length(g.xyz);
    return cov > 0.5 ? g.w / cov : 0.0;
}

vec3 view_position(vec2 px, float depth) {
    vec2 ndc = px / u_size * 2.0 - 1.0;
    return vec3(ndc * u_tan_half, -1.0) * depth;
}

// Screen position (pixels, along the permuted axes) and ray depth at step parameter t.
struct Ray2D { vec2 s0; vec2 ds; float q0; float dq; float k0; float dk; bool permute; };

vec2 ray_px(Ray2D r, float t) { vec2 s = r.s0 + r.ds * t; return r.permute ? s.yx : s; }
float ray_depth(Ray2D r, float t) { return -(r.q0 + r.dq * t) / (r.k0 + r.dk * t); }

bool inside(vec2 px) { return all(greaterThanEqual(px, vec2(0.0))) && all(lessThan(px, u_size)); }

// Trace from view-space P0 along unit R. Returns the hit pixel position (continuous) or false.
bool trace(vec3 P0, vec3 R, out vec2 hit_px, out float steps) {
    steps = 0.0;
    hit_px = vec2(-1.0);
    float len = u_max_distance;
    if (P0.z + R.z * len > -u_near) len = (-u_near - P0.z) / R.z;  // clip at the near plane
    if (len <= 0.0) return false;
    vec3 P1 = P0 + R * len;
    vec4 H0 = u_proj * vec4(P0, 1.0);
    vec4 H1 = u_proj * vec4(P1, 1.0);
    float k0 = 1.0 / H0.w, k1 = 1.0 / H1.w;
    vec2 S0 = (H0.xy * k0 * 0.5 + 0.5) * u_size;
    vec2 S1 = (H1.xy * k1 * 0.5 + 0.5) * u_size;
    vec2 d = S1 - S0;
    if (dot(d, d) < 1e-4) d = vec2(0.01, 0.0);  // degenerate: straight into the screen
    Ray2D r;
    r.permute = abs(d.x) < abs(d.y);
    if (r.permute) { d = d.yx; S0 = S0.yx; }
    float inv_dx = 1.0 / abs(d.x);          // parameter per pixel along the major axis
    float n_px = abs(d.x);
    r.s0 = S0;
    r.ds = d * inv_dx * u_stride;
    r.q0 = P0.z * k0;
    r.dq = (P1.z * k1 - P0.z * k0) * inv_dx * u_stride;
    r.k0 = k0;
    r.dk = (k1 - k0) * inv_dx * u_stride;
    float t_end = n_px / u_stride;
    float prev = ray_depth(r, 0.0);
    float t = 0.0;
    for (int i = 0; i < u_max_steps; ++i) {
        t += 1.0;
        if (t > t_end + 1.0) break;
        steps += 1.0;
        vec2 px = ray_px(r, t);
        if (!inside(px)) break;
        // the depth interval the ray spans over this pixel: from the previous step's end to
        // half a step ahead (the paper's half-pixel extents)
        float cur = ray_depth(r, min(t + 0.5, t_end + 1.0));
        float dmin = min(prev, cur), dmax = max(prev, cur);
        prev = cur;
        float zs = scene_depth(ivec2(px));
        if (zs > 0.0 && dmax >= zs && dmin <= zs + u_thickness) {
            // bisection between the last step that was in front and this one
            float lo = t - 1.0, hi = t;
            for (int j = 0; j < u_refine_steps; ++j) {
                float mid = 0.5 * (lo + hi);
                vec2 pm = ray_px(r, mid);
                float zm = scene_depth(ivec2(pm));
                float rd = ray_depth(r, mid);
                if (zm > 0.0 && rd >= zm && rd <= zm + u_thickness) hi = mid; else lo = mid;
            }
            hit_px = ray_px(r, hi);
            return true;
        }
    }
    return false;
}

void main() {
    ivec2 p = ivec2(gl_FragCoord.xy);
    vec3 base = texelFetch(u_color, p, 0).rgb;
    vec4 spec = texelFetch(u_spec, p, 0);
    vec4 g = texelFetch(u_geom, p, 0);
    float cov = length(g.xyz);
    vec3 rho_s = spec.rgb;
    bool surface = cov > 0.5 && any(greaterThan(rho_s, vec3(0.0)));
    vec3 reflected = vec3(0.0);
    float hit = 0.0, steps = 0.0;
    vec2 hit_uv = vec2(0.0);
    if (surface) {
        float alpha = spec.a / cov;
        vec3 n_w = g.xyz / cov;
        float depth = g.w / cov;
        vec3 P = view_position(gl_FragCoord.xy, depth);
        vec3 n_v = normalize(mat3(u_view) * n_w);
        vec3 R = reflect(normalize(P), n_v);
        vec3 r_w = transpose(mat3(u_view)) * R;  // view -> world (rotation)
        vec3 env = u_env_on != 0 ? env_prefiltered(r_w, alpha) : vec3(0.0);
        reflected = env;
        if (alpha <= u_max_roughness) {
            vec2 hp;
            if (trace(P + n_v * u_bias, R, hp, steps)) {
                hit_uv = hp / u_size;
                // fades toward the environment: near the screen borders, for rays toward the
                // camera (what they hit is mostly behind it, off screen) and near max roughness
                vec2 e = min(hit_uv, 1.0 - hit_uv);
                float fade = smoothstep(0.0, u_edge_fade, min(e.x, e.y));
                fade *= 1.0 - smoothstep(0.25, 0.75, R.z);
                fade *= 1.0 - smoothstep(0.8 * u_max_roughness, u_max_roughness, alpha);
                // a surface seen from behind is no hit (thickness false positives)
                vec3 nh = texelFetch(u_geom, ivec2(hp), 0).xyz;
                if (dot(mat3(u_view) * nh, R) > 0.0) fade = 0.0;
                // glossy: the previous colour blurred over the lobe's footprint, read from the
                // mip chain (the cone of half-angle ~alpha over the hit distance in pixels)
                float lod = 0.0;
                if (alpha > 0.05) lod = clamp(log2(max(1.0, alpha * length(hp - gl_FragCoord.xy))), 0.0, u_max_lod);
                vec3 c = textureLod(u_color, hit_uv, lod).rgb;
                reflected = mix(env, c, fade);
                hit = fade;
            }
        }
    }
    vec3 ssr = rho_s * reflected;
    if (u_debug == 0) frag_color = vec4(base + ssr, 1.0);
    else if (u_debug == 1) frag_color = vec4(surface ? vec3(hit) : vec3(0.0, 0.0, 0.25 * float(cov > 0.5)), 1.0);
    else if (u_debug == 2) frag_color = vec4(surface ? false_colour(steps / float(u_max_steps)) : vec3(0.0), 1.0);
    else if (u_debug == 3) frag_color = vec4(hit > 0.0 ? vec3(hit_uv, 0.0) : vec3(0.0), 1.0);
    else frag_color = vec4(ssr, 1.0);
}
