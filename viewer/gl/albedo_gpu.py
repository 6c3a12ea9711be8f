"""Directional-albedo tables on the GPU: the estimator of ``viewer.brdf.albedo`` (the mean of the
sampler's weight f cos / pdf over 4 azimuths x 576 multi-jittered samples per entry, the same
points) computed with the GLSL ``brdf_sample`` twin instead of the numpy one.

Pass 1 draws one fragment per (entry, azimuth, sample) into two RGBA32F targets (the weight of a
reflected sample into the first, of a transmitted one into the second); pass 2 sums each row of
576 samples; the 4 azimuths are averaged on readback. One program per set of models (the
material and any nested base), compiled on first use; a slider move is a uniform upload and two
small draws. ``viewer.brdf.albedo`` stays the numpy oracle the tests compare with."""

from __future__ import annotations

import numpy as np

from viewer.brdf.albedo import N_SIDE, PHIS, TABLE_SIZE, stratified_u
from viewer.gl import texture_units
from viewer.gl.brdf_glsl import choice_constants, custom_virtual, generate_dispatch, glsl_u, models_used, program_defines, uniform_block
from viewer.gl.context import release_gl
from viewer.gl.shaders import build_program, set_uniform

_VERT = """#version 410 core
void main() {
    vec2 p = vec2((gl_VertexID << 1) & 2, gl_VertexID & 2);
    gl_Position = vec4(p * 2.0 - 1.0, 0.0, 1.0);
}
"""

# one fragment per (sample s = x, row y = entry * n_phi + azimuth)
_SAMPLE_FRAG = """#version 410 core
#include "brdf/dispatch.glsl"
uniform sampler2D u_pattern;   // (samples, azimuths): the GLSL u of each sample
uniform int u_model;
uniform int u_size;            // table entries: cos_o = (k + 0.5) / size
uniform int u_nphi;
uniform float u_phi[8];
layout(location = 0) out vec4 out_refl;
layout(location = 1) out vec4 out_trans;
void main() {
    ivec2 px = ivec2(gl_FragCoord.xy);
    int k = px.y / u_nphi;
    int j = px.y - k * u_nphi;
    float c = (float(k) + 0.5) / float(u_size);
    float s = sqrt(max(0.0, 1.0 - c * c));
    vec3 wo = vec3(s * cos(u_phi[j]), s * sin(u_phi[j]), c);
    vec3 u = texelFetch(u_pattern, ivec2(px.x, j), 0).xyz;
    vec3 wi;
    float pdf;
    uint lobe;
    vec3 w = brdf_sample(u_model, 0, wo, u, wi, pdf, lobe);
    if (!(pdf > 0.0) || !all(lessThan(abs(w), vec3(3.0e38)))) w = vec3(0.0);
    bool below = wi.z < 0.0;
    out_refl = vec4(below ? vec3(0.0) : w, 1.0);
    out_trans = vec4(below ? w : vec3(0.0), 1.0);
}
"""

# the sum of each row (one fragment per row)
_REDUCE_FRAG = """#version 410 core
uniform sampler2D u_refl;
uniform sampler2D u_trans;
uniform int u_count;
layout(location = 0) out vec4 out_refl;
layout(location = 1) out vec4 out_trans;
void main() {
    int y = int(gl_FragCoord.y);
    vec3 r = vec3(0.0), t = vec3(0.0);
    for (int x = 0; x < u_count; ++x) {
        r += texelFetch(u_refl, ivec2(x, y), 0).rgb;
        t += texelFetch(u_trans, ivec2(x, y), 0).rgb;
    }
    out_refl = vec4(r, 1.0);
    out_trans = vec4(t, 1.0);
}
"""


