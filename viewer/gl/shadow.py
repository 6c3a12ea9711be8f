"""The shadow pass: one depth atlas for the first MAX_LIGHTS lights (shaders/common/shadow.glsl).
Light i owns row i of the atlas: a point light six perspective tiles (one per cube face, a little
wider than 90 degrees), a directional light one orthographic tile over the scene's bounds. The
atlas is rendered again only when a light or an object moves."""

from __future__ import annotations

import math

import numpy as np

from viewer.camera import gl_bytes, look_at, orthographic, perspective
from viewer.gl import texture_units
from viewer.gl.constants import MAX_LIGHTS
from viewer.gl.shaders import set_uniform as _set

SHADOW_TILE = 1024

# (forward, up) of the six cube faces, in the order cube_face() in shadow.glsl returns them
_FACES = [((1, 0, 0), (0, 1, 0)), ((-1, 0, 0), (0, 1, 0)), ((0, 1, 0), (0, 0, 1)),
          ((0, -1, 0), (0, 0, 1)), ((0, 0, 1), (0, 1, 0)), ((0, 0, -1), (0, 1, 0))]


def shadow_lights(scene):
    """The lights the rasterizer draws (and casts shadows of): the first MAX_LIGHTS."""
    return scene.lights[:MAX_LIGHTS]


class ShadowMaps:
    def __init__(self, ctx):
        self.ctx = ctx
        self._atlas = None  # {"tex", "fbo", "rows"}
        self._key = None
        self._mats = np.zeros((MAX_LIGHTS * 6, 4, 4))
        self._texel = np.zeros(MAX_LIGHTS)

    def update(self, scene, prog, draw):
        """Render the atlas with the shadow program ``prog`` unless the lights and objects are
        where they were; ``draw(objects, prog)`` draws the objects (instanced by mesh)."""
        lights = shadow_lights(scene)
        key = (tuple((l.type, tuple(np.round(l.position, 9)), tuple(np.round(l.direction, 9))) for l in lights),
               tuple((id(o.mesh_data), np.asarray(o.translate, float).tobytes(), np.asarray(o.scale, float).tobytes(),
                      float(o.rotate_y_deg)) for o in scene.objects))   # what the model matrices are made of
        if key == self._key and self._atlas is not None:
            return
        rows = max(1, len(lights))
        S = SHADOW_TILE
        ctx = self.ctx
        if self._atlas is None or self._atlas["rows"] != rows:
            self.release()
            tex = ctx.depth_texture((6 * S, rows * S))
            tex.compare_func = "<="
            tex.filter = (ctx.LINEAR, ctx.LINEAR)
            tex.repeat_x = False
            tex.repeat_y = False
            self._atlas = {"tex": tex, "fbo": ctx.framebuffer(depth_attachment=tex), "rows": rows}
        mats = self._matrices(scene, lights)
        fbo = self._atlas["fbo"]
        fbo.use()
        fbo.clear(depth=1.0)
        ctx.enable(ctx.DEPTH_TEST)
        ctx.disable(ctx.CULL_FACE)
        ctx.polygon_offset = (1.5, 2.0)  # slope-scaled depth bias in the shadow pass
        for i, light in enumerate(lights):
            faces = range(6) if light.type == "point" else range(1)
            for f in faces:
                fbo.viewport = (f * S, i * S, S, S)
                _set(prog, "u_mvp", gl_bytes(mats[i * 6 + f]))
                draw(scene.objects, prog)
        ctx.polygon_offset = (0.0, 0.0)
        self._mats = mats
        self._key = key

    def _matrices(self, scene, lights) -> np.ndarray:
        """The light-space view-projection of every tile (and the world size of a directional
        light's texel, into ``_texel``)."""
        S = SHADOW_TILE
        lo, hi = scene.bounds()
        center = 0.5 * (lo + hi)
        radius = max(0.5 * float(np.linalg.norm(hi - lo)), 1e-3)
        mats = np.zeros((MAX_LIGHTS * 6, 4, 4))
        for i, light in enumerate(lights):
            if light.type == "point":
                p = np.asarray(light.position, float)
                far = float(np.linalg.norm(p - center)) + radius * 1.1
                near = max(far * 1e-3, 1e-3)
                # a little wider than 90 degrees: 3 texels of margin per side for the PCF kernel
                fov = 2.0 * math.degrees(math.atan(S / (S - 6.0)))
                proj = perspective(fov, 1.0, near, far)
                for f, (fwd, up) in enumerate(_FACES):
                    mats[i * 6 + f] = proj @ look_at(p, p + np.array(fwd, float), up)
            else:
                d = np.asarray(light.direction, float)
                d = d / np.linalg.norm(d)
                up = (0, 1, 0) if abs(d[1]) < 0.99 else (0, 0, 1)
                eye = center - d * 2.0 * radius
                mats[i * 6] = orthographic(radius, radius, radius * 0.9, radius * 3.1) @ look_at(eye, center, up)
                self._texel[i] = 2.0 * radius / S
        return mats

    def bind(self, unit: int = texture_units.SHADOW_ATLAS) -> dict:
        """Bind the atlas to texture ``unit``; the uniforms the forward pass reads it with."""
        self._atlas["tex"].use(location=unit)
        return {
            "u_shadow_atlas": unit,
            "u_shadow_mat": b"".join(gl_bytes(m) for m in self._mats),
            "u_shadow_atlas_tiles": (6.0, float(self._atlas["rows"])),
            "u_shadow_tile_size": float(SHADOW_TILE),
            "u_shadow_texel_world": self._texel.astype("f4").tobytes(),
        }

    def release(self):
        if self._atlas is not None:
            self._atlas["fbo"].release()
            self._atlas["tex"].release()
            self._atlas = None
