"""The live view of a handout step: a WebGL2 canvas that draws the step's objects with the
raster's own GLSL (converted at build time by ``viewer.handout.glsl_es``), with sliders made
from the same spec and editor rules as the window's.

``write_live(scene, out_dir, step)`` writes, under ``out_dir/assets/``:

- ``live.js`` and ``live.css``: the runtime, plain classic scripts (no modules, no fetch, no
  URL outside the folder: the page works from ``file://``), written once;
- ``live-step-NN.js``: the step's data (converted programs, objects, lights, camera, the
  materials' uniform blocks and controls) as a script that adds it to ``window.BRDF_LIVE``;
- ``live-mesh-HASH.js``, ``live-env-HASH.js`` and ``live-table-HASH.js``: meshes, environment
  data and measured tables, by content, so steps that share them share the file.

What a frame is, and how it matches the desktop raster: the same forward program (per material
its variant, ``viewer.gl.programs.forward_variant``), fed with the uniforms the desktop sets:
they are recorded from the renderer's own ``MaterialUniforms.set`` and ``IBL.bind`` and from
``FramePasses.frame_uniforms``, not re-derived. MSAA into a float target, resolve, then the
converted tone-map pass. Not drawn (the page says so): shadow maps, screen-space reflections,
traced specular chains, the thickness pass of absorbing glass (absorption along the path) and
thin shells (they need dual-source blending). The environment is the split sum: the map's
prefiltered layers, its SH irradiance and the materials' directional-albedo tables, all from the
project's IBL code; those tables are the step's values' (a slider move changes the point-light
shading exactly; the environment term keeps the step's tables, and the page says so).
"""

from __future__ import annotations

import base64
import hashlib
import html
import json
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from viewer import ViewerError
from viewer.base.io import atomic_write_bytes

ASSETS = "assets"
RUNTIME = "live.js"
STYLE = "live.css"
#: float sliders whose value changes more than its own slots of the uniform block (derived
#: tables, spectral tails): the block is computed in Python at this many stops over the range
STOPS = 13


@dataclass
class LiveView:
    """What a step page embeds: ``html`` (the canvas and its controls), ``scripts`` (paths
    relative to the handout folder, in order) and ``styles`` (likewise)."""

    html: str
    scripts: list[str] = field(default_factory=list)
    styles: list[str] = field(default_factory=list)


# ------------------------------------------------------------------ the desktop's GL, once
_GL: list = []  # [(context, renderer)], made on first use


def _renderer():
    """An offscreen context and renderer, for what the desktop computes on the GPU (albedo
    tables, prefiltered environment)."""
    if not _GL:
        from viewer.gl.context import create_offscreen_context
        from viewer.gl.renderer import Renderer

        ctx = create_offscreen_context()
        _GL.append((ctx, Renderer(ctx)))
    ctx, renderer = _GL[0]
    ctx.__enter__()
    return renderer


class _Uniform:
    """What ``viewer.gl.shaders.set_uniform`` writes to: the value kept, nothing cut."""

    array_length = 1 << 20
    dimension = 16

    def __init__(self, store, name):
        self._store, self._name = store, name

    @property
    def value(self):
        return self._store.get(self._name)

    @value.setter
    def value(self, v):
        self._store[self._name] = v

    def write(self, data):
        self._store[self._name] = bytes(data)


class UniformRecorder(dict):
    """A stand-in for a moderngl program that records every uniform set on it (any name is
    "in" it), so the desktop's own code says what the live view's programs get."""

    def __contains__(self, name):
        return True

    def __getitem__(self, name):
        return _Uniform(self, name)

    def recorded(self) -> dict:
        """name -> JSON-ready value: numbers as lists, bytes as base64 (the runtime reads them
        as the uniform's own type: int32 for int uniforms, float32 otherwise)."""
        out = {}
        for k, v in dict.items(self):
            if isinstance(v, (bytes, bytearray)):
                out[k] = {"b64": base64.b64encode(bytes(v)).decode()}
            elif isinstance(v, (tuple, list, np.ndarray)):
                out[k] = [float(x) for x in np.asarray(v, float).reshape(-1)]
            elif isinstance(v, (bool, np.bool_)):
                out[k] = [int(v)]
            else:
                out[k] = [float(v)]
        return out


# ------------------------------------------------------------------ encoding
def _b64(a: np.ndarray) -> str:
    return base64.b64encode(np.ascontiguousarray(a).tobytes()).decode()


