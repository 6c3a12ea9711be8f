#version 410 core
// The glass casters of the shadow pass (viewer/gl/shadow.py): world position and normal per face.
in vec3 in_position;
in vec3 in_normal;
in mat4 in_model;           // per instance: object to world (viewer.gl.meshes.instance_data)
in mat3 in_normal_matrix;   // inverse transpose of its 3x3
uniform mat4 u_mvp;         // the tile's light-space view-projection
out vec3 v_world;
out vec3 v_normal;
void main() {
    vec4 world = in_model * vec4(in_position, 1.0);
    v_world = world.xyz;
    v_normal = in_normal_matrix * in_normal;
    gl_Position = u_mvp * world;
}
