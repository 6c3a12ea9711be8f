// The predicates of viewer/brdf/lobes.py's Lobe on the LOBE_* flags of generated/constants.glsl
// (a material's lobes, or the lobe one sample drew: the out uint lobe of brdf_sample).
#include "generated/constants.glsl"

// Every lobe is a delta lobe (mirror, smooth glass): nothing for light sampling to find.
bool lobe_is_delta(uint l) { return (l & LOBE_DELTA) != 0u && (l & LOBE_SMOOTH) == 0u; }
// Some lobe is a delta lobe (for one sample's lobe: it was drawn discretely, no MIS).
bool lobe_has_delta(uint l) { return (l & LOBE_DELTA) != 0u; }
// Some lobe scatters to the other side of the surface.
bool lobe_transmits(uint l) { return (l & LOBE_TRANSMISSION) != 0u; }
// The side a direction pair is on: reflection (wi, wo on one side) or transmission.
uint lobe_side(vec3 wi, vec3 wo) { return wi.z * wo.z >= 0.0 ? LOBE_REFLECTION : LOBE_TRANSMISSION; }