def _floats(a: np.ndarray) -> dict:
    """Texture data for the runtime: float16 where every value fits (RGB16F is filterable in
    every WebGL2), else float32 (a bright sun: the runtime then needs OES_texture_float_linear)."""
    a = np.asarray(a, np.float32)
    if np.all(np.abs(a) <= 65504.0):
        return {"f16": _b64(a.astype(np.float16))}
    return {"f32": _b64(a)}


def _digest(*parts) -> str:
    h = hashlib.sha256()
    for p in parts:
        h.update(p if isinstance(p, bytes) else str(p).encode())
    return h.hexdigest()[:16]


def _script(var: str, key: str, data: dict) -> str:
    return ("window.BRDF_LIVE = window.BRDF_LIVE || {steps: {}, meshes: {}, envs: {}, tables: {}};\n"
            f"window.BRDF_LIVE.{var}[{json.dumps(key)}] = {json.dumps(data, separators=(',', ':'))};\n")


def _write(path: Path, text: str) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    if path.is_file() and path.read_text() == text:
        return
    atomic_write_bytes(path, text.encode())


# ------------------------------------------------------------------ programs
def _es(recipe_sources) -> dict:
    from viewer.handout.glsl_es import convert_program

    es = convert_program(*recipe_sources)
    return {"vs": es.vertex, "fs": es.fragment, "attrs": sorted(es.geometry_attributes)}


def forward_program(params, env_light: bool, env_constant: bool) -> tuple[str, dict]:
    """(key, converted sources) of the forward program the raster draws ``params`` with, in a
    frame without SSR or traced chains."""
    from viewer.gl.programs import FORWARD_STAGES, Recipe, forward_variant

    key, models, defines = forward_variant(params, env_light=env_light, env_constant=env_constant)
    recipe = Recipe(*FORWARD_STAGES, models=models, defines=tuple(defines.items()))
    return page_key(key), _es(recipe.sources())


def page_key(variant_key: str) -> str:
    """The name a page gives a forward program: a digest of the raster's variant key, which
    holds a .brdf file's absolute path (a page names nothing of the machine that built it)."""
    return "forward:" + _digest(variant_key)


def pass_program(name: str) -> dict:
    """The converted sources of a fixed pass (``tonemap``, ``background``)."""
    from viewer.gl.program_set import BACKGROUND, FIXED

    recipe = FIXED["tonemap"] if name == "tonemap" else BACKGROUND
    return _es(recipe.sources())


# ------------------------------------------------------------------ controls
def _set(params, sub: str, value):
    from viewer.notebook.view import set_material_value

    return set_material_value(params, sub.split("."), value, f"live view {sub}")


def _set_all(params, subs, value):
    """``params`` with every one of the control's sub-parameters ``subs`` set to ``value``."""
    for sub in subs:
        params = _set(params, sub, value)
    return params


def _pack(params, env: tuple[bool, bool]):
    from viewer.gl.brdf_glsl import uniform_block

    key = forward_program_key(params, *env)
    return key, uniform_block(params)[1]


def forward_program_key(params, env_light: bool, env_constant: bool) -> str:
    from viewer.gl.programs import forward_variant

    return page_key(forward_variant(params, env_light=env_light, env_constant=env_constant)[0])


def _leaf(params, sub: str):
    cur = params
    for part in sub.split("."):
        cur = cur[int(part)] if part.isdigit() else cur[part]
    return cur


def _probe_values(lo: float, hi: float, log: bool, n: int) -> list[float]:
    if log and lo > 0:
        return [float(x) for x in np.geomspace(lo, hi, n)]
    return [float(x) for x in np.linspace(lo, hi, n)]


def _direct_slots(block0, block1, values) -> list[int] | None:
    """The indices of the block that hold ``values`` (one per component) when only they
    changed, or None when anything else changed too."""
    diff = set(np.flatnonzero(block1 != block0).tolist())
    slots = []
    for v in values:
        hit = [i for i in sorted(diff) if block1[i] == np.float32(v)]
        if len(hit) != 1:
            return None
        slots.append(hit[0])
        diff.discard(hit[0])
    return slots if not diff else None


