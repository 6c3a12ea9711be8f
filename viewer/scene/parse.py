"""Validation of parsed TOML data into a ``Scene``: every section, with one message per problem
(``parse_scene``); ``--set`` overrides are applied first (``viewer.scene.overrides``)."""

from __future__ import annotations

import copy
from pathlib import Path
from typing import Any, Sequence

import numpy as np

from viewer import ViewerError
from viewer.base.io import expand_user, one_line_errors, path_problem
from viewer.scene.environment import MAP_ALLOWED, Environment
from viewer.scene.model import (CAMERA_KEYS, DIRECTIONAL_KEYS, ENV_KEYS, EXPOSURE_RANGE, IBL_MODES, LIGHT_TYPES,
                                MAX_COORD, MAX_LIGHTS, MAX_OBJECTS, MAX_SCALE, MAX_SIZE, MAX_TRIANGLES, MIN_SCALE, MIN_VIEW_DISTANCE, SIZE_ALLOWED, MSAA_SAMPLES, OBJECT_KEYS, POINT_KEYS, RENDER_KEYS,
                                SCENE_VERSION, TONEMAPS, TOP_KEYS, Camera, Light, RenderSettings, Scene, SceneObject)
from viewer.scene.overrides import apply_override, is_material_switch, switch_material
from viewer.scene.validation import Checker, check_nesting, describe, short

@one_line_errors
def parse_scene(data: dict, path: Path | None, overrides: Sequence[str] = (), *,
                label: str | None = None, base_dir: Path | None = None,
                load_meshes: bool = True) -> "Scene":
    """Validate parsed TOML ``data`` (not modified) and build a ``Scene``.

    ``path`` names the file in messages and is where relative mesh and map paths resolve
    (``base_dir`` overrides that; without either they resolve against the working folder).
    ``overrides`` are ``--set`` assignments applied to a copy of ``data`` first.
    """
    path = Path(path) if path is not None else None
    if label is None:
        label = str(path) if path is not None else "<scene>"
    if base_dir is None:
        base_dir = path.parent if path is not None else Path.cwd()
    base_dir = Path(base_dir).absolute()
    check_nesting(data, label)  # before deepcopy, which recurses (a --set value is checked as parsed)
    data = copy.deepcopy(data)
    # a material's model or preset set by --set starts that material afresh (the model's defaults,
    # the preset's values); the other assignments apply after it, whatever their order
    firsts = [a for a in overrides if is_material_switch(a)]
    for a in firsts:
        switch_material(data, a)
    for a in overrides:
        if a not in firsts:
            apply_override(data, a)
    ck = Checker(label)
    ck.table(data, "", TOP_KEYS, what="section")

    if "version" in data:
        ck.integer(data["version"], "version", f"{SCENE_VERSION}", SCENE_VERSION, SCENE_VERSION)
    camera = _parse_camera(ck, data.get("camera", {}))
    environment = _parse_environment(ck, data.get("environment"), base_dir)
    render = _parse_render(ck, data.get("render", {}))
    materials = parse_materials(ck, data.get("materials", {}), base_dir)
    lights = _parse_lights(ck, data.get("lights", []))
    objects = _parse_objects(ck, data.get("objects"), materials)

    if load_meshes:
        from viewer.scene.mesh import load_mesh

        cache: dict[str, Any] = {}
        for i, obj in enumerate(objects):
            if obj.mesh not in cache:
                cache[obj.mesh] = load_mesh(obj.mesh, base_dir, where=f"{label}: objects[{i}].mesh")
            obj.mesh_data = cache[obj.mesh]
        tris = sum(len(o.mesh_data.indices) for o in objects)
        if tris > MAX_TRIANGLES:
            ck.fail("objects", f"{len(objects):,} objects hold {tris:,} triangles in all",
                    f"at most {MAX_TRIANGLES:,} triangles over all objects (see docs/scene-format.md); "
                    "a coarser mesh or fewer objects")

    return Scene(path=path, camera=camera, environment=environment, render=render, lights=lights,
                 objects=objects, materials=materials, data=data, label=label, base_dir=base_dir)


def _e(x: float) -> str:
    return f"{x:.0e}".replace("e+0", "e").replace("e-0", "e-")


POINT_ALLOWED = f"3 finite numbers [x, y, z] in metres, each between -{MAX_COORD:,.0f} and {MAX_COORD:,.0f}"


def point(ck: Checker, value, fld: str) -> np.ndarray:
    """A position or translation: 3 numbers of at most MAX_COORD in magnitude (farther, the
    camera's projection and the float32 the renderers compute in break down)."""
    arr = ck.vec3(value, fld, POINT_ALLOWED)
    if np.any(np.abs(arr) > MAX_COORD):
        ck.fail(fld, f"{[float(x) for x in arr]} is farther than {MAX_COORD:,.0f} m from the origin", POINT_ALLOWED)
    return arr


