"""Traced specular chains in the rasterizer (``[render] raytrace = true``).

Mirrors and smooth glass are drawn by a variant of the forward program (``RAYTRACE`` defined;
shaders/common/specular_chain.glsl) that follows the chain of delta bounces from the camera's
hit through the scene's triangles: the BVH in float textures of ``viewer.gl.scene_textures``
(``viewer.geometry.bvh_flat``), shared with the GPU reference engine. Every other surface keeps
the ordinary program, so ``raytrace = false`` (or a scene with no mirror or smooth glass) renders
exactly as without this module.

This module keeps the scene's data on the GPU: the ``SceneTextures`` of the current geometry and
one RGBA32F texture of every material (``material_rows``), which the chain reads when it shades
the surfaces it hits and which the variant's ``brdf_eval`` reads through ``MAT_TEXTURE``.
"""

from __future__ import annotations

import json

import numpy as np

from viewer import brdf
from viewer.gl.brdf_glsl import MAT_VEC4, choice_constants, models_used, pack_material
from viewer.gl.constants import ALBEDO_TABLE, CHAIN_KINDS, CHAIN_ROW_TEXELS, CHAIN_TEXELS

ROW_TEXELS = CHAIN_ROW_TEXELS  # texels per material row (see shaders/common/specular_chain.glsl)
T_ALBEDO, T_SPEC, T_TRANS, T_INFO, T_SIGMA, T_ETA, T_K = (CHAIN_TEXELS[k] for k in ("albedo", "spec", "trans", "info",
                                                                                    "sigma", "eta", "k"))
KIND_SHADED, KIND_MIRROR, KIND_GLASS = CHAIN_KINDS["shaded"], CHAIN_KINDS["mirror"], CHAIN_KINDS["glass"]
MAX_SEGMENTS = 32  # rays traced per pixel at most (a glass ball at depth 8 needs about 12)
# most pixels in one strip of the progressive trace: on llvmpipe (2 cores) a pixel of a glass
# ball costs about 0.04 ms traced, so a strip of 4096 such pixels takes about 180 ms
STRIP_PIXELS = 4096


def chain_kind(params) -> int:
    """How a traced chain treats a material: a mirror, smooth glass, or a surface it shades."""
    model = brdf.get(params.model)
    if model.is_delta(params):
        return KIND_GLASS if model.spec.transmissive else KIND_MIRROR
    return KIND_SHADED


def chain_eta(params) -> np.ndarray:
    """The index of refraction per colour channel along a chain: a spectral dielectric
    (``spectral = "NAME"``) gives its three channel centroids (``viewer.spectral.channel_ior``)
    and the chain traces each channel apart (dispersion); any other material its one ``ior``."""
    name = params.get("spectral", "none")
    if params.model == "dielectric" and name not in (None, "none"):
        from viewer import spectral

        return spectral.channel_ior(name)
    return np.full(3, float(params.get("ior", 1.0)))


def material_rows(scene, albedo_tables) -> np.ndarray:
    """(rows, ROW_TEXELS, 4) float32: one row per material of ``scene.materials`` (the BVH's
    material index). ``albedo_tables(params)`` is the renderer's (reflected, transmitted,
    specular, alpha, ms_f0) cache."""
    names = list(scene.materials)
    out = np.zeros((max(1, len(names)), ROW_TEXELS, 4), np.float32)
    for r, name in enumerate(names):
        params = scene.materials[name]
        # nested offsets are packed from 0; the shader adds the row's start (MAT_ROW)
        idx, data = pack_material(params)
        block = np.zeros(4 * MAT_VEC4, np.float32)
        block[: data.size] = data
        out[r, :MAT_VEC4] = block.reshape(MAT_VEC4, 4)
        refl, trans, spec, alpha, _ = albedo_tables(params)
        out[r, T_ALBEDO:T_ALBEDO + ALBEDO_TABLE, :3] = refl
        out[r, T_SPEC:T_SPEC + ALBEDO_TABLE, :3] = spec
        out[r, T_TRANS:T_TRANS + ALBEDO_TABLE, :3] = trans
        kind = chain_kind(params)
        out[r, T_INFO] = (idx, alpha, kind, float(np.any(np.asarray(trans) > 0)))
        if "sigma_a" in params and kind == KIND_GLASS:
            out[r, T_SIGMA, :3] = np.asarray(params.sigma_a, np.float32)
        if params.model == "mirror":
            out[r, T_ETA] = (*np.asarray(params.eta, float), choice_constants(params)["mirror"]["fresnel"])
            out[r, T_K] = (*np.asarray(params.k, float), float(params.ior))
        else:
            out[r, T_ETA, :3] = chain_eta(params)
    return out


