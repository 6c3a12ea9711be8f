"""Loading scenes: built-in names, ``lecture:N``, scene files (TOML), screenshots (the scene in a
PNG's text chunk), TOML text, and material files."""

from __future__ import annotations

import os
import re
from pathlib import Path
from typing import Any, Sequence

from viewer import ViewerError
from viewer.base.io import one_line_errors, path_problem
from viewer.base.resources import SCENE_DIR
from viewer.scene.model import Scene
from viewer.scene.overrides import apply_override, dotted_key
from viewer.scene.parse import parse_materials, parse_scene
from viewer.scene.validation import Checker, loads_toml

def builtin_scene_names() -> list[str]:
    """Names of the scenes shipped in ``viewer/scenes`` (``default`` first)."""
    names = sorted(p.stem for p in SCENE_DIR.glob("*.toml"))
    if "default" in names:
        names.remove("default")
        names.insert(0, "default")
    return names


LECTURE_NAME = re.compile(r"lecture:(\S*)")  # lecture:N, N = 1 .. the number of lecture steps


def lecture_scene_names() -> list[str]:
    """``lecture:1`` .. ``lecture:N``: the lecture tour's steps as built-in scene names."""
    from viewer.scene.lecture import TOUR

    return [f"lecture:{i + 1}" for i in range(len(TOUR))]


def _lecture_scene(m, overrides, load_meshes: bool) -> "Scene":
    from viewer.scene.lecture import TOUR, tour_scene

    n = len(TOUR)
    text = m.group(0)
    allowed = f"lecture:1 .. lecture:{n} (the lecture tour's steps, 1-based)"
    if not m.group(1).isdigit():
        Checker(text).fail("scene", f"{m.group(1)!r} is not a step number", allowed)
    i = int(m.group(1))
    if not 1 <= i <= n:
        Checker(text).fail("scene", f"step {i} is out of range", allowed)
    return tour_scene(i - 1, load_meshes, overrides)


def _builtin_label(name: str) -> str:
    return f"<built-in {name}>"


@one_line_errors
def load_scene(ref: str | Path | None = None, overrides: Sequence[str] = (), *,
               load_meshes: bool = True) -> "Scene":
    """Load and validate a scene.

    ``ref`` None loads the built-in ``default``; a string without a path separator and without
    a ``.toml`` suffix that names a built-in scene (``builtin_scene_names()``) loads that one;
    ``lecture:N`` loads the lecture tour's step N (1-based; ``lecture_scene_names()``);
    anything else is a file path. ``overrides`` are ``KEY=VALUE`` assignments (``--set``)
    applied before validation. Raises ``ViewerError`` (one line) on any problem.
    """
    if ref is None:
        ref = "default"
    text = str(ref)
    seps = {"/", os.sep} | ({os.altsep} if os.altsep else set())
    is_bare = isinstance(ref, str) and not any(s in text for s in seps) and not text.endswith(".toml")
    builtins = builtin_scene_names()
    m = LECTURE_NAME.fullmatch(text) if is_bare else None
    if m is not None:
        return _lecture_scene(m, overrides, load_meshes)
    if is_bare and text in builtins:
        file = SCENE_DIR / f"{text}.toml"
        label = _builtin_label(text)
        data = _read_toml(file, label)
        return parse_scene(data, None, overrides, label=label, base_dir=SCENE_DIR, load_meshes=load_meshes)
    path = Path(ref)
    label = text
    problem = path_problem(path)
    if problem == "file not found":
        hint = ("a scene file path (.toml) or a built-in scene name: " + ", ".join(builtins)
                + ", lecture:1 .. lecture:" + str(len(lecture_scene_names())))
        if is_bare:
            Checker(label).fail("scene", "no such built-in scene or file", hint)
        Checker(label).fail("file", "not found", hint)
    if problem == "is a folder, not a file":
        Checker(label).fail("file", "is a folder, not a scene file", "a scene file path (.toml)")
    if problem is not None:  # a pipe would block the read; a name too long, a NUL character
        Checker(label).fail("file", problem, "a scene file path (.toml)")
    if path.suffix.lower() == ".png":
        # a screenshot: its text chunk holds the whole scene (viewer.scene.screenshot.png_text)
        data = _read_screenshot(path, label)
        return parse_scene(data, path, overrides, label=label, load_meshes=load_meshes)
    data = _read_toml(path, label)
    return parse_scene(data, path, overrides, label=label, load_meshes=load_meshes)


