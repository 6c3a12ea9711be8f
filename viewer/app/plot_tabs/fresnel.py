"""The Fresnel tab: R, R_s and R_p against the angle of incidence (from air, or from inside the
denser medium), a thin film's and Schlick's curves, and the Brewster / pseudo-Brewster and
critical angles marked with a line and a letter inside the plot (never over the axis' ticks).
An index of 1 has neither reflection nor a Brewster angle: the tab says so instead of marking
one."""

from __future__ import annotations

import math

import numpy as np
from imgui_bundle import imgui, implot

from viewer import plots
from viewer.app.plot_tabs.common import R_P_COLOUR, R_S_COLOUR, label, same_data, vec4


def matched(d, c: int) -> bool:
    """A dielectric interface of index 1 (air against air) at channel ``c``: no reflection, so
    no Brewster or critical angle."""
    return d["type"] == "dielectric" and abs(float(d["eta"][c]) - 1.0) < 1e-9


def fresnel_marks(curves, c: int) -> list[tuple[float, str, str, str]]:
    """The Fresnel tab's angle marks for [(label, fresnel data)] at channel index ``c``:
    [(angle, tag, text, material)], one per distinct angle and kind (two materials with the
    same Brewster angle share one mark: no label printed twice); none for an index of 1."""
    out, seen = [], set()
    for lab, d in curves:
        if matched(d, c):
            continue
        who = lab.split(" = ")[0]
        b = float(d["brewster"][c])
        name = "Brewster" if d["type"] != "conductor" else "pseudo-Brewster"
        key = (name, round(b, 1))
        if key not in seen:
            seen.add(key)
            out.append((b, "B" if d["type"] != "conductor" else "pB", f"{name} {b:.1f}°", who))
        crit = float(d["critical"][c])
        if math.isfinite(crit) and ("critical", round(crit, 1)) not in seen:
            seen.add(("critical", round(crit, 1)))
            out.append((crit, "C", f"critical {crit:.1f}°", who))
    return out


def fresnel_notes(curves, c: int) -> list[str]:
    """What the marks cannot say: an index of 1 reflects nothing and has no Brewster angle (a
    thin film on it reflects by interference alone)."""
    out = []
    for lab, d in curves:
        if matched(d, c):
            film = "; what reflects is the thin film's interference (thin film R)" if "thin_film" in d else ""
            out.append(f"{lab}: n = 1 against air: the bare interface reflects nothing and has no Brewster "
                       f"angle{film}")
    return out


