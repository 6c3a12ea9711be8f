"""The scene's triangles, shading data and BVH as float textures on the GPU (OpenGL 4.1).

``SceneTextures(ctx, geom)`` uploads ``viewer.geometry.bvh_flat.flatten_scene(geom)`` once
(per geometry change: make a new one, ``release`` the old). ``bind(prog, unit)`` binds the
three textures to texture units ``unit, unit + 1, unit + 2`` and points the samplers of
``shaders/common/bvh.glsl`` (``u_bvh_nodes``, ``u_bvh_tris``, ``u_tri_shading``) at them,
returning the next free unit. Programs that ``#include "common/bvh.glsl"`` then call
``bvh_closest`` / ``bvh_occluded`` (see that file).
"""

from __future__ import annotations

import numpy as np

from viewer.gl.shaders import set_uniform
from viewer.gl.context import release_gl
from viewer.geometry.bvh_flat import FlatScene, flatten_scene

SAMPLERS = ("u_bvh_nodes", "u_bvh_tris", "u_tri_shading")


def float_texture(ctx, texels: np.ndarray):
    """An RGBA32F texture holding (rows, width, 4) float32 texels as they are (NEAREST)."""
    import moderngl

    rows, width, _ = texels.shape
    tex = ctx.texture((width, rows), 4, np.ascontiguousarray(texels, dtype=np.float32).tobytes(), dtype="f4")
    tex.filter = (moderngl.NEAREST, moderngl.NEAREST)
    tex.repeat_x = tex.repeat_y = False
    return tex


class SceneTextures:
    """One scene geometry on the GPU. Attributes: ``flat`` (the ``FlatScene``: ``prim_id``
    maps a hit's reordered triangle to the geometry's), ``n_triangles``, ``n_nodes``."""

    def __init__(self, ctx, geom=None, *, flat: FlatScene | None = None):
        self.ctx = ctx
        self.flat = flat if flat is not None else flatten_scene(geom)
        self.n_triangles = self.flat.n_triangles
        self.n_nodes = self.flat.n_nodes
        self.textures = [float_texture(ctx, a) for a in (self.flat.nodes, self.flat.tris, self.flat.shading)]

    def bind(self, prog, unit: int = 0) -> int:
        for k, (name, tex) in enumerate(zip(SAMPLERS, self.textures)):
            tex.use(location=unit + k)
            set_uniform(prog, name, unit + k)
        set_uniform(prog, "u_bvh_n_tris", self.n_triangles)
        return unit + len(self.textures)

    def release(self):
        for t in self.textures:
            t.release()
        self.textures = []

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.release()


_QUERY_FRAG = """#version 410 core
#include "common/bvh.glsl"
uniform sampler2D u_orig;   // (o.xyz, tmin)
uniform sampler2D u_dir;    // (d.xyz, tmax)
uniform int u_any;
uniform int u_n;
out vec4 color;
void main() {
    ivec2 px = ivec2(gl_FragCoord.xy);
    int i = px.y * 4096 + px.x;
    if (i >= u_n) { color = vec4(0.0); return; }
    vec4 o = texelFetch(u_orig, px, 0);
    vec4 d = texelFetch(u_dir, px, 0);
    if (u_any != 0) {
        color = vec4(bvh_occluded(o.xyz, d.xyz, o.w, d.w) ? 1.0 : 0.0, 0.0, 0.0, 0.0);
        return;
    }
    BvhHit h;
    bool hit = bvh_closest(o.xyz, d.xyz, o.w, d.w, h);
    color = vec4(h.t, intBitsToFloat(hit ? bvh_prim(h.tri) : -1), h.uv);
}
"""


class RayQuery:
    """Trace a batch of rays through ``bvh.glsl`` on the GPU and read the answers back (tests,
    debugging): ``intersect(o, d, tmin, tmax) -> (t, prim, u, v)`` with ``prim`` the scene
    geometry's triangle index (-1, t = BVH_INF on a miss); ``occluded(...) -> bool``."""

    def __init__(self, ctx):
        from viewer.gl.shaders import build_program

        self.ctx = ctx
        vert = ("#version 410 core\nvoid main() { vec2 p = vec2((gl_VertexID << 1) & 2, gl_VertexID & 2);\n"
                "    gl_Position = vec4(p * 2.0 - 1.0, 0.0, 1.0); }\n")
        self.prog = build_program(ctx, vertex_source=vert, fragment_source=_QUERY_FRAG, virtual={})
        self.vao = ctx.vertex_array(self.prog, [])

    def _run(self, scene_tex: SceneTextures, o, d, tmin, tmax, any_hit):
        from viewer.geometry.bvh_flat import TEX_WIDTH, as_texels

        o = np.asarray(o, np.float64).reshape(-1, 3)
        d = np.asarray(d, np.float64).reshape(-1, 3)
        n = len(o)
        tmax = np.broadcast_to(np.asarray(tmax, np.float64), (n,))
        ot = as_texels(np.concatenate([o, np.full((n, 1), tmin)], axis=1))
        dt = as_texels(np.concatenate([d, np.minimum(tmax, 3.0e38)[:, None]], axis=1))
        rows = ot.shape[0]
        to, td = float_texture(self.ctx, ot), float_texture(self.ctx, dt)
        out = self.ctx.texture((TEX_WIDTH, rows), 4, dtype="f4")
        fbo = self.ctx.framebuffer(color_attachments=[out])
        try:
            unit = scene_tex.bind(self.prog, 0)
            to.use(location=unit)
            td.use(location=unit + 1)
            set_uniform(self.prog, "u_orig", unit)
            set_uniform(self.prog, "u_dir", unit + 1)
            set_uniform(self.prog, "u_any", int(any_hit))
            set_uniform(self.prog, "u_n", n)
            fbo.use()
            fbo.viewport = (0, 0, TEX_WIDTH, rows)
            self.vao.render(vertices=3)
            res = np.frombuffer(fbo.read(components=4, dtype="f4"), np.float32).reshape(-1, 4)[:n]
        finally:
            release_gl(fbo, out, to, td)
        return res

    def intersect(self, scene_tex: SceneTextures, o, d, tmin: float = 0.0, tmax=np.inf):
        r = self._run(scene_tex, o, d, tmin, tmax, False)
        prim = np.ascontiguousarray(r[:, 1]).view(np.int32).astype(np.int64)
        return r[:, 0].astype(np.float64), prim, r[:, 2].astype(np.float64), r[:, 3].astype(np.float64)

    def occluded(self, scene_tex: SceneTextures, o, d, tmin: float = 0.0, tmax=np.inf) -> np.ndarray:
        return self._run(scene_tex, o, d, tmin, tmax, True)[:, 0] > 0.5

    def release(self):
        self.vao.release()
        self.prog.release()