def _classify(params, subs, kind, lo, hi, log, env, key0, block0):
    """How a control reaches the uniform block: ("direct", slots per target) when its value lands
    in its own floats and nothing else moves, ("stops", [(value, block)]) for a float whose
    change moves other floats (derived tables), ("fixed", reason) when its change needs another
    program or cannot be probed."""
    if kind == "float":
        a, b = _probe_values(lo, hi, log, 5)[1], _probe_values(lo, hi, log, 5)[3]
        slots = []
        ok = True
        for v in (a, b):
            try:
                k, blk = _pack(_set_all(params, subs, v), env)
            except (ViewerError, ValueError):
                ok = False
                break
            if k != key0:
                return "fixed", "another value needs another program: change it in the desktop viewer"
            got = _direct_slots(block0, blk, [v] * len(subs))
            if got is None:
                ok = False
                break
            slots.append(got)
        if ok and slots[0] == slots[1]:
            return "direct", slots[0]
        stops = []
        cur = float(_leaf(params, subs[0]))
        for v in sorted(set(_probe_values(lo, hi, log, STOPS)) | {cur}):
            try:
                k, blk = _pack(_set_all(params, subs, v), env)
            except (ViewerError, ValueError):
                continue
            if k == key0:
                stops.append((v, blk))
        if len(stops) < 2:
            return "fixed", "its value cannot be changed here: change it in the desktop viewer"
        return "stops", stops
    if kind == "rgb":
        cur = np.asarray(_leaf(params, subs[0]), float)
        probes = [lo + f * (hi - lo) for f in (0.21, 0.47, 0.83)]
        try:
            p = _set(params, subs[0], probes)
            k, blk = _pack(p, env)
        except (ViewerError, ValueError):
            return "fixed", "its value cannot be changed here"
        if k != key0:
            return "fixed", "another value needs another program: change it in the desktop viewer"
        got = _direct_slots(block0, blk, probes)
        if got is None or not np.all(np.isfinite(cur)):
            return "fixed", "it changes tables computed in Python: change it in the desktop viewer"
        return "direct", got
    if kind == "bool":
        cur = bool(_leaf(params, subs[0]))
        try:
            k, blk = _pack(_set(params, subs[0], not cur), env)
        except (ViewerError, ValueError):
            return "fixed", "its value cannot be changed here"
        if k != key0:
            return "fixed", "the other value needs another program: change it in the desktop viewer"
        got = _direct_slots(block0, blk, [float(not cur)])
        if got is None:
            return "stops", [(cur, block0), (not cur, blk)]
        return "direct", got
    raise AssertionError(kind)


def _choice(params, sub, choices, env, key0, block0):
    """A choice control: per choice its block (absent, with the reason, where it needs another
    program or is refused)."""
    options = []
    for c in choices:
        entry = {"value": c}
        try:
            p = _set(params, sub, c)
            k, blk = _pack(p, env)
        except (ViewerError, ValueError) as e:
            entry["disabled"] = str(e).splitlines()[0]
            options.append(entry)
            continue
        if k != key0:
            entry["disabled"] = "needs another program: pick it in the desktop viewer"
        else:
            entry["block"] = _b64(blk.astype(np.float32))
        options.append(entry)
    return options


#: at most this many combinations of a level's choices are tabulated for ``shown_table``
MAX_COMBINATIONS = 4096


def shown_table(params) -> dict[str, dict]:
    """What the editor shows (``editor_rules.shown_params``) for every combination of the
    choices of each level of a material (its own parameters, a nested material's): per level
    prefix (``""``, ``"base."``), the choices' names and, per combination of their values joined
    by ``|``, the names shown. The page shows a parameter of a tabulated level iff the current
    combination lists it."""
    import itertools

    from viewer import brdf
    from viewer.app.editor_rules import shown_params
    from viewer.brdf.spec import Params

    out: dict[str, dict] = {}

    def level(p, prefix: str):
        spec = brdf.spec_of(p)
        choices = [q for q in spec.params if q.kind == "choice"]
        if choices and math.prod(len(q.choices) for q in choices) <= MAX_COMBINATIONS:
            table = {}
            for combo in itertools.product(*(q.choices for q in choices)):
                shown = shown_params(p.replace(**{q.name: c for q, c in zip(choices, combo)}))
                table["|".join(combo)] = [prefix + n for n in shown]
            out[prefix] = {"choices": [prefix + q.name for q in choices], "table": table}
        for q in spec.params:
            v = p[q.name]
            if q.kind == "material" and isinstance(v, Params):
                level(v, f"{prefix}{q.name}.")

    level(params, "")
    return out


def _fmt(v: float) -> str:
    return f"{v:.4g}"


