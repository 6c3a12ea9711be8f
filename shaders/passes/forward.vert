#version 410 core
// Forward pass: world-space position, normal and tangent frame for per-pixel shading.
in vec3 in_position;
in vec3 in_normal;
in vec4 in_tangent;   // xyz tangent (+x of the shading frame), w = bitangent sign

// per instance (one draw per mesh and material: viewer.gl.renderer.instance_data)
in mat4 in_model;           // object to world
in mat3 in_normal_matrix;   // inverse transpose of the model matrix's 3x3
uniform mat4 u_view_proj;

out vec3 vs_position;   // to forward.geom, which adds the triangle's geometric normal
out vec3 vs_normal;
out vec4 vs_tangent;

void main() {
    vec4 world = in_model * vec4(in_position, 1.0);
    vs_position = world.xyz;
    vs_normal = in_normal_matrix * in_normal;
    vs_tangent = vec4(mat3(in_model) * in_tangent.xyz, in_tangent.w);
    gl_Position = u_view_proj * world;
}
