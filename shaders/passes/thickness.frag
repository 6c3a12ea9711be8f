#version 410 core
// Distance from the camera to this (back) face: the far side of a transmissive object.
in vec3 vs_position;
uniform vec3 u_camera_pos;
out vec4 distance_out;
void main() { distance_out = vec4(length(vs_position - u_camera_pos), 0.0, 0.0, 1.0); }