def _readout(scale: str, v: float) -> str:
    """A slider's value as shown: a roughness slider shows r and the model's alpha = r^2."""
    return f"{math.sqrt(max(v, 0.0)):.4g} (\u03b1 {v:.4g})" if scale == "sqrt" else _fmt(v)


def material_controls(name: str, params, env: tuple[bool, bool]) -> list[dict]:
    """The controls of material ``name``: the window's editor rules (``shown_params``, the
    spec's slider ranges, log scales, perceptual roughness r with alpha = r^2), each with how it
    reaches the uniform block (``_classify``)."""
    from viewer import brdf
    from viewer.app.editor_rules import ROUGHNESS_LABEL, shown_params

    key0, block0 = _pack(params, env)
    out: list[dict] = []

    def walk(sub_params, prefix: str, depth: int):
        spec = brdf.spec_of(sub_params)
        shown = shown_params(sub_params)
        by_name = {p.name: p for p in spec.params}
        pair = "alpha_x" in by_name and "alpha_y" in by_name
        iso = pair and math.isclose(float(sub_params["alpha_x"]), float(sub_params["alpha_y"]), rel_tol=1e-9)

        for p in spec.params:
            sub = prefix + p.name
            full = f"materials.{name}.{sub}"
            tip = f"{p.doc} {p.allowed()}" + (f" [{p.unit}]" if p.unit else "")
            base = {"param": full, "sub": sub, "label": p.name, "doc": tip, "hidden": p.name not in shown,
                    "depth": depth}
            if p.kind == "float":
                lo, hi = p.slider_range
                subs = [sub]
                label, scale = p.name, "log10" if (p.log and lo > 0) else "linear"
                if pair and p.name == "alpha_y" and iso:
                    continue  # one roughness slider sets both
                if p.name in ("alpha", "alpha_x", "alpha_y"):
                    scale = "sqrt"
                    lo = max(lo, 1e-4)
                    label = ROUGHNESS_LABEL + ("" if p.name == "alpha" or iso else f" ({p.name})")
                    if pair and iso:
                        subs = [prefix + "alpha_x", prefix + "alpha_y"]
                mode, how = _classify(params, subs, "float", lo, hi, scale == "log10", env, key0, block0)
                c = dict(base, kind="range", label=label, scale=scale, lo=lo, hi=hi, subs=subs,
                         value=float(sub_params[p.name]), mode=mode)
                if scale == "sqrt":
                    c["doc"] = f"perceptual roughness r; the model's alpha = r^2. {tip}"
                _attach(c, mode, how)
                out.append(c)
            elif p.kind == "rgb":
                lo, hi = p.slider_range
                mode, how = _classify(params, [sub], "rgb", lo, hi, False, env, key0, block0)
                value = [float(x) for x in np.asarray(sub_params[p.name], float).reshape(3)]
                c = dict(base, kind="color" if (p.hi is not None and p.hi <= 1.0) else "rgb", lo=lo, hi=hi,
                         subs=[sub], value=value, mode=mode)
                _attach(c, mode, how)
                out.append(c)
            elif p.kind == "bool":
                mode, how = _classify(params, [sub], "bool", 0, 1, False, env, key0, block0)
                c = dict(base, kind="checkbox", subs=[sub], value=bool(sub_params[p.name]), mode=mode)
                _attach(c, mode, how)
                out.append(c)
            elif p.kind == "choice":
                opts = _choice(params, sub, p.choices, env, key0, block0)
                out.append(dict(base, kind="select", subs=[sub], value=str(sub_params[p.name]), options=opts,
                                mode="choice"))
            elif p.kind == "table":
                out.append(dict(base, kind="heading", label=p.name))
                for f in p.fields:
                    _table_field(params, sub_params[p.name], f, f"{sub}.", name, env, key0, block0, out, depth + 1,
                                 hidden=p.name not in shown)
            elif p.kind == "lobes":
                for i, lobe in enumerate(sub_params[p.name]):
                    out.append(dict(base, kind="heading", label=f"{p.name} {i}"))
                    for f in p.fields:
                        _table_field(params, lobe, f, f"{sub}.{i}.", name, env, key0, block0, out, depth + 1,
                                     hidden=False)
            elif p.kind == "material":
                out.append(dict(base, kind="heading", label=f"{p.name}: {sub_params[p.name].model}"))
                walk(sub_params[p.name], f"{sub}.", depth + 1)
        return out

    return walk(params, "", 0)


