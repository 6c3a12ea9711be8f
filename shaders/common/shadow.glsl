// Shadow maps in one depth atlas: light i owns row i; a point light uses six 90-degree (plus a
// margin) perspective tiles, one per cube face, a directional light one orthographic tile.
// Filtering: 9 taps of hardware 2x2 comparison (bilinear PCF) with tent weights, 4 texels wide.
#include "generated/constants.glsl"

uniform sampler2DShadow u_shadow_atlas;
uniform mat4 u_shadow_mat[MAX_LIGHTS * 6];
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

float shadow_lookup(int light, int face, vec3 p) {
    vec4 c = u_shadow_mat[light * 6 + face] * vec4(p, 1.0);
    vec3 ndc = c.xyz / c.w;
    if (c.w <= 0.0 || ndc.z > 1.0) return 1.0;
    vec2 uv = ndc.xy * 0.5 + 0.5;
    float depth = ndc.z * 0.5 + 0.5;
    float texel = 1.0 / u_shadow_tile_size;
    // nine bilinear comparison taps one texel apart, weighted 1 2 1 / 2 4 2 / 1 2 1: the
    // bilinear tent convolved with a discrete tent, a smooth bell four texels wide, so that a
    // shadow edge seen up close (a texel covering several pixels) is a soft ramp, not steps
    float sum = 0.0;
    for (int k = 0; k < 9; ++k) {
        vec2 o = vec2(float(k % 3 - 1), float(k / 3 - 1));
        float w = (2.0 - abs(o.x)) * (2.0 - abs(o.y));
        // stay inside this tile so taps never read a neighbouring face
        vec2 t = clamp(uv + o * texel, vec2(texel), vec2(1.0 - texel));
        vec2 a = (vec2(float(face), float(light)) + t) / u_shadow_atlas_tiles;
        sum += w * textureLod(u_shadow_atlas, vec3(a, depth), 0.0);  // explicit LOD: no derivatives needed
    }
    return sum / 16.0;
}

// Visibility of light `light` from world point p with geometric normal ng.
// Normal-offset bias: move the lookup point along ng by about a texel's world size (more at
// grazing light), so a surface never shadows itself (acne) while contact shadows stay attached
// (no peter-panning, which a large constant depth bias would cause).
uniform float u_shadow_texel_world[MAX_LIGHTS];  // directional: world size of one texel

float shadow_visibility(int light, bool point_light, vec3 light_pos, vec3 p, vec3 ng, float ndotl) {
    if (u_shadows_on == 0) return 1.0;
    float slope = 1.0 + 2.0 * (1.0 - clamp(ndotl, 0.0, 1.0));
    if (point_light) {
        // a 90-degree face spans 2 * dist world units over the tile at distance dist
        float texel_world = 2.0 * length(p - light_pos) / u_shadow_tile_size;
        vec3 q = p + ng * texel_world * slope;
        return shadow_lookup(light, cube_face(q - light_pos), q);
    }
    vec3 q = p + ng * u_shadow_texel_world[light] * slope;
    return shadow_lookup(light, 0, q);
}
