"""What comes out of a frame: the linear HDR colour targets (viewer/gl/targets.py), the MSAA
resolve, the tone-mapping pass (exposure, tone map and sRGB encoding, to the screen or an 8-bit
target) and the read-back of float and sRGB arrays (row 0 = top, docs/conventions.md)."""

from __future__ import annotations

import numpy as np

from viewer.gl import texture_units
from viewer.gl.constants import TONEMAPS
from viewer.gl.context import release_gl
from viewer.gl.shaders import set_uniform as _set
from viewer.gl.targets import FrameTargets, HdrTarget


class FrameOutput:
    """The frame's targets and what is read from them; ``program_set`` (a ``ProgramSet``)
    holds the tone-mapping program."""

    def __init__(self, ctx, program_set):
        self.ctx = ctx
        self.program_set = program_set
        self._hdr = HdrTarget(ctx)
        self._ldr = None            # (texture, framebuffer) of read_srgb
        self._frame_targets = None  # the last frame's colour targets (resolved_framebuffer)

    def ensure(self, w, h, samples) -> FrameTargets:
        """The HDR targets of this size and sample count (remade when those change)."""
        return self._hdr.ensure(w, h, samples)

    def holds(self, w, h, samples) -> bool:
        """Whether the HDR targets are of this size and sample count (``ensure`` makes none)."""
        return self._hdr.holds(w, h, samples)

    def begin(self, targets: FrameTargets):
        """``targets`` are the frame's (the HDR targets, or the SSR pass's)."""
        self._frame_targets = targets

    def resolved_framebuffer(self, hdr):
        """The framebuffer of ``hdr``, a texture ``render`` returned (to read or copy from)."""
        t = self._frame_targets
        if t is None or t.resolved is not hdr:
            raise ValueError("not the resolved target of this renderer's last frame (an SSR frame has its own)")
        return t.resolved_fbo

    def resolve(self, t: FrameTargets, region=None):
        """The MSAA resolve of ``t`` (within ``region`` = (x, y, w, h) if given); its linear HDR
        texture."""
        if t.draw_fbo is not t.resolved_fbo:
            if region is not None:  # a blit honours the scissor: resolve the region alone
                t.resolved_fbo.scissor = region
                t.resolved_fbo.use()
            try:
                self.ctx.copy_framebuffer(t.resolved_fbo, t.draw_fbo)
            finally:
                if region is not None:
                    t.resolved_fbo.scissor = None
                    t.resolved_fbo.use()
        return t.resolved

    def tonemap_to(self, fbo, hdr, exposure: float = 0.0, tonemap: str = "none", viewport=None):
        """Exposure, tone mapping and sRGB encoding of ``hdr`` into ``fbo`` (e.g. ctx.screen)."""
        ctx = self.ctx
        fbo.use()
        if viewport is not None:
            fbo.viewport = viewport
        ctx.disable(ctx.DEPTH_TEST)
        prog = self.program_set.programs["tonemap"]
        # linear filtering when a preview resolution is stretched over the viewport
        hdr.filter = (ctx.LINEAR, ctx.LINEAR)
        hdr.use(location=texture_units.SOURCE)
        _set(prog, "u_hdr", texture_units.SOURCE)
        _set(prog, "u_exposure", float(exposure))
        _set(prog, "u_tonemap", TONEMAPS.get(tonemap, 0))
        self.program_set.fullscreen_vao(prog).render(vertices=3)

    def read_linear(self, hdr) -> np.ndarray:
        """(H, W, 3) float32 radiance, row 0 = top (docs/conventions.md)."""
        w, h = hdr.size
        a = np.frombuffer(hdr.read(), dtype="f4").reshape(h, w, 4)  # exact texels, no filtering
        return np.ascontiguousarray(a[::-1, :, :3])

    def read_srgb(self, hdr, exposure=0.0, tonemap="none") -> np.ndarray:
        """(H, W, 3) uint8 sRGB after exposure and tone mapping, row 0 = top."""
        w, h = hdr.size
        if self._ldr is None or self._ldr[0].size != (w, h):
            if self._ldr is not None:
                release_gl(self._ldr[1], self._ldr[0])
            tex = self.ctx.texture((w, h), 4, dtype="f1")
            self._ldr = (tex, self.ctx.framebuffer(color_attachments=[tex]))
        self.tonemap_to(self._ldr[1], hdr, exposure, tonemap, viewport=(0, 0, w, h))
        a = np.frombuffer(self._ldr[0].read(), dtype=np.uint8).reshape(h, w, 4)
        return np.ascontiguousarray(a[::-1, :, :3])

    def release(self):
        self._hdr.release()
        if self._ldr:
            release_gl(self._ldr[1], self._ldr[0])
            self._ldr = None
        self._frame_targets = None
