"""3D textures of measured BRDF tables for the GLSL twin ``shaders/brdf/measured.glsl``.

A program that includes the measured model with ``MEASURED_TEXTURE`` defined reads the table of
the material it draws from ``u_measured``; ``MeasuredTextures.bind`` uploads each file once and
binds the one a material names: a MERL table as float32 RGB 180 x 90 x 91 with the sampler's CDF
(about 17 MiB), an MIT anisotropic table (``MEASURED_ANISO``) as max(n_pi, 96) x n_pd x
(n_ti n_to + 1) (``viewer.brdf.mit_aniso.AnisoMeasured.texture_data``)."""

from __future__ import annotations

from viewer import brdf
from viewer.brdf.spec import Params
from viewer.gl.texture_units import MEASURED as UNIT


def measured_params(params: Params) -> Params | None:
    """The measured material inside ``params`` (itself or a nested base), or None."""
    if not brdf.is_measured(params):
        return None
    for v in params.values():
        if isinstance(v, Params) and v.model:
            hit = measured_params(v)
            if hit is not None:
                return hit
    return params   # measured, and no nested material is: itself


class MeasuredTextures:
    def __init__(self, ctx):
        self.ctx = ctx
        self._tex: dict[str, object] = {}

    def texture(self, params: Params):
        from viewer.brdf import measured

        d = measured.data(params)
        key = d.path
        tex = self._tex.get(key)
        if tex is None:
            if len(self._tex) >= 4:
                self._tex.pop(next(iter(self._tex))).release()
            tex = self.ctx.texture3d(d.texture_size(), 3, d.texture_data().tobytes(), dtype="f4")
            tex.filter = (self.ctx.NEAREST, self.ctx.NEAREST)
            self._tex[key] = tex
        return tex

    def bind(self, prog, params: Params, unit: int = UNIT) -> bool:
        """Bind the table of the measured material in ``params`` (if any) for ``prog``; always
        points ``u_measured`` at ``unit`` (a sampler left at unit 0 would clash with the
        program's 2D samplers). True when a table was bound."""
        if "u_measured" not in prog:
            return False
        prog["u_measured"].value = unit
        m = measured_params(params)
        if m is None:
            return False
        self.texture(m).use(unit)
        return True

    def release(self):
        for t in self._tex.values():
            t.release()
        self._tex.clear()
