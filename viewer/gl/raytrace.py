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

from viewer.gl.brdf_glsl import MAT_VEC4, choice_constants, models_used, pack_material
from viewer.gl.constants import ALBEDO_TABLE, CHAIN_KINDS, CHAIN_ROW_TEXELS, CHAIN_TEXELS

ROW_TEXELS = CHAIN_ROW_TEXELS  # texels per material row (see shaders/common/specular_chain.glsl)
T_ALBEDO, T_SPEC, T_TRANS, T_INFO, T_SIGMA, T_ETA, T_K = (CHAIN_TEXELS[k] for k in ("albedo", "spec", "trans", "info",
                                                                                    "sigma", "eta", "k"))
KIND_SHADED, KIND_MIRROR, KIND_GLASS = CHAIN_KINDS["shaded"], CHAIN_KINDS["mirror"], CHAIN_KINDS["glass"]
MAX_SEGMENTS = 32  # rays traced per pixel at most (a glass ball at depth 8 needs about 12)


def chain_kind(params) -> int:
    """How a traced chain treats a material: a mirror, smooth glass, or a surface it shades."""
    if params.model == "mirror":
        return KIND_MIRROR
    if params.model == "dielectric" and float(params.get("alpha", 0.0)) == 0.0:
        return KIND_GLASS
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
