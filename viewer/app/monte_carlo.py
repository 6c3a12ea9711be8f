"""Monte Carlo made visible in the window: the reference's estimator settings (strategy, MIS
heuristic, Russian roulette), error views from its running per-pixel variance (standard error,
relative error, samples needed for a target error) as heat maps with a colour bar, a
convergence plot (estimated RMSE against spp, log-log, with the -1/2 slope and a stored curve of
another strategy). The plots window's *Sampling* tab is ``viewer.app.plot_tabs.sampling``.

The numbers come from ``viewer.image.variance``; this module only draws them. Use from the app::

    mc = MonteCarloPanel(ctx)
    mc.draw_settings(reference_view, compare_uses_reference)   # in the side panel
    mc.draw_windows(reference_view)                            # the convergence window
    mc.draw_view(renderer, fbo, rect, reference_view)          # after the compare view
    mc.draw_overlay(imgui, layout, j, label)                   # its colour bar (bar j)
"""

from __future__ import annotations

import time

import numpy as np

from viewer.image.compare import auto_scale, ramp
from viewer.reference_common.estimator import STRATEGIES, STRATEGY_LABELS
from viewer.image.variance import ERROR_VIEWS, error_view

VIEWS = ("off",) + ERROR_VIEWS
HEURISTICS = ("power", "balance")
_LUT = ramp(np.linspace(0.0, 1.0, 1024)).astype(np.float32)   # the ramp, 1024 steps (4x faster per frame)
_WHAT = {"standard error": "standard error of the mean (radiance)",
         "relative error": "relative error: standard error / (mean + 0.01)",
         "samples needed": "samples per pixel for the target relative error"}