class GPUAlbedoTables:
    """``tables(params)`` = ``viewer.brdf.albedo.albedo_tables(model, params)`` computed on the
    GPU of ``ctx``: (reflected, transmitted) albedo, each (size, 3) float64."""

    def __init__(self, ctx, size: int = TABLE_SIZE, n_side: int = N_SIDE, phis=PHIS):
        self.ctx = ctx
        self.size = int(size)
        self.phis = tuple(float(p) for p in phis)
        assert len(self.phis) <= 8
        self.patterns = [stratified_u(n_side, seed) for seed in range(len(self.phis))]
        self.count = len(self.patterns[0])
        self.rows = self.size * len(self.phis)
        self._programs: dict[tuple, object] = {}
        self._pattern_tex: dict[bool, object] = {}
        self._reduce = build_program(ctx, vertex_source=_VERT, fragment_source=_REDUCE_FRAG)
        self._vaos: dict[int, object] = {}
        f4 = "f4"
        self._t1 = [ctx.texture((self.count, self.rows), 4, dtype=f4) for _ in range(2)]
        self._t2 = [ctx.texture((1, self.rows), 4, dtype=f4) for _ in range(2)]
        for t in self._t1 + self._t2:
            t.filter = (ctx.NEAREST, ctx.NEAREST)
        self._fbo1 = ctx.framebuffer(color_attachments=self._t1)
        self._fbo2 = ctx.framebuffer(color_attachments=self._t2)

    _measured = None  # MeasuredTextures, made for the first measured material

    @staticmethod
    def _key(params):
        models = models_used(params)
        fixed = choice_constants(params)
        defines = program_defines([params])
        key = (models, tuple(sorted((m, tuple(sorted(c.items()))) for m, c in fixed.items())), tuple(defines))
        return key, models, fixed, defines

    def has_program(self, params) -> bool:
        """Whether the sampling program of ``params`` is built (a table then needs no compile)."""
        return self._key(params)[0] in self._programs

    def _program(self, params):
        """The sampling program of the material's models with its choices compiled in (a
        choice switch compiles once; a slider move reuses it)."""
        key, models, fixed, defines = self._key(params)
        prog = self._programs.get(key)
        if prog is None:
            virtual = {"brdf/dispatch.glsl": generate_dispatch(models, fixed), **custom_virtual(models)}
            prog = build_program(self.ctx, vertex_source=_VERT, fragment_source=_SAMPLE_FRAG, virtual=virtual,
                                 defines=defines or None)
            self._programs[key] = prog
        return prog

    def _vao(self, prog):
        vao = self._vaos.get(id(prog))
        if vao is None:
            vao = self._vaos[id(prog)] = self.ctx.vertex_array(prog, [])
        return vao

    def _pattern(self, params):
        """The u texture: the numpy estimator's points mapped to GLSL's u (glsl_u); two layouts
        (plain, split), keyed by the first sample's third component."""
        us = [glsl_u(params, u) for u in self.patterns]
        split = bool(np.any(us[0][:, 2] != 0))
        tex = self._pattern_tex.get(split)
        if tex is None:
            data = np.zeros((len(us), self.count, 4), dtype="f4")
            for j, u in enumerate(us):
                data[j, :, :3] = np.minimum(u, np.nextafter(np.float32(1.0), np.float32(0.0)))
            tex = self.ctx.texture((self.count, len(us)), 4, data.tobytes(), dtype="f4")
            tex.filter = (self.ctx.NEAREST, self.ctx.NEAREST)
            self._pattern_tex[split] = tex
        return tex

    def tables(self, params) -> tuple[np.ndarray, np.ndarray]:
        ctx = self.ctx
        prog = self._program(params)
        idx, block = uniform_block(params)
        # Binds its own targets and leaves them bound: the framebuffer bound before may already be
        # released (a finished render's), so callers bind their target again after this call.
        ctx.disable(ctx.BLEND)
        # (the compiler drops what a model does not use: e.g. Lambert's weight ignores wo)
        set_uniform(prog, "u_model", idx)
        set_uniform(prog, "u_mat", block.tobytes())
        if "u_measured" in prog:
            if self._measured is None:
                from viewer.gl.measured_tex import MeasuredTextures

                self._measured = MeasuredTextures(ctx)
            self._measured.bind(prog, params)
        set_uniform(prog, "u_size", self.size)
        set_uniform(prog, "u_nphi", len(self.phis))
        set_uniform(prog, "u_phi", np.array(list(self.phis) + [0.0] * (8 - len(self.phis)), dtype="f4").tobytes())
        self._pattern(params).use(texture_units.ALBEDO_PATTERN)
        set_uniform(prog, "u_pattern", texture_units.ALBEDO_PATTERN)
        self._fbo1.use()
        self._fbo1.viewport = (0, 0, self.count, self.rows)
        self._vao(prog).render(vertices=3)
        red = self._reduce
        self._t1[0].use(texture_units.SOURCE)
        self._t1[1].use(texture_units.SECOND_SOURCE)
        red["u_refl"].value = texture_units.SOURCE
        red["u_trans"].value = texture_units.SECOND_SOURCE
        red["u_count"].value = self.count
        self._fbo2.use()
        self._fbo2.viewport = (0, 0, 1, self.rows)
        self._vao(red).render(vertices=3)
        r = np.frombuffer(self._fbo2.read(components=4, dtype="f4", attachment=0), dtype="f4")
        t = np.frombuffer(self._fbo2.read(components=4, dtype="f4", attachment=1), dtype="f4")
        n = self.count * len(self.phis)
        r = r.reshape(self.size, len(self.phis), 4)[:, :, :3].sum(axis=1, dtype=np.float64) / n
        t = t.reshape(self.size, len(self.phis), 4)[:, :, :3].sum(axis=1, dtype=np.float64) / n
        return r, t

    def release(self):
        if self._measured is not None:
            self._measured.release()
            self._measured = None
        release_gl(self._fbo1, self._fbo2, *self._t1, *self._t2, *self._pattern_tex.values(),
                   *self._vaos.values(), *self._programs.values(), self._reduce)
        self._programs.clear()
        self._pattern_tex.clear()
        self._vaos.clear()
