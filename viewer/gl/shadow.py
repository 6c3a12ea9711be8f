"""The shadow pass: one depth atlas for the first SHADOW_LIGHTS lights (shaders/common/shadow.glsl;
the rasterizer draws the scene's other lights, up to MAX_LIGHTS, without shadows).
Light i owns row i of the atlas: a point light six perspective tiles (one per cube face, a little
wider than 90 degrees, each cropped to the part of its face the casters cover), a directional
light one orthographic tile over the scene's bounds. The
atlas is rendered again only when a light or an object moves (or a glass caster's material
changes).

Glass (``glass_casters``: the objects of a transmissive material) is left out of the depth
atlas and casts a translucent shadow instead: a second atlas of the same tiles (RGBA16F) holds
the optical depth tau that the glass in front of the nearest opaque caster adds along each
light ray (its faces depth-tested against the opaque depth, added up; shaders/passes/
shadow_glass.frag says what each face adds), and the forward pass multiplies the light by
exp(-tau). A scene without glass renders exactly as before: no second atlas, no shader variant
(``glass_shadows``)."""

from __future__ import annotations

import math

import numpy as np

from viewer import brdf
from viewer.brdf import thin_film
from viewer.scene.camera import gl_bytes, look_at, orthographic, perspective
from viewer.gl import texture_units
from viewer.gl.constants import SHADOW_LIGHTS
from viewer.gl.context import release_gl
from viewer.gl.shaders import set_uniform as _set

SHADOW_TILE = 1024

# (forward, up) of the six cube faces, in the order cube_face() in shadow.glsl returns them
_FACES = [((1, 0, 0), (0, 1, 0)), ((-1, 0, 0), (0, 1, 0)), ((0, 1, 0), (0, 0, 1)),
          ((0, -1, 0), (0, 0, 1)), ((0, 0, 1), (0, 1, 0)), ((0, 0, -1), (0, 1, 0))]


def shadow_lights(scene):
    """The lights the rasterizer casts shadows of: the first SHADOW_LIGHTS (it draws them all)."""
    return scene.lights[:SHADOW_LIGHTS]


def transmissive(params) -> bool:
    """A material that lets light through (glass, rough glass, a thin shell)."""
    return bool(brdf.get(params.model).spec.transmissive)


def glass_casters(scene) -> list:
    """The objects that cast a translucent shadow: those of a transmissive material."""
    return [o for o in scene.objects if transmissive(scene.materials[o.material])]


def casts_shadows(scene) -> bool:
    """Whether a frame of ``scene`` draws the shadow pass: shadows on and a shadowed light."""
    return bool(scene.render.shadows) and len(shadow_lights(scene)) > 0


def glass_shadows(scene) -> bool:
    """Whether a frame of ``scene`` draws translucent shadows (the GLASS_SHADOW variant of the
    forward program and the glass atlas): it casts shadows, and has a glass caster."""
    return casts_shadows(scene) and bool(glass_casters(scene))


# how the glass pass finds a caster's path length (shaders/passes/shadow_glass.frag SHAPE_*)
SHAPE_CLOSED, SHAPE_SPHERE, SHAPE_BOX, SHAPE_OPEN = 0, 1, 2, 3


def glass_shape(obj) -> int:
    """The built-in sphere with one scale is a sphere and the built-in cube a box (their exact
    refracted path lengths), the plane is open (no inside), any other mesh a closed one (the
    straight chord along the light's ray)."""
    scale = np.broadcast_to(np.asarray(obj.scale, float), (3,))
    if obj.mesh == "sphere" and np.ptp(scale) == 0.0:
        return SHAPE_SPHERE
    if obj.mesh == "cube":
        return SHAPE_BOX
    if obj.mesh == "plane":
        return SHAPE_OPEN
    return SHAPE_CLOSED


