#version 410 core
// Screen-space reflections: the specular environment term of the forward pass, replaced by the
// scene's own radiance where the reflected ray hits something on screen.
//
// Inputs (viewer/gl/ssr.py): the forward pass's radiance, its specular environment term included
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
// With u_hiz = 1 the same steps are visited through a min-depth pyramid (trace_hiz), which skips
// only cells where no step can hit, so the result is the DDA's.
#include "generated/constants.glsl"
#include "common/math.glsl"
#include "common/colour.glsl"
#include "common/rng.glsl"
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
uniform int u_debug;          // SSR_DEBUG_COMPOSITE, _HIT (mask), _STEPS (count), _UV (hit uv), _ONLY (SSR only)
uniform int u_hiz;            // 0: the linear DDA over every stride; 1: skip empty space with u_hiz_tex
uniform sampler2D u_hiz_tex;  // Hi-Z pyramid: level k = min (closest) linear depth over 2x2 of k - 1
uniform int u_hiz_max_level;
uniform int u_hiz_max_iter;
uniform sampler2D u_back;    // distance from the camera to the nearest back face (0: none)
uniform int u_back_on;
uniform float u_max_slope;   // the largest depth change per pixel a surface is given (edge-on planes)
uniform float u_min_coverage; // a pixel whose normals average shorter than this is no hit (silhouettes)
uniform int u_jitter;         // 1: start each ray a random fraction of a stride along (u_frame_index's set)
uniform int u_frame_index;

in vec2 v_uv;
out vec4 frag_color;

