// Shadow maps in one depth atlas for the first SHADOW_LIGHTS lights: light i owns row i; a point
// light uses six 90-degree (plus a margin) perspective tiles, one per cube face, a directional
// light one orthographic tile. Lights SHADOW_LIGHTS.. (up to MAX_LIGHTS) are drawn unshadowed.
// Filtering: 4 taps of hardware 2x2 comparison (bilinear PCF), a 3x3-texel tent.
#include "generated/constants.glsl"

uniform sampler2DShadow u_shadow_atlas;
uniform mat4 u_shadow_mat[SHADOW_LIGHTS * 6];
uniform vec2 u_shadow_atlas_tiles;   // (tiles per row = 6, rows)
uniform float u_shadow_tile_size;     // texels per tile side
uniform int u_shadows_on;

// The cube face whose frustum contains direction d (major axis): +x, -x, +y, -y, +z, -z.
int cube_face(vec3 d) {
    vec3 a = abs(d);
    if (a.x >= a.y && a.x >= a.z) return d.x > 0.0 ? 0 : 1;
    if (a.y >= a.z) return d.y > 0.0 ? 2 : 3;
    return d.z > 0.0 ? 4 : 5;
}

#ifdef GLASS_SHADOW
// Glass casters (compiled in only for a scene with transmissive objects and shadows): a second
// atlas, the same tiles, holds the optical depth tau (RGB) that the glass in front of the nearest
// opaque caster adds along the light's ray (passes/shadow_glass.frag); the light is multiplied
// by exp(-tau), looked up with one bilinear tap.
uniform sampler2D u_shadow_glass;
vec3 shadow_glass_tau;  // set by shadow_lookup: the filtered optical depth of its last lookup
#endif

float shadow_lookup(int light, int face, vec3 p) {
#ifdef GLASS_SHADOW
    shadow_glass_tau = vec3(0.0);
#endif
    vec4 c = u_shadow_mat[light * 6 + face] * vec4(p, 1.0);
    vec3 ndc = c.xyz / c.w;
    if (c.w <= 0.0 || ndc.z > 1.0) return 1.0;
    vec2 uv = ndc.xy * 0.5 + 0.5;
    // a point light's tile covers only the part of its face the casters do: no caster outside
    if (any(lessThan(uv, vec2(0.0))) || any(greaterThan(uv, vec2(1.0)))) return 1.0;
    float depth = ndc.z * 0.5 + 0.5;
    float texel = 1.0 / u_shadow_tile_size;
    // four bilinear comparison taps at +-half a texel: a 3x3-texel tent filter for 4 fetches
    float sum = 0.0;
    for (int k = 0; k < 4; ++k) {
        vec2 o = vec2((k & 1) == 0 ? -0.5 : 0.5, (k & 2) == 0 ? -0.5 : 0.5);
        // stay inside this tile so taps never read a neighbouring face
        vec2 t = clamp(uv + o * texel, vec2(texel), vec2(1.0 - texel));
        vec2 a = (vec2(float(face), float(light)) + t) / u_shadow_atlas_tiles;
        sum += textureLod(u_shadow_atlas, vec3(a, depth), 0.0);  // explicit LOD: no derivatives needed
    }
#ifdef GLASS_SHADOW
    // one bilinear tap at the centre: the optical depth varies smoothly over a glass caster
    // (four taps, as for the depth, cost llvmpipe 30% of a frame for no visible change)
    vec2 tc = clamp(uv, vec2(texel), vec2(1.0 - texel));
    shadow_glass_tau = textureLod(u_shadow_glass, (vec2(float(face), float(light)) + tc) / u_shadow_atlas_tiles, 0.0).rgb;
#endif
    return 0.25 * sum;
}

// Visibility of light `light` from world point p with geometric normal ng.
// Normal-offset bias: move the lookup point along ng by about a texel's world size (more at
// grazing light), so a surface never shadows itself (acne) while contact shadows stay attached
// (no peter-panning, which a large constant depth bias would cause).
uniform float u_shadow_texel_world[SHADOW_LIGHTS];  // directional: world size of one texel
// point: the width of each face's tile in tan units (2: the whole face; it is cropped to the part
// the casters cover, viewer/gl/shadow.py; 0: no caster in that face)
uniform float u_shadow_face_tan[SHADOW_LIGHTS * 6];

float shadow_visibility(int light, bool point_light, vec3 light_pos, vec3 p, vec3 ng, float ndotl) {
    if (u_shadows_on == 0 || light >= SHADOW_LIGHTS) return 1.0;  // beyond the atlas: unshadowed
    float slope = 1.0 + 2.0 * (1.0 - clamp(ndotl, 0.0, 1.0));
    if (point_light) {
        // a face's tile spans face_tan * dist world units at distance dist (2 dist uncropped)
        float face_tan = u_shadow_face_tan[light * 6 + cube_face(p - light_pos)];
        float texel_world = max(face_tan, 0.05) * length(p - light_pos) / u_shadow_tile_size;
        vec3 q = p + ng * texel_world * slope;
        int face = cube_face(q - light_pos);
        if (u_shadow_face_tan[light * 6 + face] <= 0.0) return 1.0;  // no caster in that face
        return shadow_lookup(light, face, q);
    }
    vec3 q = p + ng * u_shadow_texel_world[light] * slope;
    return shadow_lookup(light, 0, q);
}

#ifdef GLASS_SHADOW
// The light let through: the opaque casters' visibility times the glass's transmittance exp(-tau).
vec3 shadow_transmittance(int light, bool point_light, vec3 light_pos, vec3 p, vec3 ng, float ndotl) {
    if (u_shadows_on == 0 || light >= SHADOW_LIGHTS) return vec3(1.0);
    shadow_glass_tau = vec3(0.0);  // a face with no caster returns before any lookup
    float v = shadow_visibility(light, point_light, light_pos, p, ng, ndotl);
    return v * exp(-shadow_glass_tau);
}
#endif
