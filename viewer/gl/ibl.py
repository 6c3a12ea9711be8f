"""Image-based lighting on the GPU: the environment's textures for ``shaders/common/ibl.glsl``.

``IBL.set_environment(latlong)`` builds, from a lat-long radiance map (intensity applied,
rotation *not* applied: the rotation is a uniform, so turning the map costs nothing):

1. **The map** as a float RGB 2D texture with a full mip chain (``u_env_map``): the background,
   mirror reflections and the source of every filtered lookup. The levels are made in numpy
   (``viewer.environment.latlong.mip_chain``) and uploaded: each texel is the *solid-angle
   weighted* mean of the texels under it, a box filter on the sphere (GL's
   ``glGenerateMipmap`` would weight the small polar texels like equatorial ones), exact for
   odd sizes too. (A GPU pass made them before; on llvmpipe its program's first draw cost
   70-150 ms of the window's thread at every launch, where numpy takes 12 ms for 1024 x 512.)
2. **GGX-prefiltered radiance** (``u_env_prefiltered``), one level per alpha in ``ALPHAS``
   (Walter et al. 2007's alpha): Karis 2013's split-sum first factor with n = v = r, half
   vectors drawn from D(h)(n.h) (with v = n this *is* Heitz 2018's visible-normal density),
   weights n.l, and *filtered importance sampling* (Colbert & Krivanek 2007, GPU Gems 3 ch. 20):
   each sample reads the map's mip level whose texel solid angle matches the sample's share
   1 / (N pdf), so a tiny bright sun is spread over the lobe instead of making fireflies. All
   levels come from one draw (``passes/ibl_prefilter.frag``). ``SAMPLES`` gives the Hammersley
   samples per texel of each level (the same set for every texel: the error is smooth across
   the map, not noise). The exact integral each level estimates is
       P(r, alpha) = int L(l) D(h) max(0, r.l) dl / int D(h) max(0, r.l) dl, h = (r + l) / |r + l|.
3. **The DFG table** (``u_env_dfg``), rendered on the GPU (``passes/ibl_dfg.frag``) in the
   convention of ``viewer.environment.dfg``: s = alpha, t = NoV, (r, g) = (A, B), E_ss = F0 A + B.
   It depends on no environment, so it is made once per ``IBL`` (and disk-cached).
4. **SH9 irradiance**: ``viewer.environment.sh.project_latlong`` on the CPU (exact texel
   integrals; ~tens of ms for 1024 x 512, over 100 ms for a 2048 x 1024 file), 9 vec3 uniforms
   ``u_env_sh``. A quick prefilter (``defer``) projects the map's first mip level at most
   ``SH_QUICK_WIDTH`` wide instead (its texels are solid-angle weighted means of the map's, so
   the integral is the map's and the l = 1, 2 bands differ by the box filter's blur).
5. On request, ``cubemap()``: the map resampled into a float cube map on the GPU
   (``passes/ibl_cubemap.frag``), checked against ``viewer.environment.latlong.to_cubemap``.

**Representation of the prefiltered levels, and why.** moderngl can neither attach a cube face
nor a mip level other than 0 to a framebuffer, nor write the mip levels of a cube texture, so a
mipmapped prefiltered cube map (the usual choice) would need raw GL calls. The levels are
instead lat-long images of one size (``LAYER_WIDTH`` x ``LAYER_WIDTH / 2``, smaller for smaller
maps) in one ``sampler2DArray``: layer k - 1 holds ALPHAS[k] (k >= 1); level 0, alpha = 0, is
the full-resolution map itself. Why not a lat-long *mip chain*: mip sizes halve per level,
which ties resolution to the level index; the GGX lobe does not narrow that fast and with 8
levels alpha = 1 would sit in a 4 x 2 (or 8 x 4) image, far too coarse for bilinear lookups
(the poles of a lat-long image need a few rows). Equal-size layers keep every level well
sampled (a 256 x 128 texel is 1.4 degrees; the alpha = 0.05 lobe is ~7 degrees wide), need no
seam handling (repeat in u, clamp in v, no derivatives) and the lookup interpolates between the
two nearest levels explicitly, with exactly the alphas of ``ALPHAS`` (uploaded as
``u_env_alphas``, so GLSL and Python cannot disagree). The whole stack renders in one draw into
a tall 2D target, is read back (it is needed on the CPU anyway, for the disk cache) and
written into the array with ``TextureArray.write``.

Disk cache: ``viewer.environment.cache`` by content hash (map bytes + settings + version): a
second ``set_environment`` with the same map, even in a new process, runs no prefilter pass
(``stats["cached"]``, ``stats["prefilter_passes"] == 0``). The map texture and its mip chain
are always rebuilt (a few small GPU passes).

Texture units: ``bind(prog, rotation_deg, first_unit)`` uses first_unit (map),
first_unit + 1 (prefiltered), first_unit + 2 (DFG) and, once ``cubemap()`` was made,
first_unit + 3 (``u_env_cube``); first_unit is ``viewer.gl.texture_units.IBL``.
"""