def scene_models(scene) -> tuple[str, ...]:
    """Every model any material of the scene needs (the chain may hit any of them)."""
    out = []
    for params in scene.materials.values():
        out.extend(models_used(params))
    return tuple(sorted(dict.fromkeys(out)))


def dispersive(scene) -> bool:
    return any(chain_kind(p) == KIND_GLASS and np.ptp(chain_eta(p)) > 0 for p in scene.materials.values())


class RayTrace:
    """The GPU data of traced chains for the current scene, rebuilt when it changes: the BVH
    textures when the geometry changes (meshes or transforms), the material texture when a
    material does."""

    def __init__(self, ctx):
        self.ctx = ctx
        self.textures = None  # SceneTextures
        self._geom_key = None
        self.mat_tex = None
        self._mat_key = None
        self.rows: dict[str, int] = {}

    def update(self, scene, albedo_tables):
        from viewer.gl.scene_textures import SceneTextures, float_texture
        from viewer.geometry.soup import build_geometry

        gkey = tuple((id(o.mesh_data), o.material, o.model_matrix().tobytes()) for o in scene.objects)
        gkey = (gkey, tuple(scene.materials))
        if gkey != self._geom_key or self.textures is None:
            if self.textures is not None:
                self.textures.release()
            self.textures = SceneTextures(self.ctx, build_geometry(scene))
            self._geom_key = gkey
        mkey = json.dumps({k: p.to_plain() for k, p in scene.materials.items()}, sort_keys=True)
        if mkey != self._mat_key or self.mat_tex is None:
            if self.mat_tex is not None:
                self.mat_tex.release()
            self.mat_tex = float_texture(self.ctx, material_rows(scene, albedo_tables))
            self._mat_key = mkey
        self.rows = {name: i for i, name in enumerate(scene.materials)}

    def bind(self, prog, first_unit: int = 8) -> int:
        from viewer.gl.shaders import set_uniform

        unit = self.textures.bind(prog, first_unit)
        self.mat_tex.use(location=unit)
        set_uniform(prog, "u_mat_tex", unit)
        return unit + 1

    def release(self):
        if self.textures is not None:
            self.textures.release()
            self.textures = None
        if self.mat_tex is not None:
            self.mat_tex.release()
            self.mat_tex = None
        self._geom_key = self._mat_key = None


