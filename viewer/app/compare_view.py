"""The window's compare views: raster only, reference only, a split with a draggable divider,
side by side, and difference heat maps (absolute and relative) with a colour bar, its scale and
the live RMSE and relative MSE.

Both halves go through the same exposure / tone-mapping pass (``Renderer.tonemap_to``), so
they are shown alike. The metrics compare the reference (rendered at half the view's
resolution) with the raster image box-filtered 2 x 2 down to the same pixels, the filter of
docs/conventions.md (``brdf-viewer compare`` does the same with a supersampled raster). The
window's thread only reads the raster back: the filter, the metrics and the heat map are
measured on a worker thread and adopted by a later frame (the first RMSE of a 672x540
reference took 0.3-0.45 s of the window's thread).
"""

from __future__ import annotations

import time
from typing import NamedTuple

import numpy as np

from viewer.app.layout import fit_rect
from viewer.image.compare import auto_scale, error_map, metrics, ramp

MODES = ("raster", "reference", "split", "side by side", "difference", "relative difference")
USES_REFERENCE = frozenset(MODES[1:])
# what the view says before the reference's first pass (its side of the view stays empty)
PENDING = "reference: first pass coming"
PREVIEW = "reference: coarse preview, first pass coming"
PENDING_DIFFERENCE = "difference: waiting for the reference's first pass"
METRICS_INTERVAL_S = 0.5  # recompute RMSE / relMSE at most this often (a readback + numpy pass)


def box_down(img: np.ndarray, shape: tuple[int, int]) -> np.ndarray:
    """Average ``img`` (H, W, 3) down to ``shape`` (h, w) by whole-pixel boxes; H >= h, W >= w.
    Exact 2 x 2 means when H = 2h and W = 2w; otherwise each output pixel averages the input
    pixels whose centres fall inside it."""
    h, w = shape
    H, W = img.shape[:2]
    if H == 2 * h and W == 2 * w:
        return img.reshape(h, 2, w, 2, -1).mean(axis=(1, 3))
    rows = np.minimum((np.arange(H) + 0.5) * h / H, h - 1).astype(int)
    cols = np.minimum((np.arange(W) + 0.5) * w / W, w - 1).astype(int)
    out = np.zeros((h, w, img.shape[2]))
    cnt = np.zeros((h, w, 1))
    np.add.at(out, (rows[:, None], cols[None, :]), img)
    np.add.at(cnt, (rows[:, None], cols[None, :]), 1.0)
    return out / np.maximum(cnt, 1.0)


def upload_rgb(ctx, tex, img: np.ndarray):
    """Write an (H, W, 3) image (row 0 = top) into an RGBA32F texture, GL's rows bottom-up;
    ``tex`` is reused when its size fits, else released and replaced. Returns the texture."""
    h, w = img.shape[:2]
    rgba = np.ones((h, w, 4), "f4")
    rgba[..., :3] = img[::-1]
    if tex is None or tex.size != (w, h):
        if tex is not None:
            tex.release()
        tex = ctx.texture((w, h), 4, dtype="f4")
    tex.write(rgba.tobytes())
    return tex


class _Job(NamedTuple):
    kind: str        # "metrics" or "heat"
    key: tuple       # metrics: (the reference pass, the raster frame); heat: (that, relative, scale)
    ref_key: object  # the reference's view (scene, camera, size, options) it is taken on
    spp: int
    generation: int  # CompareView's count of forgotten metrics when it was asked for
    future: object


def heat_image(small, ref, wanted):
    """A heat map on the worker thread: {"heat": (linear RGB image, its scale, ``wanted``)};
    ``wanted`` = (relative, the scale asked for or None: the 99th percentile)."""
    relative, scale = wanted
    err = error_map(small, ref, relative)
    top = auto_scale(err) if scale is None else scale
    return {"heat": (ramp(err / max(top, 1e-30)).astype(np.float32), top, wanted)}


def measure(raster, ref, small_key, heat_wanted):
    """The worker thread's part of a measurement: the raster box-filtered to the reference's
    pixels, the metrics, and the heat map a difference view shows (``heat_wanted``, or None)."""
    h, w = small_key[1:]
    small = raster if raster.shape[:2] == (h, w) else box_down(raster, (h, w)).astype(np.float32)
    out = {"small": small, "small_key": small_key}
    if not (np.isfinite(small).all() and np.isfinite(ref).all()):
        out["metrics"] = {"error": "non-finite pixels"}
        return out
    out["metrics"], out["pair"] = metrics(small, ref), (small, ref)
    if heat_wanted is not None:
        out.update(heat_image(small, ref, heat_wanted))
    return out


