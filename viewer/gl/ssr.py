"""Screen-space reflections: the forward pass's specular environment term replaced by
the scene's own radiance where the reflected ray hits something visible on screen.

When ``scene.render.ssr`` is on, the renderer draws the forward pass (compiled with ``SSR``
defined) into this class's targets: three colour attachments, MSAA like the ordinary pass:

0. the radiance, with the specular environment term ``rho_s * L_env`` as without SSR,
1. ``rho_s`` (the specular part's directional albedo at wo, the weight of that term) and the
   lobe width ``alpha``,
2. the world-space shading normal and the linear view depth (0 where no surface).

The resolve averages each over the pixel's samples. Then one fullscreen pass (shaders/passes/
ssr.frag) traces the reflected ray of every pixel with ``rho_s > 0`` and ``alpha <= max
roughness`` in screen space (McGuire & Mara 2014, "Efficient GPU Screen-Space Ray Tracing",
JCGT 3(4): a DDA over pixels with a stride, a thickness per surface, a maximum distance, then a
bisection), and writes ``radiance + rho_s * L`` with ``L`` the colour at the hit (the previous
colour's mip chain, blurred by roughness) faded toward the prefiltered environment
``env_prefiltered(r, alpha)`` near the screen borders, for rays toward the camera and near the
maximum roughness; misses take the environment. With SSR on, environment lighting is always the
split sum (the ``ibl`` mode's sampled variants mix the specular part into their estimate).

Parameters (published defaults): bias 0.01 and maximum distance 3 (Filament),
thickness 0.05 (0.2 streaked), maximum roughness 0.5, edge fade 0.075 (EEVEE); a stride of 2 pixels stands for
EEVEE's trace precision, with 6 bisection steps after the stride.

What a step hits (ssr.frag, ``surface_depth``): the pixel's surface is its tangent plane, so its
depth is taken at the ray's own screen position with a spread of its slope over half a step
(at most ``max_slope`` per pixel): grazing surfaces change depth by more than the thickness
within a pixel. Behind the front, a closed object reaches to its nearest back face (the
renderer's thickness pass over every object, ``back``), a one-sided surface by the thickness:
a ray through a ball hits it, one passing behind it does not. One frame is the answer: the
per-frame jitter of the ray start (``jitter``) is off by default.

Hi-Z (``settings["hiz"]``, on by default; 0 = the plain DDA, kept for comparison): each frame a
pyramid of the linear view depth is built (``build_hiz``: level k = the minimum, the closest
surface, over 2x2 texels of level k - 1, odd sizes folding their extra row / column into the last
texel; 1e30 where there is no surface), and the trace walks it (Uludag 2014, "Hi-Z Screen-Space
Cone-Traced Reflections", GPU Pro 5): a cell whose closest depth lies behind the ray's depth over
every DDA step inside it (each step's half-step extents included) is skipped and the walk goes
up a level, otherwise down; at level 0 the DDA's own steps run. No step that could hit is
skipped, so the first hit and its bisection are the DDA's (bit-identical on reflective_floor),
for about half the SSR pass's time at 1280x720 on llvmpipe. The pyramid is built on the GPU, one
fullscreen pass per level (shaders/passes/ssr_hiz.frag) into its own texture, copied into level k
of the mipmapped R32F pyramid through a pixel buffer (~16 ms at 1280x720 on llvmpipe; the CPU
path, readback + numpy + ``Texture.write(level=k)``, ~45 ms, is kept as ``build_hiz("cpu")``)."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from viewer.scene.camera import gl_bytes
from viewer.gl import texture_units
from viewer.gl.constants import EMPTY_DEPTH  # the pyramid's value where there is no surface (ssr_hiz.frag)
from viewer.gl.context import release_gl
from viewer.gl.programs import Recipe
from viewer.gl.shaders import set_uniform as _set
from viewer.gl.targets import FrameTargets

#: the pass's programs (name -> recipe), fullscreen passes with the one-model BRDF dispatch
PROGRAMS = {
    "trace": Recipe("passes/fullscreen.vert", "passes/ssr.frag"),
    "background": Recipe("passes/fullscreen.vert", "passes/ssr_background.frag"),
    "hiz": Recipe("passes/fullscreen.vert", "passes/ssr_hiz.frag"),
}


@dataclass
class SsrTargets(FrameTargets):
    """The SSR pass's targets: those of the forward pass (``resolved``: radiance without the
    specular environment term, the specular weight and lobe width, the normal and view depth),
    the radiance's mip chain (``mip``, ``levels`` levels; ``color_fbo`` views resolved[0] for the
    copy into it), the output (``out``), and the Hi-Z pyramid (``hiz``, its ``hiz_sizes``; level 0
    drawn through ``hiz_fbo0``, levels k > 0 into ``hiz_tmp[k]`` and copied through ``hiz_pbo``)."""

    mip: object = None
    mip_fbo: object = None
    levels: int = 1
    color_fbo: object = None
    out: object = None
    out_fbo: object = None
    hiz: object = None
    hiz_sizes: list = field(default_factory=list)
    hiz_fbo0: object = None
    hiz_tmp: list = field(default_factory=list)
    hiz_tmp_fbo: list = field(default_factory=list)
    hiz_pbo: object = None


class SSR:
    settings = {"max_distance": 3.0, "thickness": 0.05, "bias": 0.01, "stride": 2.0, "max_steps": 320,
                "refine_steps": 6, "max_roughness": 0.5, "edge_fade": 0.075,
                "hiz": True, "hiz_build": "gpu", "hiz_max_iter": 2048, "jitter": False, "min_coverage": 0.97,
                "max_slope": 0.25}

    def __init__(self, ctx):
        self.ctx = ctx
        self.programs = {name: recipe.build(ctx) for name, recipe in PROGRAMS.items()}
        self.vaos = {name: ctx.vertex_array(prog, []) for name, prog in self.programs.items()}
        self.last_hiz_s = None
        self._targets = None
        self._key = None
        self.last_pass_s = None

    def program_recipes(self) -> dict[str, Recipe]:
        """How each of the pass's programs is made (name -> Recipe), for hot reload."""
        return dict(PROGRAMS)

    def replace_program(self, name: str, prog) -> None:
        """Use ``prog`` (built from ``program_recipes()[name]``) from now on; the program and
        vertex array it replaces are released."""
        old, old_vao = self.programs[name], self.vaos[name]
        self.programs[name] = prog
        self.vaos[name] = self.ctx.vertex_array(prog, [])
        old_vao.release()
        old.release()

    # ------------------------------------------------------------------ targets
    @property
    def current(self) -> "SsrTargets | None":
        """The targets of the last ``targets`` call (the last SSR frame's), or None."""
        return self._targets

    def targets(self, w, h, samples) -> "SsrTargets":
        key = (w, h, samples)
        if self._key == key:
            return self._targets
        self._release_targets()
        ctx = self.ctx
        res = [ctx.texture((w, h), 4, dtype="f4") for _ in range(3)]
        for t in res:
            t.filter = (ctx.NEAREST, ctx.NEAREST)
        resolved_fbo = ctx.framebuffer(color_attachments=res)
        extra = []
        if samples:
            ms = [ctx.renderbuffer((w, h), 4, samples=samples, dtype="f4") for _ in range(3)]
            depth = ctx.depth_renderbuffer((w, h), samples=samples)
            draw_fbo = ctx.framebuffer(color_attachments=ms, depth_attachment=depth)
            extra = ms + [depth]
        else:
            depth = ctx.depth_renderbuffer((w, h))
            draw_fbo = ctx.framebuffer(color_attachments=res, depth_attachment=depth)
            extra = [depth]
        # the radiance attachment and depth alone: thin shells blend into the radiance only and
        # leave the specular weight and geometry of what lies behind them to the SSR pass
        shell_fbo = ctx.framebuffer(color_attachments=[(ms if samples else res)[0]], depth_attachment=depth)
        levels = 1 + int(math.floor(math.log2(max(w, h))))
        mip = ctx.texture((w, h), 4, dtype="f4")
        mip.filter = (ctx.LINEAR_MIPMAP_LINEAR, ctx.LINEAR)
        mip.repeat_x = mip.repeat_y = False
        mip_fbo = ctx.framebuffer(color_attachments=[mip])
        out = ctx.texture((w, h), 4, dtype="f4")
        out.filter = (ctx.NEAREST, ctx.NEAREST)
        out_fbo = ctx.framebuffer(color_attachments=[out])
        # single-attachment views of the resolved colour, for the copy into the mip chain
        color_fbo = ctx.framebuffer(color_attachments=[res[0]])
        # the Hi-Z pyramid: one mipmapped R32F texture (level sizes floor(n / 2^k), at least 1);
        # level 0 is rendered through a framebuffer, levels k > 0 into their own textures and
        # copied into the pyramid's level k through a pixel buffer (moderngl attaches level 0 only)
        hiz = ctx.texture((w, h), 1, dtype="f4")
        hiz.filter = (ctx.NEAREST_MIPMAP_NEAREST, ctx.NEAREST)
        hiz.repeat_x = hiz.repeat_y = False
        hiz.build_mipmaps(0, levels - 1)  # allocates every level
        hiz_sizes = [(max(1, w >> k), max(1, h >> k)) for k in range(levels)]
        hiz_fbo0 = ctx.framebuffer(color_attachments=[hiz])
        hiz_tmp = [None] + [ctx.texture(sz, 1, dtype="f4") for sz in hiz_sizes[1:]]
        hiz_tmp_fbo = [None] + [ctx.framebuffer(color_attachments=[t_]) for t_ in hiz_tmp[1:]]
        hiz_pbo = ctx.buffer(reserve=4 * hiz_sizes[1][0] * hiz_sizes[1][1]) if levels > 1 else None
        self._targets = SsrTargets(draw_fbo=draw_fbo, resolved_fbo=resolved_fbo, resolved=res, extra=extra,
                                   samples=samples, shell_fbo=shell_fbo, mip=mip, mip_fbo=mip_fbo, levels=levels, color_fbo=color_fbo,
                                   out=out, out_fbo=out_fbo, hiz=hiz, hiz_sizes=hiz_sizes, hiz_fbo0=hiz_fbo0,
                                   hiz_tmp=hiz_tmp, hiz_tmp_fbo=hiz_tmp_fbo, hiz_pbo=hiz_pbo)
        self._key = key
        return self._targets

    def _release_targets(self):
        t = self._targets
        if not t:
            return
        release_gl(t.draw_fbo if t.draw_fbo is not t.resolved_fbo else None,
                   t.resolved_fbo, t.shell_fbo, t.mip_fbo, t.out_fbo, t.color_fbo, t.mip, t.out, *t.resolved, *t.extra,
                   t.hiz_fbo0, t.hiz, t.hiz_pbo, *t.hiz_tmp_fbo, *t.hiz_tmp)
        self._targets = None
        self._key = None

    # ------------------------------------------------------------------ passes
    def background(self, ibl, cam, w, h, env_map_on: bool, constant, rotation_deg):
        """Fill every attachment behind the scene (a clear sets all three to one colour)."""
        ctx = self.ctx
        ctx.disable(ctx.DEPTH_TEST)
        prog = self.programs["background"]
        _set(prog, "u_inv_view_proj", gl_bytes(np.linalg.inv(cam.projection(w / h) @ cam.view())))
        _set(prog, "u_camera_pos", tuple(float(x) for x in cam.position))
        _set(prog, "u_use_map", int(env_map_on))
        _set(prog, "u_constant", tuple(float(x) for x in constant))
        ibl.bind(prog, rotation_deg)
        self.vaos["background"].render(vertices=3)

    def build_hiz(self, method: str | None = None):
        """The Hi-Z pyramid of this frame's linear view depth (the resolved target 2's w over
        the normal's length, the coverage; 1e30 where there is no surface): level k = the
        minimum over 2x2 texels of level k - 1, the last column / row also covering an odd
        level's extra one. ``method`` "gpu" (default): one fullscreen pass per level
        (shaders/passes/ssr_hiz.frag); "cpu": read the depth back, min-pool with numpy, upload."""
        import time

        ctx = self.ctx
        t = self._targets
        method = method or self.settings["hiz_build"]
        t0 = time.perf_counter()
        sizes = t.hiz_sizes
        if method == "cpu":
            g = np.frombuffer(t.resolved[2].read(), np.float32).reshape(sizes[0][1], sizes[0][0], 4)
            for k, z in enumerate(hiz_pyramid_numpy(depth_from_geom(g), len(sizes))):
                t.hiz.write(np.ascontiguousarray(z, np.float32).tobytes(), level=k)
        else:
            ctx.disable(ctx.DEPTH_TEST)
            prog = self.programs["hiz"]
            _set(prog, "u_src", texture_units.SOURCE)
            t.resolved[2].use(location=texture_units.SOURCE)
            _set(prog, "u_level", 0)
            t.hiz_fbo0.use()
            t.hiz_fbo0.viewport = (0, 0) + sizes[0]
            self.vaos["hiz"].render(vertices=3)
            t.hiz.use(location=texture_units.SOURCE)
            for k in range(1, len(sizes)):
                _set(prog, "u_level", k)
                _set(prog, "u_src_size", sizes[k - 1])
                fbo = t.hiz_tmp_fbo[k]
                fbo.use()
                fbo.viewport = (0, 0) + sizes[k]
                self.vaos["hiz"].render(vertices=3)
                t.hiz_tmp[k].read_into(t.hiz_pbo)
                t.hiz.write(t.hiz_pbo, level=k)
        self.last_hiz_s = time.perf_counter() - t0
        return t.hiz

    def read_resolved(self, index: int) -> np.ndarray:
        """Resolved forward target ``index`` of the last frame as float32 (H, W, 4), rows bottom
        to top: 1 the specular weight, 2 the geometry (normal, depth)."""
        tex = self._targets.resolved[index]
        w, h = tex.size
        return np.frombuffer(tex.read(), np.float32).reshape(h, w, 4).copy()

    def read_hiz(self):
        """The pyramid's levels as float32 arrays (rows bottom to top, like the textures)."""
        t = self._targets
        out = []
        for k, (w, h) in enumerate(t.hiz_sizes):
            out.append(np.frombuffer(t.hiz.read(level=k), np.float32).reshape(h, w).copy())
        return out

    def resolve_and_trace(self, ibl, cam, w, h, env_on: bool, rotation_deg: float, debug: int = 0,
                          frame_index: int = 0, back=None):
        """Resolve the forward targets, build the colour mip chain and run the SSR pass; returns
        the output texture (linear RGBA32F). ``back``: the distance from the camera to the nearest
        back face per pixel (R32F, 0 where none; the renderer's thickness pass over every object),
        the far side of what each pixel shows."""
        import time

        ctx = self.ctx
        t = self._targets
        if t.draw_fbo is not t.resolved_fbo:
            ctx.copy_framebuffer(t.resolved_fbo, t.draw_fbo)  # every attachment
        t0 = time.perf_counter()
        # framebuffer to framebuffer (a blit keeps the float values; a copy into the texture
        # itself went through an 8-bit format: reflections quantized and clamped at 1)
        ctx.copy_framebuffer(t.mip_fbo, t.color_fbo)
        t.mip.build_mipmaps(0, t.levels - 1)
        view = cam.view()
        proj = cam.projection(w / h)
        near, _ = cam.clip_planes()
        s = self.settings
        use_hiz = bool(s["hiz"])
        if use_hiz:
            self.build_hiz()
        prog = self.programs["trace"]
        t.hiz.use(location=texture_units.SSR_HIZ)
        _set(prog, "u_hiz_tex", texture_units.SSR_HIZ)
        _set(prog, "u_hiz", int(s["hiz"]))
        _set(prog, "u_hiz_max_level", len(t.hiz_sizes) - 1)
        _set(prog, "u_hiz_max_iter", int(s["hiz_max_iter"]))
        _set(prog, "u_back_on", int(back is not None))
        if back is not None:
            back.use(location=texture_units.SSR_BACK)
            _set(prog, "u_back", texture_units.SSR_BACK)
        for i, name in enumerate(("u_color", "u_spec", "u_geom")):
            tex = t.mip if i == 0 else t.resolved[i]
            tex.use(location=texture_units.SSR_INPUTS + i)
            _set(prog, name, texture_units.SSR_INPUTS + i)
        ty = math.tan(math.radians(cam.fov_y) / 2.0)
        _set(prog, "u_view", gl_bytes(view))
        _set(prog, "u_proj", gl_bytes(proj))
        _set(prog, "u_size", (float(w), float(h)))
        _set(prog, "u_tan_half", (ty * w / h, ty))
        _set(prog, "u_near", float(near))
        _set(prog, "u_max_distance", s["max_distance"])
        _set(prog, "u_thickness", s["thickness"])
        _set(prog, "u_bias", s["bias"])
        _set(prog, "u_stride", s["stride"])
        _set(prog, "u_max_steps", int(s["max_steps"]))
        _set(prog, "u_refine_steps", int(s["refine_steps"]))
        _set(prog, "u_max_roughness", s["max_roughness"])
        _set(prog, "u_edge_fade", s["edge_fade"])
        _set(prog, "u_max_lod", float(t.levels - 1))
        _set(prog, "u_env_on", int(env_on))
        _set(prog, "u_debug", int(debug))
        _set(prog, "u_min_coverage", float(s["min_coverage"]))
        _set(prog, "u_max_slope", float(s["max_slope"]))
        _set(prog, "u_jitter", int(bool(s["jitter"])))
        _set(prog, "u_frame_index", int(frame_index))
        ibl.bind(prog, rotation_deg)
        fbo = t.out_fbo
        fbo.use()
        fbo.viewport = (0, 0, w, h)
        ctx.disable(ctx.DEPTH_TEST)
        self.vaos["trace"].render(vertices=3)
        self.last_pass_s = time.perf_counter() - t0  # CPU side; call ctx.finish() to time the GPU
        return t.out

    def release(self):
        self._release_targets()
        for v in self.vaos.values():
            v.release()
        for p in self.programs.values():
            p.release()


