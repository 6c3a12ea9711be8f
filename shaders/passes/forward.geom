#version 410 core
// Passes each triangle through and adds its geometric normal (world space, from the winding) as
// a flat varying: the fragment stage needs the true surface for the light-facing test and the
// shadow offset, as the reference path tracer uses it, and screen-space derivatives are not
// reliable under per-sample shading.
layout(triangles) in;
layout(triangle_strip, max_vertices = 3) out;

in vec3 vs_position[];
in vec3 vs_normal[];
in vec4 vs_tangent[];

out vec3 v_position;
out vec3 v_normal;
out vec4 v_tangent;
flat out vec3 v_geometric_normal;

void main() {
    vec3 ng = cross(vs_position[1] - vs_position[0], vs_position[2] - vs_position[0]);
    float len = length(ng);
    ng = len > 0.0 ? ng / len : vec3(0.0, 0.0, 1.0);
    for (int k = 0; k < 3; ++k) {
        gl_Position = gl_in[k].gl_Position;
        v_position = vs_position[k];
        v_normal = vs_normal[k];
        v_tangent = vs_tangent[k];
        v_geometric_normal = ng;
        EmitVertex();
    }
    EndPrimitive();
}