from __future__ import annotations

import logging
import time

import numpy as np

from viewer.gl import texture_units

from viewer.environment import cache
from viewer.environment.dfg import DFG_SIZE, vndf_quadrature
from viewer.environment.latlong import mip_chain, rotation_y
from viewer.gl.constants import IBL_MAX_LEVELS
from viewer.gl.context import release_gl
from viewer.gl.programs import Recipe
from viewer.gl.shaders import set_uniform as _set

log = logging.getLogger(__name__)

#: GGX alphas of the prefiltered levels (Walter et al. 2007's alpha, not perceptual roughness).
#: Level 0 is the map itself. Roughly doubling lobe widths at first, then evenly up to 1.
ALPHAS = (0.0, 0.05, 0.1, 0.2, 0.35, 0.5, 0.75, 1.0)
#: Hammersley samples per texel for each level (level 0 takes none). Measured against a
#: brute-force integral on the studio map (tests/test_ibl.py): 256 per texel left median
#: relative errors of 2-6 % and up to 60 % in dark texels next to bright panels; 1024 gives
#: 1.7 % median, 13 % at the 95th percentile, 20 % worst (the FIS bias in the GGX tail; the
#: sky: ~1 % median); 1024 x 512 prefilters in 2.6 s on 2 idle llvmpipe cores. Samples are
#: drawn only where l is above the surface (theta_h < 45 degrees when n = v): none wasted.
SAMPLES = (0, 1024, 1024, 1024, 1024, 1024, 1024, 1024)
#: width of every prefiltered layer (height = width / 2), or the map's width if smaller
LAYER_WIDTH = 256
#: a map the disk cache does not hold, with ``IBL.defer`` set (the window): prefiltered at once
#: at layers this wide with this many samples per texel (about a thousandth of the full
#: prefilter's work: milliseconds), for the meantime, while the full prefilter runs elsewhere
#: (the window's background child) and fills the disk cache, which the next frame then reads
QUICK_LAYER_WIDTH = 32
QUICK_SAMPLES = 64
#: a quick prefilter's SH9 irradiance: projected from the map's first mip level at most this wide
SH_QUICK_WIDTH = 256
#: DFG table: size and quadrature points, as viewer.environment.dfg.dfg_table's defaults
DFG_SAMPLES = 4096
#: a constant environment is a small constant map (the same code path, exact results)
CONSTANT_MAP_SIZE = (16, 8)
MAX_LEVELS = IBL_MAX_LEVELS  # prefiltered levels at most (the generated GLSL constant too)

_VERT = "passes/fullscreen.vert"


def program_recipe(name: str) -> Recipe:
    """The IBL pass's program ``name``: a fullscreen pass ``passes/<name>.frag`` without BRDF code."""
    return Recipe(_VERT, f"passes/{name}.frag", models=None)


