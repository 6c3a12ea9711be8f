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
from viewer.brdf import thin_film
from viewer.gl.brdf_glsl import MAT_VEC4, choice_constants, models_used, pack_material
from viewer.brdf.lobes import Lobe
from viewer.gl.constants import ALBEDO_TABLE, CHAIN_ROW_TEXELS, CHAIN_TEXELS
from viewer.gl.context import release_gl
from viewer.gl import texture_units
from viewer.scene.camera import OrbitCamera, screen_boxes

ROW_TEXELS = CHAIN_ROW_TEXELS  # texels per material row (see shaders/common/specular_chain.glsl)
T_ALBEDO, T_SPEC, T_TRANS, T_INFO, T_SIGMA, T_ETA, T_K = (CHAIN_TEXELS[k] for k in ("albedo", "spec", "trans", "info",
                                                                                    "sigma", "eta", "k"))
T_FILM, T_FILM_Y = CHAIN_TEXELS["film"], CHAIN_TEXELS["film_y"]
MAX_SEGMENTS = 32  # rays traced per pixel at most (a glass ball at depth 8 needs about 12)
# most pixels in one tile of the progressive trace: on llvmpipe (2 cores) a pixel of a glass
# ball costs about 0.04 ms traced, so a tile of 16384 such pixels takes about 0.7 s; the budget
# keeps tiles smaller unless a frame's fixed cost (every triangle through the vertex and geometry
# stages, whatever the scissor) would dominate
STRIP_PIXELS = 16384
PROBE_PIXELS = 16      # a trace's first tile: a probe of the fixed part of a tile's time
# a tile's planned time at most, however large its fixed part seems: a tile planned at three
# times that part (so that it is a third of the tile at most) took 0.34 s of the gallery's
# frames beside two busy processes, and the window's frame around it 0.1-0.25 s more. The
# least tile time taken for the fixed part is not always fixed: the gallery's first tile of 4
# rows across its balls takes 84 ms quiet, 9 ms over 4 x 4 pixels of the same objects (its
# pixels are dear: llvmpipe shades each of the 4 MSAA samples). Tiles then do less each, and
# the frames stay short
TILE_MOST_S = 0.15


def chain_lobes(params) -> Lobe:
    """A material's lobes (``Model.lobes``), which say how a traced chain treats it: one whose
    lobes are all delta it traces through (reflecting off a mirror; reflecting and refracting
    at smooth glass, the lobes with TRANSMISSION), any other it shades."""
    return brdf.get(params.model).lobes(params)


def chain_traces(params) -> bool:
    """A traced chain goes on through the material (a mirror, smooth glass): all its lobes are
    delta lobes."""
    return chain_lobes(params).is_delta


def chain_glass(params) -> bool:
    """A material the chain refracts through (smooth glass): delta lobes that transmit."""
    lobes = chain_lobes(params)
    return lobes.is_delta and lobes.transmits


def chain_eta(params) -> np.ndarray:
    """The index of refraction per colour channel along a chain: a spectral dielectric
    (``spectral = "NAME"``) gives its three channel centroids (``viewer.spectral.channel_ior``)
    and the chain traces each channel apart (dispersion); any other material its one ``ior``."""
    name = params.get("spectral", "none")
    if brdf.is_dispersive(params) and name not in (None, "none"):   # a spectral dielectric
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
        lobes = chain_lobes(params)
        glass = lobes.is_delta and lobes.transmits
        out[r, T_INFO] = (idx, alpha, int(lobes), float(np.any(np.asarray(trans) > 0)))
        if "sigma_a" in params and glass:
            out[r, T_SIGMA, :3] = np.asarray(params.sigma_a, np.float32)
        if lobes.is_delta and not lobes.transmits:   # a mirror's Fresnel: eta, k, its choice, its dielectric ior
            out[r, T_ETA] = (*np.asarray(params.eta, float), choice_constants(params)[params.model]["fresnel"])
            out[r, T_K] = (*np.asarray(params.k, float), float(params.ior))
        else:
            out[r, T_ETA, :3] = chain_eta(params)
        film = thin_film.film_of(params) if glass and brdf.has_film(params) else None
        if film is not None:
            # a film on smooth glass (a soap bubble's shell): (film ior, thickness at the bottom, at
            # the top or -1 for a uniform film, 1); its height range: the objects' of this material
            # (exact when one object has it, as the built-in scenes' bubbles; the union otherwise)
            out[r, T_FILM] = (float(film.ior), float(film.thickness_nm), float(film.get("thickness_top_nm", -1.0)), 1.0)
            ys = [o.y_range() for o in scene.objects if o.material == name]
            if thin_film.varies(params) and ys:
                out[r, T_FILM_Y, :2] = (min(y[0] for y in ys), max(y[1] for y in ys))
    return out


def scene_models(scene) -> tuple[str, ...]:
    """Every model any material of the scene needs (the chain may hit any of them)."""
    out = []
    for params in scene.materials.values():
        out.extend(models_used(params))
    return tuple(sorted(dict.fromkeys(out)))