def _table_field(params, table, f, prefix, name, env, key0, block0, out, depth, hidden):
    sub = prefix + f.name
    full = f"materials.{name}.{sub}"
    tip = f"{f.doc} {f.allowed()}" + (f" [{f.unit}]" if f.unit else "")
    base = {"param": full, "sub": sub, "label": f.name, "doc": tip, "hidden": hidden, "depth": depth}
    if f.kind == "float":
        lo, hi = f.slider_range
        scale = "log10" if (f.log and lo > 0) else "linear"
        if f.name == "alpha":
            scale, lo = "sqrt", max(lo, 1e-4)
        mode, how = _classify(params, [sub], "float", lo, hi, scale == "log10", env, key0, block0)
        c = dict(base, kind="range", scale=scale, lo=lo, hi=hi, subs=[sub], value=float(table[f.name]), mode=mode)
        if scale == "sqrt":
            from viewer.app.editor_rules import ROUGHNESS_LABEL

            c["label"] = f"{ROUGHNESS_LABEL} ({f.name})"
    elif f.kind == "rgb":
        lo, hi = f.slider_range
        mode, how = _classify(params, [sub], "rgb", lo, hi, False, env, key0, block0)
        c = dict(base, kind="color" if (f.hi is not None and f.hi <= 1.0) else "rgb", lo=lo, hi=hi, subs=[sub],
                 value=[float(x) for x in np.asarray(table[f.name], float).reshape(3)], mode=mode)
    elif f.kind == "bool":
        mode, how = _classify(params, [sub], "bool", 0, 1, False, env, key0, block0)
        c = dict(base, kind="checkbox", subs=[sub], value=bool(table[f.name]), mode=mode)
    else:
        return
    _attach(c, mode, how)
    out.append(c)


def _attach(c: dict, mode: str, how) -> None:
    if mode == "direct":
        c["slots"] = how
    elif mode == "stops":
        c["stops"] = [{"value": (v if not isinstance(v, (bool, np.bool_)) else bool(v)),
                       "block": _b64(np.asarray(b, np.float32))} for v, b in how]
    else:
        c["why"] = how


# ------------------------------------------------------------------ the markup
def _control_html(c: dict, step: str) -> str:
    e = html.escape
    attrs = f'data-param="{e(c["param"])}" data-step="{step}"'
    row_cls = "brdf-live-row" + (" brdf-live-hidden" if c["hidden"] else "") + f" brdf-live-depth{c['depth']}"
    title = e(c.get("doc", ""))
    dis = ' disabled' if c.get("mode") == "fixed" else ""
    why = f' title="{e(c["why"])}"' if c.get("mode") == "fixed" else f' title="{title}"'
    label = f'<span class="brdf-live-label">{e(c["label"])}</span>'
    if c["kind"] == "heading":
        return f'<div class="brdf-live-heading brdf-live-depth{c["depth"]}">{e(c["label"])}</div>'
    if c["kind"] == "range":
        lo, hi, v = c["lo"], c["hi"], c["value"]
        if c["scale"] == "log10":
            smin, smax, sval = math.log10(lo), math.log10(hi), math.log10(max(v, lo))
        elif c["scale"] == "sqrt":
            smin, smax, sval = math.sqrt(lo), math.sqrt(hi), math.sqrt(max(v, 0.0))
        else:
            smin, smax, sval = lo, hi, v
        step_ = (smax - smin) / 1000.0
        return (f'<label class="{row_cls}" data-row="{e(c["param"])}"{why}>{label}'
                f'<input type="range" {attrs} min="{smin!r}" max="{smax!r}" step="{step_!r}" value="{sval!r}" '
                f'data-scale="{c["scale"]}"{dis}>'
                f'<output class="brdf-live-value" data-value-for="{e(c["param"])}">{_readout(c["scale"], v)}</output>'
                '</label>')
    if c["kind"] == "color":
        hexv = "#" + "".join(f"{int(round(min(max(x, 0.0), 1.0) * 255)):02x}" for x in c["value"])
        shown = ", ".join(_fmt(x) for x in c["value"])
        return (f'<label class="{row_cls}" data-row="{e(c["param"])}"{why}>{label}'
                f'<input type="color" {attrs} value="{hexv}"{dis}>'
                f'<output class="brdf-live-value" data-value-for="{e(c["param"])}">{shown}</output></label>')
    if c["kind"] == "rgb":
        parts = []
        for i, x in enumerate(c["value"]):
            parts.append(f'<input type="range" {attrs} data-channel="{i}" min="{c["lo"]!r}" max="{c["hi"]!r}" '
                         f'step="{(c["hi"] - c["lo"]) / 1000.0!r}" value="{x!r}" data-scale="linear"{dis}>')
        shown = ", ".join(_fmt(x) for x in c["value"])
        return (f'<label class="{row_cls}" data-row="{e(c["param"])}"{why}>{label}'
                f'<span class="brdf-live-rgb">{"".join(parts)}</span>'
                f'<output class="brdf-live-value" data-value-for="{e(c["param"])}">{shown}</output></label>')
    if c["kind"] == "checkbox":
        chk = " checked" if c["value"] else ""
        return (f'<label class="{row_cls}" data-row="{e(c["param"])}"{why}>{label}'
                f'<input type="checkbox" {attrs}{chk}{dis}>'
                f'<output class="brdf-live-value" data-value-for="{e(c["param"])}">'
                f'{"true" if c["value"] else "false"}</output></label>')
    if c["kind"] == "select":
        opts = []
        for o in c["options"]:
            sel = " selected" if o["value"] == c["value"] else ""
            d = f' disabled title="{e(o["disabled"])}"' if "disabled" in o else ""
            opts.append(f'<option value="{e(o["value"])}"{sel}{d}>{e(o["value"])}</option>')
        return (f'<label class="{row_cls}" data-row="{e(c["param"])}"{why}>{label}'
                f'<select {attrs}>{"".join(opts)}</select>'
                f'<output class="brdf-live-value" data-value-for="{e(c["param"])}"></output></label>')
    raise AssertionError(c["kind"])


