"""Parameter widgets generated from the BRDF specs (one slider per Param, ranges from the spec).

Every edited value is validated through the spec before it is stored, so a typed NaN, Inf or
out-of-range number never reaches the renderer: the old value stays and the problem is
returned as a message."""

from __future__ import annotations

import math

import numpy as np
from imgui_bundle import imgui

from viewer import ViewerError, brdf
from viewer.brdf.spec import Param, Params, validate_value
from viewer.app.editor_rules import (FILE_PREFIX, FRESNEL_USES, PRESET_NONE, ROUGHNESS_LABEL,  # noqa: F401
                                     library_files, out_of_range, perceptual, preset_names, preset_params,
                                     roughness_alpha, shown_params)


def param_widget(param: Param, value, label_prefix: str = "", on_error=None):
    """Draw one widget; return (changed, new_value). The new value is not yet validated."""
    label = f"{param.name}##{label_prefix}{param.name}"
    k = param.kind
    if k == "rgb":
        vals = [float(x) for x in np.asarray(value).reshape(3)]
        if param.hi is not None and param.hi <= 1.0:
            changed, out = imgui.color_edit3(label, vals, imgui.ColorEditFlags_.float)
        else:
            lo, hi = param.slider_range
            changed, out = imgui.drag_float3(label, vals, max((hi - lo) / 500.0, 1e-4), lo, hi)
        return changed, np.array(out, dtype=np.float64)
    if k == "float":
        lo, hi = param.slider_range
        flags = imgui.SliderFlags_.logarithmic if param.log else 0
        fmt = "%.4g" if param.log or hi - lo < 0.1 else "%.3f"
        changed, out = imgui.slider_float(label, float(value), lo, hi, fmt, flags)
        return changed, float(out)
    if k == "path":
        imgui.text(f"{param.name}: {value or '(built-in example)'}")
        return False, value
    if k == "bool":
        changed, out = imgui.checkbox(label, bool(value))
        return changed, bool(out)
    if k == "choice":
        idx = param.choices.index(value)
        changed, idx = imgui.combo(label, idx, list(param.choices))
        return changed, param.choices[idx]
    if k == "table":
        changed_any = False
        new = Params(value.model, dict(value))
        if imgui.tree_node(f"{param.name}##{label_prefix}"):
            for f in param.fields:
                c, v = param_widget(f, value[f.name], f"{label_prefix}{param.name}.", on_error)
                if c:
                    new[f.name] = v
                    changed_any = True
            imgui.tree_pop()
        return changed_any, new
    if k == "lobes":
        changed_any = False
        new = [Params(l.model, dict(l)) for l in value]
        if imgui.tree_node(f"{param.name} ({len(value)})##{label_prefix}"):
            for i, lobe in enumerate(value):
                imgui.push_id(f"{label_prefix}lobe{i}")
                imgui.text(f"lobe {i}")
                for f in param.fields:
                    c, v = param_widget(f, lobe[f.name], f"{label_prefix}{i}.", on_error)
                    if c:
                        new[i][f.name] = v
                        changed_any = True
                imgui.pop_id()
            imgui.tree_pop()
        return changed_any, new
    if k == "material":
        changed_any = False
        new = value
        if imgui.tree_node(f"{param.name}: {value.model}##{label_prefix}"):
            c, new = material_editor(value, f"{label_prefix}{param.name}.", nested=True, on_error=on_error)
            changed_any = c
            imgui.tree_pop()
        return changed_any, new
    return False, value


_anisotropic: dict[str, bool] = {}  # per material (editor prefix): the alpha_x / alpha_y sliders open


CLIPPED: list[str] = []  # editor widgets of this frame whose label ran past the panel (tests read it)


def content_right() -> float:
    """The right edge of the room left on the current line (screen x): call before a widget."""
    return imgui.get_cursor_screen_pos().x + imgui.get_content_region_avail().x


def check_fit(label: str, right: float) -> None:
    """Record ``label`` in ``CLIPPED`` when the widget just drawn (its label included) ends past
    ``right`` (``content_right()`` taken before it: where imgui cuts it off)."""
    if imgui.get_item_rect_max().x > right + 0.5:
        CLIPPED.append(label.split("##")[0])


def _roughness_slider(label: str, alpha: float, lo: float, hi: float, on_error=None):
    """One slider in perceptual roughness r = sqrt(alpha), labelled as such; returns (changed,
    alpha). A typed r outside the slider's range is refused naming this slider (not alpha_x)."""
    r_lo, r_hi = perceptual(max(lo, 1e-4)), perceptual(hi)
    right = content_right()
    changed, r = imgui.slider_float(label, perceptual(alpha), r_lo, r_hi, "%.3f")
    check_fit(label, right)
    if imgui.is_item_hovered():
        imgui.set_tooltip(f"perceptual roughness r; the model's alpha = r^2 = {alpha:.4g}")
    if not changed:
        return False, alpha
    a, msg = roughness_alpha(r, lo, hi)
    if a is None:
        _report(on_error, msg)
        return False, alpha
    return True, a


