"""The Bouguer tab: transmittance T = exp(-sigma_a d) against the distance travelled, with the
path through each object's centre marked. A material that absorbs nothing (sigma_a = 0) gets a
line saying so, not a flat curve on an axis of no meaning; with no absorbing material the tab
draws no plot at all."""

from __future__ import annotations

import numpy as np
from imgui_bundle import imgui, implot

from viewer import plots
from viewer.app.plot_tabs.common import label, same_data, vec4


def absorbs(d) -> bool:
    """The Bouguer data ``d`` has an absorbing channel."""
    return bool(np.any(np.asarray(d["sigma_a"], float) > 0))


def bouguer_marks(data: dict, extents: dict, channel: str) -> list[tuple[float, str, str]]:
    """The Bouguer tab's marks at the diameters of the objects made of each material (the path
    through a sphere's centre): [(diameter, material, text with T there)]."""
    out = []
    for n, d in data.items():
        if d["unit"] != "m":  # a coating's thickness is in um: the objects' size is not its path
            continue
        for obj, dia in extents.get(n, []):
            t = float(plots.reduce_channel(np.exp(-np.asarray(d["sigma_a"], float) * dia)[None, :], channel)[0])
            out.append((float(dia), n, f"{obj}: diameter {dia:.3g} m, T = {t:.3g} through its centre"))
    return out


def draw(panel, names, materials):
    data, missing, clear = {}, [], []
    for n in names:
        p = materials[n]
        if "bouguer" not in plots.applicable_kinds(p):
            missing.append(n)
            continue
        d = panel.data("bouguer", n, p, fn=lambda p=p: plots.bouguer_curve(p))
        if d is None:
            data[n] = None
        elif absorbs(d):
            data[n] = d
        else:
            clear.append(n)
    if panel.waiting(data):
        return
    if missing:
        panel.messages.append("no absorption coefficient sigma_a: " + ", ".join(missing))
    if clear:
        panel.messages.append("no absorption (sigma_a = 0: T = 1 at any distance): " + ", ".join(clear))
    if not data:  # (the panel writes the messages under this)
        imgui.text_wrapped("No shown material absorbs, so there is no Bouguer curve to draw; an absorbing "
                           "glass (sigma_a > 0, e.g. the preset green_glass) shows T = exp(-sigma_a d) here.")
        return
    groups = panel.groups(list(data), data, same_data)
    units = sorted({d["unit"] for d in data.values()})
    marks = bouguer_marks(data, panel.extents, panel.channel)
    for _, _, text in marks:
        panel.messages.append(text)
    size = panel.plot_size()
    panel.begin_frame_rect(size)
    # the legend under the plot (panel.legend_below): a box inside covered the curve's start at T = 1
    if implot.begin_plot("##bouguer", size, implot.Flags_.no_legend):
        implot.setup_axes(f"distance d ({' | '.join(units)})", "transmittance T = exp(-sigma_a d)")
        xmax = max([float(d["d"][-1]) for d in data.values()] + [m[0] for m in marks])
        implot.setup_axes_limits(0.0, xmax * 1.02, 0.0, 1.05, implot.Cond_.always)
        for lab, members in groups:
            n, d = members[0], data[members[0]]
            col = panel.colour(n)
            implot.plot_line(f"{lab} ({d['unit']})", d["d"], plots.reduce_channel(d["T"], panel.channel),
                             implot.Spec(line_color=vec4(col), line_weight=2.0))
            panel.key(f"{lab} ({d['unit']})", col)
            if d["thickness"]:
                implot.tag_x(float(d["thickness"]), vec4(col), "layer")
        for k, (dia, who, text) in enumerate(marks):
            col = panel.colour(who)
            implot.drag_line_x(2000 + k, dia, vec4(col, 0.8), 1.5, implot.DragToolFlags_.no_inputs)
            label(f"d{k + 1}", dia, 1.0 - 0.06 * (k % 2), left=dia > 0.5 * xmax)
            if len(marks) <= 4:
                label(text.split(":")[0], dia, 0.08 + 0.07 * k, left=dia > 0.5 * xmax)
        implot.end_plot()