def _notes(scene, shells, absorbers, env_on, file_env) -> list[str]:
    out = ["Live view: the viewer's own GLSL, converted to GLSL ES 3.00 when this handout was built, "
           "drawn by your browser (WebGL2). Drag to orbit, wheel or pinch to zoom, double-click to reset."]
    missing = []
    if scene.render.shadows and scene.lights:
        missing.append("shadows")
    if scene.render.ssr:
        missing.append("screen-space reflections")
    if scene.render.raytrace:
        missing.append("traced specular chains (mirrors and glass show the environment lookups)")
    if absorbers:
        missing.append("absorption along the path inside glass")
    if shells:
        missing.append("thin shells (" + ", ".join(sorted(shells)) + ": not drawn)")
    if file_env:
        missing.append("the environment light on .brdf file materials")
    if missing:
        out.append("Not in the live view (see the still images): " + "; ".join(missing) + ".")
    if env_on:
        out.append("Environment light: split sum with the prefiltered map and SH irradiance; its "
                   "directional-albedo tables are those of the step's values, so after a slider move only "
                   "the point-light shading is exact.")
    return out


# ------------------------------------------------------------------ the step
def _step_name(step: int) -> str:
    return f"{int(step):02d}"


def _mesh_asset(out_dir: Path, mesh) -> str:
    pos = np.asarray(mesh.positions, np.float32)
    nrm = np.asarray(mesh.normals, np.float32)
    tan = np.asarray(mesh.tangents, np.float32)
    idx = np.asarray(mesh.indices, np.uint32).reshape(-1)
    key = _digest(pos.tobytes(), nrm.tobytes(), tan.tobytes(), idx.tobytes())
    rel = f"{ASSETS}/live-mesh-{key}.js"
    path = out_dir / rel
    if not path.is_file():
        _write(path, _script("meshes", key, {"positions": _b64(pos), "normals": _b64(nrm), "tangents": _b64(tan),
                                             "indices": _b64(idx), "vertices": int(len(pos))}))
    return key, rel


def _env_asset(out_dir: Path, renderer, env_map, env_rad) -> tuple[str, str]:
    from viewer.gl.ibl import sanitize_map

    ibl = renderer.ibl()
    ibl.set_environment(env_map, constant=None if env_map is not None else env_rad)
    pre = np.asarray(ibl.prefiltered_data, np.float32)
    img = sanitize_map(env_map) if env_map is not None else None
    key = _digest(pre.tobytes(), b"" if img is None else img.tobytes())
    rel = f"{ASSETS}/live-env-{key}.js"
    path = out_dir / rel
    if not path.is_file():
        data = {"layers": [int(pre.shape[2]), int(pre.shape[1]), int(pre.shape[0])], "prefiltered": _floats(pre),
                "dfg": [int(ibl.dfg.shape[1]), int(ibl.dfg.shape[0])], "dfg_data": _floats(ibl.dfg)}
        if img is not None:
            data["map"] = [int(img.shape[1]), int(img.shape[0])]
            data["map_data"] = _floats(img)
        _write(path, _script("envs", key, data))
    return key, rel