def sanitize_map(latlong) -> np.ndarray:
    """float32 (H, W, 3), C-contiguous, non-finite and negative values set to 0."""
    a = np.asarray(latlong, dtype=np.float32)
    if a.ndim != 3 or a.shape[2] != 3 or a.shape[0] < 1 or a.shape[1] < 1:
        raise ValueError(f"an environment map must be (H, W, 3), got {a.shape}")
    bad = ~np.isfinite(a) | (a < 0)
    if bad.any():
        a = np.where(bad, np.float32(0.0), a)
    return np.ascontiguousarray(a)


def mip_sizes(width: int, height: int) -> list[tuple[int, int]]:
    """(w, h) of every level of a full GL mip chain."""
    sizes = [(width, height)]
    while sizes[-1] != (1, 1):
        w, h = sizes[-1]
        sizes.append((max(1, w // 2), max(1, h // 2)))
    return sizes


def _ident(latlong, constant):
    """What ``set_environment`` knows a map by without hashing it: the array itself (held, so
    its identity is not reused) or the constant."""
    if latlong is not None:
        return ("map", latlong)
    c = np.zeros(3) if constant is None else np.broadcast_to(np.asarray(constant, float), (3,))
    return ("constant", tuple(c))


def _same(a, b) -> bool:
    """Two ``_ident``s are of the same map (the same array, or equal constants)."""
    return a is not None and a[0] == b[0] and (a[1] is b[1] if a[0] == "map" else a[1] == b[1])


def holds(ibl, latlong: np.ndarray | None, constant=None) -> bool:
    """Whether ``ibl.set_environment(latlong, constant)`` would do no work now: the same map
    array (or the same constant) is set with its DFG table, and no full prefilter of a quick one
    waits in the disk cache."""
    last = getattr(ibl, "_last_ident", None)
    if ibl._key is None or ibl.dfg_tex is None or not _same(last, _ident(latlong, constant)):
        return False
    return ibl.provisional is None or not cache.path_for(ibl.provisional).is_file()


class DFGPass:
    """The DFG table drawn on the GPU in bands of rows: ``step(rows)`` draws the next ``rows``
    rows (``None``: all that are left) into one target held between calls, ``done`` says
    whether every row is drawn and ``result()`` reads the table back and releases the target.
    A texel depends on its own ``gl_FragCoord`` alone, so a table drawn in bands is the table
    drawn at once, texel for texel. The window draws it a band a frame (``IBL.ensure_dfg``):
    on llvmpipe a 32x32 target is one rasterizer tile, so the whole pass runs on one thread
    (80 ms quiet; beside two busy processes its frame took half a second)."""

    def __init__(self, ibl, size: int = DFG_SIZE, samples: int = DFG_SAMPLES):
        ctx = ibl.ctx
        self.ibl, self.size, self.row = ibl, int(size), 0
        u, wq = vndf_quadrature(samples)
        self.count = len(u)
        self.width = 64
        rows = (self.count + self.width - 1) // self.width
        q = np.zeros((rows * self.width, 3), "f4")
        q[: self.count, :2] = u
        q[: self.count, 2] = wq
        self.qtex = ctx.texture((self.width, rows), 3, q.tobytes(), dtype="f4")
        self.qtex.filter = (ctx.NEAREST, ctx.NEAREST)
        ibl._program("ibl_dfg")  # linked now: its first draw then makes its code
        self.tex, self.fbo = ibl._target(self.size, self.size)

    @property
    def done(self) -> bool:
        return self.row >= self.size

    def step(self, rows: int | None = None) -> bool:
        """Draw the next ``rows`` rows (at least one); True once every row is drawn."""
        n = self.size - self.row if rows is None else max(1, min(int(rows), self.size - self.row))
        if n > 0:
            prog = self.ibl._program("ibl_dfg")  # its uniforms are set again: other passes share the unit
            self.qtex.use(texture_units.SOURCE)
            _set(prog, "u_quad", texture_units.SOURCE)
            _set(prog, "u_quad_count", self.count)
            _set(prog, "u_quad_width", self.width)
            _set(prog, "u_size", float(self.size))
            try:
                self.ibl._draw("ibl_dfg", self.fbo, (0, self.row, self.size, n))
            except BaseException:
                self.release()
                raise
            self.row += n
        return self.done

    def result(self) -> np.ndarray:
        """The (size, size, 2) float32 table, once ``done``; the pass's GL objects are released."""
        try:
            data = np.frombuffer(self.tex.read(), dtype="f4").reshape(self.size, self.size, 4)[..., :2]
            return np.ascontiguousarray(data)
        finally:
            self.release()

    def release(self) -> None:
        release_gl(self.fbo, self.tex, self.qtex)
        self.fbo = self.tex = self.qtex = None


def render_dfg(ibl, size: int = DFG_SIZE, samples: int = DFG_SAMPLES) -> np.ndarray:
    """(size, size, 2) float32 DFG table computed on the GPU: table[i, j] = (A, B) at
    NoV = (i + 0.5) / size, alpha = (j + 0.5) / size (``viewer.environment.dfg``), on
    ``ibl``'s context and program, in one draw."""
    job = DFGPass(ibl, size, samples)
    job.step()
    return job.result()


def _dfg_key() -> str:
    return cache.content_key(None, {"size": DFG_SIZE, "samples": DFG_SAMPLES}, kind="dfg")


def _dfg_on_disk() -> np.ndarray | None:
    """The DFG table from the disk cache (None: not there, or unreadable)."""
    hit = cache.load(_dfg_key(), kind="dfg", expect={"dfg": (DFG_SIZE, DFG_SIZE, 2)})
    return None if hit is None else hit["dfg"].astype("f4")


class IBL:
    ALPHAS = ALPHAS
    SAMPLES = SAMPLES

    def __init__(self, ctx, *, alphas=ALPHAS, samples=SAMPLES, layer_width: int = LAYER_WIDTH,
                 use_cache: bool = True, fis_bias: float = 1.0):
        if len(alphas) != len(samples) or not 2 <= len(alphas) <= MAX_LEVELS or alphas[0] != 0.0 \
                or any(b <= a for a, b in zip(alphas, alphas[1:])):
            raise ValueError("alphas must start at 0, increase, and match samples (2..8 levels)")
        self.ctx = ctx
        self.alphas = tuple(float(a) for a in alphas)
        self.samples = tuple(int(s) for s in samples)
        self.layer_width = int(layer_width)
        self.use_cache = use_cache
        self.fis_bias = float(fis_bias)
        #: a cache miss draws with a quick low-resolution prefilter (``QUICK_LAYER_WIDTH``) instead
        #: of waiting for the full one; ``provisional`` then holds the map's cache key and
        #: ``pending_map`` the map, for whoever prefilters it fully into the disk cache
        self.defer = False
        self.provisional = None
        self.pending_map = None
        self.stats: dict = {}
        self._key = None
        self._uploaded = None       # the cache key of the map in ``map_tex``
        self._content_last = None   # (ident, map, key, settings) of the last map asked for
        self.map_tex = None
        self.prefiltered = None
        self.dfg_tex = None
        self.dfg = None  # (size, size, 2) float32, table[i, j] = (A, B) at NoV_i, alpha_j
        self.sh = np.zeros((9, 3))
        self.map_size = (0, 0)
        self.layer_size = (0, 0)
        self.prefiltered_data = None  # (levels - 1, h, w, 3) float32
        self.cube = None
        self._cube_key = None
        self._programs = {}
        self._vaos = {}
        self._dfg_s = 0.0
        self.dfg_job = None  # the DFGPass being made a band at a time (``ensure_dfg(rows)``)
        self._quick_sh_source = None

    # ------------------------------------------------------------------ helpers
    def _program(self, name: str):
        prog = self._programs.get(name)
        if prog is None:
            prog = program_recipe(name).build(self.ctx)
            self._programs[name] = prog
            self._vaos[name] = self.ctx.vertex_array(prog, [])
        return prog

    def program_recipes(self) -> dict[str, Recipe]:
        """How each program built so far is made (name -> Recipe), for hot reload."""
        return {name: program_recipe(name) for name in self._programs}

    def replace_program(self, name: str, prog) -> None:
        """Use ``prog`` (built from ``program_recipes()[name]``) from now on, release the one it
        replaces, and drop what the old one computed, so the next use recomputes it."""
        old, old_vao = self._programs.get(name), self._vaos.get(name)
        self._programs[name] = prog
        self._vaos[name] = self.ctx.vertex_array(prog, [])
        if old_vao is not None:
            old_vao.release()
        if old is not None:
            old.release()
        # the disk cache is keyed by the map and the settings, not by shader sources: bypass it
        # (and never store results of an edited shader) for the rest of this session
        self.use_cache = False
        if name == "ibl_dfg" and self.dfg_tex is not None:
            self.dfg_tex.release()
            self.dfg_tex = None
        if name == "ibl_dfg" and self.dfg_job is not None:  # its bands drawn so far are the old program's
            self.dfg_job.release()
            self.dfg_job = None
        if name in ("ibl_prefilter", "ibl_dfg"):  # prefiltered again (the mip chain is numpy's: kept)
            self._key = None
            self._last_ident = None
        if name == "ibl_cubemap":
            self._cube_key = None

    def _draw(self, name: str, fbo, viewport):
        """One fullscreen triangle into ``fbo``; the caller's framebuffer binding is restored
        (so set_environment may run between a renderer's passes)."""
        prev = self.ctx.fbo
        fbo.use()
        fbo.viewport = viewport
        try:
            self._vaos[name].render(vertices=3)
        finally:
            try:
                prev.use()
            except Exception:  # noqa: BLE001 - the previous one was released: nothing to restore
                pass

    def _target(self, w: int, h: int):
        tex = self.ctx.texture((w, h), 4, dtype="f4")
        tex.filter = (self.ctx.NEAREST, self.ctx.NEAREST)
        return tex, self.ctx.framebuffer(color_attachments=[tex])

    def _settings(self) -> dict:
        return {"alphas": self.alphas, "samples": self.samples, "layer_width": self.layer_width,
                "fis_bias": self.fis_bias, "estimator": "ggx-dcos-n=v=r-nol-weighted-fis"}

    def _map_uniforms(self, prog, rotation_deg: float = 0.0):
        w, h = self.map_size
        _set(prog, "u_env_rot", np.ascontiguousarray(rotation_y(-rotation_deg).T, dtype="f4").tobytes())
        _set(prog, "u_env_size", (float(w), float(h)))
        _set(prog, "u_env_max_lod", float(len(mip_sizes(w, h)) - 1))
        al = np.zeros(MAX_LEVELS, "f4")
        al[: len(self.alphas)] = self.alphas
        _set(prog, "u_env_alphas", al.tobytes())
        _set(prog, "u_env_num_levels", len(self.alphas))

    # ------------------------------------------------------------------ environment
    def set_environment(self, latlong: np.ndarray | None, constant=None) -> None:
        """Build (or load from the disk cache) every texture for ``latlong`` (float32 (H, W, 3)
        radiance, intensity applied, rotation not applied) or, when it is None, for the constant
        radiance ``constant`` (3,) (black if that is None too). No work if the content is the
        one already set."""
        t0 = time.perf_counter()
        # Called every frame: the same (read-only, cached) map array or the same constant needs
        # no hash. The array is held, so its identity cannot be reused by another one.
        ident = _ident(latlong, constant)
        if self._key is not None and _same(getattr(self, "_last_ident", None), ident):
            if self.provisional is None or not cache.path_for(self.provisional).is_file():
                self.stats.update({"unchanged": True, "hash_s": 0.0, "prefilter_passes": 0})
                return
            self._key = None  # the full prefilter is in the disk cache now: read it below
        img, key = self._content(latlong, constant, ident)
        t_hash = time.perf_counter() - t0
        if key == self._key:
            self.stats.update({"unchanged": True, "hash_s": t_hash, "prefilter_passes": 0})
            self._last_ident = ident
            return
        tc = time.perf_counter()
        self._program("ibl_prefilter")
        t_compile = time.perf_counter() - tc
        self.ensure_dfg()
        h, w = img.shape[:2]
        lw = min(self.layer_width, w)
        lh = max(1, min(self.layer_width // 2, h))
        nl = len(self.alphas) - 1

        t1 = time.perf_counter()
        if self._uploaded != key:  # not already by ``upload_map``
            self._upload_map(img)
            self._uploaded = key
        t_map = time.perf_counter() - t1

        cached = False
        passes = 0
        t2 = time.perf_counter()
        hit = cache.load(key, expect={"prefiltered": (nl, lh, lw, 3), "sh": (9, 3)}) if self.use_cache else None
        provisional = None
        used = self.samples
        if hit is not None:
            pre = hit["prefiltered"].astype("f4")
            coeffs = hit["sh"].astype(np.float64)
            cached = True
            t_pre = t_sh = 0.0
        elif self.defer and self.use_cache and lw > QUICK_LAYER_WIDTH:  # for the meantime: see QUICK_LAYER_WIDTH
            lw, lh = min(QUICK_LAYER_WIDTH, lw), max(1, min(QUICK_LAYER_WIDTH // 2, lh))
            used = tuple(min(s, QUICK_SAMPLES) for s in self.samples)
            pre = self._prefilter(lw, lh, samples=used)
            passes = 1
            t_pre = time.perf_counter() - t2
            from viewer.environment.sh import project_latlong

            t3 = time.perf_counter()
            # SH9 of the map's mip level at most SH_QUICK_WIDTH wide (a solid-angle weighted box
            # filter of the map: its l <= 2 bands are the map's to well under a percent), for the
            # meantime as the quick prefilter: the full one brings the full map's
            coeffs = project_latlong(self._quick_sh_source if self._quick_sh_source is not None else img)
            t_sh = time.perf_counter() - t3
            provisional = key
        else:
            pre = self._prefilter(lw, lh)
            passes = 1
            t_pre = time.perf_counter() - t2
            t3 = time.perf_counter()
            from viewer.environment.sh import project_latlong

            coeffs = project_latlong(img)
            t_sh = time.perf_counter() - t3
            if self.use_cache:
                cache.store(key, {"prefiltered": pre, "sh": coeffs})
        t4 = time.perf_counter()
        if self.prefiltered is not None:
            self.prefiltered.release()
        arr = self.ctx.texture_array((lw, lh, nl), 3, np.ascontiguousarray(pre, dtype="f4").tobytes(), dtype="f4")
        arr.filter = (self.ctx.LINEAR, self.ctx.LINEAR)
        arr.repeat_x = True
        arr.repeat_y = False
        self.prefiltered = arr
        self.prefiltered_data = pre
        self.sh = coeffs
        self.layer_size = (lw, lh)
        self._key = key
        self.provisional = provisional
        self.pending_map = img if provisional is not None else None
        self._last_ident = ident  # only once everything for it is built
        self._cube_key = None
        t_up = time.perf_counter() - t4
        self.stats = {"cached": cached, "prefilter_passes": passes, "unchanged": False,
                      "provisional": provisional is not None,
                      "prefilter_s": t_pre, "sh_s": t_sh, "map_s": t_map, "hash_s": t_hash,
                      "upload_s": t_up, "compile_s": t_compile, "dfg_s": self._dfg_s,
                      "total_s": time.perf_counter() - t0,
                      "levels": len(self.alphas), "alphas": self.alphas, "samples": used,
                      "map_size": (w, h), "layer_size": (lw, lh)}

    def _content(self, latlong, constant, ident):
        """(the map as drawn, its cache key) for ``set_environment``'s arguments; the last
        map's (by ``ident``, the array's identity or the constant) without hashing it again."""
        last, settings = self._content_last, self._settings()
        if last is not None and last[3] == settings and _same(last[0], ident):
            return last[1], last[2]
        if latlong is None:
            c = np.zeros(3) if constant is None else np.broadcast_to(np.asarray(constant, float), (3,))
            w, h = CONSTANT_MAP_SIZE
            img = sanitize_map(np.broadcast_to(c, (h, w, 3)))
        else:
            img = sanitize_map(latlong)
        key = cache.content_key(img, settings)
        self._content_last = (ident, img, key, settings)  # img: the scene's own array where it was clean
        return img, key

    def map_uploaded(self, latlong: np.ndarray | None, constant=None) -> bool:
        """Whether the map of ``set_environment(latlong, constant)`` and its mip chain are on
        the GPU already (that call then makes the prefilter alone)."""
        last = self._content_last
        return last is not None and self._uploaded == last[2] and last[3] == self._settings() \
            and _same(last[0], _ident(latlong, constant))

    def upload_map(self, latlong: np.ndarray | None, constant=None) -> None:
        """The first half of ``set_environment(latlong, constant)``: the map and its mip chain
        (the window makes each half in a frame of its own: ``viewer.app.view_prep``)."""
        img, key = self._content(latlong, constant, _ident(latlong, constant))
        if self._uploaded != key:
            self._upload_map(img)
            self._uploaded = key

    def _upload_map(self, img: np.ndarray):
        """The map with its solid-angle weighted mip chain (``latlong.mip_chain``)."""
        ctx = self.ctx
        h, w = img.shape[:2]
        chain = mip_chain(img)
        # the first level at most SH_QUICK_WIDTH wide: the quick prefilter's SH source
        self._quick_sh_source = next((lev for lev in chain[1:] if lev.shape[1] <= SH_QUICK_WIDTH), None)
        if self.map_tex is not None:
            self.map_tex.release()
        tex = ctx.texture((w, h), 3, chain[0].tobytes(), dtype="f4")
        tex.build_mipmaps()  # allocates the chain (GL's box filter); every level is overwritten
        for k, level in enumerate(chain[1:], start=1):
            tex.write(level.tobytes(), level=k)
        tex.filter = (ctx.LINEAR_MIPMAP_LINEAR, ctx.LINEAR)
        tex.repeat_x = True
        tex.repeat_y = False
        self.map_tex = tex
        self.map_size = (w, h)

    def _prefilter(self, lw: int, lh: int, samples=None) -> np.ndarray:
        """All prefiltered levels in one draw into a (lw, lh * levels) target; (L, lh, lw, 3).
        ``samples``: per level, instead of ``self.samples``."""
        nl = len(self.alphas) - 1
        prog = self._program("ibl_prefilter")
        self.map_tex.use(texture_units.SOURCE)
        _set(prog, "u_env_map", texture_units.SOURCE)
        self._map_uniforms(prog, 0.0)
        _set(prog, "u_layer_size", (float(lw), float(lh)))
        _set(prog, "u_fis_bias", self.fis_bias)
        smp = np.zeros(MAX_LEVELS, "i4")
        smp[: len(self.samples)] = self.samples if samples is None else samples
        _set(prog, "u_samples", smp.tobytes())
        tex, fbo = self._target(lw, lh * nl)
        try:
            self._draw("ibl_prefilter", fbo, (0, 0, lw, lh * nl))
            data = np.frombuffer(tex.read(), dtype="f4").reshape(nl, lh, lw, 4)[..., :3]
            return np.ascontiguousarray(data)
        finally:
            release_gl(fbo, tex)

    # ------------------------------------------------------------------ DFG
    def ensure_dfg(self, rows: int | None = None) -> bool:
        """Make the DFG table (from the disk cache, else on the GPU) unless it is made; True
        once it is. ``rows``: on a cache miss, make only so much of it this call, for a frame's
        share (``viewer.app.view_prep``): the first call links the pass's program, each later
        one draws the next ``rows`` rows (``dfg_job``, a ``DFGPass``); ``None``: all of it now."""
        if self.dfg_tex is not None:
            return True
        t0 = time.perf_counter()
        table = None
        if self.dfg_job is None:
            self._dfg_s = 0.0
            table = _dfg_on_disk() if self.use_cache else None
            if table is None:
                self.dfg_job = DFGPass(self, DFG_SIZE, DFG_SAMPLES)
                if rows is not None:
                    self._dfg_s += time.perf_counter() - t0
                    return False
        if table is None:
            job = self.dfg_job
            try:
                if not job.step(rows):
                    self._dfg_s += time.perf_counter() - t0
                    return False
                table = job.result()
            finally:
                if job.tex is None:  # read back, or failed: released
                    self.dfg_job = None
            if self.use_cache:
                cache.store(_dfg_key(), {"dfg": table}, kind="dfg")
        tex = self.ctx.texture((DFG_SIZE, DFG_SIZE), 2, np.ascontiguousarray(table).tobytes(), dtype="f4")
        tex.filter = (self.ctx.LINEAR, self.ctx.LINEAR)
        tex.repeat_x = False
        tex.repeat_y = False
        self.dfg_tex = tex
        self.dfg = table
        self._dfg_s += time.perf_counter() - t0
        return True

    # ------------------------------------------------------------------ cube map
    def cubemap(self, size: int | None = None, rotation_deg: float = 0.0, supersample: int = 1):
        """The map as a float RGB ``TextureCube`` (faces in GL order, linear filtering with a
        mip chain), resampled on the GPU: texel = mean of ``supersample``^2 bilinear lookups, as
        ``viewer.environment.latlong.to_cubemap``. Default size: map width / 4."""
        self._require_env()
        ctx = self.ctx
        size = int(size or max(1, self.map_size[0] // 4))
        key = (self._key, size, float(rotation_deg), int(supersample))
        if self.cube is not None and self._cube_key == key:
            return self.cube
        prog = self._program("ibl_cubemap")
        self.map_tex.use(texture_units.SOURCE)
        _set(prog, "u_env_map", texture_units.SOURCE)
        self._map_uniforms(prog, rotation_deg)
        _set(prog, "u_face_size", float(size))
        _set(prog, "u_supersample", int(supersample))
        faces = []
        tex, fbo = self._target(size, size)
        try:
            for f in range(6):
                _set(prog, "u_face", f)
                self._draw("ibl_cubemap", fbo, (0, 0, size, size))
                faces.append(np.frombuffer(tex.read(), dtype="f4").reshape(size, size, 4)[..., :3].copy())
        finally:
            release_gl(fbo, tex)
        if self.cube is not None:
            self.cube.release()
        cube = ctx.texture_cube((size, size), 3, None, dtype="f4")
        for f in range(6):
            cube.write(f, np.ascontiguousarray(faces[f]).tobytes())
        cube.build_mipmaps()
        cube.filter = (ctx.LINEAR_MIPMAP_LINEAR, ctx.LINEAR)
        self.cube = cube
        self.cube_data = np.stack(faces)  # (6, size, size, 3), rows t, columns s
        self._cube_key = key
        return cube

    # ------------------------------------------------------------------ binding
    def _require_env(self):
        if self._key is None:
            self.set_environment(None, np.zeros(3))

    def bind(self, prog, rotation_deg: float = 0.0, first_unit: int = texture_units.IBL) -> None:
        """Bind the textures to units first_unit.. and set every uniform of common/ibl.glsl
        (those the compiler dropped are skipped)."""
        self._require_env()
        self.map_tex.use(first_unit)
        self.prefiltered.use(first_unit + 1)
        self.dfg_tex.use(first_unit + 2)
        _set(prog, "u_env_map", first_unit)
        _set(prog, "u_env_prefiltered", first_unit + 1)
        _set(prog, "u_env_dfg", first_unit + 2)
        if self.cube is not None:
            self.cube.use(first_unit + 3)
            _set(prog, "u_env_cube", first_unit + 3)
        self._map_uniforms(prog, rotation_deg)
        _set(prog, "u_env_sh", np.ascontiguousarray(self.sh, dtype="f4").tobytes())

    def release(self):
        for t in (self.map_tex, self.prefiltered, self.dfg_tex, self.cube):
            if t is not None:
                t.release()
        self.map_tex = self.prefiltered = self.dfg_tex = self.cube = None
        if self.dfg_job is not None:
            self.dfg_job.release()
            self.dfg_job = None
        self._uploaded = self._content_last = None
        for v in self._vaos.values():
            v.release()
        for p in self._programs.values():
            p.release()
        self._vaos.clear()
        self._programs.clear()
        self._key = None
