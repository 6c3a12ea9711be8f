"""Screen-space reflections (issue 6): the forward pass's specular environment term replaced by
the scene's own radiance where the reflected ray hits something visible on screen.

When ``scene.render.ssr`` is on, the renderer draws the forward pass (compiled with ``SSR``
defined) into this class's targets: three colour attachments, MSAA like the ordinary pass:

0. the radiance without the specular environment term ``rho_s * L_env``,
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

Parameters (DESIGN.md, "SSR parameter sets"): bias 0.01 and maximum distance 3 (Filament),
thickness 0.2, maximum roughness 0.5, edge fade 0.075 (EEVEE); a stride of 2 pixels stands for
EEVEE's trace precision, with 6 bisection steps after the stride."""

from __future__ import annotations

import math

import numpy as np

from viewer.camera import gl_bytes
from viewer.gl.shaders import build_program, default_virtual
from viewer.gl.shaders import set_uniform as _set

SSR_DEBUG = {"ssr hit": 1, "ssr steps": 2, "ssr uv": 3, "ssr only": 4}


class SSR:
    settings = {"max_distance": 3.0, "thickness": 0.2, "bias": 0.01, "stride": 2.0, "max_steps": 320,
                "refine_steps": 6, "max_roughness": 0.5, "edge_fade": 0.075}

    def __init__(self, ctx):
        self.ctx = ctx
        virtual = default_virtual(("lambert",))
        self.prog = build_program(ctx, "passes/fullscreen.vert", "passes/ssr.frag", virtual=virtual)
        self.bg_prog = build_program(ctx, "passes/fullscreen.vert", "passes/ssr_background.frag", virtual=virtual)
        self.vao = ctx.vertex_array(self.prog, [])
        self.bg_vao = ctx.vertex_array(self.bg_prog, [])
        self._t = None
        self._key = None
        self.last_pass_s = None

    # ------------------------------------------------------------------ targets
    def targets(self, w, h, samples):
        key = (w, h, samples)
        if self._key == key:
            return self._t
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
        self._t = {"draw_fbo": draw_fbo, "resolved_fbo": resolved_fbo, "resolved": res, "extra": extra,
                   "samples": samples, "mip": mip, "mip_fbo": mip_fbo, "levels": levels, "out": out,
                   "out_fbo": out_fbo, "color_fbo": color_fbo}
        self._key = key
        return self._t

    def _release_targets(self):
        t = self._t
        if not t:
            return
        if t["draw_fbo"] is not t["resolved_fbo"]:
            t["draw_fbo"].release()
        for k in ("resolved_fbo", "mip_fbo", "out_fbo", "color_fbo", "mip", "out"):
            t[k].release()
        for r in t["resolved"] + t["extra"]:
            r.release()
        self._t = None
        self._key = None

    # ------------------------------------------------------------------ passes
    def background(self, ibl, cam, w, h, env_map_on: bool, constant, rotation_deg):
        """Fill every attachment behind the scene (a clear sets all three to one colour)."""
        ctx = self.ctx
        ctx.disable(ctx.DEPTH_TEST)
        _set(self.bg_prog, "u_inv_view_proj", gl_bytes(np.linalg.inv(cam.projection(w / h) @ cam.view())))
        _set(self.bg_prog, "u_camera_pos", tuple(float(x) for x in cam.position))
        _set(self.bg_prog, "u_use_map", int(env_map_on))
        _set(self.bg_prog, "u_constant", tuple(float(x) for x in constant))
        ibl.bind(self.bg_prog, rotation_deg)
        self.bg_vao.render(vertices=3)

    def resolve_and_trace(self, ibl, cam, w, h, env_on: bool, rotation_deg: float, debug: int = 0):
        """Resolve the forward targets, build the colour mip chain and run the SSR pass; returns
        the output texture (linear RGBA32F)."""
        import time

        ctx = self.ctx
        t = self._t
        if t["draw_fbo"] is not t["resolved_fbo"]:
            ctx.copy_framebuffer(t["resolved_fbo"], t["draw_fbo"])  # every attachment
        t0 = time.perf_counter()
        ctx.copy_framebuffer(t["mip"], t["color_fbo"])
        t["mip"].build_mipmaps(0, t["levels"] - 1)
        view = cam.view()
        proj = cam.projection(w / h)
        near, _ = cam.clip_planes()
        prog = self.prog
        for i, name in enumerate(("u_color", "u_spec", "u_geom")):
            tex = t["mip"] if i == 0 else t["resolved"][i]
            tex.use(location=i)
            _set(prog, name, i)
        s = self.settings
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
        _set(prog, "u_max_lod", float(t["levels"] - 1))
        _set(prog, "u_env_on", int(env_on))
        _set(prog, "u_debug", int(debug))
        ibl.bind(prog, rotation_deg)
        fbo = t["out_fbo"]
        fbo.use()
        fbo.viewport = (0, 0, w, h)
        ctx.disable(ctx.DEPTH_TEST)
        self.vao.render(vertices=3)
        self.last_pass_s = time.perf_counter() - t0  # CPU side; call ctx.finish() to time the GPU
        return t["out"]

    def release(self):
        self._release_targets()
        self.vao.release()
        self.bg_vao.release()
        self.prog.release()
        self.bg_prog.release()
