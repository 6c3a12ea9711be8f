"""The Sampling tab: the sampler's histogram beside its integrated pdf and their difference (in
standard deviations), the chi-square statistic and p-value, and a point cloud of sampled
directions, for one material at the panel's (theta_i, phi). The numbers are
``viewer.plots.sampling_histogram`` (the test suite's chi-square cells)."""

from __future__ import annotations

import json

import numpy as np
from imgui_bundle import imgui, implot

from viewer import plots

SAMPLING_SAMPLES = 50_000   # per histogram in the window (about 0.2-1 s; `plot` takes --samples)
PHI_TICKS = (0.0, 180.0, 360.0)  # three ticks fit a third of a docked panel (implot's defaults collide)
_sampling_cache: dict = {}


def sampling_data(p, theta_i: float, phi: float, cached=None):
    """``plots.sampling_histogram`` for the window, cached per (parameters, angles); through
    ``cached(key, fn)`` (the panel's: None while its worker computes it) when given."""
    key = (json.dumps(p.to_plain(), sort_keys=True, default=str), round(theta_i, 3), round(phi, 3))
    if cached is not None:
        return cached(("sampling",) + key,
                      lambda: plots.sampling_histogram(p, theta_i, phi, samples=SAMPLING_SAMPLES, seed=0))
    if key not in _sampling_cache:
        if len(_sampling_cache) > 32:
            _sampling_cache.clear()
        _sampling_cache[key] = plots.sampling_histogram(p, theta_i, phi, samples=SAMPLING_SAMPLES, seed=0)
    return _sampling_cache[key]


def headline(d) -> str:
    """The tab's first line: the test's verdict first (p), then what it was run on, so a narrow
    panel wraps the details, never the p-value."""
    return (f"chi-square p = {d['p_value']:.3g} ({d['chi2']:.1f} over {d['dof']} dof); wo at theta "
            f"{d['theta_i']:.1f} deg, phi {d['phi']:.0f} deg; {d['samples']} samples")


class SamplingTab:
    """``draw(names, materials, theta_i, phi)``; the material shown is ``material``."""

    def __init__(self):
        self.material = None
        self.shown = None   # the last data drawn (kept while a slider is held)

    def draw(self, names, materials, theta_i: float, phi: float, cached=None) -> None:
        ok = [n for n in names if "sampling" in plots.applicable_kinds(materials[n])]
        skipped = [n for n in names if n not in ok]
        if not ok:
            imgui.text_wrapped("no shown material has a sampled density (delta lobes only): "
                               + ", ".join(skipped))
            return
        if self.material not in ok:
            self.material = ok[0]
        ch, i = imgui.combo("material##sampling", ok.index(self.material), ok)
        if ch:
            self.material = ok[i]
        p = materials[self.material]
        if imgui.is_any_item_active() and self.shown is not None:
            d = self.shown  # a slider is held: recompute when it is released
        else:
            d = sampling_data(p, theta_i, phi, cached)
            if d is None and (self.shown is None or self.shown.get("material") != self.material):
                imgui.text_wrapped(f"computing the sampling histogram for {self.material} ...")
                return
            if d is None:
                d = self.shown
                imgui.text_wrapped("(computing the new histogram ... drawn as before meanwhile)")
            else:
                self.shown = dict(d, material=self.material)
        imgui.text_wrapped(headline(d))
        if skipped:
            imgui.push_style_color(imgui.Col_.text, imgui.get_style_color_vec4(imgui.Col_.text_disabled))
            imgui.text_wrapped(f"(delta lobes, not sampled: {', '.join(skipped)})")
            imgui.pop_style_color()
        avail = imgui.get_content_region_avail()
        w = max(120.0, (avail.x - 2 * imgui.get_style().item_spacing.x) / 3)
        h = max(120.0, avail.y * 0.48)
        lo = -1.0 if d["sphere"] else 0.0
        vmax = max(float(np.max(d["observed"])), float(np.max(d["expected"])), 1e-12)
        dmax = max(3.0, float(np.abs(d["difference"]).max()))
        grids = (("histogram", d["observed"], 0.0, vmax, implot.Colormap_.viridis),
                 ("integrated pdf", d["expected"], 0.0, vmax, implot.Colormap_.viridis),
                 ("difference (sigma)", d["difference"], -dmax, dmax, implot.Colormap_.rd_bu))
        # each title over its plot where it fits whole, else all three in one wrapped line above
        # (a title is centred over the plot area, which is the frame less the cos theta axis)
        fits = all(imgui.calc_text_size(g[0]).x <= w - 70 * imgui.get_font_size() / 16.0 for g in grids)
        if not fits:
            imgui.text_wrapped("left to right: " + ", ".join(g[0] for g in grids))
        for j, (title, a, vmin, vm, cmap) in enumerate(grids):
            if j:
                imgui.same_line()
            implot.push_colormap(cmap)
            if implot.begin_plot(f"{title if fits else ''}##samp{j}", imgui.ImVec2(w, h)):
                implot.setup_axes("phi (deg)", "cos theta")
                implot.setup_axis_ticks(implot.ImAxis_.x1, list(PHI_TICKS))
                implot.setup_axes_limits(0.0, 360.0, lo, 1.0, implot.Cond_.always)
                implot.plot_heatmap(f"##h{j}", np.ascontiguousarray(a, np.float64), vmin, vm, "",
                                    implot.Point(0.0, lo), implot.Point(360.0, 1.0))
                implot.end_plot()
            implot.pop_colormap()
        pts = np.asarray(d["points"], np.float64)
        # the colours said in words, not in a legend box over the points
        imgui.text_wrapped("sampled directions seen from above: blue above the surface, red below; orange: wo")
        size = min(avail.x, max(120.0, imgui.get_content_region_avail().y))
        if implot.begin_plot("##cloud", imgui.ImVec2(size, size), implot.Flags_.equal | implot.Flags_.no_legend):
            implot.setup_axes("x (tangent)", "y")
            implot.setup_axes_limits(-1.05, 1.05, -1.05, 1.05, implot.Cond_.always)
            t = np.linspace(0.0, 2 * np.pi, 121)
            implot.plot_line("##horizon", np.cos(t), np.sin(t))
            up = pts[:, 2] >= 0
            for sel, col, lab in ((up, (0.12, 0.47, 0.71), "above"), (~up, (0.84, 0.15, 0.16), "below")):
                if np.any(sel):
                    implot.plot_scatter(lab, np.ascontiguousarray(pts[sel, 0]), np.ascontiguousarray(pts[sel, 1]),
                                        implot.Spec(marker_fill_color=imgui.ImVec4(*col, 0.7),
                                                    marker_line_color=imgui.ImVec4(*col, 0.7), marker_size=1.5))
            wo = np.asarray(d["wo"], np.float64)
            implot.plot_line("wo", np.array([0.0, wo[0]]), np.array([0.0, wo[1]]),
                             implot.Spec(line_color=imgui.ImVec4(0.95, 0.55, 0.1, 1.0), line_weight=2.5))
            implot.end_plot()


def draw(panel, names, materials):
    panel.sampling.draw(names, materials, panel.theta_i, panel.phi, panel.cached)