def dispersive(scene) -> bool:
    return any(chain_glass(p) and np.ptp(chain_eta(p)) > 0 for p in scene.materials.values())


def upscale(img: np.ndarray, s: int, h: int, w: int) -> np.ndarray:
    """(h, w, C) float32: ``img`` (about (h / s, w / s, C)) enlarged ``s`` times with bilinear
    interpolation between its pixel centres (clamped at the borders), so that a preview's
    antialiased silhouettes stay smooth instead of turning into steps ``s`` pixels tall, as
    repeating each pixel would. Output pixel s i + k of an axis lies at i + (k + 1/2) / s - 1/2
    in the input's pixel centres: the same two neighbours and weight for every i, so each of the
    ``s`` phases is one shifted slice (a third of the time gathers by index take at 1344x1080)."""
    def along(a, n_out, ax):
        n = a.shape[ax]
        pad = [(0, 0)] * a.ndim
        pad[ax] = (1, 1)
        edge = np.pad(a, pad, mode="edge")  # the borders clamp

        def shifted(lo):
            at = [slice(None)] * a.ndim
            at[ax] = slice(lo, lo + n)
            return edge[tuple(at)]
        out = np.empty(a.shape[:ax] + (n, s) + a.shape[ax + 1:], np.float32)
        for k in range(s):
            d = np.float32((k + 0.5) / s - 0.5)
            lo, hi, f = (1, 2, d) if d >= 0 else (0, 1, np.float32(1) + d)
            at = [slice(None)] * out.ndim
            at[ax + 1] = k
            phase = out[tuple(at)]  # written in place: no stacked copy
            np.subtract(shifted(hi), shifted(lo), out=phase)
            phase *= f
            phase += shifted(lo)
        shape = list(a.shape)
        shape[ax] = n * s
        out = out.reshape(shape)
        at = [slice(None)] * a.ndim
        at[ax] = slice(0, n_out)
        out = out[tuple(at)]
        if n_out > n * s:  # more pixels than the input covers: its last one's value
            pad[ax] = (0, n_out - n * s)
            out = np.pad(out, pad, mode="edge")
        return out

    src = np.asarray(img, np.float32)
    return np.ascontiguousarray(along(along(src, w, 1), h, 0))


#: the disk cache's kind for a scene's flattened BVH (``cached_flat_scene``); bump the version
#: in ``viewer.environment.cache`` or this name when ``flatten_scene``'s output changes
BVH_CACHE_KIND = "bvh1"


def cached_flat_scene(geom):
    """``viewer.geometry.bvh_flat.flatten_scene(geom)``, from the disk cache when it holds the
    same triangles (a lecture step seen before, or drawn by the compile-ahead child, which builds
    it first): the build and its flattening take 1.5-2 s for the soap bubbles or the gallery on a
    loaded machine (``RayTrace.ready`` runs them on a thread of their own)."""
    from viewer.environment import cache
    from viewer.geometry.bvh_flat import FlatScene, flatten_scene

    if geom.n_triangles == 0:
        return flatten_scene(geom)
    import hashlib

    digest = hashlib.blake2b(digest_size=20)
    for a in (geom.triangles, geom.normals, geom.tangents, geom.object_index, geom.material_index):
        a = np.ascontiguousarray(a)
        digest.update(f"{a.dtype.str}{a.shape}".encode())
        digest.update(memoryview(a).cast("B"))
    key = cache.content_key(None, {"n": geom.n_triangles, "arrays": digest.hexdigest()}, kind=BVH_CACHE_KIND)
    hit = cache.load(key, kind=BVH_CACHE_KIND)
    names = ("nodes", "tris", "shading", "prim_id")
    if hit is not None and all(n in hit for n in names + ("sizes",)) and hit["prim_id"].shape == (geom.n_triangles,):
        n_nodes, n_tris, depth = (int(x) for x in hit["sizes"])
        return FlatScene(*(hit[n] for n in names), n_nodes, n_tris, depth)
    flat = flatten_scene(geom)
    cache.store(key, {"nodes": flat.nodes, "tris": flat.tris, "shading": flat.shading, "prim_id": flat.prim_id,
                      "sizes": np.array([flat.n_nodes, flat.n_triangles, flat.depth], np.int64)},
                kind=BVH_CACHE_KIND)
    return flat


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
        self._building = None  # (geometry key, {"flat": FlatScene or "error": exception}, thread)

    @staticmethod
    def _key(scene):
        gkey = tuple((id(o.mesh_data), o.material, o.model_matrix().tobytes()) for o in scene.objects)
        return gkey, tuple(scene.materials)

    def ready(self, scene) -> bool:
        """Whether ``update`` can make ``scene``'s textures at once: its geometry is the one the
        textures hold, or its flattened BVH has been made. If not, that is started on a thread of
        its own (``build_geometry`` and the BVH or its cache entry: 0.3-1.5 s of numpy and
        Python for the gallery, which the window's thread would spend in one frame); the window
        keeps its untraced frame until then. ``update`` alone (offscreen rendering) makes it
        where it is called."""
        import copy
        import threading

        gkey = self._key(scene)
        if gkey == self._geom_key and self.textures is not None:
            return True
        job = self._building
        if job is not None and job[0] == gkey:
            return not job[2].is_alive()
        # a snapshot of what the soup is made of: the window may edit the scene meanwhile
        snap = copy.copy(scene)
        snap.objects = [copy.copy(o) for o in scene.objects]
        snap.materials = dict.fromkeys(scene.materials)
        out: dict = {}

        def build():
            from viewer.geometry.soup import build_geometry

            try:
                out["flat"] = cached_flat_scene(build_geometry(snap))
            except Exception as e:  # noqa: BLE001 - update() makes it again where it is called, and raises there
                out["error"] = e
        thread = threading.Thread(target=build, name="brdf-viewer-bvh", daemon=True)
        self._building = (gkey, out, thread)
        thread.start()
        return False

    def update(self, scene, albedo_tables):
        from viewer.gl.scene_textures import SceneTextures, float_texture
        from viewer.geometry.soup import build_geometry

        gkey = self._key(scene)
        if gkey != self._geom_key or self.textures is None:
            job, self._building = self._building, None
            if job is not None and job[0] == gkey and not job[2].is_alive() and "flat" in job[1]:
                flat = job[1]["flat"]
            else:
                flat = cached_flat_scene(build_geometry(scene))
            if self.textures is not None:
                self.textures.release()
            self.textures = SceneTextures(self.ctx, flat=flat)
            self._geom_key = gkey
        mkey = json.dumps({k: p.to_plain() for k, p in scene.materials.items()}, sort_keys=True)
        if mkey != self._mat_key or self.mat_tex is None:
            if self.mat_tex is not None:
                self.mat_tex.release()
            self.mat_tex = float_texture(self.ctx, material_rows(scene, albedo_tables))
            self._mat_key = mkey
        self.rows = {name: i for i, name in enumerate(scene.materials)}

    def invalidate_materials(self) -> None:
        """Rebuild the material rows on the next ``update`` even when no parameter changed
        (what the rows are made of may depend on more than the parameters)."""
        self._mat_key = None

    def bind(self, prog, first_unit: int = texture_units.TRACED) -> int:
        from viewer.gl.shaders import set_uniform

        unit = self.textures.bind(prog, first_unit)
        self.mat_tex.use(location=unit)
        set_uniform(prog, "u_mat_tex", unit)
        return unit + 1

    def release(self):
        self._building = None  # a thread still at work finishes into nothing
        if self.textures is not None:
            self.textures.release()
            self.textures = None
        if self.mat_tex is not None:
            self.mat_tex.release()
            self.mat_tex = None
        self._geom_key = self._mat_key = None