def depth_from_geom(g):
    """Linear view depth from the resolved normal/depth target (h, w, 4): w / coverage where the
    coverage (the normal's length) is over 0.5, else EMPTY_DEPTH (float32, as the shader)."""
    g = np.asarray(g, np.float32)
    cov = np.sqrt(np.sum(g[..., :3] * g[..., :3], axis=-1, dtype=np.float32)).astype(np.float32)
    with np.errstate(divide="ignore", invalid="ignore"):
        z = np.where(cov > 0.5, g[..., 3] / np.where(cov > 0.5, cov, 1.0), EMPTY_DEPTH)
    return z.astype(np.float32)


def hiz_pyramid_numpy(depth, levels=None):
    """Min-pooling pyramid of ``depth`` (h, w): level k has max(1, n >> k) texels per axis, each
    the minimum over 2x2 texels of level k - 1; the last column / row also takes an odd level's
    extra one (``np.minimum.reduceat`` over segments starting at the even indices)."""
    z = np.asarray(depth, np.float32)
    if levels is None:
        levels = 1 + int(math.floor(math.log2(max(z.shape))))
    out = [z]
    for _ in range(1, levels):
        h, w = z.shape
        iy = 2 * np.arange(max(1, h // 2))
        ix = 2 * np.arange(max(1, w // 2))
        z = np.minimum.reduceat(np.minimum.reduceat(z, iy, axis=0), ix, axis=1)
        out.append(z)
    return out
