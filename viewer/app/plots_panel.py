"""The window's "BRDF plots" panel: polar lobe, 3D lobe, directional albedo, Fresnel, Bouguer,
spectral (n, k and R(theta, lambda) of a spectral material, as ``plot --kind spectral``) and
sampling (histogram against pdf) plots of the scene's materials, overlaid (implot / implot3d), from the data functions of
``viewer.plots`` (the same numbers ``brdf-viewer plot`` draws).

Each material keeps one colour in every tab (BRDF Explorer's convention); a checkbox shows or
hides it and 'solo' shows it alone. Data are cached per (kind, material parameters, angles) and
recomputed only when those change; the albedo curve (tens of ms per material) waits while a
slider is held and is recomputed when it is released.

Use from the app (one instance for the window's lifetime)::

    panel = PlotsPanel()
    ...in the frame, between imgui.new_frame() and imgui.render():
    panel.draw(scene.materials)        # draws nothing while panel.visible is False
    ...at shutdown, before implot / imgui destroy their contexts:
    panel.close()
"""

from __future__ import annotations

import json
import math

import numpy as np
from imgui_bundle import imgui, implot

from viewer import ViewerError, plots

TABS = ("Polar", "3D lobe", "Albedo", "Fresnel", "Bouguer", "Spectral", "Sampling", "Check")
CHANNELS = ("lum", "r", "g", "b")
CHANNEL_LABELS = ("luminance", "red", "green", "blue")
# one colour per material, in the order materials are first seen (Tableau 10, then lighter tints)
PALETTE = ((0.12, 0.47, 0.71), (1.00, 0.50, 0.05), (0.17, 0.63, 0.17), (0.84, 0.15, 0.16),
           (0.58, 0.40, 0.74), (0.55, 0.34, 0.29), (0.89, 0.47, 0.76), (0.50, 0.50, 0.50),
           (0.74, 0.74, 0.13), (0.09, 0.75, 0.81),
           (0.68, 0.78, 0.91), (1.00, 0.73, 0.47), (0.60, 0.87, 0.54), (1.00, 0.60, 0.59),
           (0.77, 0.69, 0.84), (0.77, 0.61, 0.58), (0.97, 0.71, 0.82), (0.78, 0.78, 0.78),
           (0.86, 0.86, 0.55), (0.62, 0.85, 0.90))
# the incident direction: a colour of its own, far from every material's (a test checks it)
LIGHT = (1.00, 0.92, 0.20)
# Fresnel components: hues of their own (R keeps the material's colour), as the CLI plot's
R_S_COLOUR, R_P_COLOUR = (0.30, 0.80, 1.00), (1.00, 0.30, 0.65)
_CACHE_MAX = 256
DOCK_POINTS = 380.0  # a docked plots window is laid out as if at least this many points wide


def _vec4(rgb, a=1.0):
    return imgui.ImVec4(float(rgb[0]), float(rgb[1]), float(rgb[2]), float(a))


def _label(text, x, y, left: bool = False):
    """Text in a plot starting just right of (x, y), or ending just left of it (plot_text
    centres it)."""
    half = imgui.calc_text_size(text).x / 2 + 4
    implot.plot_text(text, x, y, imgui.ImVec2(-half if left else half, 0))


def same_data(a, b) -> bool:
    """Two plot data (dicts of arrays, lists, numbers, strings) hold the same curves."""
    if isinstance(a, dict) and isinstance(b, dict):
        return a.keys() == b.keys() and all(same_data(a[k], b[k]) for k in a)
    if isinstance(a, (list, tuple)) and isinstance(b, (list, tuple)):
        return len(a) == len(b) and all(same_data(x, y) for x, y in zip(a, b))
    if isinstance(a, np.ndarray) or isinstance(b, np.ndarray):
        a, b = np.asarray(a), np.asarray(b)
        if a.shape != b.shape:
            return False
        if a.dtype.kind in "fc" or b.dtype.kind in "fc":
            return bool(np.allclose(a, b, rtol=1e-9, atol=1e-12, equal_nan=True))
        return bool(np.array_equal(a, b))
    return a == b


def _params_key(p) -> str:
    return json.dumps(p.to_plain(), sort_keys=True, default=str)