def load_scene_text(text: str, overrides: Sequence[str] = (), *, base_dir: str | Path | None = None,
                    label: str = "<scene text>", load_meshes: bool = True) -> "Scene":
    """Load and validate a scene given as TOML text (the Python API's third kind of scene).
    Relative mesh and map paths resolve against ``base_dir`` (default: the working folder).
    Raises ``ViewerError`` (one line) on any problem, as ``load_scene`` does."""
    data = loads_toml(str(text), label)
    return parse_scene(data, None, overrides, label=label, base_dir=base_dir, load_meshes=load_meshes)


SCREENSHOT_KEY = "brdf-viewer:scene"


def _read_screenshot(path: Path, label: str) -> dict:
    """The scene stored in a screenshot's PNG text chunk. Mesh and map paths in it resolve
    against the screenshot's folder; built-in names work anywhere."""
    try:
        from viewer.base.io import read_png_text

        text = read_png_text(path)
    except Exception as e:  # noqa: BLE001 - Pillow raises many kinds for a broken PNG
        Checker(label).fail("file", f"cannot be read as PNG ({type(e).__name__}: {e})",
                             "a brdf-viewer screenshot (.png) or a scene file (.toml)")
    if SCREENSHOT_KEY not in text:
        Checker(label).fail(SCREENSHOT_KEY, "this PNG holds no scene",
                             "a screenshot saved by brdf-viewer (F12 or render)")
    return _beside(loads_toml(text[SCREENSHOT_KEY], label), path.parent)


def _beside(data: dict, folder: Path) -> dict:
    """A screenshot's scene names its mesh and map files by absolute path; one that no longer
    exists there but does beside the screenshot (the PNG was copied with its files) is taken
    from there."""
    from viewer import brdf

    def moved(value):
        if not isinstance(value, str) or not os.path.isabs(value) or os.path.exists(value):
            return value
        here = folder / Path(value).name
        return str(here) if here.is_file() else value

    for obj in data.get("objects", []) if isinstance(data.get("objects"), list) else []:
        if isinstance(obj, dict) and "mesh" in obj:
            obj["mesh"] = moved(obj["mesh"])
    env = data.get("environment")
    if isinstance(env, dict) and "map" in env:
        env["map"] = moved(env["map"])
    mats = data.get("materials")
    for m in mats.values() if isinstance(mats, dict) else []:
        for key in brdf.path_params(m.get("model")) if isinstance(m, dict) else ():
            if key in m:
                m[key] = moved(m[key])
    return data


def _read_toml(path: Path, label: str) -> dict:
    from viewer.base.input_bounds import MAX_TOML_BYTES, file_size_problem

    try:
        problem = file_size_problem(os.stat(path).st_size, MAX_TOML_BYTES, "scene file")
        if problem:  # before a byte of it is read
            Checker(label).fail("file", problem, "a scene as in docs/scene-format.md")
        raw = path.read_bytes()
    except OSError as e:
        Checker(label).fail("file", f"cannot be read ({e.strerror or e})", "a readable scene file (.toml)")
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as e:
        Checker(label).fail("file", f"is not UTF-8 text (byte {e.start})", "a UTF-8 TOML text file")
    return loads_toml(text, label)


def load_material_file(path) -> tuple[str, Any]:
    """(name, Params) of the first ``[materials.NAME]`` table of a TOML file (a material file or
    a whole scene), validated like a scene's materials. Raises ViewerError (one line)."""
    path = Path(path).expanduser()
    label = str(path)
    data = _read_toml(path, label)
    mats = data.get("materials")
    if not isinstance(mats, dict) or not mats:
        Checker(label).fail("materials", "no [materials.NAME] table in the file",
                             "a file with [materials.NAME] and model = ... (or preset = ...)")
    name = next(iter(mats))
    return name, parse_materials(Checker(label), {name: mats[name]}, path.parent.absolute())[name]