def _measured_asset(out_dir: Path, params) -> tuple[str, str] | None:
    """The 3D texture of a measured material's table (float32 RGB, exact: the desktop's
    ``viewer.gl.measured_tex``), or None when the material holds none."""
    from viewer.brdf import measured
    from viewer.gl.measured_tex import measured_params

    m = measured_params(params)
    if m is None:
        return None
    d = measured.data(m)
    data = np.asarray(d.texture_data(), np.float32)
    key = _digest(str(d.texture_size()), data.tobytes())
    rel = f"{ASSETS}/live-table-{key}.js"
    path = out_dir / rel
    if not path.is_file():
        _write(path, _script("tables", key, {"size": [int(x) for x in d.texture_size()], "data": _b64(data)}))
    return key, rel


def write_runtime(out_dir: Path) -> tuple[str, str]:
    """Write the shared runtime (``assets/live.js``, ``assets/live.css``); their relative paths."""
    here = Path(__file__).resolve().parent
    js, css = f"{ASSETS}/{RUNTIME}", f"{ASSETS}/{STYLE}"
    _write(out_dir / js, (here / "live_runtime.js").read_text())
    _write(out_dir / css, (here / "live_runtime.css").read_text())
    return js, css


def step_data(scene, out_dir: Path, step: int) -> tuple[dict, list[str], list[dict]]:
    """(the step's data, the mesh and environment scripts it needs, its controls per material)."""
    from viewer import brdf
    from viewer.gl.constants import MAX_LIGHTS, TONEMAPS
    from viewer.gl.frame_passes import Frame
    from viewer.gl.meshes import instance_data
    from viewer.gl.program_set import absorbing, frame_switches, thin_shell
    from viewer.scene.camera import OrbitCamera

    renderer = _renderer()
    env = scene.environment
    _, env_on, env_constant, _ = frame_switches(scene, False)
    env_rad = np.zeros(3) if env.constant is None else np.asarray(env.constant, float) * env.intensity
    env_map = env.radiance_map() if env.map is not None else None
    assets: list[str] = []

    shells = {o.material for o in scene.objects if thin_shell(scene.materials[o.material])}
    absorbers = {o.material for o in scene.objects if absorbing(scene.materials[o.material])}
    file_env = env_on and any(brdf.is_file(scene.materials[o.material]) for o in scene.objects)

    cam = OrbitCamera.from_scene(scene)
    w, h = int(scene.camera.width), int(scene.camera.height)
    frame = Frame(w, h, cam, None, 0, False, 0, scene.lights[:MAX_LIGHTS], False, env_rad, env_map, env_on,
                  False, None)
    frame_uniforms = renderer.passes.frame_uniforms(scene, frame, 0)
    for k in ("u_view_proj", "u_camera_pos", "u_view"):
        frame_uniforms.pop(k, None)  # the runtime's camera
    fu = UniformRecorder()
    for k, v in frame_uniforms.items():
        fu[k] = v

    env_key = None
    eu = UniformRecorder()
    if env_on or env_map is not None:
        env_key, rel = _env_asset(out_dir, renderer, env_map, env_rad)
        assets.append(rel)
        renderer.ibl().bind(eu, env.rotation_deg)
        for k in ("u_env_map", "u_env_prefiltered", "u_env_dfg", "u_env_cube"):
            dict.pop(eu, k, None)  # texture units: the runtime's
    programs: dict[str, dict] = {}
    materials: dict[str, dict] = {}
    objects = []
    meshes: dict[str, str] = {}
    controls: list[dict] = []
    ms_scene = bool(getattr(scene.render, "ms_compensation", False))
    for obj in scene.objects:
        params = scene.materials[obj.material]
        if obj.material in shells:
            continue
        lit = env_on and not brdf.is_file(params)
        if obj.material not in materials:
            key, src = forward_program(params, lit, env_constant)
            programs.setdefault(key, src)
            if lit:
                renderer.material_uniforms.prepare(_OneMaterial(scene, obj), env_tables=True)
            rec = UniformRecorder()
            renderer.material_uniforms.set(rec, obj, params, ms_scene, None, env=lit)
            dict.pop(rec, "u_thickness", None)
            dict.pop(rec, "u_measured", None)
            if not lit:
                rec["u_env_on"] = 0  # a .brdf file material draws without its (sampled) environment light
            materials[obj.material] = {"program": key, "uniforms": rec.recorded(), "model": params.model}
            table = _measured_asset(out_dir, params)
            if table is not None:
                materials[obj.material]["textures"] = {"u_measured": table[0]}
                if table[1] not in assets:
                    assets.append(table[1])
            ctl = material_controls(obj.material, params, (lit, env_constant))
            materials[obj.material]["controls"] = [
                {k: v for k, v in c.items() if k not in ("doc",)} for c in ctl]
            materials[obj.material]["shown"] = shown_table(params)
            controls.append({"name": obj.material, "model": params.model,
                             "title": brdf.spec_of(params).title, "controls": ctl})
        mkey = id(obj.mesh_data)
        if mkey not in meshes:
            mk, rel = _mesh_asset(out_dir, obj.mesh_data)
            meshes[mkey] = mk
            if rel not in assets:
                assets.append(rel)
        inst = instance_data([obj])[0]
        objects.append({"mesh": meshes[mkey], "material": obj.material,
                        "model": [float(x) for x in inst[:16]], "normal": [float(x) for x in inst[16:]]})
    lo, hi = scene.bounds()
    data = {
        "step": _step_name(step),
        "size": [w, h],
        "camera": {"target": [float(x) for x in cam.target], "distance": float(cam.distance),
                   "yaw": float(cam.yaw), "pitch": float(cam.pitch), "fov_y": float(cam.fov_y),
                   "up": [float(x) for x in cam.up], "bounds": [[float(x) for x in lo], [float(x) for x in hi]]},
        "programs": programs,
        "tonemap": pass_program("tonemap"),
        "background": pass_program("background") if env_map is not None else None,
        "env": env_key,
        "env_uniforms": eu.recorded(),
        "frame_uniforms": fu.recorded(),
        "clear": [float(x) for x in env_rad],
        "msaa": int(scene.render.msaa),
        "exposure": float(scene.render.exposure),
        "tonemap_mode": int(TONEMAPS.get(scene.render.tonemap, 0)),
        "materials": materials,
        "objects": objects,
    }
    notes = _notes(scene, shells, absorbers, env_on, file_env)
    return {"data": data, "notes": notes}, assets, controls


