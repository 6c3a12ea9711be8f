"""Saving: a ``Scene`` (its current values) or one material as TOML in the scene file's format,
as text or written atomically to a file."""

from __future__ import annotations

import math
import os
import re
from pathlib import Path
from typing import Any

import numpy as np

from viewer.scene.model import SCENE_VERSION, Scene

try:  # Python >= 3.11
    import tomllib
except ModuleNotFoundError:  # pragma: no cover - Python 3.10
    import tomli as tomllib

import tomli_w


def scene_to_data(scene: Scene, absolute_paths: bool = False) -> dict:
    """The scene's current values as plain TOML data (every value explicit, presets expanded).
    Mesh and map files are written relative to the scene's folder, or (``absolute_paths``, as a
    screenshot embeds its scene) as absolute paths, so the text means the same from any folder."""
    cam = scene.camera
    d: dict[str, Any] = {"version": SCENE_VERSION}
    d["camera"] = {"position": _list(cam.position), "target": _list(cam.target), "up": _list(cam.up),
                   "fov_y": float(cam.fov_y), "width": int(cam.width), "height": int(cam.height)}
    env = scene.environment
    e: dict[str, Any] = {}
    if env.map is not None:
        e["map"] = env.map if isinstance(env.map, str) else (
            str(_base(scene) / env.map) if absolute_paths else _rel(env.map, scene))
    else:
        e["constant"] = _list(env.constant if env.constant is not None else np.zeros(3))
    e["intensity"] = float(env.intensity)
    e["rotation_deg"] = float(env.rotation_deg)
    d["environment"] = e
    r = scene.render
    d["render"] = {"ibl": r.ibl, "ssr": bool(r.ssr), "shadows": bool(r.shadows), "msaa": int(r.msaa),
                   "exposure": float(r.exposure), "tonemap": r.tonemap,
                   "ms_compensation": bool(r.ms_compensation)}
    if r.raytrace or r.raytrace_depth != 8:
        d["render"].update(raytrace=bool(r.raytrace), raytrace_depth=int(r.raytrace_depth))
    lights = []
    for light in scene.lights:
        if light.type == "point":
            lights.append({"type": "point", "position": _list(light.position), "intensity": _list(light.intensity)})
        else:
            lights.append({"type": light.type, "direction": _list(light.direction),
                           "irradiance": _list(light.irradiance)})
    if lights:
        d["lights"] = lights
    objs = []
    for o in scene.objects:
        s = o.scale
        scale = _list(s) if np.ndim(s) else float(s)
        mesh = o.mesh
        if absolute_paths:
            from viewer.scene.meshgen import GENERATORS

            if mesh not in GENERATORS:
                mesh = str(_base(scene) / Path(mesh).expanduser())   # as load_mesh resolves it
        objs.append({"mesh": mesh, "material": o.material, "translate": _list(o.translate),
                     "scale": scale, "rotate_y_deg": float(o.rotate_y_deg)})
    d["objects"] = objs
    d["materials"] = {name: _plain(p.to_plain()) for name, p in scene.materials.items()}
    return d


def _list(a) -> list:
    return [float(x) for x in np.asarray(a, dtype=np.float64).reshape(-1)]


def _plain(v):
    if isinstance(v, dict):
        return {k: _plain(x) for k, x in v.items()}
    if isinstance(v, (list, tuple)):
        return [_plain(x) for x in v]
    if isinstance(v, np.ndarray):
        return _list(v)
    if isinstance(v, np.generic):
        return v.item()
    return v


def _base(scene: Scene) -> Path:
    """The folder the scene's relative paths resolve against (absolute)."""
    return Path(scene.base_dir or (scene.path.parent if scene.path else Path.cwd())).absolute()


def _rel(p: Path, scene: Scene) -> str:
    p = Path(p)
    try:
        return Path(os.path.relpath(p, _base(scene))).as_posix()
    except ValueError:  # another drive on Windows
        return str(p)


def scene_to_toml(scene_or_data, absolute_paths: bool = False) -> str:
    """TOML text for a ``Scene`` (its current values, see ``scene_to_data``) or for plain data.
    ``parse_scene(tomllib.loads(scene_to_toml(s)), s.path) == s``."""
    data = (scene_to_data(scene_or_data, absolute_paths) if isinstance(scene_or_data, Scene)
            else _plain(scene_or_data))
    lines: list[str] = []
    _emit_table(lines, [], data, header=None)
    text = "\n".join(lines).strip("\n") + "\n"
    # tomli_w is the reference writer: fall back to it should our layout ever fail to parse back.
    try:
        if tomllib.loads(text) != data:
            raise ValueError
    except (tomllib.TOMLDecodeError, ValueError):
        text = tomli_w.dumps(data)
    return text


_BARE_KEY = re.compile(r"^[A-Za-z0-9_-]+$")


def _key(k: str) -> str:
    return k if _BARE_KEY.match(k) else _string(k)


def _string(s: str) -> str:
    return tomli_w.dumps({"v": s})[4:].strip()


def _is_aot(v) -> bool:
    return isinstance(v, list) and bool(v) and all(isinstance(x, dict) for x in v)


def _value(v) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        if math.isnan(v):
            return "nan"
        if math.isinf(v):
            return "inf" if v > 0 else "-inf"
        return repr(v)
    if isinstance(v, str):
        return _string(v)
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(_value(x) for x in v) + "]"
    if isinstance(v, dict):
        return "{ " + ", ".join(f"{_key(k)} = {_value(x)}" for k, x in v.items()) + " }"
    return tomli_w.dumps({"v": v})[4:].strip()


def _emit_table(lines: list, prefix: list, tbl: dict, header: str | None):
    """Readable TOML: scalars and number arrays inline, tables as [a.b], arrays of tables as
    [[a.b]]. ``header`` is "[]" or "[[]]" for the kind of header this table gets (None: root)."""
    simple = [(k, v) for k, v in tbl.items() if not isinstance(v, dict) and not _is_aot(v)]
    nested = [(k, v) for k, v in tbl.items() if isinstance(v, dict) or _is_aot(v)]
    name = ".".join(_key(p) for p in prefix)
    if header == "[[]]" or (header == "[]" and (simple or not nested)):
        if lines:
            lines.append("")
        lines.append(f"[[{name}]]" if header == "[[]]" else f"[{name}]")
    for k, v in simple:
        lines.append(f"{_key(k)} = {_value(v)}")
    for k, v in nested:
        if isinstance(v, dict):
            _emit_table(lines, prefix + [k], v, "[]")
        else:
            for item in v:
                _emit_table(lines, prefix + [k], item, "[[]]")


def material_to_toml(name: str, params) -> str:
    """One material as a ``[materials.NAME]`` table, the scene file's format (a material file)."""
    return scene_to_toml({"materials": {name: _plain(params.to_plain())}})


def save_scene(scene_or_data, path) -> Path:
    """Write ``scene_to_toml(scene_or_data)`` to ``path`` atomically (``viewer.base.io``: a complete
    new file or the old one, never a half-written one); returns the path."""
    from viewer.base.io import atomic_write_bytes

    return atomic_write_bytes(Path(path).expanduser(), scene_to_toml(scene_or_data).encode("utf-8"))


def save_material(name: str, params, path) -> Path:
    """Write ``material_to_toml(name, params)`` to ``path`` atomically; returns the path."""
    from viewer.base.io import atomic_write_bytes

    return atomic_write_bytes(Path(path).expanduser(), material_to_toml(name, params).encode("utf-8"))