class CompareView:
    metrics_for = None  # the reference's key (scene, camera, size, options) the metrics were taken on

    def __init__(self, ctx):
        self.ctx = ctx
        self.mode = "raster"
        self.split = 0.5              # divider position, fraction of the view's width
        self.dragging = False
        self.metrics: dict | None = None
        self.metrics_spp = 0
        self.scale = 1.0              # heat map: the error at the top of the colour bar
        self.auto_scale = True
        self._heat_tex = None
        self._heat_key = None
        self._raster_small = None     # (key, array): the raster box-filtered to the reference's size
        self._pair = None             # (raster box-filtered, reference) the metrics were taken of
        self._metrics_key = None      # (the reference pass, the raster frame) of the metrics
        self._last_metrics_t = 0.0
        self._pool = None             # the worker thread measuring (started on first use)
        self._jobs: list[_Job] = []   # measurements under way, in the order asked
        self._generation = 0          # how often the metrics were forgotten (jobs carry it)
        self._view_key = None         # the reference's view the metrics are (being) taken on

    # ------------------------------------------------------------------ layout
    @property
    def uses_reference(self) -> bool:
        return self.mode in USES_REFERENCE

    def raster_rect(self, view):
        """Where the raster image goes (framebuffer pixels) and the size to render it at. Side by
        side fits the whole view's framing into each half (letterboxed), so nothing is cropped."""
        x, y, w, h = view
        if self.mode == "side by side":
            return fit_rect(w, h, (x, y, w // 2, h))
        return view

    def reference_rect(self, view):
        x, y, w, h = view
        if self.mode == "side by side":
            return fit_rect(w, h, (x + w // 2, y, w - w // 2, h))
        return view

    # ------------------------------------------------------------------ metrics
    def forget_metrics(self) -> None:
        """No metrics (and no heat map) until they are taken again: the view they were taken on
        is gone. A measurement under way for it is not adopted either."""
        self.metrics, self._pair, self._metrics_key, self.metrics_for = None, None, None, None
        self._heat_key, self._view_key = None, None
        self._generation += 1   # what is under way was asked for that view: never adopted

    def follow(self, ref_key) -> None:
        """The reference's view is now ``ref_key`` (scene, camera, size, options): metrics taken
        or under way on another one are forgotten."""
        if ref_key != self._view_key:
            self.forget_metrics()
            self._view_key = ref_key

    def _executor(self):
        if self._pool is None:
            from concurrent.futures import ThreadPoolExecutor

            self._pool = ThreadPoolExecutor(max_workers=1, thread_name_prefix="brdf-viewer-metrics")
        return self._pool

    def _submit(self, kind, key, ref_key, spp, fn, *args) -> None:
        self._jobs.append(_Job(kind, key, ref_key, spp, self._generation, self._executor().submit(fn, *args)))

    def _heat_wanted(self, relative=None):
        """The heat map ``relative`` (default: the one the view draws, None when the view is not
        a difference view) as asked for: (relative, the scale asked for or None for automatic)."""
        if relative is None:
            if self.mode not in ("difference", "relative difference"):
                return None
            relative = self.mode == "relative difference"
        return (relative, None if self.auto_scale else float(self.scale))

    def _adopt(self) -> None:
        """Take the measurements finished on the worker thread, in the order asked; those asked
        for before the metrics were last forgotten (another view of the reference) are dropped,
        never shown beside this one."""
        while self._jobs and self._jobs[0].future.done():
            job = self._jobs.pop(0)
            out = job.future.result()
            if job.generation != self._generation:
                continue
            if job.kind == "metrics":
                self._raster_small = out["small_key"], out["small"]
                self._metrics_key, self.metrics_for = job.key, job.ref_key
                self.metrics, self.metrics_spp, self._pair = out["metrics"], job.spp, out.get("pair")
            heat = out.get("heat")
            if heat is not None:
                rgb, self.scale, wanted = heat
                self._heat_tex = upload_rgb(self.ctx, self._heat_tex, rgb)
                self._heat_key = (self._metrics_key,) + wanted

    def settle(self) -> None:
        """Wait for the measurements under way and adopt them (tests, screenshots: one snapshot,
        never "whatever is newest")."""
        for job in list(self._jobs):
            job.future.result()
        self._adopt()

    def update_metrics(self, renderer, raster_tex, raster_version, ref_view):
        """Measure RMSE / relMSE when the reference has a new pass or the raster image changed
        (at most every METRICS_INTERVAL_S). Only the raster's readback is on this (the GL)
        thread: the box filter, the metrics and a difference view's heat map are computed on a
        worker thread and adopted by a later call, the frames meanwhile showing the last ones.
        Metrics taken on another view of the reference (its ``key``: scene, camera, size,
        options) are dropped first, never shown beside this one."""
        self.follow(ref_view.key)
        self._adopt()
        img = ref_view.latest()
        if img is None or raster_tex is None or img[1] == 0:  # nothing, or the coarse preview
            self.metrics = None
            return
        if self._jobs:
            return  # one measurement at a time: the worker's, then the next
        ref, spp = img
        key = (id(ref), raster_version)
        now = time.perf_counter()
        if key == self._metrics_key or (self.metrics is not None and now - self._last_metrics_t < METRICS_INTERVAL_S):
            return
        h, w = ref.shape[:2]
        small_key = (raster_version, h, w)
        if self._raster_small is not None and self._raster_small[0] == small_key:
            raster = self._raster_small[1]
        else:
            raster = renderer.read_linear(raster_tex)
            if raster.shape[0] < h or raster.shape[1] < w:
                return  # a preview-resolution raster: wait for the full-quality frame
        self._last_metrics_t = now
        self._submit("metrics", key, ref_view.key, spp, measure, raster, ref, small_key, self._heat_wanted())

    def heat_texture(self, relative: bool):
        """The heat map as a float texture (linear colours from the same ramp as `compare`),
        None before the first. A change of mode or scale is measured on the worker thread; the
        last heat map of the same kind is shown meanwhile."""
        if self._pair is None:
            return None
        wanted = self._heat_wanted(relative)
        key = (self._metrics_key,) + wanted
        if key != self._heat_key and not any(j.key == key for j in self._jobs):
            self._submit("heat", key, self.metrics_for, self.metrics_spp, heat_image, *self._pair, wanted)
        self._adopt()
        if self._heat_key is None or self._heat_key[1] != relative:
            return None
        return self._heat_tex

    # ------------------------------------------------------------------ drawing
    def draw(self, renderer, fbo, view, raster_tex, ref_tex, exposure, tonemap):
        """Compose the view into ``fbo`` (the screen) inside ``view`` = (x, y, w, h)."""
        ctx = self.ctx
        x, y, w, h = view
        m = self.mode
        if m == "split" and ref_tex is None:
            # no reference yet: the raster on its side only; the reference's side stays empty
            # under its label ("first pass coming"), never the raster shown as the reference
            if raster_tex is not None:
                ctx.scissor = (x, y, int(round(w * self.split)), h)
                try:
                    renderer.tonemap_to(fbo, raster_tex, exposure, tonemap, viewport=view)
                finally:
                    ctx.scissor = None
            return
        if m == "raster" or (ref_tex is None and m == "side by side"):
            if raster_tex is not None:
                renderer.tonemap_to(fbo, raster_tex, exposure, tonemap, viewport=self.raster_rect(view))
            return
        if m == "reference":
            if ref_tex is not None:
                renderer.tonemap_to(fbo, ref_tex, exposure, tonemap, viewport=view)
            return
        if m == "split":
            if raster_tex is not None:
                renderer.tonemap_to(fbo, raster_tex, exposure, tonemap, viewport=view)
            cut = int(round(w * self.split))
            ctx.scissor = (x + cut, y, w - cut, h)
            try:
                renderer.tonemap_to(fbo, ref_tex, exposure, tonemap, viewport=view)
            finally:
                ctx.scissor = None
            return
        if m == "side by side":
            if raster_tex is not None:
                renderer.tonemap_to(fbo, raster_tex, exposure, tonemap, viewport=self.raster_rect(view))
            renderer.tonemap_to(fbo, ref_tex, exposure, tonemap, viewport=self.reference_rect(view))
            return
        heat = self.heat_texture(relative=(m == "relative difference"))
        if heat is not None:  # the ramp is already a display colour: no exposure, no tone map
            renderer.tonemap_to(fbo, heat, 0.0, "none", viewport=view)

    # ------------------------------------------------------------------ imgui overlays
    def divider_x(self, view_logical) -> float:
        x, _, w, _ = view_logical
        return x + w * self.split

    def handle_mouse(self, imgui, view_logical) -> bool:
        """Drag the split divider; True when the mouse belongs to the divider this frame."""
        if self.mode != "split":
            self.dragging = False
            return False
        io = imgui.get_io()
        mx, my = io.mouse_pos.x, io.mouse_pos.y
        x, y, w, h = view_logical
        near = abs(mx - self.divider_x(view_logical)) <= 6 and y <= my <= y + h
        if near or self.dragging:
            imgui.set_mouse_cursor(imgui.MouseCursor_.resize_ew)
        if imgui.is_mouse_clicked(imgui.MouseButton_.left) and near:
            self.dragging = True
        if self.dragging:
            if imgui.is_mouse_down(imgui.MouseButton_.left):
                self.split = float(np.clip((mx - x) / max(w, 1), 0.0, 1.0))
            else:
                self.dragging = False
            return True
        return near

    def metrics_text(self, key=None) -> str:
        """The RMSE read-out, the same words in the panel and over the image (with the samples
        per pixel of the reference the metrics were taken of); empty when there is none, or when
        ``key`` (the reference's key now) is not the one they were taken on."""
        m = self.metrics
        if not (self.uses_reference and self.mode != "reference" and m and "rmse" in m):
            return ""
        if key != self.metrics_for:
            return ""
        return f"RMSE {m['rmse']:.4g}   relMSE {m['relative_mse']:.4g}   ({self.metrics_spp} spp)"

    def overlay_labels(self, view_logical, ref_spp: int, preview: bool = False, error: str = "",
                       estimator: str = "") -> list:
        """[(anchor x, text)] for the label row at the top of the view (``layout.overlay_layout``);
        ``preview``: the reference shows its coarse first image; ``error``: why there is no
        reference image (its one line stands where the label would); ``estimator``: the
        reference's integrator in words (``caustics.INTEGRATOR_LABELS``), after its spp."""
        x, y, w, h = view_logical
        more = f", {estimator}" if estimator else ""
        ref_label = f"reference ({ref_spp} spp{more})" if ref_spp else (PREVIEW if preview else PENDING)
        if error and not ref_spp and not preview:
            ref_label = f"reference: {error}"
        if self.mode in ("difference", "relative difference") and self._pair is None:
            return [(x, f"difference: no reference ({error})" if error else PENDING_DIFFERENCE)]
        if self.mode == "split":
            return [(x, "raster"), (self.divider_x(view_logical), ref_label)]
        if self.mode == "side by side":
            return [(x, "raster"), (x + w / 2, ref_label)]
        if self.mode == "reference":
            return [(x, ref_label)]
        return []

    def overlay_bars(self, view_logical) -> list:
        """[(owner rect, what)] of the colour bar of a difference view (none before there is a
        difference: a 0-1 bar over an empty view would claim a scale)."""
        if self.mode not in ("difference", "relative difference") or self._pair is None:
            return []
        from viewer.app.layout import Rect

        rel = self.mode == "relative difference"
        return [(Rect(*view_logical), "|raster - reference| / (reference + 0.01)" if rel else "|raster - reference|")]

    def draw_overlay(self, imgui, view_logical, lay: dict, label) -> None:
        """The divider and the labels into the boxes of ``lay`` (``layout.overlay_layout``)."""
        dl = imgui.get_background_draw_list()  # over the 3D view, under imgui windows
        x, y, w, h = view_logical
        white = imgui.get_color_u32(imgui.ImVec4(1, 1, 1, 1))
        if self.mode == "split":
            dx = self.divider_x(view_logical)
            k = imgui.get_font_size() / 16.0
            dl.add_line(imgui.ImVec2(dx, y), imgui.ImVec2(dx, y + h), white, 2.0 * k)
            dl.add_circle_filled(imgui.ImVec2(dx, y + h / 2), 7.0 * k, white)

    def release(self):
        if self._pool is not None:
            self._pool.shutdown(wait=True, cancel_futures=True)
            self._pool, self._jobs = None, []
        if self._heat_tex is not None:
            self._heat_tex.release()
            self._heat_tex = None


def draw_colour_bar(imgui, dl, lay: dict, j: int, label, scale: float, what: str, low: str = "0"):
    """Colour bar ``j`` of an overlay layout (``viewer.image.compare.ramp``): the ramp in ``bar{j}``,
    ``low`` and ``scale`` at its ends, ``what`` above it; ``label(rect, text)`` draws a text box."""
    r = lay[f"bar{j}"]
    n = 48
    for i in range(n):
        c = ramp(np.array([(i + 0.5) / n]))[0]
        srgb = np.where(c <= 0.0031308, 12.92 * c, 1.055 * np.power(c, 1 / 2.4) - 0.055)
        col = imgui.get_color_u32(imgui.ImVec4(float(srgb[0]), float(srgb[1]), float(srgb[2]), 1.0))
        dl.add_rect_filled(imgui.ImVec2(r.x + r.w * i / n, r.y), imgui.ImVec2(r.x + r.w * (i + 1) / n + 1, r.bottom), col)
    lo, hi = lay[f"bar{j}_lo"], lay[f"bar{j}_hi"]
    label(lo, low)
    txt = f"{scale:.3g}"
    label(hi, txt, align_right=True)
    label(lay[f"bar{j}_what"], what)