def _parse_camera(ck: Checker, t) -> Camera:
    ck.table(t, "camera", CAMERA_KEYS)
    cam = Camera()
    if "position" in t:
        cam.position = point(ck, t["position"], "camera.position")
    if "target" in t:
        cam.target = point(ck, t["target"], "camera.target")
    if "up" in t:
        cam.up = ck.vec3(t["up"], "camera.up", "3 finite numbers, not all zero", nonzero=True)
    if "fov_y" in t:
        cam.fov_y = ck.number(t["fov_y"], "camera.fov_y", "a number of degrees in (0, 180), the full vertical field of view",
                              0.0, 180.0, lo_open=True, hi_open=True)
    for k in ("width", "height"):
        if k in t:
            setattr(cam, k, ck.integer(t[k], f"camera.{k}", SIZE_ALLOWED, 1, MAX_SIZE))
    view = cam.target - cam.position
    if not np.any(view != 0):
        ck.fail("camera.target", "equals camera.position, so there is no viewing direction",
                "a target different from the position")
    dist = float(np.linalg.norm(view))
    if dist < MIN_VIEW_DISTANCE:  # the orbit camera clamps its distance there; 1e-300 would not normalize
        ck.fail("camera.target", f"is only {dist:.3g} m from camera.position",
                f"a target at least {MIN_VIEW_DISTANCE:g} m from the position")
    up = cam.up / np.max(np.abs(cam.up))  # scaled first: the norm of [0, 1e-200, 0] underflows
    cam.up = up / np.linalg.norm(up)      # stored unit length, as a light's direction
    if np.linalg.norm(np.cross(view / dist, cam.up)) < 1e-6:
        ck.fail("camera.up", "is parallel to the viewing direction (target - position)",
                "a vector not parallel to the viewing direction, e.g. [0, 1, 0]")
    return cam


def _parse_environment(ck: Checker, t, base_dir: Path) -> Environment:
    from viewer.environment.io import check_environment_file
    from viewer.environment.procedural import builtin_names

    env = Environment()
    env.__dict__["_where"] = ck.label
    if t is None:
        return env
    ck.table(t, "environment", ENV_KEYS)
    if "constant" in t and "map" in t:
        ck.fail("environment.map", "given together with environment.constant",
                "either constant = [r, g, b] or map = \"file.hdr\", not both")
    if "constant" in t:
        env.constant = ck.vec3(t["constant"], "environment.constant",
                               "3 numbers >= 0 (radiance, linear RGB), or one number for grey",
                               grey=True, nonneg=True)
    if "map" in t:
        env.constant = None
        name = ck.string(t["map"], "environment.map", MAP_ALLOWED)
        if name in builtin_names():  # a bare built-in name; files have a suffix
            env.map = name
        else:
            env.map = _check_file(ck, name, "environment.map", base_dir, MAP_ALLOWED)
            try:  # the file's signature only; it is decoded when first used (radiance_map)
                check_environment_file(env.map)
            except ViewerError as e:
                ck.fail("environment.map", str(e), MAP_ALLOWED)
    if "intensity" in t:
        env.intensity = ck.number(t["intensity"], "environment.intensity", "a number >= 0 (a scale factor)", 0.0)
    if "rotation_deg" in t:
        env.rotation_deg = ck.number(t["rotation_deg"], "environment.rotation_deg",
                                     "a finite number of degrees (rotation about +y)")
    return env


def _check_file(ck: Checker, value, fld: str, base_dir: Path, allowed: str) -> Path:
    ref = ck.string(value, fld, allowed)
    p = expand_user(ref)
    if not p.is_absolute():
        p = base_dir / p
    problem = path_problem(p)
    if problem == "file not found":
        ck.fail(fld, f"file not found: {p}", allowed)
    if problem is not None:
        ck.fail(fld, f"not a file: {p} ({problem})", allowed)
    try:
        with open(p, "rb") as fh:
            fh.read(1)
    except OSError as e:
        ck.fail(fld, f"cannot be read: {p} ({e.strerror or e})", allowed)
    return p


def _parse_render(ck: Checker, t) -> RenderSettings:
    ck.table(t, "render", RENDER_KEYS)
    lo, hi = EXPOSURE_RANGE
    checks = {  # the keys that are not booleans; checked in the order of RENDER_KEYS
        "ibl": lambda v, fld: ck.choice(v, fld, IBL_MODES),
        "msaa": lambda v, fld: ck.integer(v, fld, "one of " + ", ".join(map(str, MSAA_SAMPLES)), choices=MSAA_SAMPLES),
        "exposure": lambda v, fld: ck.number(v, fld, f"a number of EV in [{lo:g}, {hi:g}]", lo, hi),
        "tonemap": lambda v, fld: ck.choice(v, fld, TONEMAPS),
        "raytrace_depth": lambda v, fld: ck.integer(
            v, fld, "an integer 1..16, the most scattering events along a traced chain", 1, 16),
    }
    r = RenderSettings()
    for key in RENDER_KEYS:
        if key in t:
            check = checks.get(key, lambda v, fld: ck.boolean(v, fld))
            setattr(r, key, check(t[key], f"render.{key}"))
    return r


