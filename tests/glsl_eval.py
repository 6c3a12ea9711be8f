"""Evaluate the GLSL twin of a BRDF on the GPU: directions go in as float textures, the BRDF
value comes back from a float32 render target (the GPU path, not a CPU emulation)."""

from __future__ import annotations

import numpy as np

from viewer.brdf.glsl import uniform_block
from viewer.gl.shaders import build_program

_VERT = """#version 410 core
out vec2 v_uv;
void main() {
    vec2 p = vec2((gl_VertexID << 1) & 2, gl_VertexID & 2);
    v_uv = p;
    gl_Position = vec4(p * 2.0 - 1.0, 0.0, 1.0);
}
"""

_FRAG = """#version 410 core
#include "brdf/dispatch.glsl"
uniform sampler2D u_wi;
uniform sampler2D u_wo;
uniform int u_model;
uniform int u_what;  // 0 eval, 1 terms
out vec4 color;
void main() {
    ivec2 px = ivec2(gl_FragCoord.xy);
    vec3 wi = texelFetch(u_wi, px, 0).xyz;
    vec3 wo = texelFetch(u_wo, px, 0).xyz;
    color = vec4(u_what == 0 ? brdf_eval(u_model, 0, wi, wo) : brdf_terms(u_model, 0, wi, wo), 1.0);
}
"""


class GLSLEvaluator:
    WIDTH = 128

    def __init__(self, ctx):
        self.ctx = ctx
        self.prog = build_program(ctx, vertex_source=_VERT, fragment_source=_FRAG)
        self.vao = ctx.vertex_array(self.prog, [])

    def _tex(self, a, w, h):
        data = np.zeros((h * w, 4), dtype="f4")
        data[: len(a), :3] = a
        t = self.ctx.texture((w, h), 4, data.tobytes(), dtype="f4")
        t.filter = (self.ctx.NEAREST, self.ctx.NEAREST)
        return t

    def eval(self, params, wi, wo, what=0) -> np.ndarray:
        """(N, 3) float32 values of the GLSL function for float32-rounded (wi, wo)."""
        n = len(wi)
        w = self.WIDTH
        h = (n + w - 1) // w
        twi, two = self._tex(wi, w, h), self._tex(wo, w, h)
        out = self.ctx.texture((w, h), 4, dtype="f4")
        fbo = self.ctx.framebuffer(color_attachments=[out])
        try:
            idx, block = uniform_block(params)
            self.prog["u_model"].value = idx
            u = self.prog["u_mat"]
            u.write(block[: u.array_length * 4].tobytes())
            twi.use(0)
            two.use(1)
            self.prog["u_wi"].value = 0
            self.prog["u_wo"].value = 1
            if "u_what" in self.prog:
                self.prog["u_what"].value = what
            fbo.use()
            fbo.viewport = (0, 0, w, h)
            self.vao.render(vertices=3)
            res = np.frombuffer(out.read(), dtype="f4").reshape(h * w, 4)[:n, :3]
            return res.copy()
        finally:
            fbo.release()
            out.release()
            twi.release()
            two.release()
