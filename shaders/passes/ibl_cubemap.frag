#version 410 core
// One face of a cube map from the lat-long map (viewer/gl/ibl.py; the numpy reference is
// viewer.environment.latlong.to_cubemap). Pixel (x, y) of the face has s = (x + 0.5) / size,
// t = (y + 0.5) / size, and its direction inverts the OpenGL 4.6 core specification's table of
// section 8.13 "Cube Map Texture Selection" (sc = 2 s - 1, tc = 2 t - 1, |ma| = 1):
//   +X: (1, -tc, -sc)   -X: (-1, -tc, sc)   +Y: (sc, 1, tc)
//   -Y: (sc, -1, -tc)   +Z: (sc, -tc, 1)    -Z: (-sc, -tc, -1)
// Each texel is the mean of u_supersample^2 bilinear lookups spread over it (map rotation by
// u_env_rot, like every lookup of common/ibl.glsl).
#include "common/math.glsl"
#include "common/ibl.glsl"

uniform int u_face;
uniform float u_face_size;
uniform int u_supersample;
out vec4 frag_color;

vec3 face_dir(int face, float sc, float tc) {
    if (face == 0) return vec3(1.0, -tc, -sc);
    if (face == 1) return vec3(-1.0, -tc, sc);
    if (face == 2) return vec3(sc, 1.0, tc);
    if (face == 3) return vec3(sc, -1.0, -tc);
    if (face == 4) return vec3(sc, -tc, 1.0);
    return vec3(-sc, -tc, -1.0);
}

void main() {
    int n = max(u_supersample, 1);
    vec3 sum = vec3(0.0);
    for (int j = 0; j < n; ++j) {
        for (int i = 0; i < n; ++i) {
            vec2 off = (vec2(float(i), float(j)) + 0.5) / float(n) - 0.5;
            vec2 st = (floor(gl_FragCoord.xy) + 0.5 + off) / u_face_size;
            vec3 d = normalize(face_dir(u_face, 2.0 * st.x - 1.0, 2.0 * st.y - 1.0));
            sum += env_radiance(d);
        }
    }
    frag_color = vec4(sum / float(n * n), 1.0);
}