def _parse_lights(ck: Checker, lst) -> list[Light]:
    if isinstance(lst, dict):
        ck.fail("lights", "is a single table", "an array of tables: write [[lights]] for each light")
    if not isinstance(lst, list):
        ck.fail("lights", f"expected an array of tables, got {describe(lst)}", "[[lights]] tables")
    if len(lst) > MAX_LIGHTS:
        ck.fail("lights", f"{len(lst):,} lights", f"at most {MAX_LIGHTS} [[lights]] tables (see docs/scene-format.md)")
    out = []
    for i, t in enumerate(lst):
        fld = f"lights[{i}]"
        if not isinstance(t, dict):
            ck.fail(fld, f"expected a table, got {describe(t)}", "a [[lights]] table")
        kind = ck.choice(t.get("type", "point"), f"{fld}.type", LIGHT_TYPES)
        if kind == "point":
            ck.table(t, fld, POINT_KEYS, what="key for a point light")
            if "position" not in t:
                ck.fail(f"{fld}.position", "missing (a point light needs a position)", "3 finite numbers [x, y, z] in metres")
            light = Light("point")
            light.position = point(ck, t["position"], f"{fld}.position")
            light.intensity = ck.vec3(t.get("intensity", [1.0, 1.0, 1.0]), f"{fld}.intensity",
                                      "3 numbers >= 0 (radiant intensity, W/sr), or one number for grey",
                                      grey=True, nonneg=True)
        else:
            ck.table(t, fld, DIRECTIONAL_KEYS, what="key for a directional light")
            allowed = "3 finite numbers, not all zero: the direction the light travels (from the light toward the scene)"
            if "direction" not in t:
                ck.fail(f"{fld}.direction", "missing (a directional light needs a direction)", allowed)
            light = Light("directional")
            d = ck.vec3(t["direction"], f"{fld}.direction", allowed, nonzero=True)
            d = d / np.max(np.abs(d))  # scaled first: the norm of [1e-200, -1e-200, 0] underflows
            light.direction = d / np.linalg.norm(d)
            light.irradiance = ck.vec3(t.get("irradiance", [1.0, 1.0, 1.0]), f"{fld}.irradiance",
                                       "3 numbers >= 0 (irradiance, W/m^2), or one number for grey",
                                       grey=True, nonneg=True)
        out.append(light)
    return out


def _mesh_allowed() -> str:
    try:
        from viewer.scene.mesh import builtin_names

        names = ", ".join(builtin_names())
    except Exception:  # mesh module absent or broken: still give a useful hint
        names = "sphere, plane, ..."
    return f"a built-in mesh name ({names}) or a mesh file path relative to the scene file"


def _parse_objects(ck: Checker, lst, materials: dict) -> list[SceneObject]:
    need = "one or more [[objects]] tables, each with mesh and material"
    if lst is None:
        ck.fail("objects", "missing (a scene needs at least one object)", need)
    if isinstance(lst, dict):
        ck.fail("objects", "is a single table", "an array of tables: write [[objects]] for each object")
    if not isinstance(lst, list):
        ck.fail("objects", f"expected an array of tables, got {describe(lst)}", need)
    if not lst:
        ck.fail("objects", "is empty (a scene needs at least one object)", need)
    if len(lst) > MAX_OBJECTS:
        ck.fail("objects", f"{len(lst):,} objects", f"at most {MAX_OBJECTS:,} (see docs/scene-format.md)")
    mat_allowed = ", ".join(materials) if materials else "none defined yet: add a [materials.NAME] table"
    out = []
    for i, t in enumerate(lst):
        fld = f"objects[{i}]"
        ck.table(t, fld, OBJECT_KEYS)
        if "mesh" not in t:
            ck.fail(f"{fld}.mesh", "missing", _mesh_allowed())
        mesh = ck.string(t["mesh"], f"{fld}.mesh", _mesh_allowed())
        if "material" not in t:
            ck.fail(f"{fld}.material", "missing", "the name of a [materials.NAME] table: " + mat_allowed)
        mat = ck.string(t["material"], f"{fld}.material", "a material name: " + mat_allowed)
        if mat not in materials:
            ck.fail(f"{fld}.material", f"unknown material {mat!r}", mat_allowed)
        obj = SceneObject(mesh=mesh, material=mat)
        if "translate" in t:
            obj.translate = point(ck, t["translate"], f"{fld}.translate")
        if "scale" in t:
            s = t["scale"]
            allowed = f"a number > 0, or 3 numbers > 0 [sx, sy, sz], each in [{_e(MIN_SCALE)}, {_e(MAX_SCALE)}]"
            if isinstance(s, list):
                obj.scale = ck.vec3(s, f"{fld}.scale", allowed, positive=True)
            else:
                obj.scale = ck.number(s, f"{fld}.scale", allowed, 0.0, lo_open=True)
            if np.any(np.asarray(obj.scale) < MIN_SCALE) or np.any(np.asarray(obj.scale) > MAX_SCALE):
                shown = [float(x) for x in obj.scale] if isinstance(obj.scale, np.ndarray) else obj.scale
                ck.fail(f"{fld}.scale", f"{shown} is outside [{_e(MIN_SCALE)}, {_e(MAX_SCALE)}]", allowed)
        if "rotate_y_deg" in t:
            obj.rotate_y_deg = ck.number(t["rotate_y_deg"], f"{fld}.rotate_y_deg",
                                         "a finite number of degrees (rotation about +y)")
        out.append(obj)
    return out


