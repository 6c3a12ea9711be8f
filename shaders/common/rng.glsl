// Counter-based random numbers: every number is a hash of (pixel, sample, seed, dimension), so a
// sample's numbers do not depend on which pass or tile rendered it, and the same seed gives the
// same image. pcg4d of Jarzynski and Olano 2020, "Hash Functions for GPU Rendering", JCGT 9(3):
// four 32-bit outputs per call, passing TestU01's BigCrush in their tests.
uvec4 pcg4d(uvec4 v) {
    v = v * 1664525u + 1013904223u;
    v.x += v.y * v.w; v.y += v.z * v.x; v.z += v.x * v.y; v.w += v.y * v.z;
    v ^= v >> 16u;
    v.x += v.y * v.w; v.y += v.z * v.x; v.z += v.x * v.y; v.w += v.y * v.z;
    return v;
}

// the top 24 bits as a float in [0, 1) (every value exact in float32, never 1.0)
vec4 u01(uvec4 h) { return vec4(h >> 8u) * (1.0 / 16777216.0); }

// One float in [0, 1) per (pixel, frame): Thomas Wang's 32-bit integer hash of a mix of the
// two (the rasterizer's per-frame jitter; the reference engines use the counter-based numbers
// below).
float pixel_hash(uvec2 p, uint frame) {
    uint h = p.x * 1973u + p.y * 9277u + frame * 26699u;
    h = (h ^ 61u) ^ (h >> 16u);
    h *= 9u;
    h ^= h >> 4u;
    h *= 0x27d4eb2du;
    h ^= h >> 15u;
    return float(h) * 2.3283064365386963e-10;
}

// state: (pixel x, pixel y, sample index, seed); each call draws 4 numbers of the next dimension block
struct Rng { uvec4 key; uint dim; };
Rng rng_init(ivec2 px, uint sample_index, uint seed) {
    Rng r;
    r.key = uvec4(uint(px.x), uint(px.y), sample_index, seed);
    r.dim = 0u;
    return r;
}
vec4 rng_next4(inout Rng r) {
    // the dimension block is mixed into the seed word; pcg4d diffuses it into all four outputs
    uvec4 k = r.key;
    k.w ^= (r.dim * 0x9E3779B9u);
    r.dim += 1u;
    return u01(pcg4d(k));
}
