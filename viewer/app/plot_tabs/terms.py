"""The Terms tab: the factors of one material's microfacet lobe (its model's ``terms`` hook:
the built-in microfacet model, a ``.brdf`` file defining D, F and G) plotted apart, D, F, G and
1 / (4 cos_i cos_o), with their product and f, against the light's angle theta_l in the plane of
incidence, the view fixed at the panel's theta_i (``viewer.plots.theta.term_curves``, as
``plot --kind terms``). The log switch puts the values on a log10 axis (D spans decades)."""

from __future__ import annotations

import numpy as np
from imgui_bundle import imgui, implot

from viewer import plots
from viewer.app.plot_tabs.theta import kinds_of, pick_material
from viewer.app.plot_tabs.common import vec4
from viewer.plots import theta

LOG_FLOOR = 1e-4  # the log axis starts here (F, G and D's tails reach below it)
# the terms' colours: hues of their own (f in red under the product, which is drawn in the text's colour)
COLOURS = {"D": (0.20, 0.55, 0.95), "F": (1.00, 0.55, 0.10), "G": (0.25, 0.80, 0.30),
           "1/(4 cos cos)": (0.70, 0.45, 0.95), "f": (0.95, 0.20, 0.20), "other": (0.65, 0.45, 0.35)}


def draw(panel, names, materials):
    have = [n for n in names if "terms" in kinds_of(panel, n, materials[n])]
    for n in names:
        if n not in have:
            panel.messages.append(f"{n} ({materials[n].model}): no D, F, G decomposition (the microfacet model "
                                  "and .brdf files defining D, F and G have one)")
    if not have:
        for m in panel.messages:
            imgui.text_wrapped(m)
        panel.messages = []
        return
    name = pick_material(panel, have, "terms")
    p = materials[name]
    tv, ph = round(panel.theta_i, 3), round(panel.phi, 3)
    d = panel.data("terms", name, p, tv, ph, fn=lambda: theta.term_curves(p, tv, ph))
    if panel.waiting({name: d}):
        return
    imgui.text_wrapped(f"{name}: view at theta_i = {tv:g} deg; x: the light's angle in the plane phi = {ph:g} deg")
    ch = panel.channel
    series = [("D", d["D"]), ("F", plots.reduce_channel(d["F"], ch)), ("G", d["G"]),
              ("1/(4 cos cos)", d["1/(4 cos cos)"])]
    product = plots.reduce_channel(d["product"], ch)
    f = plots.reduce_channel(d["f"], ch)
    other = plots.reduce_channel(d["other"], ch) if "other" in d else None
    top = max([float(np.max(v)) for k, v in series if k != "1/(4 cos cos)"] + [float(product.max()), float(f.max()), 1.0])
    x = np.ascontiguousarray(d["x"], dtype=np.float64)
    size = panel.plot_size()
    panel.begin_frame_rect(size)
    if implot.begin_plot("##terms", size, implot.Flags_.no_legend):
        implot.setup_axes("theta_l (deg) of the light", "term (log10 axis)" if panel.log else "term value")
        if panel.log:
            implot.setup_axis_scale(implot.ImAxis_.y1, implot.Scale_.log10)
            pos = [float(np.min(v[v > 0])) for _, v in series + [("", product), ("", f)] if np.any(v > 0)]
            low = max(LOG_FLOOR, 0.5 * min(pos, default=LOG_FLOOR))  # down to the smallest term shown
            implot.setup_axes_limits(-90.0, 90.0, low, top * 2.0, implot.Cond_.always)
        else:
            implot.setup_axes_limits(-90.0, 90.0, 0.0, plots.nice_ceil(top * 1.05), implot.Cond_.always)

        def line(label, y, colour, weight=2.0):
            y = np.ascontiguousarray(np.maximum(y, LOG_FLOOR) if panel.log else y, dtype=np.float64)
            implot.plot_line(label, x, y, implot.Spec(line_color=vec4(colour), line_weight=weight))
            panel.key(label, colour)

        for k, v in series:
            line(k, v, COLOURS[k])
        text = imgui.get_style_color_vec4(imgui.Col_.text)
        line("f (the model)", f, COLOURS["f"], 5.0)
        line("D F G / (4 cos cos)", product, (text.x, text.y, text.z), 2.0)
        if other is not None:
            line("f - D F G / (4 cos cos)", other, COLOURS["other"], 1.5)
        implot.end_plot()