class _OneMaterial:
    """A scene seen through one object (``MaterialUniforms.prepare`` builds its tables)."""

    def __init__(self, scene, obj):
        self.objects = [obj]
        self.materials = scene.materials
        self.render = scene.render


def write_live(scene, out_dir: Path, step: int) -> LiveView:
    """Write the runtime (once) and step ``step``'s data under ``out_dir/assets``; the markup,
    scripts and styles the step page embeds."""
    out_dir = Path(out_dir)
    name = _step_name(step)
    js, css = write_runtime(out_dir)
    info, assets, controls = step_data(scene, out_dir, step)
    data = info["data"]
    rel = f"{ASSETS}/live-step-{name}.js"
    _write(out_dir / rel, _script("steps", name, data))
    w, h = data["size"]
    e = html.escape
    parts = [f'<div class="brdf-live" data-step="{name}">',
             f'<div class="brdf-live-stage" style="aspect-ratio: {w} / {h}">'
             f'<canvas data-step="{name}" class="brdf-live-canvas" width="{w}" height="{h}" '
             f'aria-label="live view of step {name}"></canvas></div>',
             f'<p class="brdf-live-status" data-status-for="{name}">Starting the live view...</p>',
             '<div class="brdf-live-controls">']
    for m in controls:
        parts.append(f'<fieldset class="brdf-live-material" data-material="{e(m["name"])}">'
                     f'<legend>{e(m["name"])} <span class="brdf-live-model">{e(m["title"])}</span></legend>')
        parts.extend(_control_html(c, name) for c in m["controls"])
        parts.append(f'<p class="brdf-live-baked" data-baked-for="{e(m["name"])}" hidden>'
                     'environment light: tables of the step\'s values</p>')
        parts.append("</fieldset>")
    parts.append("</div>")
    parts.extend(f'<p class="brdf-live-note">{e(n)}</p>' for n in info["notes"])
    parts.append("</div>")
    return LiveView("\n".join(parts), scripts=assets + [rel, js], styles=[css])