def draw(panel, names, materials):
    _, panel.inside = imgui.checkbox("light inside the denser medium (critical angle)", panel.inside)
    if imgui.get_content_region_avail().x > 560 * panel.font_k():
        imgui.same_line()
    _, panel.show_components = imgui.checkbox("R_s, R_p", panel.show_components)
    ch = "g" if panel.channel == "lum" else panel.channel
    data, missing = {}, []
    for n in names:
        p = materials[n]
        if "fresnel" not in plots.applicable_kinds(p):
            missing.append(n)
            continue
        src = plots.fresnel_source(p)
        inside = panel.inside and src["type"] == "dielectric"
        if panel.inside and not inside:
            panel.messages.append(f"{n}: {src['type']} Fresnel, seen from air (no inside)")
        data[n] = panel.data("fresnel", n, p, inside, fn=lambda p=p, inside=inside: plots.fresnel_curves(p, inside))
    if panel.waiting(data):
        return
    if missing:
        panel.messages.append("no Fresnel term (no index of refraction): " + ", ".join(missing))
    if panel.channel == "lum" and any(not np.allclose(d["eta"], d["eta"][0]) for d in data.values()):
        panel.messages.append("channel: green (a Fresnel curve is per wavelength)")
    keys = ("type", "R", "Rs", "Rp", "thin_film", "schlick")  # the curves, not where they came from
    groups = panel.groups(list(data), data, lambda a, b: same_data({k: a[k] for k in keys if k in a},
                                                                   {k: b[k] for k in keys if k in b}))
    c = "rgb".index(ch)
    curves = [(lab, data[members[0]]) for lab, members in groups]
    marks = fresnel_marks(curves, c)
    panel.messages.extend(fresnel_notes(curves, c))
    size = panel.plot_size()
    # the marks' words inside the plot, a row of 0.07 of its height each, where at most four rows
    # fit (a plot shortened by many materials' lines gets them under it instead)
    words_inside = len(marks) <= 4 and 0.07 * (size.y - 3 * imgui.get_text_line_height()) \
        >= 1.2 * imgui.get_text_line_height()
    if not words_inside:
        size = imgui.ImVec2(size.x, size.y - imgui.get_text_line_height_with_spacing())
    panel.begin_frame_rect(size)
    if implot.begin_plot("##fresnel", size, implot.Flags_.no_legend):
        implot.setup_axes("angle of incidence (deg)", "reflectance")
        implot.setup_axes_limits(0.0, 90.0, 0.0, 1.05, implot.Cond_.always)
        for lab, members in groups:
            n, d = members[0], data[members[0]]
            col = panel.colour(n)
            bare = not matched(d, c)  # an index of 1: R = R_s = R_p = 0 (said under the plot)
            if bare:
                implot.plot_line(f"{lab} R", d["theta"], np.ascontiguousarray(d["R"][:, c]),
                                 implot.Spec(line_color=vec4(col), line_weight=3.0))
                panel.key(f"{lab} R", col)
            if panel.show_components and bare:
                implot.plot_line(f"{lab} R_s", d["theta"], np.ascontiguousarray(d["Rs"][:, c]),
                                 implot.Spec(line_color=vec4(R_S_COLOUR), line_weight=1.5,
                                             marker=implot.Marker_.square, marker_size=1.5))
                implot.plot_line(f"{lab} R_p", d["theta"], np.ascontiguousarray(d["Rp"][:, c]),
                                 implot.Spec(line_color=vec4(R_P_COLOUR), line_weight=1.5,
                                             marker=implot.Marker_.circle, marker_size=1.5))
                # one entry each: every material's R_s (R_p) has the same hue
                panel.key("R_s", R_S_COLOUR)
                panel.key("R_p", R_P_COLOUR)
            if "thin_film" in d:
                implot.plot_line(f"{lab} thin film R", d["theta"], np.ascontiguousarray(d["thin_film"][:, c]),
                                 implot.Spec(line_color=vec4(col, 0.9), line_weight=2.0,
                                             marker=implot.Marker_.square, marker_size=1.5))
                panel.key(f"{lab} thin film R", col)
            if "schlick" in d:
                implot.plot_line(f"{lab} Schlick", d["theta"], np.ascontiguousarray(d["schlick"][:, c]),
                                 implot.Spec(line_color=vec4(col, 0.8), line_weight=1.0,
                                             marker=implot.Marker_.diamond, marker_size=2.0))
                panel.key(f"{lab} Schlick", col, "dots")
        for k, (angle, tag, text, who) in enumerate(marks):
            col = (0.85, 0.15, 0.15) if tag == "C" else panel.colour(who)
            implot.drag_line_x(1000 + k, angle, vec4(col, 0.8), 1.5 if tag == "C" else 1.0,
                               implot.DragToolFlags_.no_inputs)
            # the letter at the top of its line, inside the plot: an axis tag would hide a tick
            implot.push_style_color(implot.Col_.inlay_text, vec4(col))
            label(tag, angle, 1.0 - 0.06 * (k % 2), left=angle > 45.0)
            implot.pop_style_color()
            if words_inside:
                label(text, angle, 0.55 - 0.07 * k, left=angle > 45.0)
        implot.end_plot()
    if marks and not words_inside:  # under the plot, where they cannot overlap
        panel.messages.append("marks: " + ", ".join(f"{tag} {text}" for _, tag, text, _ in marks))
