"""The window's "BRDF plots" panel, its tabs: Polar (the lobe in the plane of incidence), 3D
lobe, Albedo (directional albedo), Fresnel, Bouguer (absorption), Spectral (n, k and
R(theta, lambda) of a spectral material, as ``plot --kind spectral``), Sampling (histogram
against pdf), BRDF Explorer's Theta H, Theta D, Theta V and Image slice, Terms (a microfacet
lobe's D, F, G) and Check (the report card), each a module of ``viewer.app.plot_tabs``, drawing the scene's materials overlaid
(implot / implot3d) from the data functions of ``viewer.plots`` (the same numbers
``brdf-viewer plot`` draws).

Each material keeps one colour in every tab (BRDF Explorer's convention) and from run to run
(chosen from its name, ``colour_slots``); a checkbox shows or
hides it and 'solo' shows it alone. The tabs' data are the panel's part ``store``
(``viewer.app.plot_data.PlotData``): cached per (kind, material parameters, angles), and in the
window (``background``) computed in a worker thread beside the frames, the tab saying
"computing ..." until they arrive. The tab names flow onto
a second row when the panel is narrow (never shortened to "Sa...").

Use from the app (one instance for the window's lifetime)::

    panel = PlotsPanel()
    ...in the frame, between imgui.new_frame() and imgui.render():
    panel.draw(scene.materials)        # draws nothing while panel.visible is False
    ...at shutdown, before implot / imgui destroy their contexts:
    panel.close()
"""

from __future__ import annotations

import numpy as np
from imgui_bundle import imgui, implot

from viewer import ViewerError
from viewer.app.parts import Part
from viewer.app.plot_data import PlotData
from viewer.app.plot_tabs import (albedo, bouguer, check, fresnel, image_slice, lobe, polar, sampling, spectral,
                                  terms, theta)
from viewer.app.plot_tabs.albedo import albedo_note  # noqa: F401 - part of this module's interface
from viewer.app.plot_tabs.bouguer import bouguer_marks  # noqa: F401
from viewer.app.plot_tabs.common import (CHANNEL_LABELS, CHANNELS, LIGHT, PALETTE, R_P_COLOUR,  # noqa: F401
                                         CURVE_TOL, R_S_COLOUR, colour_slot, colour_slots, curve_gap, legend_below, legend_layout, legend_text, WAVELENGTH_TICKS, flow_rows, params_key, same_data, vec4)
from viewer.app.plot_tabs.fresnel import fresnel_marks  # noqa: F401
from viewer.app.plot_tabs.lobe import shaded_quads  # noqa: F401

TABS = ("Polar", "3D lobe", "Albedo", "Fresnel", "Bouguer", "Spectral", "Sampling", "Theta H", "Theta D",
        "Theta V", "Terms", "Image slice", "Check")
TAB_MODULES = {"Polar": polar, "3D lobe": lobe, "Albedo": albedo, "Fresnel": fresnel, "Bouguer": bouguer,
               "Spectral": spectral, "Sampling": sampling, "Theta H": theta.THETA_H, "Theta D": theta.THETA_D,
               "Theta V": theta.THETA_V, "Terms": terms, "Image slice": image_slice, "Check": check}
DOCK_POINTS = 380.0  # a docked plots window is laid out as if at least this many points wide
# the material list takes at most this many rows open; longer (the gallery's 11 in one column) it
# starts folded under a header, so the plot keeps its room (its legend names every curve)
LIST_ROWS = 4


