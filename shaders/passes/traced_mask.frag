#version 410 core
// Which pixels a traced specular chain starts at: 1 where the front-most surface is a mirror or
// smooth glass drawn with the traced variant, 0 elsewhere (viewer.gl.renderer.traced_mask).
uniform float u_traced;
out vec4 mask_out;
void main() { mask_out = vec4(u_traced, 0.0, 0.0, 1.0); }
