"""The window's compare views: raster only, reference only, a split with a draggable divider,
side by side, and difference heat maps (absolute and relative) with a colour bar, its scale and
the live RMSE and relative MSE.

Both halves go through the same exposure / tone-mapping pass (``Renderer.tonemap_to``), so
they are shown alike. The metrics compare the reference (rendered at half the view's
resolution) with the raster image box-filtered 2 x 2 down to the same pixels, the filter of
docs/conventions.md (``brdf-viewer compare`` does the same with a supersampled raster).
"""

from __future__ import annotations

import time

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
        is gone."""
        self.metrics, self._pair, self._metrics_key, self.metrics_for = None, None, None, None

    def update_metrics(self, renderer, raster_tex, raster_version, ref_view):
        """Recompute RMSE / relMSE when the reference has a new pass or the raster image changed
        (at most every METRICS_INTERVAL_S). Metrics taken on another view of the reference (its
        ``key``: scene, camera, size, options) are dropped first, never shown beside this one."""
        if self.metrics_for != ref_view.key:
            self.forget_metrics()
        img = ref_view.latest()
        if img is None or raster_tex is None or img[1] == 0:  # nothing, or the coarse preview
            self.metrics = None
            return
        ref, spp = img
        key = (id(ref), raster_version)
        now = time.perf_counter()
        if key == self._metrics_key or (self.metrics is not None and now - self._last_metrics_t < METRICS_INTERVAL_S):
            return
        h, w = ref.shape[:2]
        if self._raster_small is None or self._raster_small[0] != (raster_version, h, w):
            big = renderer.read_linear(raster_tex)
            if big.shape[0] < h or big.shape[1] < w:
                return  # a preview-resolution raster: wait for the full-quality frame
            self._raster_small = ((raster_version, h, w), box_down(big, (h, w)).astype(np.float32))
        small = self._raster_small[1]
        self._metrics_key, self._last_metrics_t = key, now
        if not (np.isfinite(small).all() and np.isfinite(ref).all()):
            self.metrics, self._pair = {"error": "non-finite pixels"}, None
            self.metrics_for = ref_view.key
            return
        self.metrics = metrics(small, ref)
        self.metrics_spp = spp
        self.metrics_for = ref_view.key
        self._pair = (small, ref)

    def heat_texture(self, relative: bool):
        """The heat map as a float texture (linear colours from the same ramp as `compare`)."""
        if self._pair is None:
            return None
        key = (self._metrics_key, relative, self.auto_scale, None if self.auto_scale else self.scale)
        if key != self._heat_key:
            err = error_map(self._pair[0], self._pair[1], relative)
            if self.auto_scale:
                self.scale = auto_scale(err)
            self._heat_tex = upload_rgb(self.ctx, self._heat_tex, ramp(err / max(self.scale, 1e-30)))
            self._heat_key = key
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