def _object_tops(scene, camera, w, h) -> frozenset:
    """The blocks of 4 rows (from the bottom) of a w x h frame where the projected box of one of
    ``scene``'s objects begins, seen from the top (the raster tiles' order); boxes crossing the
    camera's plane or outside the frame are left out."""
    return frozenset(int(min(box[3], h - 1)) // 4 for box in screen_boxes(camera, w, h, scene.objects)
                     if box is not None and box[3] >= 0 and box[1] < h and box[2] >= 0 and box[0] < w)


class _Pass:
    """One resolution of the progressive trace: its size, its mask of traced pixels and, per
    block of 4 rows from the bottom (software rasterizers shade 4 x 4 blocks), the columns
    [x0, x1) the mask covers (x1 = 0: nothing to trace in the block)."""

    def __init__(self, w: int, h: int, mask: np.ndarray, scale: int):
        self.w, self.h, self.mask, self.scale = w, h, mask, scale
        nb = (h + 3) // 4
        rows = np.zeros((nb * 4, w), bool)
        rows[:h] = mask
        blocks = rows.reshape(nb, 4, w).any(axis=1)
        any_col = blocks.any(axis=1)
        self.x0 = np.where(any_col, np.argmax(blocks, axis=1), 0)
        self.x1 = np.where(any_col, w - np.argmax(blocks[:, ::-1], axis=1), 0)
        self.block = nb - 1      # the next block from the top
        self.x = 0               # columns of that block traced (when a block is cut into tiles)
        self.total = int(mask.sum())

    def rows(self, b: int) -> int:
        return min(4 * b + 4, self.h) - 4 * b

    def skip_empty(self):
        while self.block >= 0 and self.x1[self.block] == 0:
            self.block -= 1
            self.x = 0

    @property
    def done(self) -> bool:
        self.skip_empty()
        return self.block < 0

    def next_tile(self, pixels: int):
        """(x, y, w, h) of the next tile of about ``pixels`` pixels: whole blocks from the top
        over the union of their masked columns, or one block cut into tiles from the left."""
        self.skip_empty()
        b = self.block
        x0, x1 = int(self.x0[b]), int(self.x1[b])
        rows = self.rows(b)
        if self.x > 0 or (x1 - x0) * rows > pixels:
            start = max(self.x, x0)
            tw = min(x1 - start, max(16, pixels // rows // 4 * 4))
            return start, 4 * b, tw, rows
        last = b
        while last - 1 >= 0 and self.x1[last - 1] > 0:
            nx0, nx1 = min(x0, int(self.x0[last - 1])), max(x1, int(self.x1[last - 1]))
            if (nx1 - nx0) * (4 * (b - last + 2)) > pixels:
                break
            last, x0, x1 = last - 1, nx0, nx1
        return x0, 4 * last, x1 - x0, 4 * b + rows - 4 * last

    def advance(self, tile):
        x, y, tw, th = tile
        b = (y + th - 1) // 4
        if th <= 4 and x + tw < int(self.x1[b]):  # a block cut into tiles: its next one
            self.x = x + tw
            return
        self.block = y // 4 - 1
        self.x = 0


def planned_tile_s(least_s: float, budget_s: float, overhead_s: float) -> float:
    """The time a tile is planned to take: enough that its fixed part (``overhead_s``) is a
    third of it at most, and ``least_s`` at least; never over ``TILE_MOST_S`` (or the frame's
    ``budget_s`` where that is larger: a bake's tiles)."""
    return min(max(least_s, 3.0 * overhead_s), max(budget_s, TILE_MOST_S))


class RasterTileSizes:
    """The sizes of a raster frame's tiles (``ProgressiveTrace.start(traced=False)``), from what
    its tiles cost so far and what the last frame's cost in each block of 4 rows (``like_last``),
    and where the objects' projected boxes begin (``contacts``)."""

    def __init__(self):
        self.worst_px = 0.0     # this frame's highest cost per pixel so far
        self.rows_cost = None   # this frame's cost per pixel in each block of 4 rows (NaN: not drawn)
        self.prior = None       # the last frame's, for a view of the same size
        self.scale = 1.0        # this frame's cost over the last one's, on its last tile
        self.next_s = 0.0       # the predicted time of the next tile
        self.width = 0
        self.contacts = frozenset()  # the blocks where an object's box begins

    def start(self, w: int, h: int, like_last: bool, contacts: frozenset) -> None:
        """A new frame of (w, h); ``like_last``: the same scene seen as the last frame."""
        nb = (h + 3) // 4
        last = self.rows_cost
        same = like_last and last is not None and last.shape == (nb,) and self.width == w
        self.prior = last if same else None
        self.rows_cost, self.width, self.scale, self.worst_px = np.full(nb, np.nan), w, 1.0, 0.0
        self.contacts = contacts

    def next_pixels(self, p, y, th, per_px, budget_s, n, overhead_s) -> int:
        """A raster frame's next tile, after one over rows [y, y + th) cost ``per_px`` a pixel:
        whole blocks of rows from the next one down, as many as a third of the budget covers.
        The cost of a block is the last frame's there (``like_last``), times what this frame
        cost over the last one on this tile, at least 1 (a changed material: the costly rows are
        where they were, the cost differs), and at least the highest cost per pixel seen so far
        in this frame; where the last frame gives none, that highest cost alone, at
        most 1.5 times as many pixels as this tile (the cost jumps 5-20 times over where the
        tiles reach an object from the sky above it). Returns the next tile's pixels;
        ``next_s`` is its predicted time."""
        b0, b1 = y // 4, (y + th - 1) // 4
        self.rows_cost[b0:b1 + 1] = per_px
        self.worst_px = max(self.worst_px, per_px)
        prior = self.prior
        ref = np.inf  # the last frame's cost where the scale was measured
        if prior is not None:
            before = prior[b0:b1 + 1]
            before = before[np.isfinite(before)]
            if before.size and before.mean() > 0:  # never below the last frame's: a cheaper
                # first tile (the sky) says nothing of the object below it
                ref = float(before.mean())
                self.scale = max(1.0, per_px / ref)
        o = 0.9 * overhead_s
        target = planned_tile_s(budget_s / 3.0, budget_s, overhead_s)
        row_px = 4 * p.w
        total, blocks, b, guessed, dearer = o, 0, p.block, False, 0
        while b >= 0:
            c = prior[b] * self.scale if prior is not None and np.isfinite(prior[b]) else np.nan
            unknown = not np.isfinite(c)
            if unknown:
                c, guessed = self.worst_px, True
            else:
                if prior[b] > 2.0 * ref:  # rows dearer than where the scale was measured: a
                    dearer += 1           # changed material may cost more there, take two
                # never below the dearest pixel of this frame so far: a block of the last frame
                # holds the mean of a tile, which may have spanned the sky and the object
                c = max(c, self.worst_px)
            # where an object's box begins and its cost is not known, the tile ends above it,
            # and the block where it begins is a tile of its own (a probe of its cost): a tile
            # sized at the sky's cost that ran into the soap bubbles took 0.6-0.8 s
            contact = unknown and b in self.contacts
            if blocks and (total + c * row_px > target or dearer > 2 or contact):
                break
            total += c * row_px
            blocks += 1
            b -= 1
            if contact:
                break
        pixels = blocks * row_px
        if guessed:  # 1.5 times as many, and at least a block more (tiles are whole blocks)
            pixels = min(pixels, max(int(1.5 * n) + 16, n + row_px))
        self.next_s = total
        return pixels


class ProgressiveTrace:
    """The traced image of a still view, built over several frames (the window on software
    OpenGL, where one traced frame takes seconds).

    ``start`` renders the view with the untraced approximation (the view's MSAA) into a texture
    of its own and finds the pixels a traced chain changes (``Renderer.traced_mask``: the
    front-most surface is a mirror or smooth glass); only those are traced. Each ``step`` traces
    tiles (``Renderer.render(region=...)``, no MSAA: a scissor, every pixel inside exactly as in a
    whole frame), first at half resolution (``coarse``: the whole traced area appears at a quarter
    of the cost, each traced pixel standing for its 2 x 2), then at full resolution. A tile spans
    the masked columns of whole blocks of rows from the top, or cuts a block into tiles from the
    left; its pixel count follows the time of the last one, so that a step takes about
    ``budget_s``. Every pixel shows at any moment the untraced view, its half-resolution trace or
    its trace: never a hole. Once ``done`` the texture holds the untraced view with every masked
    pixel replaced by its traced value (float32 texels, pixels are independent): the same image
    whether traced in tiles, in one piece, or read from the traced-frame cache
    (``viewer.gl.trace_cache``, when ``start(cache=True)``: then no frame is rendered at all),
    which a finished trace fills (``store=True``).

    ``start(traced=False)`` builds a raster frame the same way, for a view whose whole frame
    takes longer than a frame's budget (the window after a change, on software OpenGL): the
    texture first holds an image given for the meantime (the view as it was before the change)
    or the view at half resolution without MSAA (or a quarter with it), enlarged with bilinear
    interpolation (``upscale``: smooth silhouettes, not steps), then every
    pixel is drawn in tiles from the top with the view's MSAA and no traced chains. Once
    ``done`` it holds exactly the whole frame ``Renderer.render(raytrace=False)`` draws: the
    tiles are scissors of it."""

    def __init__(self, ctx):
        self.ctx = ctx
        self.texture = None
        self._fbo = None
        self._job = None
        self._passes: list[_Pass] = []
        self.base = None       # (H, W, 4) float32: a view read from the traced-frame cache, texture row order
        self.mask = None       # (H, W) bool: the pixels traced at full resolution (None from the cache)
        self.steps = 0         # tiles traced since start
        self.height = 0
        self.width = 0
        self.pixels = 0        # the next tile's pixels
        self.overhead_s = 0.0  # a tile's fixed cost (the least any tile took), None before the first
        self.max_pixels = STRIP_PIXELS
        self.trace_s = 0.0     # time spent tracing tiles since start
        self.started = 0.0     # perf_counter() at start
        self.elapsed_s = 0.0   # wall-clock time from start until done (the true time)
        self.traced_px = 0     # masked pixels traced (both passes)
        self.total_px = 0
        self.from_cache = False
        self.cache_key = None
        self.cache_message = ""  # why an entry was set aside ("" when none was)
        self.stored = None       # the cache entry a finished trace wrote, or None
        self._store = False
        self._tile_args = {"msaa": 0, "raytrace": None}  # how a tile is drawn
        self.raster = False      # a raster frame in tiles (start(traced=False)), not a trace
        self._sizes = RasterTileSizes()  # a raster frame's tiles: their sizes from their costs
        # a tile draws only the objects that can reach it (False: every object, as the
        # compile-ahead child's tiles must, to make each program's code for a scissored draw)
        self.cull = True
        self.msaa_made = False  # the programs' machine code at the view's MSAA is made (see _start_raster)
        self._kept = None       # the last target, at another size, until it is read (``_target``)
        self._raster_objects = None  # the objects of the last raster frame (``raster_cost_px``)

    @property
    def active(self) -> bool:
        return self._job is not None

    @property
    def pass_size(self) -> tuple[int, int]:
        """(w, h) of the pass the next tile belongs to (half the view's size in a coarse pass),
        or of the view once done."""
        if self._passes and not self.done:
            p = self._pass()
            return p.w, p.h
        return self.width, self.height

    def preview_scale(self, scene, w: int, h: int, base: int, goal_s: float) -> int:
        """A raster frame's preview of ``scene`` at (w, h) drawn at 1 / this of the resolution:
        ``base`` (2, or 4 for a scene whose cost is not known yet), or coarser, down to a 16th,
        where the last raster frame's tiles of this scene showed what a pixel costs
        (``raster_cost_px``) and the preview would take over ``goal_s`` at the dearest cost
        they met (an overestimate: most pixels cost less, and the preview has no MSAA). The
        soap bubbles' quarter-resolution preview at the whole view (lecture mode left, the strip
        gone) took 0.3 s of llvmpipe's threads, 0.53 s of the window's frame beside two busy
        processes."""
        scale = int(base)
        per_px = self.raster_cost_px(scene)
        if per_px is not None:
            while scale < 16 and per_px * w * h / scale ** 2 > goal_s:
                scale *= 2
        return scale

    def raster_cost_px(self, scene) -> float | None:
        """The dearest time per pixel (s) that the last raster frame's tiles took where that
        frame was ``scene``'s (the same objects, at whatever size): what its preview at another
        size will cost about, per pixel; None where it is not known."""
        if self._raster_objects is scene.objects and self._sizes.worst_px > 0:
            return self._sizes.worst_px
        return None

    @property
    def done(self) -> bool:
        return self._job is not None and all(p.done for p in self._passes)

    @property
    def coarse(self) -> bool:
        """The half-resolution pass is still running."""
        return bool(self._passes) and self._passes[0].scale == 2 and not self._passes[0].done

    @property
    def progress(self) -> float:
        if self.done:
            return 1.0
        return self.traced_px / self.total_px if self.total_px else 0.0

    def _target(self, w, h, keep=None):
        """The texture at (w, h), made anew at another size; ``keep``: a texture read after this
        call, which may be the old one (then released once read, ``_kept``)."""
        if self.texture is None or self.texture.size != (w, h):
            if keep is not None and keep is self.texture:
                if self._kept is not None:
                    release_gl(self._kept)
                release_gl(self._fbo)
                self._job, self._kept = None, keep
            else:
                self.release()
            self.texture = self.ctx.texture((w, h), 4, dtype="f4")
            self.texture.filter = (self.ctx.NEAREST, self.ctx.NEAREST)
            self._fbo = self.ctx.framebuffer(color_attachments=[self.texture])
        return self.texture

    def start(self, renderer, scene, camera, w: int, h: int, view_mode: int = 0, msaa=None, rows: int = 0,
              coarse: bool = True, cache: bool = False, store: bool = False, max_pixels: int = STRIP_PIXELS,
              traced: bool = True, under=None, like_last: bool = False, untraced=None, preview_scale: int = 2):
        """The untraced view (returned, also the texture's content), and the trace set to begin.
        ``rows``: the first tile's height (default 2: the cost per pixel is not known yet);
        ``coarse``: a half-resolution pass first; ``cache``: open from the traced-frame cache
        when it holds this view (then ``done`` at once); ``store``: write the finished trace
        there; ``max_pixels``: the largest tile. ``traced=False``: the raster frame in tiles
        (see the class), over ``under`` when given (an (h, w, 4) float32 image or a texture, or the view at
        half resolution, texture row order) or over the half-resolution view drawn here;
        ``like_last``: the same scene seen as the last raster frame, with materials or lights
        edited (its tiles are sized by the cost of the last one's rows); ``coarse``, ``cache``
        and ``store`` do not apply; ``preview_scale``: the preview drawn here at 1 / 2 or 1 / 4
        of the resolution, or less (4: a scene whose cost is not known yet, e.g. thin films over the
        whole view, whose half-resolution frame alone may take seconds on software OpenGL; 8 or
        16: one whose tiles showed it dear, ``raster_cost_px``).
        The quarter-resolution preview is drawn with the tiles' MSAA (the half-resolution one
        without). ``untraced``: a texture of the view's size holding the untraced view already drawn (the
        window's tiles): copied instead of rendered again."""
        import time

        from viewer.gl import trace_cache

        self.started = time.perf_counter()
        resized = (not traced and under is not None and not isinstance(under, np.ndarray)
                   and tuple(under.size) != (w, h))   # the view drawn at another size
        tex = self._target(w, h, keep=under if resized else None)
        self._job = (renderer, scene, camera, w, h, view_mode)
        self.height, self.width = h, w
        self.steps, self.trace_s, self.elapsed_s, self.traced_px = 0, 0.0, 0.0, 0
        self.max_pixels = max(16, int(max_pixels))
        self.pixels = min(self.max_pixels, max(1, int(rows) if rows else 2) * w)
        self.from_cache, self.cache_message, self.stored = False, "", None
        self.cache_key = None
        self._store = bool(store) and traced
        self._passes = []
        if not traced:
            return self._start_raster(renderer, scene, camera, w, h, view_mode, msaa, under, like_last,
                                      preview_scale)
        self._tile_args = {"msaa": 0, "raytrace": None}
        self.raster = False
        # the first tile a probe of PROBE_PIXELS: its time is the fixed part of every tile (the
        # scene's vertex work), which sizes the next; a first tile of whole rows over glass took
        # 0.3 s on software OpenGL and, taken for that fixed part, grew the next ones to a second
        self.pixels = min(self.pixels, PROBE_PIXELS)
        if cache or store:
            self.cache_key = trace_cache.frame_key(scene, camera, w, h, view_mode, msaa,
                                                   renderer.ctx.info.get("GL_RENDERER", ""))
        if cache:  # a hit: the finished view at once, no frame rendered
            image, self.cache_message = trace_cache.load(self.cache_key, (h, w))
            if image is not None:
                tex.write(image)
                self.base, self.mask = image, None
                self.from_cache = True
                self.total_px = self.traced_px = 1
                self.elapsed_s = time.perf_counter() - self.started
                return tex
        if untraced is not None and tuple(untraced.size) == (w, h):
            if untraced is not tex:
                src = self.ctx.framebuffer(color_attachments=[untraced])
                self.ctx.copy_framebuffer(self._fbo, src)
                release_gl(src)
        else:
            hdr = renderer.render(scene, camera, w, h, view_mode, msaa=msaa, raytrace=False)
            self.ctx.copy_framebuffer(self._fbo, renderer.resolved_framebuffer(hdr))
        # the untraced view is the texture's content, and stays so wherever no tile traced:
        # a tile composes over the texels it covers, read then (a whole frame's read and copy,
        # 0.2-0.3 s at 1344x1000 in the frame the trace starts, is not needed)
        self.base = None
        self.mask = renderer.traced_mask(scene, camera, w, h)
        self._passes = []
        if coarse and self.mask.any() and w >= 8 and h >= 8:
            w2, h2 = (w + 1) // 2, (h + 1) // 2
            self._passes.append(_Pass(w2, h2, renderer.traced_mask(scene, camera, w2, h2), 2))
        self._passes.append(_Pass(w, h, self.mask, 1))
        self.total_px = sum(p.total for p in self._passes)
        self.overhead_s = None
        self._maybe_finish()
        return tex

    def _start_raster(self, renderer, scene, camera, w, h, view_mode, msaa, under, like_last, preview_scale=2):
        """``start(traced=False)``: the meantime's image in the texture, every pixel to draw.
        ``under``: an array, or a texture (this one: kept as it is; another of the view's size:
        copied on the GPU)."""
        w2, h2 = (w + 1) // 2, (h + 1) // 2
        if under is not None and not isinstance(under, np.ndarray):  # a texture
            if under is self.texture or tuple(under.size) == (w, h):
                if under is not self.texture:
                    fbo = self.ctx.framebuffer(color_attachments=[under])
                    self.ctx.copy_framebuffer(self._fbo, fbo)
                    release_gl(fbo)
                under = True  # in the texture now
            else:  # the view drawn at another size (a compare view's half): resampled on the GPU
                self.enlarge(renderer, under, None, w, h)
                if under is self._kept:  # the old target, read: released now
                    release_gl(self._kept)
                    self._kept = None
                under = True
        if isinstance(under, np.ndarray) and under.shape[:2] not in ((h, w), (h2, w2)):
            under = None
        if under is None:
            s = max(2, int(preview_scale))
            ws, hs = (w + s - 1) // s, (h + s - 1) // s
            # a quarter-resolution preview with the tiles' MSAA: llvmpipe makes a program's
            # machine code per sample count at its first draw, so the tiles reuse the preview's;
            # without it where that code was made already (``msaa_made``: the window's view
            # preparation drew each program at the view's MSAA; the soap bubbles' preview took
            # 0.6 s with it)
            pm = 0 if s == 2 or self.msaa_made else msaa
            hdr = renderer.render(scene, camera, ws, hs, view_mode, msaa=pm, raytrace=False)
            self.enlarge(renderer, hdr, s, w, h)  # on the GPU: ``upscale`` took 0.3-0.6 s at 1344x1000
            under = True
        if isinstance(under, np.ndarray):
            if under.shape[:2] != (h, w):
                under = upscale(under, 2, h, w)
            self.texture.write(np.ascontiguousarray(under, np.float32))
        self.base = None  # every pixel is a tile's
        self.mask = np.ones((h, w), bool)
        self._tile_args = {"msaa": msaa, "raytrace": False}
        self.raster = True
        self._sizes.start(w, h, like_last, _object_tops(scene, camera or OrbitCamera.from_scene(scene), w, h))
        self._raster_objects = scene.objects
        self._passes = [_Pass(w, h, self.mask, 1)]
        self.total_px = self._passes[0].total
        self.overhead_s = None
        return self.texture

    def enlarge(self, renderer, src, s: int | None, w: int, h: int):
        """``src`` (a texture) resampled into the texture, of (w, h): enlarged ``s`` times
        (``upscale``'s weights), or with ``s`` None from whatever size it has (bilinear between
        its texel centres; shaders/passes/enlarge.frag); returns the texture."""
        from viewer.gl.shaders import set_uniform

        ctx = self.ctx
        self._target(w, h)
        prog = renderer.program_set.enlarge()
        self._fbo.use()
        self._fbo.viewport = (0, 0, w, h)
        ctx.disable(ctx.DEPTH_TEST | ctx.BLEND)
        src.use(location=texture_units.SOURCE)
        set_uniform(prog, "u_src", texture_units.SOURCE)
        ratio = (1.0 / s, 1.0 / s) if s else (src.width / w, src.height / h)
        set_uniform(prog, "u_ratio", ratio)
        renderer.program_set.fullscreen_vao(prog).render(vertices=3)
        return self.texture

    def step(self, budget_s: float = 0.15):
        """Trace tiles into the texture (returned) until about ``budget_s`` is spent (at least
        one; the next is left out when its predicted time would overrun); nothing once ``done``."""
        import time

        t0 = time.perf_counter()
        while self._job is not None and not self.done:
            dt, n = self._tile(budget_s)
            if time.perf_counter() - t0 + self._predict(self.pixels, dt, n) > budget_s:
                break
        self._maybe_finish()
        return self.texture

    def finish(self):
        """Trace everything that is left, in tiles of ``max_pixels`` (the bake's way)."""
        while self._job is not None and not self.done:
            self.pixels = self.max_pixels
            self._tile(1e9)
        self._maybe_finish()
        return self.texture

    def _pass(self) -> _Pass:
        return next(p for p in self._passes if not p.done)

    def _tile(self, budget_s):
        """Trace the next tile; (its time, its pixels)."""
        import time

        renderer, scene, camera, w, h, view_mode = self._job
        p = self._pass()
        asked = self.pixels
        tile = p.next_tile(asked)
        x, y, tw, th = tile
        t0 = time.perf_counter()
        hdr = renderer.render(scene, camera, p.w, p.h, view_mode, region=tile, cull=self.cull, **self._tile_args)
        data = renderer.resolved_framebuffer(hdr).read(viewport=tile, components=4, dtype="f4")
        traced = np.frombuffer(data, np.float32).reshape(th, tw, 4)
        s = p.scale
        fx, fy = s * x, s * y
        fw, fh = min(w, s * (x + tw)) - fx, min(h, s * (y + th)) - fy
        sel = self.mask[fy:fy + fh, fx:fx + fw]
        if s > 1:  # each half-resolution pixel stands for its 2 x 2 where both masks agree
            traced = np.repeat(np.repeat(traced, s, axis=0), s, axis=1)[:fh, :fw]
            sel = sel & np.repeat(np.repeat(p.mask[y:y + th, x:x + tw], s, axis=0), s, axis=1)[:fh, :fw]
        if self.raster:
            out = traced
        else:  # untraced where the mask is not set: the texels there were never written
            under = np.frombuffer(self._fbo.read(viewport=(fx, fy, fw, fh), components=4, dtype="f4"),
                                  np.float32).reshape(fh, fw, 4)
            out = np.where(sel[..., None], traced, under)
        self.texture.write(np.ascontiguousarray(out), viewport=(fx, fy, fw, fh))
        self.ctx.finish()
        dt = max(time.perf_counter() - t0, 1e-6)
        self.trace_s += dt
        self.steps += 1
        self.traced_px += int(p.mask[y:y + th, x:x + tw].sum())
        p.advance(tile)
        # the next tile: a tile costs a fixed part (the least any tile took: the vertex work of
        # the whole scene, whatever the scissor) and a part per pixel. As many pixels as fill
        # the budget at this tile's cost per pixel, or, where the fixed part is most of the
        # budget, enough that it is a third of the tile's time at most; at most 1.5 times as
        # many as this tile (the cost jumps where a glass object begins: a tile must stay small
        # where the cost is not known yet) and max_pixels in all
        n = tw * th
        self.overhead_s = dt if self.overhead_s is None else min(self.overhead_s, dt)
        per_px = max(dt - 0.9 * self.overhead_s, 1e-9) / n
        target = planned_tile_s(budget_s, budget_s, self.overhead_s)
        if self.raster:
            pixels = self._sizes.next_pixels(p, y, th, per_px, budget_s, n, self.overhead_s)
            self.pixels = max(16, min(pixels, self.max_pixels))
            return dt, n
        # at the dearest cost per pixel of the trace so far: the cost jumps 10 times over where a
        # tile reaches the glass from the sky beside it, and a tile sized at the sky's would
        # take seconds; past the dear part the tiles stay small (more tiles, no long frame)
        want = int((target - 0.9 * self.overhead_s) / per_px)
        # grown from the size asked for, not the size drawn: the last tile of a block is cut short
        self.pixels = max(16, min(int(1.5 * max(n, asked)) + 16, want, self.max_pixels))
        return dt, n

    def _predict(self, pixels, dt, n) -> float:
        """The predicted time of a tile of ``pixels`` after one of ``n`` took ``dt``."""
        if self.raster:
            return self._sizes.next_s
        o = 0.9 * (self.overhead_s or 0.0)
        return o + pixels * max(dt - o, 1e-9) / n

    def _maybe_finish(self):
        """Once done: the true elapsed time, and the cache entry when asked for."""
        import time

        if self._job is None or self.elapsed_s or not self.done:
            return
        self.elapsed_s = time.perf_counter() - self.started
        if self._store and not self.from_cache:
            from viewer.gl import trace_cache

            img = np.frombuffer(self.texture.read(), np.float32).reshape(self.height, self.width, 4)
            self.stored = trace_cache.store(self.cache_key, img)

    def image(self) -> np.ndarray:
        """(H, W, 3) float32 linear radiance of the texture, row 0 = top (as ``read_linear``)."""
        a = np.frombuffer(self.texture.read(), np.float32).reshape(self.height, self.width, 4)
        return np.ascontiguousarray(a[::-1, :, :3])

    def cancel(self):
        self._job = None

    def keep_out_of_cache(self):
        """Do not store this trace when it finishes (what it shows is provisional)."""
        self._store = False

    def release(self):
        self._job = None
        if self._fbo is not None:
            release_gl(self._fbo, self.texture)
        self._fbo = self.texture = None
        if self._kept is not None:
            release_gl(self._kept)
            self._kept = None