class ProgressiveTrace:
    """The traced image of a still view, built over several frames (the window on software
    OpenGL, where one traced frame takes seconds): ``start`` renders the view with the untraced
    approximation into a texture of its own, each ``step`` renders the next tile with the chains
    traced (``Renderer.render(region=...)``: a scissor, every pixel inside exactly as in a whole
    frame) and copies it in: bands of rows from the top down, a band in tiles from the left when
    a whole band is over the budget. The tile's pixel count follows the time of the last one so
    that a tile takes about ``budget_s``, and a step traces tiles until that is spent. Once ``done``, the texture holds the one-shot traced
    render bit for bit (pixels are independent, and the copy is of float32 texels)."""

    def __init__(self, ctx):
        self.ctx = ctx
        self.texture = None
        self._fbo = None
        self._job = None
        self.steps = 0         # tiles traced since start
        self.rows_done = 0     # whole rows traced, from the top
        self.x = 0             # columns of the band below them traced
        self.band = 0          # that band's rows (0: none started)
        self.height = 0
        self.width = 0
        self.pixels = 0        # the next tile's pixels
        self.rows = 0          # the first strip's rows
        self.trace_s = 0.0     # time spent in steps since start

    @property
    def active(self) -> bool:
        return self._job is not None

    @property
    def done(self) -> bool:
        return self._job is not None and self.rows_done >= self.height

    @property
    def progress(self) -> float:
        n = self.width * self.height
        return (self.rows_done * self.width + self.x * self.band) / n if n else 0.0

    def _target(self, w, h):
        if self.texture is None or self.texture.size != (w, h):
            self.release()
            self.texture = self.ctx.texture((w, h), 4, dtype="f4")
            self.texture.filter = (self.ctx.NEAREST, self.ctx.NEAREST)
            self._fbo = self.ctx.framebuffer(color_attachments=[self.texture])
        return self.texture

    def start(self, renderer, scene, camera, w: int, h: int, view_mode: int = 0, msaa=None, rows: int = 0):
        """The untraced view (returned, also the texture's content), and the trace set to begin.
        ``rows``: the first strip's height (default 2: the cost per pixel is not known yet)."""
        hdr = renderer.render(scene, camera, w, h, view_mode, msaa=msaa, raytrace=False)
        tex = self._target(w, h)
        self.ctx.copy_framebuffer(self._fbo, renderer.resolved_framebuffer(hdr))
        self._job = (renderer, scene, camera, w, h, view_mode, msaa)
        self.rows_done, self.x, self.band, self.height, self.width = 0, 0, 0, h, w
        self.steps, self.trace_s = 0, 0.0
        self.rows = max(1, int(rows) if rows else 2)
        self.pixels = self.rows * w
        return tex

    def _next_tile(self):
        """(x, y, w, h) of the next tile. Bands end on rows that are multiples of 4 from the
        bottom (software rasterizers shade blocks of 4 x 4 pixels: a band of one row costs about
        what four do), tiles are whole blocks wide."""
        w, h = self.width, self.height
        top = h - self.rows_done
        if self.x == 0:
            if self.steps == 0:
                rows = self.rows
            else:
                rows = max(4, self.pixels // w // 4 * 4) + top % 4 if self.pixels >= 4 * w else (top % 4 or 4)
            self.band = min(rows, top)
        bh = self.band
        tw = w - self.x if self.x == 0 and self.pixels >= bh * w else max(16, self.pixels // bh // 4 * 4)
        tw = min(tw, w - self.x)
        return self.x, top - bh, tw, bh

    def step(self, budget_s: float = 0.15):
        """Trace tiles into the texture (returned) until about ``budget_s`` is spent (at least
        one; the next is left out when its predicted time would overrun); nothing once ``done``."""
        import time

        t0 = time.perf_counter()
        while self._job is not None and not self.done:
            dt, n = self._tile(budget_s)
            if time.perf_counter() - t0 + self.pixels * dt / n > budget_s:
                break
        return self.texture

    def _tile(self, budget_s):
        """Trace the next tile; (its time, its pixels)."""
        import time

        renderer, scene, camera, w, h, view_mode, msaa = self._job
        x, y, tw, th = self._next_tile()
        t0 = time.perf_counter()
        hdr = renderer.render(scene, camera, w, h, view_mode, msaa=msaa, region=(x, y, tw, th))
        data = renderer.resolved_framebuffer(hdr).read(viewport=(x, y, tw, th), components=4, dtype="f4")
        self.texture.write(data, viewport=(x, y, tw, th))
        self.ctx.finish()
        dt = max(time.perf_counter() - t0, 1e-6)
        self.trace_s += dt
        self.steps += 1
        self.x += tw
        if self.x >= w:
            self.rows_done += th
            self.x = self.band = 0
        # the next tile: as many pixels as the budget allows at this tile's cost per pixel, at
        # most 1.5 times as many and STRIP_PIXELS in all (the cost jumps where a glass object
        # begins: a tile must stay small where the cost is not known yet)
        n = tw * th
        self.pixels = max(16, min(int(1.5 * n) + 16, int(n * budget_s / dt), STRIP_PIXELS))
        return dt, n

    def cancel(self):
        self._job = None

    def release(self):
        self._job = None
        if self._fbo is not None:
            self._fbo.release()
            self.texture.release()
        self._fbo = self.texture = None
