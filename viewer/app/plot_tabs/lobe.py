"""The 3D lobe tab: f cos(theta_o) over the hemisphere as a shaded surface (implot3d), a delta
lobe as a thick line of length R along the mirror direction. The axes span the largest lobe or
delta line (a delta-only material has a zero surface: its axes follow its delta line, never a
span of +-1e-6)."""

from __future__ import annotations

import numpy as np

from viewer import plots
from viewer.app.plot_tabs.common import LIGHT, same_data, vec4


def extent(data: dict, y) -> float:
    """The half-width of the 3D lobe's axes for {material: lobe_3d data}: the largest value of
    a surface or of a delta line (after ``y``, the panel's linear or log scale), rounded up; 1
    when everything is zero (an index of 1 reflects nothing)."""
    top = 0.0
    for d in data.values():
        top = max(top, float(y(d["value"]).max()),
                  *[float(y(plots.reduce_channel(x["reflectance"], d.get("channel", "lum")))) for x in d["delta"]])
    return plots.nice_ceil(top * 1.05) if top > 1e-4 else 1.0


def draw(panel, names, materials):
    from imgui_bundle import implot3d

    panel.ensure_implot3d()
    data = {n: panel.data("lobe", n, materials[n], round(panel.theta_i, 3), round(panel.phi, 3), panel.channel,
                          fn=lambda n=n: plots.lobe_3d(materials[n], panel.theta_i, panel.phi, n_theta=31,
                                                       n_phi=61, channel=panel.channel))
            for n in names}
    if panel.waiting(data):
        return
    rmax = extent(data, panel.y)
    panel.lobe_extent = rmax
    size = panel.plot_size()
    panel.begin_frame_rect(size)
    if implot3d.begin_plot("##lobe3d", size, implot3d.Flags_.no_legend):
        implot3d.setup_axes("x (tangent)", "y", "z (normal)")
        implot3d.setup_axes_limits(-rmax, rmax, -rmax, rmax, 0.0, rmax, implot3d.Cond_.always)
        implot3d.setup_box_initial_rotation(25.0, -60.0)
        wi = plots.direction(panel.theta_i, panel.phi) * rmax
        implot3d.plot_line("light (wi)", np.array([wi[0], 0.0]), np.array([wi[1], 0.0]), np.array([wi[2], 0.0]),
                           implot3d.Spec(line_color=vec4(LIGHT), line_weight=2.5))
        panel.key("light (wi)", LIGHT)
        for label, members in panel.groups(names, data, same_data):
            n = members[0]
            d = data[n]
            v = panel.y(d["value"])
            col = panel.colour(n)
            quads = shaded_quads(v[..., None] * d["wo"])
            top = len(quads) - 1  # the legend's swatch: the brightest level, the material's colour
            if d["delta"] and not np.any(v > 0):
                quads = []  # a mirror or smooth glass: no lobe, its delta line alone (and one entry)
            else:
                panel.key(label, col)
            for k, (level, (xs, ys, zs)) in enumerate(quads):
                implot3d.plot_quad(label if k == top else f"##{label}{k}", xs, ys, zs,
                                   implot3d.Spec(fill_color=vec4(np.asarray(col) * level, 0.95),
                                                 line_color=vec4(col, 0.0), line_weight=0.0))
            for x in d["delta"]:
                rr = float(panel.y(plots.reduce_channel(x["reflectance"], panel.channel)))
                w = x["wo"] * rr
                implot3d.plot_line(f"{label} (delta, R = {rr:.3g})", np.array([0.0, w[0]]), np.array([0.0, w[1]]),
                                   np.array([0.0, w[2]]), implot3d.Spec(line_color=vec4(col), line_weight=5.0))
                panel.key(f"{label} (delta, R = {rr:.3g})", col)
        implot3d.end_plot()


def shaded_quads(points: np.ndarray, levels: int = 8, light=(0.35, -0.45, 0.82)):
    """The lobe surface (grid of points (rows, cols, 3)) as quads grouped by Lambert shading
    under a fixed light, so a few draw calls give a shaded surface: [(brightness, (xs, ys, zs))],
    brightness in [0.35, 1]. Degenerate quads (at the lobe's tip) are kept at mid brightness."""
    p = np.asarray(points, np.float64)
    a, b, c, e = p[:-1, :-1], p[1:, :-1], p[1:, 1:], p[:-1, 1:]
    n = np.cross(c - a, e - b)
    nn = np.linalg.norm(n, axis=-1)
    lv = np.asarray(light, float) / np.linalg.norm(light)
    shade = np.where(nn > 1e-20, np.abs(n @ lv) / np.maximum(nn, 1e-30), 0.5)
    bright = 0.35 + 0.65 * shade
    idx = np.minimum((bright - 0.35) / 0.65 * levels, levels - 1).astype(int)
    quads = np.stack([a, b, c, e], axis=-2)  # (rows-1, cols-1, 4, 3)
    out = []
    for k in range(levels):
        sel = quads[idx == k]
        if len(sel):
            q = sel.reshape(-1, 3)
            out.append((0.35 + 0.65 * (k + 0.5) / levels,
                        tuple(np.ascontiguousarray(q[:, i], dtype=np.float64) for i in range(3))))
    return out