# wavelength ticks of the spectral tab's half-width plots (implot's defaults collide there)
WAVELENGTH_TICKS = (400.0, 550.0, 700.0)

class PlotsPanel:
    """An imgui window "BRDF plots" with tabs Polar / 3D lobe / Albedo / Fresnel / Bouguer.

    ``draw(materials)`` takes the scene's ``{name: Params}``; ``visible`` opens and closes the
    window (its close button sets it False)."""

    def __init__(self):
        self.visible = True
        self.extents: dict[str, list] = {}  # material -> [(object label, diameter in m)] (Bouguer tab)
        self.theta_i = 45.0  # degrees (polar, 3D lobe)
        self.phi = 0.0  # azimuth of the plane of incidence: 0 = tangent (x-z), 90 = bitangent (y-z)
        self.channel = "lum"
        self.log = False  # log10(1 + f cos) in the polar and 3D plots
        self.inside = False  # Fresnel: light inside the denser medium (critical angle, TIR)
        self.show_components = True  # Fresnel: R_s and R_p besides R
        self.shown: dict[str, bool] = {}
        self.solo: str | None = None
        self.tab = TABS[0]  # the tab drawn last
        self.messages: list[str] = []  # why a material is missing from the current tab
        self._select: str | None = None
        self._colours: dict[str, int] = {}
        self._cache: dict = {}
        self._albedo_shown: dict[str, tuple] = {}
        self._albedo_stale: set[str] = set()
        self._own_implot3d = False

    # ------------------------------------------------------------------ public
    def select_tab(self, tab: str) -> None:
        """Open one of ``TABS`` on the next ``draw``."""
        if tab not in TABS:
            raise ValueError(f"unknown tab {tab!r}; allowed: {', '.join(TABS)}")
        self._select = tab

    def colour(self, name: str) -> tuple:
        if name not in self._colours:
            self._colours[name] = len(self._colours)
        return PALETTE[self._colours[name] % len(PALETTE)]

    def active(self, materials) -> list[str]:
        """The materials drawn: the solo one, else every checked one."""
        if self.solo in materials:
            return [self.solo]
        return [n for n in materials if self.shown.setdefault(n, True)]

    def close(self) -> None:
        """Destroy the implot3d context if this panel created it (call before imgui's)."""
        if self._own_implot3d:
            from imgui_bundle import implot3d

            implot3d.destroy_context()
            self._own_implot3d = False

    def draw(self, materials: dict, rect=None) -> None:
        """The window; ``rect`` (x, y, w, h attributes, window points): docked there (beside the
        3D view, not over it), else a free window."""
        if not self.visible:
            return
        for name in materials:
            self.colour(name)
        flags = 0
        pushed = False
        if rect is not None:
            # docked narrow beside a projector-scaled view: the plots' text no larger than lets
            # a plot about 380 points wide fit (never below the scale-1 size)
            main = max(imgui.get_style().font_scale_main, 1e-6)
            want = max(1.0, min(main, rect.w / DOCK_POINTS))
            if want < main:
                imgui.push_font(None, 16.0 * want / main)
                pushed = True
            imgui.set_next_window_pos(imgui.ImVec2(rect.x, rect.y))
            imgui.set_next_window_size(imgui.ImVec2(rect.w, rect.h))
            flags = imgui.WindowFlags_.no_move | imgui.WindowFlags_.no_resize | imgui.WindowFlags_.no_collapse
        else:
            imgui.set_next_window_pos(imgui.ImVec2(380, 20), imgui.Cond_.first_use_ever)
            imgui.set_next_window_size(imgui.ImVec2(860, 700), imgui.Cond_.first_use_ever)
        expanded, opened = imgui.begin("BRDF plots", self.visible, flags)
        if opened is False:
            self.visible = False
        if expanded:
            self._controls(materials)
            self.messages = []
            if imgui.begin_tab_bar("##plot_kinds"):
                for tab in TABS:
                    flags = imgui.TabItemFlags_.set_selected if self._select == tab else 0
                    selected, _ = imgui.begin_tab_item(tab, None, flags)
                    if selected:
                        self.tab = tab
                        try:
                            self._draw_tab(tab, materials)
                        except ViewerError as e:  # a parameter the plots cannot use: say so, keep going
                            imgui.text_wrapped(str(e))
                        imgui.end_tab_item()
                imgui.end_tab_bar()
            self._select = None
        imgui.end()
        if pushed:
            imgui.pop_font()

    # ------------------------------------------------------------------ controls
    def _controls(self, materials):
        k = imgui.get_font_size() / 16.0
        avail = imgui.get_content_region_avail().x
        cols = max(1, min(len(materials), 3, int(avail // (150 * k))))
        if materials and imgui.begin_table("##plot_materials", cols, imgui.TableFlags_.sizing_stretch_same):
            for name in materials:
                imgui.table_next_column()
                imgui.push_id(f"plotmat_{name}")
                imgui.color_button("##colour", _vec4(self.colour(name)), imgui.ColorEditFlags_.no_tooltip,
                                   imgui.ImVec2(14, 14))
                imgui.same_line()
                solo = self.solo == name
                if solo:
                    imgui.push_style_color(imgui.Col_.button, _vec4((0.85, 0.55, 0.1)))
                if imgui.small_button("solo"):
                    self.solo = None if solo else name
                if solo:
                    imgui.pop_style_color()
                imgui.same_line()
                _, self.shown[name] = imgui.checkbox(name, self.shown.get(name, True))
                if imgui.is_item_hovered():
                    imgui.set_tooltip(f"{name}: {materials[name].model}")
                imgui.pop_id()
            imgui.end_table()
        wide = avail > 640 * k  # two controls a row when there is room
        imgui.push_item_width(min(180 * k, max(avail - 130 * k, 60 * k)))
        _, self.theta_i = imgui.slider_float("theta_i (deg)", self.theta_i, 0.0, 89.0, "%.1f")
        if wide:
            imgui.same_line()
        _, self.phi = imgui.slider_float("plane phi (deg)", self.phi, 0.0, 90.0, "%.0f")
        if imgui.is_item_hovered():
            imgui.set_tooltip("azimuth of the plane of incidence: 0 = tangent (x-z), 90 = bitangent (y-z)")
        ch, i = imgui.combo("channel", CHANNELS.index(self.channel), list(CHANNEL_LABELS))
        if ch:
            self.channel = CHANNELS[i]
        if wide:
            imgui.same_line()
        _, self.log = imgui.checkbox("log10(1 + f cos)", self.log)
        imgui.pop_item_width()

    # ------------------------------------------------------------------ data (cached)
    def _cached(self, key, fn):
        if key not in self._cache:
            if len(self._cache) > _CACHE_MAX:
                self._cache.clear()
            self._cache[key] = fn()
        return self._cache[key]

    def _data(self, kind, name, p, *args, fn):
        return self._cached((kind, name, _params_key(p)) + args, fn)

    def _albedo(self, name, p):
        key = ("albedo", name, _params_key(p))
        if key not in self._cache and imgui.is_any_item_active() and name in self._albedo_shown:
            self._albedo_stale.add(name)  # a slider is held: keep the old curve until it is released
            return self._albedo_shown[name]
        self._albedo_stale.discard(name)
        self._albedo_shown[name] = self._cached(key, lambda: plots.albedo_curve(p))
        return self._albedo_shown[name]

    # ------------------------------------------------------------------ tabs
    def _draw_tab(self, tab, materials):
        names = self.active(materials)
        if not names:
            imgui.text("no material shown: tick one above")
            return
        {"Polar": self._polar, "3D lobe": self._lobe, "Albedo": self._albedo_tab,
         "Fresnel": self._fresnel, "Bouguer": self._bouguer, "Spectral": self._spectral,
         "Sampling": self._sampling_tab, "Check": self._check_tab}[tab](names, materials)
        for m in self.messages:
            imgui.text_wrapped(m)

    _sampling = None
    _check = None  # CheckTab, made when the Check tab is first shown
    spectral_material: str | None = None  # the Spectral tab's material (the first one with a table)

    def _spectral(self, names, materials):
        """One spectral material (``spectral = "NAME"``): n(lambda) and k(lambda); R(theta, lambda)
        as an image with the RGB colour per angle beside it; the errors of Schlick (with the
        spectral f0) and of the three-wavelength RGB Fresnel against the spectral integral, per
        channel. The data are ``viewer.plots.spectral.spectral_data``, as in ``plot --kind spectral``."""
        from viewer.plots.spectral import spectral_data

        have = [n for n in names if plots.spectral_source(materials[n]) is not None]
        missing = [n for n in names if n not in have]
        if missing:
            self.messages.append("no spectral table (spectral = \"NAME\"): " + ", ".join(missing))
        if not have:
            for m in self.messages:
                imgui.text_wrapped(m)
            self.messages = []
            return
        if self.spectral_material not in have:
            self.spectral_material = have[0]
        if len(have) > 1:
            imgui.push_item_width(180)
            ch, i = imgui.combo("material##spectral", have.index(self.spectral_material), have)
            imgui.pop_item_width()
            if ch:
                self.spectral_material = have[i]
        name = self.spectral_material
        p = materials[name]
        d = self._data("spectral", name, p, fn=lambda p=p: spectral_data(p))
        imgui.text(f"{name}: {d['name']} ({d['description']}); max |error| Schlick {d['max_err_schlick']:.3f}, "
                   f"3 wavelengths (650/550/450 nm) {d['max_err_three']:.3f}")
        imgui.text_disabled(f"normal incidence RGB {np.round(d['rgb'][0], 3).tolist()}; {d['source'][:90]}")
        size = self._plot_size()
        half = imgui.ImVec2(max(150.0, (size.x if size.x > 0 else imgui.get_content_region_avail().x) / 2 - 4),
                            max(140.0, size.y * 0.5 - 4))
        lam = np.ascontiguousarray(d["wavelength_nm"], dtype=np.float64)
        if implot.begin_plot("##spectral_nk", half):
            implot.setup_axes("wavelength (nm)", "n (solid), k (dots)")
            implot.setup_axis_ticks(implot.ImAxis_.x1, list(WAVELENGTH_TICKS))  # readable in half a panel
            self._legend()
            ymax = max(float(np.max(d["n"])), float(np.max(d["k"])), 1.0) * 1.05
            implot.setup_axes_limits(float(lam[0]), float(lam[-1]), 0.0, ymax, implot.Cond_.always)
            col = self.colour(name)
            implot.plot_line("n", lam, np.ascontiguousarray(d["n"], dtype=np.float64),
                             implot.Spec(line_color=_vec4(col), line_weight=2.5))
            if np.any(np.asarray(d["k"]) > 0):
                k = np.ascontiguousarray(d["k"], dtype=np.float64)
                implot.plot_line("k", lam, k, implot.Spec(line_color=_vec4(col, 0.8), line_weight=1.0))
                # dots every ~25 nm (a marker at every sample would draw a thick band)
                every = max(1, len(lam) // 16)
                implot.plot_scatter("k", np.ascontiguousarray(lam[::every]), np.ascontiguousarray(k[::every]),
                                    implot.Spec(line_color=_vec4(col, 0.8), fill_color=_vec4(col, 0.8),
                                                marker=implot.Marker_.circle, marker_size=3.0))
            implot.end_plot()
        imgui.same_line()
        if implot.begin_plot("##spectral_R", half, implot.Flags_.no_legend):  # one heat map: no legend
            implot.setup_axes("wavelength (nm); RGB at the right", "angle of incidence (deg)")
            implot.setup_axis_ticks(implot.ImAxis_.x1, list(WAVELENGTH_TICKS))
            x_sw0, x_sw1 = float(lam[-1]) + 10.0, float(lam[-1]) + 60.0  # the swatch column
            implot.setup_axes_limits(float(lam[0]), x_sw1, 0.0, 90.0, implot.Cond_.always)
            implot.push_colormap(implot.Colormap_.viridis)
            R = np.ascontiguousarray(np.asarray(d["R"], dtype=np.float64)[::-1])  # row 0 = 90 deg, drawn on top
            implot.plot_heatmap("R", R, 0.0, 1.0, "", implot.Point(float(lam[0]), 0.0),
                                implot.Point(float(lam[-1]), 90.0))
            implot.pop_colormap()
            from viewer.colour import to_srgb8

            rgb = to_srgb8(np.clip(np.asarray(d["rgb"], dtype=np.float32), 0.0, 1.0))
            theta = np.asarray(d["theta"], dtype=np.float64)
            dl = implot.get_plot_draw_list()
            step = (theta[1] - theta[0]) / 2 if len(theta) > 1 else 0.5
            for t, c in zip(theta, rgb):
                a = implot.plot_to_pixels(x_sw0, float(min(t + step, 90.0)))
                b = implot.plot_to_pixels(x_sw1, float(max(t - step, 0.0)))
                dl.add_rect_filled(a, b, imgui.get_color_u32(imgui.ImVec4(*(c / 255.0), 1.0)))
            implot.end_plot()
        if implot.begin_plot("##spectral_err", imgui.ImVec2(-1, max(140.0, size.y * 0.5 - 4))):
            implot.setup_axes("angle of incidence (deg)", "RGB error against the spectral integral")
            self._legend()
            emax = max(d["max_err_schlick"], d["max_err_three"], 1e-3) * 1.1
            implot.setup_axes_limits(0.0, 90.0, -emax, emax, implot.Cond_.always)
            th = np.ascontiguousarray(d["theta"], dtype=np.float64)
            for c, cc in enumerate(((0.85, 0.15, 0.15), (0.15, 0.65, 0.15), (0.15, 0.3, 0.9))):
                implot.plot_line(f"Schlick ({'rgb'[c]})", th, np.ascontiguousarray(d["err_schlick"][:, c]),
                                 implot.Spec(line_color=_vec4(cc), line_weight=2.0))
                implot.plot_line(f"3 wavelengths ({'rgb'[c]})", th, np.ascontiguousarray(d["err_three"][:, c]),
                                 implot.Spec(line_color=_vec4(cc, 0.8), line_weight=1.0,
                                             marker=implot.Marker_.diamond, marker_size=2.0))
            implot.end_plot()

    def _sampling_tab(self, names, materials):
        """The sampler against its pdf (``viewer.app.monte_carlo.SamplingTab``) at theta_i, phi."""
        if self._sampling is None:
            from viewer.app.monte_carlo import SamplingTab

            self._sampling = SamplingTab()
        self._sampling.draw(names, materials, self.theta_i, self.phi)

    def _check_tab(self, names, materials):
        """The report card of one material (``viewer.app.check_tab.CheckTab``)."""
        if self._check is None:
            from viewer.app.check_tab import CheckTab

            self._check = CheckTab()
        self._check.draw(names, materials)

    def _plot_size(self):
        """The rest of the window, less room for the messages under the plot."""
        avail = imgui.get_content_region_avail()
        lines = sum(1 + len(m) * imgui.calc_text_size("x").x // max(avail.x, 1.0) for m in self.messages)
        return imgui.ImVec2(-1, max(150.0, avail.y - lines * imgui.get_text_line_height_with_spacing()))

    def _legend(self):
        """Outside the plot when the window is wide, inside (top left, where the curves rarely
        are) when it is docked narrow."""
        if imgui.get_content_region_avail().x > 560 * imgui.get_font_size() / 16.0:
            implot.setup_legend(implot.Location_.north_east, implot.LegendFlags_.outside)
        else:
            implot.setup_legend(implot.Location_.north_west)

    def groups(self, names, data, same) -> list[tuple[str, list[str]]]:
        """Materials whose curves are identical drawn once: [(label "a = b", [a, b])], so one
        does not hide under the other; a message says which were merged."""
        out: list[tuple[str, list[str]]] = []
        for n in names:
            for _, members in out:
                if same(data[members[0]], data[n]):
                    members.append(n)
                    break
            else:
                out.append((n, [n]))
        res = []
        for _, members in out:
            res.append((" = ".join(members), members))
            if len(members) > 1:
                self.messages.append(f"{', '.join(members[1:])}: the same curve as {members[0]} (drawn once)")
        return res

    def _y(self, v):
        v = np.asarray(v, dtype=np.float64)
        return np.log10(1.0 + v) if self.log else v

    def _polar(self, names, materials):
        data = {n: self._data("polar", n, materials[n], round(self.theta_i, 3), round(self.phi, 3),
                              fn=lambda n=n: plots.polar_lobe(materials[n], self.theta_i, self.phi))
                for n in names}
        rmax = 0.0
        curves = {}
        for n, d in data.items():
            r = self._y(plots.reduce_channel(d["fcos"], self.channel))
            curves[n] = r
            rmax = max(rmax, float(r.max()) if r.size else 0.0,
                       *[float(self._y(plots.reduce_channel(x["reflectance"], self.channel))) for x in d["delta"]])
        rmax = plots.nice_ceil(rmax * 1.05) if rmax > 0 else 1.0
        size = self._plot_size()
        if implot.begin_plot("##polar", size, implot.Flags_.equal):
            implot.setup_axes("x (theta_o > 0: mirror side)", "z (normal)")
            self._legend()
            implot.setup_axes_limits(-rmax * 1.05, rmax * 1.05, -0.02 * rmax, rmax * 1.05, implot.Cond_.always)
            grey = implot.Spec(line_color=_vec4((0.5, 0.5, 0.5), 0.5), line_weight=1.0)
            t = np.radians(np.linspace(-90.0, 90.0, 91))
            for k, v in enumerate(plots.nice_ticks(0.0, rmax, 4)[1:]):
                implot.plot_line(f"##ring{k}", v * np.sin(t), v * np.cos(t), grey)
            implot.plot_line("##surface", np.array([-rmax, rmax]), np.array([0.0, 0.0]),
                             implot.Spec(line_color=_vec4((0.7, 0.7, 0.7)), line_weight=2.0))
            ti = math.radians(self.theta_i)
            implot.plot_line("light (wi)", np.array([-rmax * math.sin(ti), 0.0]), np.array([rmax * math.cos(ti), 0.0]),
                             implot.Spec(line_color=_vec4(LIGHT), line_weight=2.5))
            implot.plot_line("##mirror", np.array([0.0, rmax * math.sin(ti)]), np.array([0.0, rmax * math.cos(ti)]), grey)
            for label, members in self.groups(names, data, same_data):
                n = members[0]
                d, r = data[n], curves[n]
                t = np.radians(d["theta_o"])
                implot.plot_line(label, r * np.sin(t), r * np.cos(t),
                                 implot.Spec(line_color=_vec4(self.colour(n)), line_weight=2.0))
                for x in d["delta"]:
                    rr = float(self._y(plots.reduce_channel(x["reflectance"], self.channel)))
                    implot.plot_line(f"{label} (delta, R = {rr:.3g})##delta", np.array([0.0, rr * math.sin(ti)]),
                                     np.array([0.0, rr * math.cos(ti)]),
                                     implot.Spec(line_color=_vec4(self.colour(n)), line_weight=5.0))
            implot.end_plot()

    def _lobe(self, names, materials):
        from imgui_bundle import implot3d

        if implot3d.get_current_context() is None:
            implot3d.create_context()
            self._own_implot3d = True
        data = {n: self._data("lobe", n, materials[n], round(self.theta_i, 3), round(self.phi, 3), self.channel,
                              fn=lambda n=n: plots.lobe_3d(materials[n], self.theta_i, self.phi, n_theta=31,
                                                           n_phi=61, channel=self.channel))
                for n in names}
        rmax = max([float(self._y(d["value"]).max()) for d in data.values()] + [1e-6])
        rmax = plots.nice_ceil(rmax * 1.05)
        size = self._plot_size()
        if implot3d.begin_plot("##lobe3d", size):
            implot3d.setup_axes("x (tangent)", "y", "z (normal)")
            implot3d.setup_axes_limits(-rmax, rmax, -rmax, rmax, 0.0, rmax, implot3d.Cond_.always)
            implot3d.setup_box_initial_rotation(25.0, -60.0)
            wi = plots.direction(self.theta_i, self.phi) * rmax
            implot3d.plot_line("light (wi)", np.array([wi[0], 0.0]), np.array([wi[1], 0.0]), np.array([wi[2], 0.0]),
                               implot3d.Spec(line_color=_vec4(LIGHT), line_weight=2.5))
            for label, members in self.groups(names, data, same_data):
                n = members[0]
                d = data[n]
                v = self._y(d["value"])
                col = self.colour(n)
                quads = shaded_quads(v[..., None] * d["wo"])
                top = len(quads) - 1  # the legend's swatch: the brightest level, the material's colour
                for k, (level, (xs, ys, zs)) in enumerate(quads):
                    implot3d.plot_quad(label if k == top else f"##{label}{k}", xs, ys, zs,
                                       implot3d.Spec(fill_color=_vec4(np.asarray(col) * level, 0.95),
                                                     line_color=_vec4(col, 0.0), line_weight=0.0))
                for x in d["delta"]:
                    rr = float(self._y(plots.reduce_channel(x["reflectance"], self.channel)))
                    w = x["wo"] * rr
                    implot3d.plot_line(f"{label} (delta)", np.array([0.0, w[0]]), np.array([0.0, w[1]]),
                                       np.array([0.0, w[2]]), implot3d.Spec(line_color=_vec4(col), line_weight=5.0))
            implot3d.end_plot()

    def _albedo_tab(self, names, materials):
        data = {n: self._albedo(n, materials[n]) for n in names}
        ymax = max([1.0] + [float(plots.reduce_channel(d["albedo"], self.channel).max()) for d in data.values()])
        if self._albedo_stale:
            self.messages.append("(updating when the slider is released: " + ", ".join(sorted(self._albedo_stale)) + ")")
        for n in names:
            note = albedo_note(materials[n], data[n])
            if note:
                self.messages.append(f"{n}: {note}")
        size = self._plot_size()
        if implot.begin_plot("##albedo", size):
            implot.setup_axes("theta (deg) of wo", "directional albedo")
            self._legend()
            implot.setup_axes_limits(0.0, 90.0, 0.0, ymax * 1.05, implot.Cond_.always)
            for label, members in self.groups(names, data, same_data):
                n = members[0]
                d = data[n]
                col = self.colour(n)
                stale = n in self._albedo_stale
                implot.plot_line(label, d["theta"], plots.reduce_channel(d["albedo"], self.channel),
                                 implot.Spec(line_color=_vec4(col, 0.4 if stale else 1.0), line_weight=2.0))
                if d["transmissive"]:
                    implot.plot_line(f"{label} reflected", d["theta"], plots.reduce_channel(d["reflected"], self.channel),
                                     implot.Spec(line_color=_vec4(col, 0.6), line_weight=1.0,
                                                 marker=implot.Marker_.square, marker_size=2.0))
            implot.end_plot()

    def _fresnel(self, names, materials):
        _, self.inside = imgui.checkbox("light inside the denser medium (critical angle)", self.inside)
        if imgui.get_content_region_avail().x > 560 * imgui.get_font_size() / 16.0:
            imgui.same_line()
        _, self.show_components = imgui.checkbox("R_s, R_p", self.show_components)
        ch = "g" if self.channel == "lum" else self.channel
        data, missing = {}, []
        for n in names:
            p = materials[n]
            if "fresnel" not in plots.applicable_kinds(p):
                missing.append(n)
                continue
            src = plots.fresnel_source(p)
            inside = self.inside and src["type"] == "dielectric"
            if self.inside and not inside:
                self.messages.append(f"{n}: {src['type']} Fresnel, seen from air (no inside)")
            data[n] = self._data("fresnel", n, p, inside, fn=lambda p=p, inside=inside: plots.fresnel_curves(p, inside))
        if missing:
            self.messages.append("no Fresnel term (no index of refraction): " + ", ".join(missing))
        if self.channel == "lum" and any(not np.allclose(d["eta"], d["eta"][0]) for d in data.values()):
            self.messages.append("channel: green (a Fresnel curve is per wavelength)")
        keys = ("type", "R", "Rs", "Rp", "thin_film", "schlick")  # the curves, not where they came from
        groups = self.groups(list(data), data, lambda a, b: same_data({k: a[k] for k in keys if k in a},
                                                                      {k: b[k] for k in keys if k in b}))
        marks = fresnel_marks([(label, data[members[0]]) for label, members in groups], "rgb".index(ch))
        size = self._plot_size()
        if implot.begin_plot("##fresnel", size):
            implot.setup_axes("angle of incidence (deg)", "reflectance")
            self._legend()
            implot.setup_axes_limits(0.0, 90.0, 0.0, 1.05, implot.Cond_.always)
            c = "rgb".index(ch)
            for label, members in groups:
                n, d = members[0], data[members[0]]
                col = self.colour(n)
                implot.plot_line(f"{label} R", d["theta"], np.ascontiguousarray(d["R"][:, c]),
                                 implot.Spec(line_color=_vec4(col), line_weight=3.0))
                if self.show_components:
                    implot.plot_line(f"{label} R_s", d["theta"], np.ascontiguousarray(d["Rs"][:, c]),
                                     implot.Spec(line_color=_vec4(R_S_COLOUR), line_weight=1.5,
                                                 marker=implot.Marker_.square, marker_size=1.5))
                    implot.plot_line(f"{label} R_p", d["theta"], np.ascontiguousarray(d["Rp"][:, c]),
                                     implot.Spec(line_color=_vec4(R_P_COLOUR), line_weight=1.5,
                                                 marker=implot.Marker_.circle, marker_size=1.5))
                if "thin_film" in d:
                    implot.plot_line(f"{label} thin film R", d["theta"], np.ascontiguousarray(d["thin_film"][:, c]),
                                     implot.Spec(line_color=_vec4(col, 0.9), line_weight=2.0,
                                                 marker=implot.Marker_.square, marker_size=1.5))
                if "schlick" in d:
                    implot.plot_line(f"{label} Schlick", d["theta"], np.ascontiguousarray(d["schlick"][:, c]),
                                     implot.Spec(line_color=_vec4(col, 0.8), line_weight=1.0,
                                                 marker=implot.Marker_.diamond, marker_size=2.0))
            for k, (angle, tag, text, who) in enumerate(marks):
                col = (0.85, 0.15, 0.15) if tag == "C" else self.colour(who)
                implot.drag_line_x(1000 + k, angle, _vec4(col, 0.8), 1.5 if tag == "C" else 1.0,
                                   implot.DragToolFlags_.no_inputs)
                implot.tag_x(angle, _vec4(col), tag)
                if len(marks) <= 4:  # more would overlap: the tags on the axis remain
                    _label(text, angle, 0.55 - 0.07 * k, left=angle > 45.0)  # clear of the legend and curves
            implot.end_plot()

    def _bouguer(self, names, materials):
        data, missing = {}, []
        for n in names:
            p = materials[n]
            if "bouguer" not in plots.applicable_kinds(p):
                missing.append(n)
                continue
            data[n] = self._data("bouguer", n, p, fn=lambda p=p: plots.bouguer_curve(p))
        if missing:
            self.messages.append("no absorption coefficient sigma_a: " + ", ".join(missing))
        groups = self.groups(list(data), data, same_data)
        units = sorted({d["unit"] for d in data.values()})
        marks = bouguer_marks(data, self.extents, self.channel)
        for _, _, text in marks:
            self.messages.append(text)
        size = self._plot_size()
        if implot.begin_plot("##bouguer", size):
            implot.setup_axes(f"distance d ({' | '.join(units) or 'm'})", "transmittance T = exp(-sigma_a d)")
            self._legend()
            xmax = max([float(d["d"][-1]) for d in data.values()] + [m[0] for m in marks] + [1e-9])
            implot.setup_axes_limits(0.0, xmax * 1.02, 0.0, 1.05, implot.Cond_.always)
            for label, members in groups:
                n, d = members[0], data[members[0]]
                col = self.colour(n)
                implot.plot_line(f"{label} ({d['unit']})", d["d"], plots.reduce_channel(d["T"], self.channel),
                                 implot.Spec(line_color=_vec4(col), line_weight=2.0))
                if d["thickness"]:
                    implot.tag_x(float(d["thickness"]), _vec4(col), "layer")
            for k, (dia, who, text) in enumerate(marks):
                col = self.colour(who)
                implot.drag_line_x(2000 + k, dia, _vec4(col, 0.8), 1.5, implot.DragToolFlags_.no_inputs)
                implot.tag_x(dia, _vec4(col), f"d{k + 1}")
                if len(marks) <= 4:
                    _label(text.split(":")[0], dia, 0.08 + 0.07 * k, left=dia > 0.5 * xmax)  # under the legend
            implot.end_plot()


def fresnel_marks(curves, c: int) -> list[tuple[float, str, str, str]]:
    """The Fresnel tab's angle marks for [(label, fresnel data)] at channel index ``c``:
    [(angle, axis tag, text, material)], one per distinct angle and kind (two materials with the
    same Brewster angle share one mark: no label printed twice)."""
    out, seen = [], set()
    for label, d in curves:
        who = label.split(" = ")[0]
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