def _glass_uniforms(scene, obj) -> dict:
    """The glass pass's uniforms of one caster (its material and shape)."""
    params = scene.materials[obj.material]
    sigma = np.asarray(params.get("sigma_a", [0.0, 0.0, 0.0]), float) * np.ones(3)
    ior = float(params.get("ior", 1.5))
    name = params.get("spectral", "none")
    if brdf.is_dispersive(params) and name not in (None, "none"):
        from viewer import spectral

        ior = float(np.mean(spectral.channel_ior(name)))  # one index: the caustic is left out anyway
    film = thin_film.film_of(params) if brdf.has_film(params) else None
    film_v = (0.0, 0.0, -1.0, 0.0) if film is None else (
        float(film.ior), float(film.thickness_nm), float(film.get("thickness_top_nm", -1.0)), 1.0)
    y0, y1 = obj.y_range()
    scale = np.broadcast_to(np.asarray(obj.scale, float), (3,))
    return {"u_ior": ior, "u_sigma_a": tuple(float(x) for x in sigma), "u_shape": glass_shape(obj),
            "u_center": tuple(float(x) for x in obj.translate), "u_radius": float(scale[0]),
            "u_world_to_local": gl_bytes(np.linalg.inv(obj.model_matrix())),
            "u_film": film_v, "u_film_y": (float(y0), float(y1))}


def unshadowed_note(scene) -> str | None:
    """One line for a scene with more lights than the shadow atlas holds ("lights 5-9 are drawn
    without shadows (the raster shadow-maps 4)"), else None. The CLI prints it on stderr, the
    window in its status line."""
    n = len(scene.lights)
    if n <= SHADOW_LIGHTS:
        return None
    which = f"light {n}" if n == SHADOW_LIGHTS + 1 else f"lights {SHADOW_LIGHTS + 1}-{n}"
    verb = "is" if n == SHADOW_LIGHTS + 1 else "are"
    return f"{which} {verb} drawn without shadows (the raster shadow-maps {SHADOW_LIGHTS})"


def _caster_corners(scene) -> np.ndarray:
    """(8 k, 3) corners of the world boxes of the objects that can shadow anything: every object
    but a plane with nothing below it (a floor: it shadows no object, and its box would cover a
    point light's whole view)."""
    boxes = []
    for o in scene.objects:
        if o.mesh_data is None:
            continue
        pts = o.world_positions()
        if len(pts):
            boxes.append((o, pts.min(axis=0), pts.max(axis=0)))
    out = []
    for o, lo, hi in boxes:
        flat = hi[1] - lo[1] <= 1e-9 * max(1.0, float(np.max(hi - lo)))
        if flat and not any(b[1][1] < lo[1] - 1e-9 for b in boxes if b[0] is not o):
            continue
        out.extend([lo[0] if i & 1 else hi[0], lo[1] if i & 2 else hi[1], lo[2] if i & 4 else hi[2]]
                   for i in range(8))
    return np.asarray(out, float).reshape(-1, 3)


def _crop(view_proj, corners, S) -> tuple[np.ndarray, float]:
    """The crop matrix that fits a cube face's tile to the part of the face the casters cover
    (their boxes' projected corners, with a margin of 6 texels for the PCF kernel), and the
    cropped width in the face's NDC (2: the whole face; 0: no caster in the face, nothing to
    draw or look up). A corner behind the light's plane of the face: the whole face."""
    if not len(corners):
        return np.eye(4), 0.0
    c = np.c_[corners, np.ones(len(corners))] @ view_proj.T
    if np.any(c[:, 3] <= 1e-9):
        return np.eye(4), 2.0
    ndc = c[:, :2] / c[:, 3:4]
    lo = np.maximum(ndc.min(axis=0), -1.0)
    hi = np.minimum(ndc.max(axis=0), 1.0)
    if np.any(hi <= lo):
        return np.eye(4), 0.0
    size = float(np.max(hi - lo))  # square texels: one scale for both axes
    size = min(2.0, size * (1.0 + 12.0 / S) + 1e-6)
    mid = 0.5 * (lo + hi)
    scale = 2.0 / size
    crop = np.eye(4)
    crop[0, 0] = crop[1, 1] = scale
    crop[0, 3], crop[1, 3] = -mid * scale
    return crop, size