def material_editor(params: Params, prefix: str, nested: bool = False, on_error=None):
    """Preset picker, model switch and the model's sliders. Returns (changed, params); a value
    the spec refuses (NaN, out of range) keeps the old one and its message goes to
    ``on_error(text)`` (the session's error notification). A microfacet lobe gets one perceptual roughness slider (r, alpha = r^2) and
    an *anisotropic* toggle that reveals alpha_x / alpha_y; parameters that do nothing in the
    chosen variant are hidden (``shown_params``). The widgets are as wide as leaves room for
    the longest label beside them (never wider than imgui's default), so no label is cut.
    A file material whose ``.brdf`` file was saved with other parameters is first fitted to the
    file (``viewer.brdf.file_carry``) and returned as changed, so the session stores it."""
    if brdf.is_file(params):
        from viewer.brdf.file_carry import carry_over

        fitted = carry_over(params)
        if fitted is not params:
            return True, fitted
    labels = ["preset", "model", ROUGHNESS_LABEL] + shown_params(params)
    room = imgui.get_content_region_avail().x
    widest = max(imgui.calc_text_size(t).x for t in labels) + imgui.get_style().item_inner_spacing.x
    imgui.push_item_width(max(min(0.65 * imgui.get_window_width(), room - widest - 2.0), 40.0))
    try:
        return _material_editor(params, prefix, nested, on_error)
    finally:
        imgui.pop_item_width()


def _material_editor(params: Params, prefix: str, nested: bool, on_error):
    presets = [PRESET_NONE] + preset_names(nested) + ([] if nested else library_files())
    ch, i = imgui.combo(f"preset##{prefix}preset", 0, presets)
    if imgui.is_item_hovered():
        imgui.set_tooltip("start this material from a preset (gold, copper, glass...): its model and values")
    if ch and i > 0:
        try:
            return True, preset_params(presets[i])
        except ViewerError as e:
            _report(on_error, str(e))
    names = [n for n in brdf.names() if not (nested and brdf.get(n).spec.nests_material)]
    if brdf.is_file(params):  # a .brdf file (dropped or loaded): shown by its name
        names = names + [params.model]
    idx = names.index(params.model) if params.model in names else 0
    changed, idx = imgui.combo(f"model##{prefix}model", idx, names)
    if changed and names[idx] != params.model and not brdf.is_file_model(names[idx]):
        return True, brdf.get(names[idx]).params()
    spec = brdf.spec_of(params)
    by_name = {p.name: p for p in spec.params}
    shown = shown_params(params)
    new = params
    any_change = False
    pair = "alpha_x" in shown and "alpha_y" in by_name
    if pair:
        # open when asked, and always for a lobe that is anisotropic already
        aniso = _anisotropic.get(prefix, False) or not math.isclose(params.alpha_x, params.alpha_y, rel_tol=1e-9)
        _anisotropic[prefix] = aniso
        if "alpha_y" not in shown:  # an isotropic distribution: one slider, no toggle
            aniso = False
        px = by_name["alpha_x"]
        lo, hi = px.slider_range
        if not aniso:
            c, a = _roughness_slider(f"{ROUGHNESS_LABEL}##{prefix}r", params.alpha_x, lo, hi, on_error)
            if c:
                new = new.replace(alpha_x=a, alpha_y=a)
                any_change = True
        if "alpha_y" in shown:
            c, aniso = imgui.checkbox(f"anisotropic##{prefix}aniso", aniso)
            if c:
                _anisotropic[prefix] = aniso
                if not aniso and not math.isclose(params.alpha_x, params.alpha_y, rel_tol=1e-9):
                    a = math.sqrt(params.alpha_x * params.alpha_y)  # the same mean roughness, isotropic
                    new = new.replace(alpha_x=a, alpha_y=a)
                    any_change = True
    for p in spec.params:
        if p.name not in shown:
            continue
        if pair and p.name in ("alpha_x", "alpha_y") and not _anisotropic.get(prefix, False):
            continue
        if p.name == "alpha" and p.kind == "float":
            lo, hi = p.slider_range
            c, v = _roughness_slider(f"{ROUGHNESS_LABEL}##{prefix}alpha", params[p.name], lo, hi, on_error)
        else:
            right = content_right()
            c, v = param_widget(p, params[p.name], prefix, on_error)
            if p.kind in ("float", "rgb", "choice", "bool"):
                check_fit(p.name, right)
            if imgui.is_item_hovered() and p.doc:
                imgui.set_tooltip(f"{p.doc}\n{p.allowed()}" + (f" [{p.unit}]" if p.unit else ""))
        if c:
            try:
                v = validate_value(p, v if p.kind != "rgb" else list(v), f"{params.model}.{p.name}", brdf.lookup_spec) \
                    if p.kind in ("float", "rgb", "choice") else v
            except ViewerError as e:
                _report(on_error, str(e))
                continue
            new = new.replace(**{p.name: v})
            any_change = True
    return any_change, new


def _report(on_error, text: str) -> None:
    if on_error is not None:
        on_error(text)


def finite_or(value: float, old: float) -> float:
    return value if math.isfinite(value) else old
