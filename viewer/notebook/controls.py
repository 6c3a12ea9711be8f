"""The notebook's material editors (ipywidgets) built from the BRDF specs with the window's rules
(``viewer.app.editor_rules``): the same parameters shown and hidden (``shown_params``), the same
slider ranges (``Param.slider_range``, log where the spec says so), the same labels, one
perceptual roughness slider r (alpha = r^2) with an *anisotropic* toggle for a microfacet lobe,
and the preset / model pickers. Every change goes through ``set(key, value)`` (the view's, so a
slider and ``Viewer.set`` are one path); a refused value is shown and the widget returns to the
old one."""

from __future__ import annotations

import math

import ipywidgets as W
import numpy as np

from viewer import ViewerError, brdf
from viewer.app.editor_rules import (PRESET_NONE, ROUGHNESS_LABEL, library_files, perceptual, preset_names,
                                     preset_params, roughness_alpha, shown_params)

STYLE = {"description_width": "initial"}


def hex_colour(rgb) -> str:
    """The colour picker's #rrggbb of an rgb value in [0, 1] (the window's colour edit shows the
    stored numbers as they are, without an sRGB conversion; so does this)."""
    v = np.clip(np.asarray(rgb, float).reshape(3), 0.0, 1.0)
    return "#" + "".join(f"{int(round(x * 255)):02x}" for x in v)


def colour_value(text: str) -> list[float]:
    """The rgb value of a picker's #rrggbb."""
    text = text.lstrip("#")
    if len(text) == 3:
        text = "".join(c * 2 for c in text)
    return [int(text[i:i + 2], 16) / 255.0 for i in (0, 2, 4)]


