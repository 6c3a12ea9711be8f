"""Evaluate the GLSL twin of a BRDF on the GPU: directions go in as float textures, the BRDF
value comes back from a float32 render target (the GPU path, not a CPU emulation)."""

from __future__ import annotations

import numpy as np

from viewer.gl.brdf_glsl import generate_dispatch, models_used, program_defines, uniform_block
from viewer.gl.measured_tex import MeasuredTextures
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
uniform int u_what;  // 0 eval, 1 terms, 2 pdf
uniform float u_film_height;  // the shading point's relative height (a thin film over height)
out vec4 color;
void main() {
    brdf_film_height = u_film_height;
    ivec2 px = ivec2(gl_FragCoord.xy);
    vec3 wi = texelFetch(u_wi, px, 0).xyz;
    vec3 wo = texelFetch(u_wo, px, 0).xyz;
    vec3 v = u_what == 0 ? brdf_eval(u_model, 0, wi, wo)
           : (u_what == 1 ? brdf_terms(u_model, 0, wi, wo) : vec3(brdf_pdf(u_model, 0, wi, wo)));
    color = vec4(v, 1.0);
}
"""

# brdf_sample: wo and u in, (wi, pdf) and (weight, lobe) out through two float32 targets.
_FRAG_SAMPLE = """#version 410 core
#include "brdf/dispatch.glsl"
uniform sampler2D u_wo;
uniform sampler2D u_u;
uniform int u_model;
layout(location = 0) out vec4 out_wi_pdf;
layout(location = 1) out vec4 out_weight;
void main() {
    ivec2 px = ivec2(gl_FragCoord.xy);
    vec3 wo = texelFetch(u_wo, px, 0).xyz;
    vec3 u = texelFetch(u_u, px, 0).xyz;
    vec3 wi;
    float pdf;
    uint lobe;
    vec3 w = brdf_sample(u_model, 0, wo, u, wi, pdf, lobe);
    out_wi_pdf = vec4(wi, pdf);
    out_weight = vec4(w, float(lobe));
}
"""


def _set(prog, name, value):
    if name in prog:  # the compiler drops uniforms a program does not use (mirror's eval ignores wi)
        prog[name].value = value


class _FilmPrograms:
    """One program of every model, and programs of a material's own models where it needs a
    variant: THIN_FILM for a film (common/fresnel.glsl compiles the film's wavelength loop only
    then, as the renderers do; every model with the loop takes software GL more than 10 minutes
    to compile), MEASURED_TEXTURE for a measured table (a 3D texture). Built on first use;
    ``use(params)`` sets ``prog`` and ``vao`` to the one the material needs."""

    def _init_programs(self, ctx, fragment):
        self.ctx = ctx
        self._fragment = fragment
        self._programs = {}
        self.measured = MeasuredTextures(ctx)
        self.use(None)

    def use(self, params):
        defines = {} if params is None else program_defines([params])
        key = (models_used(params), tuple(sorted(defines))) if defines else None
        if key not in self._programs:
            if key is None:
                prog = build_program(self.ctx, vertex_source=_VERT, fragment_source=self._fragment)
            else:
                prog = build_program(self.ctx, vertex_source=_VERT, fragment_source=self._fragment,
                                     virtual={"brdf/dispatch.glsl": generate_dispatch(key[0])},
                                     defines=defines)
            self._programs[key] = (prog, self.ctx.vertex_array(prog, []))
        self.prog, self.vao = self._programs[key]


class GLSLEvaluator(_FilmPrograms):
    WIDTH = 128

    def __init__(self, ctx):
        self._init_programs(ctx, _FRAG)

    def _tex(self, a, w, h):
        data = np.zeros((h * w, 4), dtype="f4")
        data[: len(a), :3] = a
        t = self.ctx.texture((w, h), 4, data.tobytes(), dtype="f4")
        t.filter = (self.ctx.NEAREST, self.ctx.NEAREST)
        return t

    def eval(self, params, wi, wo, what=0, film_height=0.0) -> np.ndarray:
        """(N, 3) float32 values of the GLSL function for float32-rounded (wi, wo); ``film_height``
        the relative height (0 bottom .. 1 top) a film's ``thickness_top_nm`` applies at, as the
        forward pass sets it (``brdf_film_height``; 0 where nothing sets it)."""
        n = len(wi)
        w = self.WIDTH
        h = (n + w - 1) // w
        twi, two = self._tex(wi, w, h), self._tex(wo, w, h)
        out = self.ctx.texture((w, h), 4, dtype="f4")
        fbo = self.ctx.framebuffer(color_attachments=[out])
        try:
            self.use(params)
            idx, block = uniform_block(params)
            _set(self.prog, "u_model", idx)
            if "u_mat" in self.prog:
                u = self.prog["u_mat"]
                u.write(block[: u.array_length * 4].tobytes())
            twi.use(0)
            two.use(1)
            for name, unit in (("u_wi", 0), ("u_wo", 1)):
                if name in self.prog:  # a model whose value ignores wi (mirror: 0) drops it
                    self.prog[name].value = unit
            if "u_what" in self.prog:
                _set(self.prog, "u_what", what)
            _set(self.prog, "u_film_height", float(film_height))
            self.measured.bind(self.prog, params)
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


class GLSLSampler(_FilmPrograms):
    """``brdf_sample`` on the GPU path: (wo, u) in as float textures, (wi, weight, pdf,
    lobe) back from two float32 render targets, in chunks of at most CHUNK rows."""

    WIDTH = 1024
    CHUNK = 1024 * 256

    def __init__(self, ctx):
        self._init_programs(ctx, _FRAG_SAMPLE)

    def _tex(self, a, w, h):
        data = np.zeros((h * w, 4), dtype="f4")
        data[: len(a), : a.shape[1]] = a
        t = self.ctx.texture((w, h), 4, data.tobytes(), dtype="f4")
        t.filter = (self.ctx.NEAREST, self.ctx.NEAREST)
        return t

    def sample(self, params, wo, u):
        """(wi (N, 3), weight (N, 3), pdf (N,), lobe (N,) uint8: the Lobe each sample drew), float64
        copies of the float32 results for float32-rounded wo (N, 3) and u (N, 3)."""
        wo = np.broadcast_to(np.asarray(wo, dtype=np.float64), (len(u), 3))
        out = [self._chunk(params, wo[s:s + self.CHUNK], u[s:s + self.CHUNK])
               for s in range(0, len(u), self.CHUNK)]
        return tuple(np.concatenate(parts) for parts in zip(*out))

    def _chunk(self, params, wo, u):
        n = len(u)
        w = self.WIDTH
        h = (n + w - 1) // w
        two, tu = self._tex(wo, w, h), self._tex(u, w, h)
        a = self.ctx.texture((w, h), 4, dtype="f4")
        b = self.ctx.texture((w, h), 4, dtype="f4")
        fbo = self.ctx.framebuffer(color_attachments=[a, b])
        try:
            self.use(params)
            idx, block = uniform_block(params)
            _set(self.prog, "u_model", idx)
            if "u_mat" in self.prog:
                um = self.prog["u_mat"]
                um.write(block[: um.array_length * 4].tobytes())
            two.use(0)
            tu.use(1)
            _set(self.prog, "u_wo", 0)
            _set(self.prog, "u_u", 1)
            self.measured.bind(self.prog, params)
            fbo.use()
            fbo.viewport = (0, 0, w, h)
            self.vao.render(vertices=3)
            ra = np.frombuffer(a.read(), dtype="f4").reshape(h * w, 4)[:n].astype(np.float64)
            rb = np.frombuffer(b.read(), dtype="f4").reshape(h * w, 4)[:n].astype(np.float64)
            return ra[:, :3], rb[:, :3], ra[:, 3], np.rint(rb[:, 3]).astype(np.uint8)
        finally:
            fbo.release()
            a.release()
            b.release()
            two.release()
            tu.release()