class PlotsPanel:
    """An imgui window "BRDF plots" with the tabs of ``TABS``.

    ``draw(materials)`` takes the scene's ``{name: Params}``; ``visible`` opens and closes the
    window (its close button sets it False). After a frame, ``aspects["polar"]`` is the polar
    plot's pixels per unit along x over those along y (1: equal aspect) and ``clipped`` lists the
    labels drawn this frame that did not fit their room (empty when all text fits).
    The tabs' data are the part ``store`` (``viewer.app.plot_data.PlotData``: cached, computed
    in a worker thread with ``background``), read through the panel (``data``, ``cached``,
    ``albedo``, ``computing``, ...)."""

    background = Part("store")
    wake = Part("store")
    updating = Part("store")
    albedo_stale = Part("store")
    computing = Part("store")
    cached = Part("store")
    data = Part("store")
    albedo = Part("store")

    def __init__(self):
        self.visible = True
        self.check_tab = None  # the Check tab's report card (plot_tabs/check.py), made when first shown
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
        self._groups: dict = {}  # groups' results: see groups
        self.spectral_material: str | None = None  # the Spectral tab's material (the first one with a table)
        self.sampling = sampling.SamplingTab()
        self.slices = theta.SliceSettings()  # the Theta, Terms and Image slice tabs' angles and options
        self.areas: dict[str, tuple] = {}  # plot area (pixels) of the last frame, by tab
        self.aspects: dict[str, float] = {}  # measured x/y pixel-per-unit ratio, by tab
        self.lobe_extent = 1.0  # the 3D lobe's axis half-width of the last frame
        self.nk_range = (0.0, 1.0)  # the Spectral tab's n, k axis of the last frame
        self.clipped: list[str] = []  # labels that did not fit this frame (should stay empty)
        self.listed = False  # the material list this frame: True shown, None folded under its header
        # the legend under the plot, by tab, from the last frame (window pixels): its box, its
        # cells (plot_tabs.common.LegendCell, from the box's corner) and the plot's frame above it
        self.legend_boxes: dict[str, tuple] = {}
        self.legend_cells: dict[str, list] = {}
        self.plot_rects: dict[str, tuple] = {}
        self._keys: list[tuple] = []  # (text, colour, style) given to key this frame
        self._select: str | None = None
        self._colours: dict[str, int] = {}  # palette entry by material, for the scene's names
        self._colour_names: frozenset = frozenset()
        self._own_implot3d = False
        self.store = PlotData()  # the tabs' data: cached, computed in the worker thread

    # ------------------------------------------------------------------ public
    def select_tab(self, tab: str) -> None:
        """Open one of ``TABS`` on the next ``draw``."""
        if tab not in TABS:
            raise ValueError(f"unknown tab {tab!r}; allowed: {', '.join(TABS)}")
        self._select = tab

    def set_materials(self, names) -> None:
        """The materials the colours are shared out among (``colour_slots``: a function of the
        names alone, the same in every run)."""
        names = frozenset(names)
        if names != self._colour_names:
            self._colour_names = names
            self._colours = colour_slots(names)

    def colour(self, name: str) -> tuple:
        """The material's colour: its entry among the scene's materials (``set_materials``), or,
        for a name outside them, the entry its name asks for."""
        return PALETTE[self._colours.get(name, colour_slot(name))]

    def active(self, materials) -> list[str]:
        """The materials drawn: the solo one, else every checked one."""
        if self.solo in materials:
            return [self.solo]
        return [n for n in materials if self.shown.setdefault(n, True)]

    def close(self) -> None:
        """Destroy the implot3d context if this panel created it (call before imgui's); the
        worker thread stops after the job it runs."""
        self.store.shutdown()
        if self._own_implot3d:
            from imgui_bundle import implot3d

            implot3d.destroy_context()
            self._own_implot3d = False

    def ensure_implot3d(self) -> None:
        """An implot3d context for the 3D lobe (created on first use, destroyed by ``close``)."""
        from imgui_bundle import implot3d

        if implot3d.get_current_context() is None:
            implot3d.create_context()
            self._own_implot3d = True

    def draw(self, materials: dict, rect=None) -> None:
        """The window; ``rect`` (x, y, w, h attributes, window points): docked there (beside the
        3D view, not over it), else a free window."""
        if not self.visible:
            return
        self.set_materials(materials)
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
            self.clipped = []
            self._controls(materials)
            self.messages = []
            self.updating = set()
            if self._select is not None:
                self.tab = self._select
                self._select = None
            self._tab_row()
            try:
                self._draw_tab(self.tab, materials)
            except ViewerError as e:  # a parameter the plots cannot use: say so, keep going
                imgui.text_wrapped(str(e))
        imgui.end()
        if pushed:
            imgui.pop_font()

    # ------------------------------------------------------------------ layout helpers (for the tabs)
    def font_k(self) -> float:
        """The current font size over the scale-1 size (16 px)."""
        return imgui.get_font_size() / 16.0

    def avail_x(self) -> float:
        return imgui.get_content_region_avail().x

    def check_fits(self, text: str, room: float) -> None:
        """Record ``text`` in ``clipped`` when it is wider than ``room`` (window points)."""
        if imgui.calc_text_size(text).x > room + 0.5:
            self.clipped.append(text)

    def plot_size(self, least: float = 150.0):
        """The rest of the window, less room for the legend (its height in the last frame) and
        the messages under the plot; at least ``least`` tall (the window scrolls then)."""
        avail = imgui.get_content_region_avail()
        lines = sum(1 + len(m) * imgui.calc_text_size("x").x // max(avail.x, 1.0) for m in self.messages)
        box = self.legend_boxes.get(self.tab)
        below = box[3] - box[1] + imgui.get_style().item_spacing.y if box else 0.0
        return imgui.ImVec2(-1, max(least, avail.y - below - lines * imgui.get_text_line_height_with_spacing()))

    def key(self, label: str, colour, style: str = "line") -> None:
        """A legend entry for the plot item ``label`` (its text before ``##``; none for a hidden
        one) in ``colour`` (``style`` "line", or "dots" for a curve drawn with markers), once per
        text and colour: the tabs that draw their legend under the plot (``legend_below``) call it
        beside each item they plot."""
        entry = (legend_text(label), tuple(float(c) for c in colour[:3]), style)
        if entry[0] and all(e[:2] != entry[:2] for e in self._keys):
            self._keys.append(entry)

    def begin_frame_rect(self, size) -> None:
        """Record the frame of the plot about to begin at the cursor (``size`` as given to
        ``begin_plot``), for the legend's check against it."""
        pos = imgui.get_cursor_screen_pos()
        w = size.x if size.x > 0 else imgui.get_content_region_avail().x
        self.plot_rects[self.tab] = (pos.x, pos.y, pos.x + w, pos.y + size.y)

    def legend_below(self) -> None:
        """The entries given to ``key`` as a legend under the plot, outside the axes
        (``plot_tabs.common.legend_below``: never over a curve, however many materials)."""
        entries, self._keys = self._keys, []
        legend_below(self, entries)

    def groups(self, names, data, same) -> list[tuple[str, list[str]]]:
        """Materials whose curves are identical (``same``), or differ by no more than
        ``CURVE_TOL`` of their largest value (``curve_gap``: one would hide under the other),
        drawn once: [(label "a = b", [a, b])]; a message says which were merged, and by how
        little they differ where they are not identical. Worked out once for the same data
        objects (the store's, never changed once made: held here, so their identities stand for
        their content): every pair compared each frame took 40-80 ms of the gallery's frames."""
        key = (self.tab, tuple(names), tuple(id(data[n]) for n in names))
        hit = self._groups.get(key)
        if hit is None:
            if len(self._groups) >= 16:
                self._groups.clear()
            hit = self._groups[key] = ([data[n] for n in names],) + self._compare(names, data, same)
        self.messages.extend(hit[2])
        return hit[1]

    def _compare(self, names, data, same):
        """``groups`` worked out: (the groups, the messages)."""
        out: list[tuple[list[str], list[str], list[str]]] = []  # members, the identical ones, notes of near ones
        for n in names:
            for members, same_as, notes in out:
                if same(data[members[0]], data[n]):
                    members.append(n)
                    same_as.append(n)
                    break
                gap = curve_gap(data[members[0]], data[n])
                if gap is not None and gap <= CURVE_TOL:
                    members.append(n)
                    notes.append(f"{n}: the same curve as {members[0]}, at most {gap:.1g} of its peak apart "
                                 f"(drawn once)")
                    break
            else:
                out.append(([n], [], []))
        messages = []
        for members, same_as, notes in out:  # one line for the identical ones of a curve
            if same_as:
                messages.append(f"{', '.join(same_as)}: the same curve as {members[0]} (drawn once)")
            messages.extend(notes)
        return [(" = ".join(members), members) for members, _, _ in out], messages

    def y(self, v):
        """The plotted value of f cos: linear, or log10(1 + v) with the log switch."""
        v = np.asarray(v, dtype=np.float64)
        return np.log10(1.0 + v) if self.log else v

    def waiting(self, data: dict) -> bool:
        """Some of ``data`` (name -> data or None) is still being computed: the tab says so, in
        place of its plot (True), and draws nothing else this frame."""
        names = [n for n, d in data.items() if d is None]
        if names:
            imgui.text_wrapped(f"computing the {self.tab} plot for {', '.join(names)} ...")
        return bool(names)

    # ------------------------------------------------------------------ controls
    def _controls(self, materials):
        k = self.font_k()
        avail = imgui.get_content_region_avail().x
        style = imgui.get_style()
        sp_x = style.item_spacing.x
        # a cell: the swatch, "solo", the checkbox and the longest name whole (names were cut
        # to "ashikhmin_shirle" in two columns of a docked panel)
        fixed = (14 * k + sp_x + imgui.calc_text_size("solo").x + 2 * style.frame_padding.x + sp_x
                 + imgui.get_frame_height() + style.item_inner_spacing.x)
        longest = max((imgui.calc_text_size(n).x for n in materials), default=0.0)
        cols = max(1, min(len(materials), 3, int((avail + sp_x) // (fixed + longest + 2 * sp_x))))
        listed = self.listed = bool(materials)
        if -(-len(materials) // cols) > LIST_ROWS:  # many materials: the list folded, the room the plot's
            shown = sum(1 for n in materials if self.shown.get(n, True)) if self.solo not in materials else 1
            listed = imgui.collapsing_header(f"materials: {shown} of {len(materials)} drawn##plot_materials")
            self.listed = None if not listed else True
        if listed and imgui.begin_table("##plot_materials", cols, imgui.TableFlags_.sizing_stretch_same):
            for name in materials:
                imgui.table_next_column()
                imgui.push_id(f"plotmat_{name}")
                imgui.color_button("##colour", vec4(self.colour(name)), imgui.ColorEditFlags_.no_tooltip,
                                   imgui.ImVec2(14 * k, 14 * k))
                imgui.same_line()
                solo = self.solo == name
                if solo:
                    imgui.push_style_color(imgui.Col_.button, vec4((0.85, 0.55, 0.1)))
                if imgui.small_button("solo"):
                    self.solo = None if solo else name
                if solo:
                    imgui.pop_style_color()
                imgui.same_line()
                room = imgui.get_content_region_avail().x - imgui.get_frame_height() - style.item_inner_spacing.x
                _, self.shown[name] = imgui.checkbox(name, self.shown.get(name, True))
                if cols > 1:  # one column: the window's width is all there is
                    self.check_fits(name, room)
                if imgui.is_item_hovered():
                    imgui.set_tooltip(f"{name}: {materials[name].model}")
                imgui.pop_id()
            imgui.end_table()
        sp = imgui.get_style().item_inner_spacing.x
        labels = ("theta_i (deg)", "plane phi (deg)", "channel", "log10(1 + f cos)")
        widest = max(imgui.calc_text_size(t).x for t in labels[:3]) + sp
        wide = avail > 2 * (widest + 180 * k) + 4 * sp  # two controls a row when both fit whole
        item = min(180 * k, max((avail / 2 if wide else avail) - widest - sp, 60 * k))
        imgui.push_item_width(item)
        _, self.theta_i = imgui.slider_float(labels[0], self.theta_i, 0.0, 89.0, "%.1f")
        if wide:
            imgui.same_line()
        _, self.phi = imgui.slider_float(labels[1], self.phi, 0.0, 90.0, "%.0f")
        if imgui.is_item_hovered():
            imgui.set_tooltip("azimuth of the plane of incidence: 0 = tangent (x-z), 90 = bitangent (y-z)")
        ch, i = imgui.combo(labels[2], CHANNELS.index(self.channel), list(CHANNEL_LABELS))
        if ch:
            self.channel = CHANNELS[i]
        if wide:
            imgui.same_line()
        _, self.log = imgui.checkbox(labels[3], self.log)
        imgui.pop_item_width()
        room = (avail / 2 if wide else avail) - item - sp
        for t in labels[:3]:
            self.check_fits(t, room)

    def _tab_row(self):
        """The tab names as a row of buttons that wraps onto further rows (the selected one
        highlighted): every name whole at any width and UI scale."""
        style = imgui.get_style()
        pad = style.frame_padding.x
        widths = [imgui.calc_text_size(t).x + 2 * pad for t in TABS]
        avail = imgui.get_content_region_avail().x
        for row in flow_rows(widths, avail, style.item_spacing.x):
            if len(row) == 1:
                self.check_fits(TABS[row[0]], avail - 2 * pad)
            for j, i in enumerate(row):
                if j:
                    imgui.same_line()
                tab = TABS[i]
                on = tab == self.tab
                if on:
                    imgui.push_style_color(imgui.Col_.button, imgui.get_style_color_vec4(imgui.Col_.tab_selected))
                if imgui.button(f"{tab}##tab", imgui.ImVec2(widths[i], 0)):
                    self.tab = tab
                if on:
                    imgui.pop_style_color()
        imgui.separator()

    # ------------------------------------------------------------------ tabs
    def _draw_tab(self, tab, materials):
        names = self.active(materials)
        if not names:
            imgui.text("no material shown: tick one above")
            return
        self._keys = []
        TAB_MODULES[tab].draw(self, names, materials)
        self.legend_below()
        if self.updating:
            self.messages.append("(computing ... drawn as before meanwhile: " + ", ".join(sorted(self.updating)) + ")")
        for m in self.messages:
            imgui.text_wrapped(m)