class MaterialEditor:
    """The editor of one material (``prefix`` is its ``--set`` path with a trailing dot:
    ``materials.ball.``); ``box`` is the widget. ``get()`` returns the material's current Params,
    ``set(key, value)`` applies a change (raises ``ViewerError`` when refused), ``changed()`` is
    called after each applied change."""

    def __init__(self, get, set_value, prefix: str, changed=None, nested: bool = False):
        self.get, self.set_value, self.prefix, self.nested = get, set_value, prefix, nested
        self.on_changed = changed
        self.anisotropic = False
        self.message = W.HTML("")
        self.box = W.VBox([])
        self.controls: dict[str, W.Widget] = {}   # key (below the prefix) -> widget, for tests
        self.children: list[MaterialEditor] = []
        self.reverting: set[str] = set()
        self.rebuild()

    # ------------------------------------------------------------------ applying a change
    def apply(self, key: str, value, widget=None, old=None, rebuild=False) -> bool:
        try:
            self.set_value(self.prefix + key if key else self.prefix[:-1], value)
        except ViewerError as e:
            self.message.value = f"<span style='color:#c33'>{_escape(str(e))}</span>"
            if widget is not None and old is not None:
                widget.value = old
            return False
        self.message.value = ""
        if rebuild:
            self.rebuild()
        if self.on_changed is not None:
            self.on_changed()
        return True

    def _observe(self, widget, key, convert=lambda v: v, rebuild=False):
        def handler(change):
            if key in self.reverting:   # the refused value's widget going back: not a change
                return
            self.reverting.add(key)
            try:
                self.apply(key, convert(change["new"]), widget, change["old"], rebuild)
            finally:
                self.reverting.discard(key)
        widget.observe(handler, names="value")
        self.controls[key] = widget
        return widget

    # ------------------------------------------------------------------ the widgets
    def rebuild(self):
        params = self.get()
        self.controls, self.children = {}, []
        rows = [self._pickers(params)]
        spec = brdf.spec_of(params)
        by_name = {p.name: p for p in spec.params}
        shown = shown_params(params)
        pair = "alpha_x" in shown and "alpha_y" in by_name
        if pair:
            self.anisotropic = self.anisotropic or not math.isclose(params["alpha_x"], params["alpha_y"], rel_tol=1e-9)
            if "alpha_y" not in shown:
                self.anisotropic = False
            lo, hi = by_name["alpha_x"].slider_range
            if not self.anisotropic:
                rows.append(self._roughness("alpha_x", ("alpha_x", "alpha_y"), params["alpha_x"], lo, hi))
            if "alpha_y" in shown:
                box = W.Checkbox(value=self.anisotropic, description="anisotropic", indent=False,
                                 tooltip="separate roughness along the tangent (alpha_x) and bitangent (alpha_y)")
                box.observe(self._toggle_anisotropic, names="value")
                self.controls["anisotropic"] = box
                rows.append(box)
        for p in spec.params:
            if p.name not in shown:
                continue
            if pair and p.name in ("alpha_x", "alpha_y") and not self.anisotropic:
                continue
            if p.name == "alpha" and p.kind == "float":
                lo, hi = p.slider_range
                rows.append(self._roughness("alpha", ("alpha",), params["alpha"], lo, hi))
                continue
            rows.append(self._param(p, params[p.name], p.name))
        self.box.children = rows + [self.message]

    def _pickers(self, params):
        presets = [PRESET_NONE] + preset_names(self.nested) + ([] if self.nested else library_files())
        preset = W.Dropdown(options=presets, value=PRESET_NONE, description="preset", style=STYLE,
                            tooltip="start this material from a preset (gold, copper, glass...): its model and values")

        def pick(change):
            if change["new"] == PRESET_NONE:
                return
            try:
                new = preset_params(change["new"])
            except ViewerError as e:
                self.message.value = f"<span style='color:#c33'>{_escape(str(e))}</span>"
                return
            self.apply("", new, rebuild=True)

        preset.observe(pick, names="value")
        names = [n for n in brdf.names() if not (self.nested and brdf.get(n).spec.nests_material)]
        if brdf.is_file(params):
            names = names + [params.model]
        model = W.Dropdown(options=names, value=params.model if params.model in names else names[0],
                           description="model", style=STYLE)

        def switch(change):
            if change["new"] != params.model and not brdf.is_file_model(change["new"]):
                self.apply("", brdf.get(change["new"]).params(), rebuild=True)

        model.observe(switch, names="value")
        self.controls["preset"], self.controls["model"] = preset, model
        return W.HBox([preset, model])

    def _roughness(self, key, targets, alpha, lo, hi):
        """One slider in perceptual roughness r = sqrt(alpha) (the window's), setting ``targets``."""
        r_lo, r_hi = perceptual(max(lo, 1e-4)), perceptual(hi)
        s = W.FloatSlider(value=perceptual(alpha), min=r_lo, max=r_hi, step=(r_hi - r_lo) / 1000.0,
                          description=ROUGHNESS_LABEL, readout_format=".3f", style=STYLE,
                          tooltip=f"perceptual roughness r; the model's alpha = r^2 = {alpha:.4g}")

        def handler(change):
            a, msg = roughness_alpha(change["new"], lo, hi)
            if a is None:
                self.message.value = f"<span style='color:#c33'>{_escape(msg)}</span>"
                return
            ok = self.apply(targets[0], a)
            for t in targets[1:]:   # alpha_x and alpha_y together, as the window's slider sets them
                ok = ok and self.apply(t, a)

        s.observe(handler, names="value")
        self.controls[ROUGHNESS_LABEL] = s
        return s

    def _toggle_anisotropic(self, change):
        self.anisotropic = bool(change["new"])
        p = self.get()
        if not self.anisotropic and not math.isclose(p["alpha_x"], p["alpha_y"], rel_tol=1e-9):
            a = math.sqrt(p["alpha_x"] * p["alpha_y"])   # the same mean roughness, isotropic
            self.apply("alpha_x", a)
            self.apply("alpha_y", a)
        self.rebuild()

    def _param(self, p, value, key):
        tip = f"{p.doc}\n{p.allowed()}" + (f" [{p.unit}]" if p.unit else "")
        k = p.kind
        if k == "float":
            lo, hi = p.slider_range
            if p.log and lo > 0:
                w = W.FloatLogSlider(value=float(value), base=10, min=math.log10(lo), max=math.log10(hi),
                                     step=(math.log10(hi) - math.log10(lo)) / 500.0, description=p.name,
                                     readout_format=".4g", style=STYLE, tooltip=tip)
            else:
                w = W.FloatSlider(value=float(value), min=lo, max=hi, step=(hi - lo) / 1000.0, description=p.name,
                                  readout_format=".4g" if hi - lo < 0.1 else ".3f", style=STYLE, tooltip=tip)
            return self._observe(w, key, float)
        if k == "rgb":
            if p.hi is not None and p.hi <= 1.0:
                w = W.ColorPicker(value=hex_colour(value), description=p.name, concise=False, style=STYLE,
                                  tooltip=tip)
                return self._observe(w, key, colour_value)
            lo, hi = p.slider_range
            parts = []
            for i, x in enumerate(np.asarray(value, float).reshape(3)):
                t = W.BoundedFloatText(value=float(x), min=lo, max=hi, step=max((hi - lo) / 500.0, 1e-4),
                                       description=p.name if i == 0 else "", layout=W.Layout(width="9em"),
                                       style=STYLE, tooltip=tip)
                t.observe(lambda ch, i=i: self.apply(key, self._component(key, i, ch["new"])), names="value")
                parts.append(t)
            self.controls[key] = parts[0]
            return W.HBox(parts)
        if k == "bool":
            return self._observe(W.Checkbox(value=bool(value), description=p.name, indent=False, tooltip=tip), key, bool)
        if k == "choice":
            w = W.Dropdown(options=list(p.choices), value=value, description=p.name, style=STYLE, tooltip=tip)
            return self._observe(w, key, str, rebuild=True)   # another choice may show other parameters
        if k == "path":
            return W.Label(f"{p.name}: {value or '(built-in example)'}")
        if k == "table":
            rows = [self._param(f, value[f.name], f"{key}.{f.name}") for f in p.fields]
            return W.VBox([W.HTML(f"<b>{p.name}</b>")] + rows, layout=W.Layout(margin="0 0 0 1em"))
        if k == "lobes":
            rows = [W.HTML(f"<b>{p.name}</b> ({len(value)})")]
            for i, lobe in enumerate(value):
                rows.append(W.Label(f"lobe {i}"))
                rows += [self._param(f, lobe[f.name], f"{key}.{i}.{f.name}") for f in p.fields]
            return W.VBox(rows, layout=W.Layout(margin="0 0 0 1em"))
        if k == "material":
            sub = MaterialEditor(lambda: self.get()[key], self.set_value, self.prefix + key + ".",
                                 self.on_changed, nested=True)
            self.children.append(sub)
            return W.VBox([W.HTML(f"<b>{p.name}: {value.model}</b>"), sub.box], layout=W.Layout(margin="0 0 0 1em"))
        return W.Label(f"{p.name}: {value!r}")

    def _component(self, key, i, x):
        cur = self.get()
        for part in key.split("."):
            cur = cur[int(part)] if part.isdigit() else cur[part]
        v = [float(c) for c in np.asarray(cur, float).reshape(3)]
        v[i] = float(x)
        return v



def _escape(text: str) -> str:
    return text.replace("&", "&amp;").replace("<", "&lt;").replace(">", "&gt;")
