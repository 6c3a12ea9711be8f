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


def param_widget(param: Param, value, label_prefix: str = ""):
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
                c, v = param_widget(f, value[f.name], f"{label_prefix}{param.name}.")
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
                    c, v = param_widget(f, lobe[f.name], f"{label_prefix}{i}.")
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
            c, new = material_editor(value, f"{label_prefix}{param.name}.", nested=True)
            changed_any = c
            imgui.tree_pop()
        return changed_any, new
    return False, value


def material_editor(params: Params, prefix: str, nested: bool = False):
    """Model switch plus the model's sliders. Returns (changed, params); messages via last_error."""
    global last_error
    names = [n for n in brdf.names() if not (nested and brdf.get(n).spec.nests_material)]
    idx = names.index(params.model) if params.model in names else 0
    changed, idx = imgui.combo(f"model##{prefix}model", idx, names)
    if changed and names[idx] != params.model:
        return True, brdf.get(names[idx]).params()
    spec = brdf.get(params.model).spec
    new = params
    any_change = False
    for p in spec.params:
        c, v = param_widget(p, params[p.name], prefix)
        if imgui.is_item_hovered() and p.doc:
            imgui.set_tooltip(f"{p.doc}\n{p.allowed()}" + (f" [{p.unit}]" if p.unit else ""))
        if c:
            try:
                v = validate_value(p, v if p.kind != "rgb" else list(v), f"{params.model}.{p.name}", brdf.lookup_spec) \
                    if p.kind in ("float", "rgb", "choice") else v
            except ViewerError as e:
                last_error = str(e)
                continue
            new = new.replace(**{p.name: v})
            any_change = True
    return any_change, new


last_error = ""


def finite_or(value: float, old: float) -> float:
    return value if math.isfinite(value) else old
