"""The Theta H, Theta D and Theta V tabs: BRDF Explorer's cartesian slices of f, one curve per
material (``viewer.plots.theta``, as ``plot --kind theta_h | theta_d | theta_v``): f against
theta_h at a held theta_d, against theta_d at a held theta_h (both with phi_d = 90 degrees), and
against the view angle theta_v for the panel's light (theta_i, plane phi). The settings these
tabs, the Terms tab and the Image slice tab add to the panel's are ``SliceSettings``
(``panel.slices``)."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from imgui_bundle import imgui, implot

from viewer import plots
from viewer.app.plot_tabs.common import params_key, same_data, vec4
from viewer.plots import theta


@dataclass
class SliceSettings:
    """The held angles (degrees) and options of the slice tabs."""
    theta_d: float = 0.0     # Theta H: the held difference angle
    theta_h: float = 0.0     # Theta D: the held half angle
    phi_d: float = 90.0      # Image slice: the held difference azimuth (BRDF Explorer's default)
    cos: bool = False        # f times cos theta_i of the light (BRDF Explorer's "N . L")
    material: str | None = None  # the Terms and Image slice tabs' material (one at a time)
    kinds: dict = field(default_factory=dict)  # (name, parameters) -> the plot kinds that apply


def kinds_of(panel, name: str, p) -> tuple:
    """``plots.applicable_kinds(p)``, remembered per material and parameters (asking a file's
    model for its terms runs its GLSL: not once a frame)."""
    key = (name, params_key(p))
    cache = panel.slices.kinds
    if key not in cache:
        if len(cache) > 64:
            cache.clear()
        cache[key] = plots.applicable_kinds(p)
    return cache[key]


def pick_material(panel, have: list[str], tag: str) -> str:
    """The one material of a single-material tab: the last one chosen while it is shown, else the
    first; a combo when there are several."""
    s = panel.slices
    if s.material not in have:
        s.material = have[0]
    if len(have) > 1:
        imgui.push_item_width(200 * panel.font_k())
        ch, i = imgui.combo(f"material##{tag}", have.index(s.material), have)
        imgui.pop_item_width()
        if ch:
            s.material = have[i]
    return s.material


def cos_checkbox(panel, tag: str) -> None:
    text = "x cos theta_i (N.L)"
    _, panel.slices.cos = imgui.checkbox(f"{text}##{tag}", panel.slices.cos)
    if imgui.is_item_hovered():
        imgui.set_tooltip("f times the cosine of the light's angle (BRDF Explorer's N.L option)")


class ThetaTab:
    """One of the three slices: ``kind`` is "theta_h", "theta_d" or "theta_v"."""

    def __init__(self, kind: str):
        self.kind = kind

    def _held(self, panel):
        """The held angle's slider and the data function's arguments."""
        s = panel.slices
        imgui.push_item_width(180 * panel.font_k())
        if self.kind == "theta_h":
            _, s.theta_d = imgui.slider_float("theta_d (deg)##th", s.theta_d, 0.0, 89.0, "%.1f")
            args = (round(s.theta_d, 3),)
        elif self.kind == "theta_d":
            _, s.theta_h = imgui.slider_float("theta_h (deg)##td", s.theta_h, 0.0, 89.0, "%.1f")
            args = (round(s.theta_h, 3),)
        else:
            imgui.text_wrapped(f"light at theta_i = {panel.theta_i:.1f} deg; the view in its plane (phi = "
                               f"{panel.phi:.0f} deg), theta_v > 0: the mirror side")
            args = (round(panel.theta_i, 3), round(panel.phi, 3))
        imgui.pop_item_width()
        cos_checkbox(panel, self.kind)
        return args

    def _curve(self, p, args, cos):
        if self.kind == "theta_h":
            return theta.theta_h_curve(p, args[0], cos=cos)
        if self.kind == "theta_d":
            return theta.theta_d_curve(p, args[0], cos=cos)
        return theta.theta_v_curve(p, args[0], args[1], cos=cos)

    def draw(self, panel, names, materials):
        args = self._held(panel)
        cos = panel.slices.cos
        smooth = [n for n in names if "theta_h" in kinds_of(panel, n, materials[n])]
        for n in names:
            if n not in smooth:
                panel.messages.append(f"{n}: a delta lobe (f is 0 as a function): nothing to slice")
        data = {n: panel.data(self.kind, n, materials[n], *args, cos,
                              fn=lambda n=n: self._curve(materials[n], args, cos)) for n in smooth}
        if panel.waiting(data) or not data:
            return
        ys = {n: panel.y(plots.reduce_channel(d["y"], panel.channel)) for n, d in data.items()}
        ymax, peak = theta.axis_top(next(iter(data.values()))["x"], list(ys.values()))
        if peak is not None:
            panel.messages.append(f"toward grazing f runs off the axis, up to {peak:.4g} (the axis is set by "
                                  f"|angle| <= {theta.CENTRAL:g} deg)")
        x_name = {"theta_h": "theta_h", "theta_d": "theta_d", "theta_v": "theta_v"}[self.kind]
        what = "f cos theta_i" if cos else "f"
        size = panel.plot_size()
        panel.begin_frame_rect(size)
        if implot.begin_plot(f"##{self.kind}", size, implot.Flags_.no_legend):
            implot.setup_axes(f"{x_name} (deg)", f"log10(1 + {what})" if panel.log else f"{what} (1/sr)")
            x0 = 0.0 if self.kind == "theta_d" else -90.0
            implot.setup_axes_limits(x0, 90.0, 0.0, plots.nice_ceil(ymax * 1.05), implot.Cond_.always)
            for label, members in panel.groups(smooth, data, same_data):
                n = members[0]
                x = np.ascontiguousarray(data[n]["x"], dtype=np.float64)
                implot.plot_line(label, x, np.ascontiguousarray(ys[n]),
                                 implot.Spec(line_color=vec4(panel.colour(n)), line_weight=2.0))
                panel.key(label, panel.colour(n))
            implot.end_plot()


THETA_H, THETA_D, THETA_V = ThetaTab("theta_h"), ThetaTab("theta_d"), ThetaTab("theta_v")