class ShadowMaps:
    def __init__(self, ctx):
        self.ctx = ctx
        self._atlas = None  # {"tex", "fbo", "rows"}
        self._glass = None  # the glass atlas: {"tex", "fbo", "rows"}, while the scene has glass
        self._key = None
        self._mats = np.zeros((SHADOW_LIGHTS * 6, 4, 4))
        self._texel = np.zeros(SHADOW_LIGHTS)
        self._face_tan = np.zeros(SHADOW_LIGHTS * 6)

    @staticmethod
    def _key_of(scene, lights, glass):
        """What the atlas is drawn from: the lights, what the model matrices are made of, and
        the glass casters' uniforms."""
        return (tuple((l.type, tuple(np.round(l.position, 9)), tuple(np.round(l.direction, 9))) for l in lights),
                tuple((id(o.mesh_data), np.asarray(o.translate, float).tobytes(), np.asarray(o.scale, float).tobytes(),
                       float(o.rotate_y_deg)) for o in scene.objects),
                tuple(repr(sorted(_glass_uniforms(scene, o).items())) for o in glass))

    def holds(self, scene) -> bool:
        """Whether the atlas is ``scene``'s as ``update`` would draw it (nothing to draw)."""
        glass = glass_casters(scene) if glass_shadows(scene) else []
        return self._atlas is not None and self._key == self._key_of(scene, shadow_lights(scene), glass)

    def update(self, scene, prog, draw, glass_prog=None):
        """Render the atlas with the shadow program ``prog`` unless the lights and objects are
        where they were; ``draw(objects, prog)`` draws the objects (instanced by mesh).
        ``glass_prog``: the glass pass's program (``shadow_glass``), needed when the scene has
        glass casters (``glass_shadows``), which it draws into the glass atlas."""
        lights = shadow_lights(scene)
        glass = glass_casters(scene) if glass_prog is not None else []
        glass_ids = {id(o) for o in glass}
        key = self._key_of(scene, lights, glass)
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
        opaque = [o for o in scene.objects if id(o) not in glass_ids] if glass else scene.objects
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
                draw(opaque, prog)
        ctx.polygon_offset = (0.0, 0.0)
        if glass:
            self._draw_glass(scene, lights, mats, glass, glass_prog, draw)
        elif self._glass is not None:
            self._release_glass()
        self._mats = mats
        self._key = key

    def _draw_glass(self, scene, lights, mats, glass, prog, draw):
        """The glass atlas: every glass caster's faces in front of the opaque depth add their
        optical depth (additive blending, no depth writes)."""
        S = SHADOW_TILE
        ctx = self.ctx
        rows = self._atlas["rows"]
        if self._glass is None or self._glass["rows"] != rows:
            self._release_glass()
            tex = ctx.texture((6 * S, rows * S), 4, dtype="f2")
            tex.filter = (ctx.LINEAR, ctx.LINEAR)
            tex.repeat_x = False
            tex.repeat_y = False
            fbo = ctx.framebuffer(color_attachments=[tex], depth_attachment=self._atlas["tex"])
            self._glass = {"tex": tex, "fbo": fbo, "rows": rows}
        fbo = self._glass["fbo"]
        fbo.use()
        fbo.depth_mask = False   # before the clear too: the depth is the opaque casters', kept
        fbo.clear(0.0, 0.0, 0.0, 0.0)
        ctx.enable(ctx.DEPTH_TEST | ctx.BLEND)
        ctx.disable(ctx.CULL_FACE)   # both faces: where the light enters and where it leaves
        ctx.blend_func = (ctx.ONE, ctx.ONE)
        per_object = [_glass_uniforms(scene, o) for o in glass]
        try:
            for i, light in enumerate(lights):
                point = light.type == "point"
                _set(prog, "u_point", int(point))
                _set(prog, "u_light", tuple(float(x) for x in (light.position if point else light.direction)))
                for f in (range(6) if point else range(1)):
                    fbo.viewport = (f * S, i * S, S, S)
                    _set(prog, "u_mvp", gl_bytes(mats[i * 6 + f]))
                    for obj, uniforms in zip(glass, per_object):
                        for k, v in uniforms.items():
                            _set(prog, k, v)
                        draw([obj], prog)
        finally:
            fbo.depth_mask = True
            ctx.disable(ctx.BLEND)
            ctx.blend_func = ctx.DEFAULT_BLENDING

    def _matrices(self, scene, lights) -> np.ndarray:
        """The light-space view-projection of every tile (and the world size of a directional
        light's texel, into ``_texel``)."""
        S = SHADOW_TILE
        lo, hi = scene.bounds()
        corners = _caster_corners(scene)
        self._face_tan[:] = 0.0
        center = 0.5 * (lo + hi)
        radius = max(0.5 * float(np.linalg.norm(hi - lo)), 1e-3)
        mats = np.zeros((SHADOW_LIGHTS * 6, 4, 4))
        for i, light in enumerate(lights):
            if light.type == "point":
                p = np.asarray(light.position, float)
                far = float(np.linalg.norm(p - center)) + radius * 1.1
                near = max(far * 1e-3, 1e-3)
                # a little wider than 90 degrees: 3 texels of margin per side for the PCF kernel
                t = S / (S - 6.0)
                fov = 2.0 * math.degrees(math.atan(t))
                proj = perspective(fov, 1.0, near, far)
                for f, (fwd, up) in enumerate(_FACES):
                    view_proj = proj @ look_at(p, p + np.array(fwd, float), up)
                    crop, width = _crop(view_proj, corners, S)
                    mats[i * 6 + f] = crop @ view_proj
                    self._face_tan[i * 6 + f] = width * t  # the tile's width in tan units (0: empty)
            else:
                d = np.asarray(light.direction, float)
                d = d / np.linalg.norm(d)
                up = (0, 1, 0) if abs(d[1]) < 0.99 else (0, 0, 1)
                eye = center - d * 2.0 * radius
                mats[i * 6] = orthographic(radius, radius, radius * 0.9, radius * 3.1) @ look_at(eye, center, up)
                self._texel[i] = 2.0 * radius / S
        return mats

    @property
    def glass_atlas(self):
        """The glass casters' atlas (a texture), or None while the scene has no glass caster."""
        return None if self._glass is None else self._glass["tex"]

    def bind(self, unit: int = texture_units.SHADOW_ATLAS) -> dict:
        """Bind the atlas to texture ``unit``; the uniforms the forward pass reads it with."""
        self._atlas["tex"].use(location=unit)
        out = {}
        if self._glass is not None:
            self._glass["tex"].use(location=texture_units.GLASS_SHADOW)
            out["u_shadow_glass"] = texture_units.GLASS_SHADOW
        return out | {
            "u_shadow_atlas": unit,
            "u_shadow_mat": b"".join(gl_bytes(m) for m in self._mats),
            "u_shadow_atlas_tiles": (6.0, float(self._atlas["rows"])),
            "u_shadow_tile_size": float(SHADOW_TILE),
            "u_shadow_texel_world": self._texel.astype("f4").tobytes(),
            "u_shadow_face_tan": self._face_tan.astype("f4").tobytes(),
        }

    def _release_glass(self):
        if self._glass is not None:
            release_gl(self._glass["fbo"], self._glass["tex"])
            self._glass = None

    def release(self):
        self._release_glass()
        if self._atlas is not None:
            release_gl(self._atlas["fbo"], self._atlas["tex"])
            self._atlas = None
