"""The Albedo tab: directional albedo against the angle of wo (reflected and transmitted parts
of a transmissive material), recomputed when a held slider is released."""

from __future__ import annotations

import numpy as np
from imgui_bundle import implot

from viewer import plots
from viewer.app.plot_tabs.common import same_data, vec4


def draw(panel, names, materials):
    data = {n: panel.albedo(n, materials[n]) for n in names}
    if panel.waiting(data):
        return
    ymax = max([1.0] + [float(plots.reduce_channel(d["albedo"], panel.channel).max()) for d in data.values()])
    if panel.albedo_stale:
        panel.messages.append("(updating when the slider is released: " + ", ".join(sorted(panel.albedo_stale)) + ")")
    for n in names:
        note = albedo_note(materials[n], data[n])
        if note:
            panel.messages.append(f"{n}: {note}")
    size = panel.plot_size()
    panel.begin_frame_rect(size)
    if implot.begin_plot("##albedo", size, implot.Flags_.no_legend):
        implot.setup_axes("theta (deg) of wo", "directional albedo")
        implot.setup_axes_limits(0.0, 90.0, 0.0, ymax * 1.05, implot.Cond_.always)
        for label, members in panel.groups(names, data, same_data):
            n = members[0]
            d = data[n]
            col = panel.colour(n)
            stale = n in panel.albedo_stale
            implot.plot_line(label, d["theta"], plots.reduce_channel(d["albedo"], panel.channel),
                             implot.Spec(line_color=vec4(col, 0.4 if stale else 1.0), line_weight=2.0))
            panel.key(label, col)
            if d["transmissive"]:
                implot.plot_line(f"{label} reflected", d["theta"], plots.reduce_channel(d["reflected"], panel.channel),
                                 implot.Spec(line_color=vec4(col, 0.6), line_weight=1.0,
                                             marker=implot.Marker_.square, marker_size=2.0))
                panel.key(f"{label} reflected", col)
        implot.end_plot()


def albedo_note(p, d) -> str:
    """Why a transmissive material's albedo is below 1 although it absorbs nothing: the albedo
    adds radiance, and radiance entering a denser medium is compressed by 1/eta^2."""
    if not d.get("transmissive") or "ior" not in p:
        return ""
    eta = float(p["ior"])
    if eta <= 1.0:
        return ""
    a0 = float(np.mean(d["albedo"][0]))
    flux = float(np.mean(d["reflected"][0] + eta * eta * d["transmitted"][0]))
    return (f"albedo {a0:.2f} at normal incidence counts radiance: the transmitted radiance is scaled by "
            f"1/eta^2 = {1 / eta ** 2:.2f} (the beam narrows entering n = {eta:g}); the energy balance "
            f"R + eta^2 T = {flux:.2f}")
