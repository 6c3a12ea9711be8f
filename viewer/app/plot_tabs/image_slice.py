"""The Image slice tab: BRDF Explorer's image slice of one material, f over (theta_h, theta_d)
at a held phi_d (default 90 degrees), theta_h across on the MERL table's square-root mapping
(the specular peak near theta_h = 0 gets half of the width) and theta_d up, as a heat map of the
luminance log(1 + f) / log(1 + its 99th percentile) (``viewer.plots.measured.slice_data``, as
``plot --kind slice``, which draws the RGB image with theta_d down)."""

from __future__ import annotations

import math

import numpy as np
from imgui_bundle import imgui, implot

from viewer.app.plot_tabs.theta import cos_checkbox, kinds_of, pick_material
from viewer.plots.kinds import LUMINANCE

TICKS_DEG = (0.0, 2.0, 10.0, 22.5, 45.0, 90.0)  # theta_h ticks, at their sqrt-mapped places


def draw(panel, names, materials):
    from viewer.plots.measured import slice_data

    have = [n for n in names if "slice" in kinds_of(panel, n, materials[n])]
    for n in names:
        if n not in have:
            panel.messages.append(f"{n}: a delta lobe (f is 0 as a function): no image slice")
    if not have:
        for m in panel.messages:
            imgui.text_wrapped(m)
        panel.messages = []
        return
    name = pick_material(panel, have, "slice")
    s = panel.slices
    imgui.push_item_width(180 * panel.font_k())
    _, s.phi_d = imgui.slider_float("phi_d (deg)##slice", s.phi_d, 0.0, 180.0, "%.0f")
    imgui.pop_item_width()
    cos_checkbox(panel, "slice")
    p = materials[name]
    pd, cos = round(s.phi_d, 3), s.cos
    d = panel.data("slice", name, p, pd, cos, fn=lambda: slice_data(p, phi_d=pd, cos=cos))
    if panel.waiting({name: d}):
        return
    lum = np.maximum(np.asarray(d["f"]) @ LUMINANCE, 0.0)
    valid = np.asarray(d["valid"])
    # the scale's top: the 99th percentile, so the grazing rows (f of a rough metal reaches
    # hundreds at theta_d -> 90) do not darken the rest of the image
    top = max(float(np.percentile(lum[valid], 99.0)) if valid.any() else 0.0, 1e-12)
    img = np.minimum(np.log1p(lum) / math.log1p(top), 1.0)
    img = np.ascontiguousarray(np.where(valid, img, 0.0)[::-1], dtype=np.float64)  # row 0 = theta_d 90: on top
    what = "f cos theta_i" if cos else "f"
    imgui.text_wrapped(f"{name}: max {what} = {float(lum.max()):.4g} /sr (luminance); colour: log(1 + {what}) / "
                       f"log(1 + {top:.3g}), the 99th percentile (1 above it)")
    size = panel.plot_size()
    k = panel.font_k()
    bar = 60.0 * k
    full = size.x if size.x > 0 else imgui.get_content_region_avail().x
    w = max(150.0, full - bar - imgui.get_style().item_spacing.x)
    implot.push_colormap(implot.Colormap_.viridis)
    panel.begin_frame_rect(imgui.ImVec2(w, size.y))
    if implot.begin_plot("##image_slice", imgui.ImVec2(w, size.y), implot.Flags_.no_legend):
        implot.setup_axes("theta_h (deg, sqrt scale)", "theta_d (deg)")
        implot.setup_axes_limits(0.0, 1.0, 0.0, 90.0, implot.Cond_.always)
        implot.setup_axis_ticks(implot.ImAxis_.x1, [math.sqrt(t / 90.0) for t in TICKS_DEG],
                                [f"{t:g}" for t in TICKS_DEG])
        implot.plot_heatmap("##f", img, 0.0, 1.0, "", implot.Point(0.0, 0.0), implot.Point(1.0, 90.0))
        implot.end_plot()
    imgui.same_line()
    implot.colormap_scale("##slice_scale", 0.0, 1.0, imgui.ImVec2(bar, size.y), "%.1f")
    implot.pop_colormap()