def file_material(model, assignments=()):
    """Validated parameters of a file BRDF (``viewer.brdf.load``) with ``--set NAME=VALUE``
    applied to its declared parameters."""
    raw = model.params().to_plain()
    raw.pop("model", None)
    for a in assignments:
        apply_override(raw, a)
    return model.params(**raw)


def material_from_name(name: str, assignments=()):
    """Validated Params of a material named on the command line (``plot MODEL``, ``fit --model``):
    a model (its defaults), a preset, a material file (.toml), a measured file (.binary, .dat) or
    a BRDF Explorer file (.brdf, or .bparam: the values of the .brdf file it names), with
    ``--set KEY=VALUE`` applied; KEY is a parameter name, dotted into tables and nested materials
    (coating.ior, base.albedo, lobes.0.n), read as the scene's ``--set`` (``apply_override``)."""
    from viewer import brdf
    from viewer.brdf.presets import PRESETS, get_preset
    from viewer.brdf.spec import validate_params

    if name.lower().endswith(".brdf"):  # a BRDF Explorer file: its declarations are the parameters
        return file_material(brdf.load(name), assignments)
    if name.lower().endswith(".bparam"):  # BRDF Explorer's values of a .brdf file (the one it names)
        import sys

        from viewer.brdf import bparam

        lines, note = bparam.overrides(name)
        if note:
            print(f"brdf-viewer: {note}", file=sys.stderr)
        return file_material(brdf.load(bparam.parse(name).brdf_path()), lines + list(assignments))
    if name.lower().endswith((".binary", ".dat")):  # a measured BRDF file (MERL or MIT format)
        raw = {"model": "measured", "file": name}
    elif name.endswith(".toml"):
        raw = load_material_file(name)[1].to_plain()
        if brdf.is_file_model(raw.get("model")):  # a material file holding a .brdf file's material
            import json

            return file_material(brdf.load(raw["file"]),
                                 [f"{k}={json.dumps(v)}" for k, v in raw.items() if k not in ("model", "file")]
                                 + list(assignments))
    elif name in brdf.names():
        raw = {"model": name}
    elif name in PRESETS:
        raw = get_preset(name)
    else:
        raise ViewerError(f"MODEL: {name!r} is not a BRDF model or preset; allowed: models "
                          f"{', '.join(brdf.names())}; presets {', '.join(sorted(PRESETS))}")
    for a in assignments:
        if "=" not in a:
            raise ViewerError(f"--set {a}: no '=' in the assignment; allowed: KEY=VALUE with a parameter "
                              "name, e.g. alpha=0.2 or coating.ior=1.3")
        key = dotted_key(a.split("=", 1)[0])  # lobes[0].n = lobes.0.n, as apply_override
        parts = key.split(".")
        if not all(parts):
            raise ViewerError(f"--set {a}: empty part in {key!r}; allowed: a parameter name, dotted "
                              "into tables (coating.ior)")
        model_name = raw.get("model")
        spec = brdf.lookup_spec(model_name, "--set model") if isinstance(model_name, str) else None
        if spec is not None and len(parts) == 1:
            # aliases (microfacet: alpha -> alpha_x, alpha_y): the newer assignment wins
            for alias, targets in spec.aliases.items():
                if parts[0] == alias:
                    for t in targets:
                        raw.pop(t, None)
                elif parts[0] in targets and alias in raw:
                    v = raw.pop(alias)
                    for t in targets:
                        raw[t] = v
        if len(parts) > 1 and raw.get(parts[0]) is None:
            # a table, list or nested material not given yet: start from its defaults (an unknown
            # name gets an empty table, which validation below names)
            known = spec is not None and parts[0] in spec.names
            raw[parts[0]] = brdf.get(model_name).params().to_plain()[parts[0]] if known else {}
        apply_override(raw, a)
    model = raw.pop("model")
    if not isinstance(model, str):
        raise ViewerError(f"--set model: expected a model name; allowed: {', '.join(brdf.names())}")
    spec = brdf.lookup_spec(model, "--set model")
    return validate_params(spec, raw, model, brdf.lookup_spec)
