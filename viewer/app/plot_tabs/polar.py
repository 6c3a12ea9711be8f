"""The Polar tab: f cos(theta_o) in the plane of incidence, one curve per material, drawn at
equal aspect (a Lambert lobe is a circle, the light at 45 degrees is drawn at 45 degrees); a
delta lobe as a thick line of length R along the mirror direction, a smooth dielectric's
refracted ray below the surface with length T = 1 - R."""

from __future__ import annotations

import math

import numpy as np
from imgui_bundle import imgui, implot

from viewer import plots
from viewer.app.plot_tabs.common import LIGHT, equal_aspect_limits, pixel_aspect, same_data, vec4


def delta_label(label: str, rr: float, p) -> str:
    """The legend entry of a delta lobe: its reflectance, and why it is 0 where it is (an index
    of 1 against air reflects nothing)."""
    if rr <= 0.0:
        src = plots.fresnel_source(p)
        if src is not None and src["type"] == "dielectric" and src["ior"] == 1.0:
            return f"{label} (delta: n = 1 reflects nothing)##delta"
    return f"{label} (delta, R = {rr:.3g})##delta"


def draw(panel, names, materials):
    data = {n: panel.data("polar", n, materials[n], round(panel.theta_i, 3), round(panel.phi, 3),
                          fn=lambda n=n: plots.polar_lobe(materials[n], panel.theta_i, panel.phi))
            for n in names}
    if panel.waiting(data):
        return
    rmax = 0.0
    curves = {}
    below = 0.0  # how far the refracted rays reach under the surface
    for n, d in data.items():
        r = panel.y(plots.reduce_channel(d["fcos"], panel.channel))
        curves[n] = r
        rmax = max(rmax, float(r.max()) if r.size else 0.0,
                   *[float(panel.y(plots.reduce_channel(x["reflectance"], panel.channel))) for x in d["delta"]])
        for x in d.get("refracted", []):
            below = max(below, float(panel.y(plots.reduce_channel(x["transmittance"], panel.channel))))
    rmax = max(rmax, below)
    rmax = plots.nice_ceil(rmax * 1.05) if rmax > 0 else 1.0
    size = panel.plot_size()
    y0 = -(below * 1.05 if below > 0 else 0.02 * rmax)
    x0, x1, y1 = -rmax * 1.05, rmax * 1.05, rmax * 1.05
    k = panel.font_k()
    frame_w = max(size.x if size.x > 0 else panel.avail_x(), 100.0)
    # the axes' room around the plot area: measured on the last frame, estimated before
    room_w, room_h = panel.areas.get("polar_room", (70 * k, 60 * k))
    area_w = frame_w - room_w
    # no taller than the lobe needs at this width (the room below is the messages')
    size = imgui.ImVec2(size.x, min(size.y, max(150.0, area_w * (y1 - y0) / (x1 - x0) + room_h)))
    lim = equal_aspect_limits(x0, x1, y0, y1, area_w, size.y - room_h)
    panel.begin_frame_rect(size)
    if implot.begin_plot("##polar", size, implot.Flags_.no_legend):
        implot.setup_axes("x (theta_o > 0: mirror side)", "z (normal)")
        implot.setup_axes_limits(*lim, implot.Cond_.always)
        grey = implot.Spec(line_color=vec4((0.5, 0.5, 0.5), 0.5), line_weight=1.0)
        t = np.radians(np.linspace(-90.0, 90.0, 91))
        for k, v in enumerate(plots.nice_ticks(0.0, rmax, 4)[1:]):
            implot.plot_line(f"##ring{k}", v * np.sin(t), v * np.cos(t), grey)
        implot.plot_line("##surface", np.array([-rmax, rmax]), np.array([0.0, 0.0]),
                         implot.Spec(line_color=vec4((0.7, 0.7, 0.7)), line_weight=2.0))
        ti = math.radians(panel.theta_i)
        implot.plot_line("light (wi)", np.array([-rmax * math.sin(ti), 0.0]), np.array([rmax * math.cos(ti), 0.0]),
                         implot.Spec(line_color=vec4(LIGHT), line_weight=2.5))
        panel.key("light (wi)", LIGHT)
        implot.plot_line("##mirror", np.array([0.0, rmax * math.sin(ti)]), np.array([0.0, rmax * math.cos(ti)]), grey)
        for label, members in panel.groups(names, data, same_data):
            n = members[0]
            d, r = data[n], curves[n]
            t = np.radians(d["theta_o"])
            col = vec4(panel.colour(n))
            if not (d["delta"] and not np.any(r > 0)):  # a mirror or smooth glass: its delta line alone
                implot.plot_line(label, r * np.sin(t), r * np.cos(t), implot.Spec(line_color=col, line_weight=2.0))
                panel.key(label, panel.colour(n))
            for x in d["delta"]:
                rr = float(panel.y(plots.reduce_channel(x["reflectance"], panel.channel)))
                implot.plot_line(delta_label(label, rr, materials[n]), np.array([0.0, rr * math.sin(ti)]),
                                 np.array([0.0, rr * math.cos(ti)]), implot.Spec(line_color=col, line_weight=5.0))
                panel.key(delta_label(label, rr, materials[n]), panel.colour(n))
            for x in d.get("refracted", []):
                tt = float(panel.y(plots.reduce_channel(x["transmittance"], panel.channel)))
                a = math.radians(x["theta_t"])
                refr = f"{label} (refracted at {x['theta_t']:.1f} deg, T = {tt:.3g})##refr"
                implot.plot_line(refr, np.array([0.0, tt * math.sin(a)]), np.array([0.0, -tt * math.cos(a)]),
                                 implot.Spec(line_color=vec4(panel.colour(n), 0.7), line_weight=3.0))
                panel.key(refr, panel.colour(n))
        area = implot.get_plot_size()
        panel.areas["polar_room"] = (frame_w - area.x, size.y - area.y)
        panel.aspects["polar"] = pixel_aspect()
        implot.end_plot()
