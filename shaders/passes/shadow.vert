#version 410 core
in vec3 in_position;
in mat4 in_model;     // per instance: object to world (viewer.gl.renderer.instance_data)
uniform mat4 u_mvp;   // the tile's light-space view-projection
void main() { gl_Position = u_mvp * (in_model * vec4(in_position, 1.0)); }