class MonteCarloPanel:
    def __init__(self, ctx):
        self.ctx = ctx
        self.view = "off"            # one of VIEWS
        self.target = 0.01           # relative error the 'samples needed' view aims at
        self.auto_scale = True
        self.scale = 1.0
        self.show_convergence = False
        self.stored = None           # a ConvergenceCurve kept for comparison
        self.view_ms = 0.0           # last error map's compute + upload time
        self.map_stats: dict = {}    # of the last map: min, median, max
        self._tex = None
        self._key = None

    # ------------------------------------------------------------------ state
    @property
    def active(self) -> bool:
        """The reference must run (an error view or the convergence plot is shown)."""
        return self.view != "off" or self.show_convergence

    def set_options(self, ref_view, **options) -> None:
        """Change the reference's estimator (strategy, mis_heuristic, russian_roulette); the
        reference restarts on its next update."""
        for k, v in options.items():
            if k not in ref_view.options:
                raise ValueError(f"unknown reference option {k!r}; allowed: {', '.join(ref_view.options)}")
            ref_view.options[k] = v

    def store_curve(self, ref_view) -> bool:
        curve = ref_view.curve
        if curve is None or len(curve) < 2:
            return False
        self.stored = curve.copy(f"{STRATEGY_LABELS.get(curve.label, curve.label)} (stored)")
        return True

    # ------------------------------------------------------------------ side panel
    def draw_settings(self, ref_view, compare_uses_reference: bool) -> None:
        from imgui_bundle import imgui

        if not imgui.collapsing_header("Reference"):
            return
        was_active = self.active
        o = ref_view.options
        labels = [STRATEGY_LABELS[s] for s in STRATEGIES]
        ch, i = imgui.combo("strategy", STRATEGIES.index(o["strategy"]), labels)
        if imgui.is_item_hovered():
            imgui.set_tooltip("how the environment is reached; point and directional lights are always "
                              "next-event estimated")
        if ch:
            self.set_options(ref_view, strategy=STRATEGIES[i])
        if o["strategy"] == "mis":
            ch, i = imgui.combo("MIS heuristic", HEURISTICS.index(o["mis_heuristic"]), list(HEURISTICS))
            if ch:
                self.set_options(ref_view, mis_heuristic=HEURISTICS[i])
        ch, v = imgui.checkbox("Russian roulette", bool(o["russian_roulette"]))
        if ch:
            self.set_options(ref_view, russian_roulette=v)
        ch, i = imgui.combo("error view", VIEWS.index(self.view), list(VIEWS))
        if ch:
            self.view = VIEWS[i]
        if self.view == "samples needed":
            ch, v = imgui.slider_float("target rel. error", float(self.target), 0.001, 0.2, "%.3f",
                                       imgui.SliderFlags_.logarithmic)
            if ch and np.isfinite(v) and v > 0:
                self.target = float(v)
        if self.view != "off":
            ch, v = imgui.checkbox("auto scale (99th pct)##mc", self.auto_scale)
            if ch:
                self.auto_scale = v
            if not self.auto_scale:
                ch, v = imgui.slider_float("scale##mc", float(self.scale), 1e-4, 1e6, "%.4g",
                                           imgui.SliderFlags_.logarithmic)
                if ch and np.isfinite(v) and v > 0:
                    self.scale = float(v)
            if self.map_stats:
                s = self.map_stats
                imgui.text(f"median {s['median']:.3g}, max {s['max']:.3g} ({self.view_ms:.1f} ms)")
        _, self.show_convergence = imgui.checkbox("convergence plot", self.show_convergence)
        curve = ref_view.curve
        if curve is not None and len(curve):
            imgui.text(f"est. RMSE {curve.rmse[-1]:.4g} at {curve.spp[-1]} spp, slope {curve.fitted_slope():.2f}")
        if imgui.button("store curve"):
            self.store_curve(ref_view)
        if imgui.is_item_hovered():
            imgui.set_tooltip("keep this strategy's convergence curve, then switch strategy to compare")
        if self.stored is not None:
            imgui.same_line()
            if imgui.button("clear stored"):
                self.stored = None
        if was_active and not self.active and not compare_uses_reference:
            ref_view.stop(timeout=0)  # cancelled, it publishes nothing more: the frame never waits for it

    # ------------------------------------------------------------------ convergence window
    def draw_windows(self, ref_view) -> None:
        if not self.show_convergence or ref_view is None:
            return
        from imgui_bundle import imgui, implot

        imgui.set_next_window_size(imgui.ImVec2(460, 340), imgui.Cond_.first_use_ever)
        imgui.set_next_window_pos(imgui.ImVec2(420, 60), imgui.Cond_.first_use_ever)
        expanded, opened = imgui.begin("Convergence", self.show_convergence)
        if opened is False:
            self.show_convergence = False
        if expanded:
            curves = [c for c in (ref_view.curve, self.stored) if c is not None and len(c)]
            if implot.begin_plot("##convergence", imgui.ImVec2(-1, -1)):
                implot.setup_axes("samples per pixel", "estimated RMSE")
                implot.setup_axis_scale(implot.ImAxis_.x1, implot.Scale_.log10)
                implot.setup_axis_scale(implot.ImAxis_.y1, implot.Scale_.log10)
                implot.setup_legend(implot.Location_.north_east)
                if curves:  # log axes do not fit themselves to data that arrive over time
                    xs = [v for c in curves for v in c.spp]
                    ys = [v for c in curves for v in c.rmse]
                    implot.setup_axes_limits(min(xs) / 1.2, max(max(xs), min(xs) * 4) * 1.2, min(ys) / 1.5,
                                             max(ys) * 1.5, implot.Cond_.always)
                for j, c in enumerate(curves):
                    x = np.asarray(c.spp, np.float64)
                    y = np.asarray(c.rmse, np.float64)
                    label = c.label if j else STRATEGY_LABELS.get(c.label, c.label)
                    col = (0.12, 0.47, 0.71) if j == 0 else (0.84, 0.15, 0.16)
                    implot.plot_line(label, x, y, implot.Spec(line_color=imgui.ImVec4(*col, 1.0), line_weight=2.0))
                    sx, sy = c.slope_line()
                    implot.plot_line(f"slope -1/2##{j}", sx, sy,
                                     implot.Spec(line_color=imgui.ImVec4(*col, 0.5), line_weight=1.0))
                implot.end_plot()
        imgui.end()

    # ------------------------------------------------------------------ the view
    def heat_map(self, snap):
        """(map (H, W), linear RGB heat image) of the current error view for one reference
        snapshot (``ReferenceView.snapshot()``), or None (no snapshot, or the view is off)."""
        if snap is None or self.view == "off":
            return None
        err = error_view(self.view, snap.mean, snap.variance, snap.spp, self.target)
        err = np.where(np.isfinite(err), err, 0.0)
        if self.auto_scale:
            self.scale = auto_scale(err)
        t = np.clip(err * (1023.0 / max(self.scale, 1e-30)), 0.0, 1023.0)
        return err, _LUT[t.astype(np.int32)]

    def invalidate(self) -> None:
        """Recompute the error map on the next ``draw_view`` even when nothing changed."""
        self._key = None

    def draw_view(self, renderer, fbo, rect, ref_view) -> None:
        """Draw the error view into ``rect`` (framebuffer pixels) of ``fbo``, recomputed when the
        reference has a new pass or a setting changed."""
        if self.view == "off" or ref_view is None:
            return
        snap = ref_view.snapshot()   # one pass for the key and the map alike
        if snap is None:
            return
        key = (snap.version, snap.spp, self.view, self.target, self.auto_scale,
               None if self.auto_scale else self.scale)
        if key != self._key or self._tex is None:
            t0 = time.perf_counter()
            err, rgb = self.heat_map(snap)
            from viewer.app.compare_view import upload_rgb

            self._tex = upload_rgb(self.ctx, self._tex, rgb)
            self.map_stats = {"median": float(np.median(err)), "max": float(err.max())}
            self.view_ms = 1000 * (time.perf_counter() - t0)
            self._key = key
        renderer.tonemap_to(fbo, self._tex, 0.0, "none", viewport=rect)  # a display colour already

    def overlay_bars(self, view_logical) -> list:
        """[(owner rect, what)]: the error view's colour bar, for ``layout.overlay_layout``."""
        if self.view == "off" or self._tex is None:
            return []
        from viewer.app.layout import Rect

        what = _WHAT[self.view]
        if self.view == "samples needed":
            what += f" ({100 * self.target:g}%)"
        return [(Rect(*view_logical), what)]

    def draw_overlay(self, imgui, lay: dict, j: int, label) -> None:
        """Its colour bar into bar ``j`` of an overlay layout."""
        if self.view == "off" or self._tex is None:
            return
        from viewer.app.compare_view import draw_colour_bar

        draw_colour_bar(imgui, imgui.get_background_draw_list(), lay, j, label, self.scale,
                        self.overlay_bars((0, 0, 1, 1))[0][1])

    def release(self) -> None:
        if self._tex is not None:
            self._tex.release()
            self._tex = None
