"""The Spectral tab: one spectral material (``spectral = "NAME"``): n(lambda) and k(lambda);
R(theta, lambda) as an image with its colour scale and the RGB colour per angle beside it; the
errors of Schlick (with the spectral f0) and of the three-wavelength RGB Fresnel against the
spectral integral, per channel. The data are ``viewer.plots.spectral.spectral_data``, as in
``plot --kind spectral``."""

from __future__ import annotations

import math

import numpy as np
from imgui_bundle import imgui, implot

from viewer import plots
from viewer.app.plot_tabs.common import WAVELENGTH_TICKS, vec4


def nk_limits(n, k) -> tuple[float, float]:
    """The n, k plot's vertical range: from 0 where k is drawn (a metal's k dwarfs its n);
    about n's own span for a dielectric (k = 0), so SF11's 1.77-1.83 fills the plot instead of
    looking flat on an axis from 0."""
    n, k = np.asarray(n, float), np.asarray(k, float)
    if np.any(k > 0):
        return 0.0, max(float(n.max()), float(k.max()), 1.0) * 1.05
    lo, hi = float(n.min()), float(n.max())
    pad = max(0.1 * (hi - lo), 0.005)
    return lo - pad, hi + pad


def draw(panel, names, materials):
    from viewer.image.colour import to_srgb8
    from viewer.plots.spectral import rgb_over_one, spectral_data

    have = [n for n in names if plots.spectral_source(materials[n]) is not None]
    missing = [n for n in names if n not in have]
    if missing:
        panel.messages.append("no spectral table (spectral = \"NAME\"): " + ", ".join(missing))
    if not have:
        for m in panel.messages:
            imgui.text_wrapped(m)
        panel.messages = []
        return
    if panel.spectral_material not in have:
        panel.spectral_material = have[0]
    if len(have) > 1:
        imgui.push_item_width(180 * panel.font_k())
        ch, i = imgui.combo("material##spectral", have.index(panel.spectral_material), have)
        imgui.pop_item_width()
        if ch:
            panel.spectral_material = have[i]
    name = panel.spectral_material
    p = materials[name]
    d = panel.data("spectral", name, p, fn=lambda p=p: spectral_data(p))
    if panel.waiting({name: d}):
        return
    # three short lines (the docked panel's room goes to the plots); the table's description and
    # source in the first line's tooltip
    imgui.text_wrapped(f"{name}: {d['name']}, normal incidence RGB {np.round(d['rgb'][0], 2).tolist()}"
                       f"{rgb_over_one(d['rgb'][0])}")
    if imgui.is_item_hovered():
        imgui.set_tooltip(f"{d['description']}\n{d['source']}")
    imgui.text_wrapped(f"max |error| Schlick {d['max_err_schlick']:.3f}, 3 wavelengths (650/550/450 nm) "
                       f"{d['max_err_three']:.3f}")
    imgui.push_style_color(imgui.Col_.text, imgui.get_style_color_vec4(imgui.Col_.text_disabled))
    imgui.text_wrapped("R(theta, lambda); its right-hand column: the RGB colour per angle")
    imgui.pop_style_color()
    size = panel.plot_size(least=0.0)
    k = panel.font_k()
    full = size.x if size.x > 0 else imgui.get_content_region_avail().x
    bar = 70.0 * k  # the R(theta, lambda) colour scale's width (its ticks and label)
    sp = imgui.get_style().item_spacing.x
    half_w = max(150.0, (full - bar - 2 * sp) / 2)
    # the two rows of plots share the room left (a row no lower than 100 points: its axes' text)
    half_h = max(100.0 * k, (size.y - imgui.get_style().item_spacing.y) * 0.5)
    lam = np.ascontiguousarray(d["wavelength_nm"], dtype=np.float64)
    col = panel.colour(name)
    # no legend box: the axis names the two curves (a box over half a docked panel covered them)
    if implot.begin_plot("##spectral_nk", imgui.ImVec2(half_w, half_h), implot.Flags_.no_legend):
        implot.setup_axes("lambda (nm)", "n (solid), k (dots)")  # short: half a docked panel
        implot.setup_axis_ticks(implot.ImAxis_.x1, list(WAVELENGTH_TICKS))  # readable in half a panel
        lo, hi = nk_limits(d["n"], d["k"])
        panel.nk_range = (lo, hi)
        implot.setup_axes_limits(float(lam[0]), float(lam[-1]), lo, hi, implot.Cond_.always)
        implot.plot_line("n", lam, np.ascontiguousarray(d["n"], dtype=np.float64),
                         implot.Spec(line_color=vec4(col), line_weight=2.5))
        if np.any(np.asarray(d["k"]) > 0):
            kk = np.ascontiguousarray(d["k"], dtype=np.float64)
            implot.plot_line("k", lam, kk, implot.Spec(line_color=vec4(col, 0.8), line_weight=1.0))
            # dots every ~25 nm (a marker at every sample would draw a thick band)
            every = max(1, len(lam) // 16)
            implot.plot_scatter("k", np.ascontiguousarray(lam[::every]), np.ascontiguousarray(kk[::every]),
                                implot.Spec(line_color=vec4(col, 0.8), fill_color=vec4(col, 0.8),
                                            marker=implot.Marker_.circle, marker_size=3.0))
        implot.end_plot()
    imgui.same_line()
    R = np.ascontiguousarray(np.asarray(d["R"], dtype=np.float64)[::-1])  # row 0 = 90 deg, drawn on top
    rmax = 1.0  # reflectance: the colour scale spans all of it
    implot.push_colormap(implot.Colormap_.viridis)
    if implot.begin_plot("##spectral_R", imgui.ImVec2(half_w, half_h), implot.Flags_.no_legend):
        implot.setup_axes("lambda (nm)", "angle of incidence (deg)")
        implot.setup_axis_ticks(implot.ImAxis_.x1, list(WAVELENGTH_TICKS))
        x_sw0, x_sw1 = float(lam[-1]) + 10.0, float(lam[-1]) + 60.0  # the swatch column
        implot.setup_axes_limits(float(lam[0]), x_sw1, 0.0, 90.0, implot.Cond_.always)
        implot.plot_heatmap("R", R, 0.0, rmax, "", implot.Point(float(lam[0]), 0.0),
                            implot.Point(float(lam[-1]), 90.0))
        rgb = to_srgb8(np.clip(np.asarray(d["rgb"], dtype=np.float32), 0.0, 1.0))
        theta = np.asarray(d["theta"], dtype=np.float64)
        dl = implot.get_plot_draw_list()
        step = (theta[1] - theta[0]) / 2 if len(theta) > 1 else 0.5
        for t, c in zip(theta, rgb):
            a = implot.plot_to_pixels(x_sw0, float(min(t + step, 90.0)))
            b = implot.plot_to_pixels(x_sw1, float(max(t - step, 0.0)))
            # whole pixels, each band reaching the next: fractional edges left dark seams between them
            dl.add_rect_filled(imgui.ImVec2(round(a.x), math.floor(a.y)), imgui.ImVec2(round(b.x), math.ceil(b.y)),
                               imgui.get_color_u32(imgui.ImVec4(*(c / 255.0), 1.0)))
        implot.end_plot()
    imgui.same_line()
    implot.colormap_scale("R##scale", 0.0, rmax, imgui.ImVec2(bar, half_h), "%.2f")
    implot.pop_colormap()
    err_size = imgui.ImVec2(-1, half_h)
    panel.begin_frame_rect(err_size)
    # the legend under the plot (panel.legend_below), never over the curves
    if implot.begin_plot("##spectral_err", err_size, implot.Flags_.no_legend):
        implot.setup_axes("angle of incidence (deg)", "RGB - spectral")  # short: the axis is half a panel tall
        emax = max(d["max_err_schlick"], d["max_err_three"], 1e-3) * 1.1
        implot.setup_axes_limits(0.0, 90.0, -emax, emax, implot.Cond_.always)
        th = np.ascontiguousarray(d["theta"], dtype=np.float64)
        for c, cc in enumerate(((0.85, 0.15, 0.15), (0.15, 0.65, 0.15), (0.15, 0.3, 0.9))):
            implot.plot_line(f"Schlick ({'rgb'[c]})", th, np.ascontiguousarray(d["err_schlick"][:, c]),
                             implot.Spec(line_color=vec4(cc), line_weight=2.0))
            implot.plot_line(f"3 wavelengths ({'rgb'[c]})", th, np.ascontiguousarray(d["err_three"][:, c]),
                             implot.Spec(line_color=vec4(cc, 0.8), line_weight=1.0,
                                         marker=implot.Marker_.diamond, marker_size=2.0))
        # two entries, not six: the line's colour is its channel (the axis says RGB)
        panel.key("Schlick", (0.85, 0.85, 0.85))
        panel.key("3 wavelengths", (0.85, 0.85, 0.85), "dots")
        implot.end_plot()