// Surface depth (positive, along -z of the view) at a pixel; 0 = no surface. A pixel whose
// samples saw different surfaces (a silhouette under MSAA: the averaged normal is shorter than
// u_min_coverage) holds a depth between them that no surface has, and a ray passing behind the
// silhouette would hit it (dark stray pixels beside silhouettes): such pixels are no hit.
float scene_depth(ivec2 p) {
    vec4 g = texelFetch(u_geom, p, 0);
    float cov = length(g.xyz);
    return cov > u_min_coverage ? g.w / cov : 0.0;
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

// The surface seen at pixel p, taken as its tangent plane (the pixel's normal through the point
// at its centre's depth). A surface at a grazing angle to the view changes depth by far more
// than any fixed thickness within one pixel, so comparing the ray with the pixel centre's depth
// missed rays that hit it (a speckled edge on a reflected sphere); against the plane, the ray
// and the surface are compared at the same screen positions. `behind` is how deep the surface
// reaches behind its front: to a closed object's nearest back face (u_back), so a ray that
// passes behind its front but inside the object hits it (the reflection of a ball's underside,
// which the camera cannot see: without this a band of background where the ball touches a
// mirror floor) and one that passes behind the object misses; a one-sided surface (no back
// face behind it) reaches the thickness. False where there is no surface (or a silhouette
// pixel, see scene_depth).
struct Plane { vec3 n; float np; float zc; float behind; };

bool surface_plane(ivec2 p, out Plane s) {
    vec4 g = texelFetch(u_geom, p, 0);
    float cov = length(g.xyz);
    s.n = vec3(0.0, 0.0, 1.0);
    s.np = 0.0;
    s.zc = 0.0;
    s.behind = u_thickness;
    if (cov <= u_min_coverage) return false;
    s.zc = g.w / cov;
    s.n = mat3(u_view) * (g.xyz / cov);
    s.np = dot(s.n, view_position(vec2(p) + 0.5, s.zc));
    if (u_back_on != 0) {
        vec3 dc = vec3(((vec2(p) + 0.5) / u_size * 2.0 - 1.0) * u_tan_half, -1.0);
        float zb = texelFetch(u_back, p, 0).r / length(dc);  // distance -> linear depth
        if (zb > s.zc) s.behind = zb - s.zc;
    }
    return true;
}

// The plane's depth along the view ray through the screen position px; nearly edge-on planes
// are held within u_max_slope per pixel of distance from the pixel's centre depth.
float plane_depth(Plane s, ivec2 p, vec2 px) {
    vec3 d = vec3((px / u_size * 2.0 - 1.0) * u_tan_half, -1.0);  // the view ray of depth 1
    float nd = dot(s.n, d);
    float lim = u_max_slope * max(1.0, length(px - (vec2(p) + 0.5)));
    float z = abs(nd) > 1e-6 ? s.np / nd : s.zc + lim;
    return clamp(z, s.zc - lim, s.zc + lim);
}

// One step of the DDA at step t (an integer): 0 no hit, 1 hit, 2 off screen (the trace ends).
// Over the step's extent (from the previous step's end to half a step ahead, the paper's
// half-pixel extents) the ray's depth less the surface's, at both ends: a hit where that goes
// from in front (< 0) to behind, or stays within [0, behind].
int dda_step(Ray2D r, float t, float t_end) {
    vec2 px = ray_px(r, t);
    if (!inside(px)) return 2;
    float ta = t <= 1.0 ? 0.0 : min(t - 0.5, t_end + 1.0);
    float tb = min(t + 0.5, t_end + 1.0);
    ivec2 p = ivec2(px);
    Plane s;
    if (!surface_plane(p, s)) return 0;
    float da = ray_depth(r, ta) - plane_depth(s, p, ray_px(r, ta));
    float db = ray_depth(r, tb) - plane_depth(s, p, ray_px(r, tb));
    return (max(da, db) >= 0.0 && min(da, db) <= s.behind) ? 1 : 0;
}

// Bisection between the last step that was in front (t - 1) and the hit at step t.
vec2 refine(Ray2D r, float t) {
    float lo = t - 1.0, hi = t;
    for (int j = 0; j < u_refine_steps; ++j) {
        float mid = 0.5 * (lo + hi);
        vec2 pm = ray_px(r, mid);
        ivec2 p = ivec2(pm);
        Plane s;
        float dm = surface_plane(p, s) ? ray_depth(r, mid) - plane_depth(s, p, pm) : -1.0;
        if (dm >= 0.0 && dm <= s.behind) hi = mid; else lo = mid;
    }
    return ray_px(r, hi);
}

// Hierarchical traversal (Uludag 2014, GPU Pro 5, on a pyramid of the linear view depth whose
// texels hold the closest depth of the pixels below them): at parameter u (in DDA steps) the
// ray is in one cell of level L; u_exit is where it leaves that cell. If the ray's depth over
// the DDA intervals of every step in [u, u_exit) (each extends half a step to either side) stays
// in front of the cell's closest depth, none of those steps can hit (the DDA's test needs the
// interval to reach the pixel's depth): skip to u_exit and go up a level. Otherwise go down;
// at level 0 run the DDA's own steps inside the pixel. The first hit is therefore the DDA's
// first hit, with the same bisection, for far fewer texel reads over empty space.
bool trace_hiz(Ray2D r, float t_end, out vec2 hit_px, out float steps) {
    steps = 0.0;
    hit_px = vec2(-1.0);
    float u_last = min(float(u_max_steps), floor(t_end + 1.0));  // the DDA's last step
    vec2 ds = r.ds;
    vec2 pos_dir = step(0.0, ds);
    // 1 / ds with the zero component made harmless (that axis never exits)
    vec2 inv_ds = vec2(abs(ds.x) > 1e-12 ? 1.0 / ds.x : 1e30, abs(ds.y) > 1e-12 ? 1.0 / ds.y : 1e30);
    float u = 0.0;
    int level = 0;
    for (int it = 0; it < u_hiz_max_iter; ++it) {
        if (u > u_last) break;
        vec2 s = r.s0 + ds * u;
        vec2 sp = r.permute ? s.yx : s;
        if (!inside(sp)) break;  // the screen is convex: the later steps are off screen too
        steps += 1.0;
        float c = exp2(float(level));
        // the cell the ray is in, taking the side it moves toward on a boundary
        vec2 q = s / c;
        vec2 cell = mix(ceil(q) - 1.0, floor(q), pos_dir);
        vec2 bound = (cell + pos_dir) * c;
        vec2 te = (bound - r.s0) * inv_ds;
        te = mix(te, vec2(1e30), lessThanEqual(abs(ds), vec2(1e-12)));
        float u_exit = max(min(te.x, te.y), u + 1e-4);
        ivec2 fc = ivec2(r.permute ? cell.yx : cell);
        // level sizes are max(1, n >> k); the last texel also covers an odd level's extra row / column
        fc = clamp(fc, ivec2(0), max(ivec2(u_size) >> level, ivec2(1)) - 1);
        float zmin = texelFetch(u_hiz_tex, fc, level).r;
        float a = u <= 1.0 ? 0.0 : min(u - 0.5, t_end + 1.0);
        float b = min(u_exit + 0.5, t_end + 1.0);
        float dmax = max(ray_depth(r, a), ray_depth(r, b));
        // (a step compares the ray with a pixel's plane up to a step and a pixel from its
        // centre, at most u_max_slope per pixel in front of its depth: skipped only before that)
        if (dmax < zmin - u_max_slope * (0.5 * u_stride + 1.5)) {
            u = u_exit;
            level = min(level + 1, u_hiz_max_level);
            continue;
        }
        if (level > 0) { level -= 1; continue; }
        for (float i = max(1.0, ceil(u)); i < u_exit && i <= u_last; i += 1.0) {
            int res = dda_step(r, i, t_end);
            if (res == 2) return false;
            if (res == 1) { hit_px = refine(r, i); return true; }
        }
        u = u_exit;
    }
    return false;
}

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
    if (u_jitter != 0) {
        // A fixed stride samples the depth buffer at the same phase along neighbouring rays, so
        // where a ray grazes a surface (within the thickness for a few steps) neighbouring
        // pixels alternate between hit and miss: comb-like streaks. Starting each ray a random
        // fraction of a stride along, a new fraction each frame, turns that pattern into noise
        // that the frame average (the window's accumulation while the view is still, or
        // render_arrays(frames=K)) removes.
        float j = pixel_hash(uvec2(gl_FragCoord.xy), uint(u_frame_index));
        r.s0 += r.ds * j;
        r.q0 += r.dq * j;
        r.k0 += r.dk * j;
        t_end -= j;
    }
    if (u_hiz != 0) return trace_hiz(r, t_end, hit_px, steps);
    float t = 0.0;
    for (int i = 0; i < u_max_steps; ++i) {
        t += 1.0;
        if (t > t_end + 1.0) break;
        steps += 1.0;
        int res = dda_step(r, t, t_end);
        if (res == 2) break;
        if (res == 1) { hit_px = refine(r, t); return true; }
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
    // a pixel whose samples saw different surfaces (a silhouette: cov <= u_min_coverage) has no
    // one normal to reflect about; it keeps the forward pass's resolved radiance, whose
    // specular environment term is right for each sample (the dark pixels along a ball's
    // silhouette over a mirror floor came from dropping that term there)
    bool surface = cov > u_min_coverage && any(greaterThan(rho_s, vec3(0.0)));
    vec3 reflected = vec3(0.0), env = vec3(0.0);
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
        env = u_env_on != 0 ? env_prefiltered(r_w, alpha) : vec3(0.0);
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
                // a sharp reflection reads the hit pixel itself: a bilinear lookup near a
                // silhouette mixes in the neighbour behind it (a mirror floor's own colour
                // there is black: dark streaks across the reflection's edge)
                vec3 c = lod > 0.0 ? textureLod(u_color, hit_uv, lod).rgb : texelFetch(u_color, ivec2(hp), 0).rgb;
                reflected = mix(env, c, fade);
                hit = fade;
            }
        }
    }
    // base holds rho_s * env already (the forward pass's split sum, the same lookup): add the
    // difference, so a miss is the SSR-off pixel exactly
    vec3 ssr = rho_s * reflected;
    base -= rho_s * env;
    if (u_debug == SSR_DEBUG_COMPOSITE) frag_color = vec4(base + ssr, 1.0);
    else if (u_debug == SSR_DEBUG_HIT) frag_color = vec4(surface ? vec3(hit) : vec3(0.0, 0.0, 0.25 * float(cov > 0.5)), 1.0);
    else if (u_debug == SSR_DEBUG_STEPS) frag_color = vec4(surface ? false_colour(steps / float(u_max_steps)) : vec3(0.0), 1.0);
    else if (u_debug == SSR_DEBUG_UV) frag_color = vec4(hit > 0.0 ? vec3(hit_uv, 0.0) : vec3(0.0), 1.0);
    else frag_color = vec4(ssr, 1.0);
}
