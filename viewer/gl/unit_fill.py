"""Placeholder textures for the forward pass's optional texture units.

llvmpipe makes a program's machine code at its first draw for the state in use, and that state
includes the kind of texture (format, filter, wrap, comparison) at every unit the program's
samplers name, even a sampler a runtime switch leaves unread: the shadow atlas of a frame
without shadows, the thickness of a scene without absorbers, the glass shadow, the traced
chains' textures and the measured table. Left alone, such a unit holds whatever texture an
earlier pass left there (the tone map's source, the environment map being prefiltered), which
changes with the steps drawn before: the same program drawn again then gets new machine code on
the calling thread (seconds for a traced program). Each frame binds these placeholders to those
units first, so a unit the frame does not fill always holds the same kind of texture; the real
textures are bound over them after."""

from __future__ import annotations

from viewer.gl import texture_units

#: (unit, kind) of every unit a forward program may name that the frame may leave unfilled:
#: "depth" a depth texture compared (sampler2DShadow, as the shadow atlas), "2d" a float RGBA
#: texture, "3d" a float RGB volume (the measured table)
FILLS = ((texture_units.SHADOW_ATLAS, "depth"), (texture_units.THICKNESS, "2d"),
         (texture_units.GLASS_SHADOW, "2d"),
         *((u, "2d") for u in range(texture_units.TRACED, texture_units.TRACED + texture_units.TRACED_COUNT)),
         (texture_units.MEASURED, "3d"))


class UnitFill:
    """The 1x1 placeholders (made on first use) and their binding."""

    def __init__(self, ctx):
        self.ctx = ctx
        self._tex: dict[str, object] = {}

    def _make(self, kind: str):
        ctx = self.ctx
        if kind == "depth":  # as the shadow atlas (viewer/gl/shadow.py): compared, linear, clamped
            tex = ctx.depth_texture((1, 1), data=b"\x00\x00\x80\x3f")
            tex.compare_func = "<="
            tex.filter = (ctx.LINEAR, ctx.LINEAR)
        elif kind == "3d":
            tex = ctx.texture3d((1, 1, 1), 3, bytes(12), dtype="f4")
            tex.filter = (ctx.NEAREST, ctx.NEAREST)
        else:
            tex = ctx.texture((1, 1), 4, bytes(16), dtype="f4")
            tex.filter = (ctx.NEAREST, ctx.NEAREST)
        tex.repeat_x = tex.repeat_y = False
        if kind == "3d":
            tex.repeat_z = False
        return tex

    def bind(self) -> None:
        """Bind every placeholder to its unit (before the frame's real textures)."""
        for unit, kind in FILLS:
            tex = self._tex.get(kind)
            if tex is None:
                tex = self._tex[kind] = self._make(kind)
            tex.use(location=unit)

    def release(self) -> None:
        for t in self._tex.values():
            t.release()
        self._tex.clear()
