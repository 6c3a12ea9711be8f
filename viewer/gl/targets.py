"""Render targets of the rasterizer: the linear HDR colour target (RGBA32F, with an MSAA draw
target resolved into it), and the thickness pass, the distance to the nearest back face of
absorbing objects that the forward pass turns into a path length inside them."""

from __future__ import annotations

from dataclasses import dataclass

from viewer.scene.camera import gl_bytes
from viewer.gl.context import release_gl
from viewer.gl.shaders import set_uniform as _set


@dataclass
class FrameTargets:
    """A frame's colour targets: ``draw_fbo`` (multisampled when ``samples`` > 1, with depth) is
    resolved into ``resolved_fbo``, whose colour is ``resolved`` (one RGBA32F texture, or the
    SSR pass's three); ``extra``: the renderbuffers behind ``draw_fbo``; ``shell_fbo``: the
    first colour attachment of ``draw_fbo`` and its depth alone, for the thin shells' pass
    (dual-source blending writes one draw buffer; ``draw_fbo`` itself when it has one)."""

    draw_fbo: object
    resolved_fbo: object
    resolved: object
    extra: list
    samples: int
    shell_fbo: object = None


class HdrTarget:
    """The colour and depth targets of one (width, height, samples), remade when those change:
    ``draw_fbo`` (multisampled when samples > 1) is resolved into ``resolved`` (RGBA32F)."""

    def __init__(self, ctx):
        self.ctx = ctx
        self._targets = None
        self._key = None

    def holds(self, w, h, samples) -> bool:
        """Whether the targets are of this size and sample count."""
        return self._key == self._key_of(w, h, samples)

    def _key_of(self, w, h, samples):
        samples = samples if samples > 1 else 0
        return (w, h, min(samples, self.ctx.max_samples))

    def ensure(self, w, h, samples) -> FrameTargets:
        """The targets of this size and sample count."""
        key = self._key_of(w, h, samples)
        samples = key[2]
        if self._key == key:
            return self._targets
        self.release()
        ctx = self.ctx
        resolved = ctx.texture((w, h), 4, dtype="f4")
        resolved.filter = (ctx.NEAREST, ctx.NEAREST)
        resolved_fbo = ctx.framebuffer(color_attachments=[resolved])
        if samples:
            ms_color = ctx.renderbuffer((w, h), 4, samples=samples, dtype="f4")
            ms_depth = ctx.depth_renderbuffer((w, h), samples=samples)
            ms_fbo = ctx.framebuffer(color_attachments=[ms_color], depth_attachment=ms_depth)
            extra = [ms_color, ms_depth]
        else:
            depth = ctx.depth_renderbuffer((w, h))
            ms_fbo = ctx.framebuffer(color_attachments=[resolved], depth_attachment=depth)
            extra = [depth]
        self._targets = FrameTargets(draw_fbo=ms_fbo, resolved_fbo=resolved_fbo, resolved=resolved, extra=extra,
                                     samples=samples, shell_fbo=ms_fbo)
        self._key = key
        return self._targets

    def release(self):
        if self._targets:
            t = self._targets
            release_gl(t.draw_fbo if t.draw_fbo is not t.resolved_fbo else None, t.resolved_fbo, t.resolved, *t.extra)
        self._targets = None
        self._key = None


class ThicknessPass:
    """Distance from the camera to the nearest back face of absorbing transmissive objects, per
    pixel (R32F). The forward pass takes back - front as the path length inside, the
    rasterizer's approximation of Bouguer absorption (the reference path tracer follows the
    refracted path exactly)."""

    def __init__(self, ctx):
        self.ctx = ctx
        self._thick = None  # (size, texture, depth, framebuffer)

    def render(self, objects, cam, w, h, prog, draw):
        """The thickness texture of ``objects`` drawn with ``prog``; ``draw(objects, prog)``
        draws them (instanced by mesh)."""
        ctx = self.ctx
        key = (w, h)
        if self._thick is None or self._thick[0] != key:
            self.release()
            tex = ctx.texture((w, h), 1, dtype="f4")
            tex.filter = (ctx.NEAREST, ctx.NEAREST)
            depth = ctx.depth_renderbuffer((w, h))
            self._thick = (key, tex, depth, ctx.framebuffer(color_attachments=[tex], depth_attachment=depth))
        _, tex, _, fbo = self._thick
        fbo.use()
        fbo.viewport = (0, 0, w, h)
        fbo.clear(0.0, 0.0, 0.0, 0.0, depth=1.0)
        ctx.enable(ctx.DEPTH_TEST | ctx.CULL_FACE)
        ctx.cull_face = "front"  # keep back faces: the far side of each object
        _set(prog, "u_view_proj", gl_bytes(cam.projection(w / h) @ cam.view()))
        _set(prog, "u_camera_pos", tuple(float(x) for x in cam.position))
        draw(objects, prog)
        ctx.cull_face = "back"
        ctx.disable(ctx.CULL_FACE)
        return tex

    def release(self):
        if self._thick is not None:
            release_gl(*self._thick[1:])
            self._thick = None
