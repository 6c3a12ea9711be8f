// The lookup of a directional-albedo table (viewer/brdf/albedo.py): entry k holds
// cos(theta_o) = (k + 0.5) / ALBEDO_TABLE, linear between entries and clamped at both ends.
// k0, k1: the two entries; fx: the weight of k1.
#include "generated/constants.glsl"
void albedo_lerp(float cos_o, out int k0, out int k1, out float fx) {
    float x = clamp(cos_o, 0.0, 1.0) * float(ALBEDO_TABLE) - 0.5;
    k0 = clamp(int(floor(x)), 0, ALBEDO_TABLE - 1);
    k1 = min(k0 + 1, ALBEDO_TABLE - 1);
    fx = clamp(x - float(k0), 0.0, 1.0);
}