def custom_material(raw: dict, where: str, base_dir: Path | None):
    """Validated parameters of a ``model = "custom"`` material: ``file`` (relative to the scene
    file) names a ``.brdf`` file whose declarations are the other keys."""
    from viewer import brdf
    from viewer.brdf.spec import validate_params

    f = raw.get("file")
    if not isinstance(f, str) or not f:
        raise ViewerError(f"{where}.file: {'missing' if f is None else 'expected a file name'}; allowed: "
                          f"a .brdf file (BRDF Explorer's format) relative to the scene file")
    path = Path(f).expanduser()
    if not path.is_absolute() and base_dir is not None:
        path = Path(base_dir) / path
    if path.suffix.lower() != ".brdf":
        raise ViewerError(f"{where}.file: {f!r} is not a .brdf file; allowed: a .brdf file relative to the scene file")
    if not path.is_file():
        raise ViewerError(f"{where}.file: no such BRDF file {f!r} (relative to the scene file)")
    model = brdf.load(path)
    raw = dict(raw)
    raw["file"] = str(model.bfile.path)
    return validate_params(model.spec, raw, where)


def parse_materials(ck: Checker, t, base_dir: Path | None = None) -> dict:
    from viewer import brdf
    from viewer.brdf.presets import PRESETS
    from viewer.brdf.spec import validate_params

    if not isinstance(t, dict):
        ck.fail("materials", f"expected a table, got {describe(t)}", "[materials.NAME] tables")
    out = {}
    for name, raw in t.items():
        fld = f"materials.{short(name, 40)}"
        if not isinstance(raw, dict):
            ck.fail(fld, f"expected a table, got {describe(raw)}",
                    f"a [{fld}] table with model = one of {', '.join(brdf.names())} (or preset = ...)")
        raw = dict(raw)
        if "preset" in raw:
            pname = raw.pop("preset")
            allowed = ", ".join(PRESETS) or "none defined"
            if not isinstance(pname, str):
                ck.fail(f"{fld}.preset", f"expected a string, got {describe(pname)}", allowed)
            if pname not in PRESETS:
                ck.fail(f"{fld}.preset", f"unknown preset {pname!r}", allowed)
            merged = copy.deepcopy(PRESETS[pname])
            if "model" in raw and raw["model"] != merged.get("model"):
                # The table picks another model: keep only the preset's parameters it knows.
                other = brdf.lookup_spec(raw["model"], f"{ck.label}: {fld}.model") if isinstance(
                    raw["model"], str) else None
                known = set(other.names) | set(other.aliases) if other else set()
                merged = {k: v for k, v in merged.items() if k in known}
            merged.update(raw)
            raw = merged
        if "model" not in raw:
            ck.fail(f"{fld}.model", "missing", ", ".join(brdf.names()) + " (or give preset = one of "
                    + (", ".join(PRESETS) or "none") + ")")
        model = raw.pop("model")
        if not isinstance(model, str):
            ck.fail(f"{fld}.model", f"expected a string, got {describe(model)}", ", ".join(brdf.names()))
        if brdf.is_file_model(model):  # a .brdf file: its declarations are the parameters
            out[name] = custom_material(raw, f"{ck.label}: {fld}", base_dir)
            continue
        spec = brdf.lookup_spec(model, f"{ck.label}: {fld}.model")
        for key in brdf.path_params(model) if base_dir is not None else ():
            if isinstance(raw.get(key), str) and raw[key]:   # a file parameter: relative to the scene file
                raw[key] = str(Path(base_dir) / Path(raw[key]).expanduser())
        out[name] = validate_params(spec, raw, f"{ck.label}: {fld}", brdf.lookup_spec)
    return out
