"""Scene files: validation messages, overrides, presets, saving, built-in scenes, transforms."""

from __future__ import annotations

import math
import os
import textwrap

try:
    import tomllib
except ModuleNotFoundError:  # pragma: no cover
    import tomli as tomllib

import numpy as np
import pytest

from viewer import ViewerError, brdf
from viewer.brdf.presets import PRESETS
from viewer.scene import (
    Scene,
    SceneObject,
    apply_override,
    builtin_scene_names,
    load_scene,
    parse_scene,
    scene_to_toml,
)

GOOD = """
[camera]
position = [0.0, 1.0, 5.0]
fov_y = 35.0
width = 320
height = 200

[[lights]]
type = "point"
position = [2.0, 3.0, 2.0]
intensity = [10.0, 10.0, 10.0]

[[lights]]
type = "directional"
direction = [0.0, -2.0, 0.0]
irradiance = 2.0

[[objects]]
mesh = "sphere"
material = "ball"

[[objects]]
mesh = "plane"
material = "floor"
translate = [0.0, -1.0, 0.0]
scale = [4.0, 1.0, 4.0]
rotate_y_deg = 30.0

[materials.ball]
model = "lambert"
albedo = [0.8, 0.3, 0.1]

[materials.floor]
model = "lambert"
albedo = 0.5
"""


def write(tmp_path, text, name="bad.toml"):
    p = tmp_path / name
    p.write_text(textwrap.dedent(text))
    return p


def error(tmp_path, text, name="bad.toml", **kw) -> str:
    p = write(tmp_path, text, name)
    with pytest.raises(ViewerError) as e:
        load_scene(str(p), load_meshes=False, **kw)
    msg = str(e.value)
    assert "\n" not in msg, msg
    return msg


def check(msg, field, *allowed, file="bad.toml"):
    """The message names the file, the field (right after it) and the allowed values."""
    assert file in msg, msg
    assert f": {field}: " in msg, msg
    assert "allowed: " in msg, msg
    tail = msg.split("allowed: ", 1)[1]
    for a in allowed:
        assert a in tail, msg


# A minimal valid body that errors below are added to.
BASE = """
[[objects]]
mesh = "sphere"
material = "m"

[materials.m]
model = "lambert"
"""


# ------------------------------------------------------------------ valid input and defaults

def test_good_scene_parses(tmp_path):
    s = load_scene(str(write(tmp_path, GOOD, "good.toml")), load_meshes=False)
    assert s.camera.width == 320 and s.camera.height == 200 and s.camera.fov_y == 35.0
    np.testing.assert_array_equal(s.camera.target, [0, 0, 0])  # default
    assert [l.type for l in s.lights] == ["point", "directional"]
    np.testing.assert_allclose(s.lights[1].direction, [0, -1, 0])  # normalized
    np.testing.assert_array_equal(s.lights[1].irradiance, [2, 2, 2])  # grey scalar
    np.testing.assert_array_equal(s.objects[1].scale, [4, 1, 4])
    assert s.materials["ball"].model == "lambert"
    np.testing.assert_array_equal(s.materials["floor"].albedo, [0.5, 0.5, 0.5])
    assert s.environment.map is None and not np.any(s.environment.constant)  # black when absent
    assert s.render.ibl == "split_sum" and s.render.msaa == 4 and s.render.shadows and not s.render.ssr
    assert s.render.tonemap == "none" and s.render.exposure == 0.0


def test_defaults_and_no_lights(tmp_path):
    s = load_scene(str(write(tmp_path, BASE, "min.toml")), load_meshes=False)
    c = s.camera
    np.testing.assert_array_equal(c.position, [0, 0, 4])
    np.testing.assert_array_equal(c.up, [0, 1, 0])
    assert (c.fov_y, c.width, c.height) == (40.0, 256, 256)
    assert s.lights == []


def test_parse_scene_does_not_modify_its_input():
    data = tomllib.loads(BASE)
    before = tomllib.loads(BASE)
    parse_scene(data, None, ["materials.m.albedo=0.1"], load_meshes=False)
    assert data == before


# ------------------------------------------------------------------ one test per kind of bad input

def test_toml_syntax_error_names_line(tmp_path):
    msg = error(tmp_path, "[camera]\nfov_y = 40\nwidth = = 3\n")
    check(msg, "line 3", "TOML")


def test_missing_file(tmp_path):
    with pytest.raises(ViewerError) as e:
        load_scene(str(tmp_path / "nope.toml"))
    assert "nope.toml" in str(e.value) and "not found" in str(e.value) and "allowed: " in str(e.value)


def test_unknown_bare_name_lists_builtins():
    with pytest.raises(ViewerError) as e:
        load_scene("no_such_scene_xyz")
    msg = str(e.value)
    assert "no_such_scene_xyz" in msg and "default" in msg.split("allowed: ")[1]


def test_unknown_section(tmp_path):
    check(error(tmp_path, BASE + "[lightz]\nx = 1\n"), "lightz", "camera", "environment", "lights", "materials")


@pytest.mark.parametrize("section,key,allowed", [
    ("camera", "fovy", ["fov_y", "position", "width"]),
    ("render", "gamma", ["ibl", "ssr", "tonemap"]),
    ("environment", "colour", ["constant", "map", "rotation_deg"]),
])
def test_unknown_key_in_section(tmp_path, section, key, allowed):
    check(error(tmp_path, BASE + f"[{section}]\n{key} = 1\n"), f"{section}.{key}", *allowed)


def test_unknown_key_in_light_and_object(tmp_path):
    msg = error(tmp_path, BASE + '[[lights]]\nposition = [0, 1, 0]\nirradiance = [1, 1, 1]\n')
    check(msg, "lights[0].irradiance", "position", "intensity")
    msg = error(tmp_path, '[[objects]]\nmesh = "sphere"\nmaterial = "m"\nrotate_x_deg = 3\n'
                '[materials.m]\nmodel = "lambert"\n')
    check(msg, "objects[0].rotate_x_deg", "rotate_y_deg", "translate", "scale")


def test_unknown_material_parameter(tmp_path):
    msg = error(tmp_path, BASE + "alpha = 0.3\n")
    check(msg, "materials.m.alpha", "albedo")


def test_string_where_three_numbers_needed(tmp_path):
    check(error(tmp_path, BASE + '[camera]\nposition = "far away"\n'), "camera.position", "3 finite numbers")
    msg = error(tmp_path, BASE + '[[lights]]\nposition = [0, 1, 0]\nintensity = "bright"\n')
    check(msg, "lights[0].intensity", "3 numbers >= 0")


def test_bool_for_float(tmp_path):
    msg = error(tmp_path, BASE + "[camera]\nfov_y = true\n")
    check(msg, "camera.fov_y", "(0, 180)")
    assert "boolean" in msg


def test_float_for_int(tmp_path):
    check(error(tmp_path, BASE + "[camera]\nwidth = 256.5\n"), "camera.width", "integer", "16384")


def test_wrong_length(tmp_path):
    msg = error(tmp_path, BASE + "[camera]\ntarget = [1.0, 2.0]\n")
    check(msg, "camera.target", "3 finite numbers")
    assert "got 2" in msg


def test_element_of_wrong_type(tmp_path):
    check(error(tmp_path, BASE + '[camera]\nup = [0, "y", 0]\n'), "camera.up[1]", "3 finite numbers")


@pytest.mark.parametrize("text,field", [
    ("[camera]\nfov_y = nan\n", "camera.fov_y"),
    ("[camera]\nposition = [0.0, inf, 4.0]\n", "camera.position"),
    ("[environment]\nconstant = [nan, 0, 0]\n", "environment.constant"),
])
def test_nan_and_inf(tmp_path, text, field):
    msg = error(tmp_path, BASE + text)
    check(msg, field)
    assert "finite" in msg


@pytest.mark.parametrize("text,field,allowed", [
    ("[camera]\nfov_y = 180.0\n", "camera.fov_y", "(0, 180)"),
    ("[camera]\nfov_y = 0\n", "camera.fov_y", "(0, 180)"),
    ("[camera]\nwidth = 0\n", "camera.width", "[1, 16384]"),
    ("[camera]\nheight = 20000\n", "camera.height", "[1, 16384]"),
    ("[render]\nmsaa = 3\n", "render.msaa", "0, 1, 2, 4, 8"),
    ("[render]\nexposure = 25.0\n", "render.exposure", "[-20, 20]"),
    ("[render]\nibl = \"magic\"\n", "render.ibl", '"split_sum", "fis", "brute_force", "off"'),
    ("[render]\ntonemap = \"hable\"\n", "render.tonemap", '"aces"'),
    ("[render]\nssr = 1\n", "render.ssr", "true, false"),
    ("[environment]\nconstant = [1, -1, 1]\n", "environment.constant", ">= 0"),
    ("[environment]\nintensity = -2\n", "environment.intensity", ">= 0"),
    ("[[lights]]\nposition = [0, 1, 0]\nintensity = [1, -1, 1]\n", "lights[0].intensity", ">= 0"),
    ("[[lights]]\ntype = \"directional\"\ndirection = [0, -1, 0]\nirradiance = -1\n",
     "lights[0].irradiance", ">= 0"),
    ("[[lights]]\ntype = \"spot\"\nposition = [0, 1, 0]\n", "lights[0].type", '"point", "directional"'),
])
def test_out_of_range(tmp_path, text, field, allowed):
    check(error(tmp_path, BASE + text), field, allowed)


@pytest.mark.parametrize("scale", ["0.0", "-1", "[1.0, 0.0, 1.0]", "[1, 2]"])
def test_bad_scale(tmp_path, scale):
    msg = error(tmp_path, f'[[objects]]\nmesh = "sphere"\nmaterial = "m"\nscale = {scale}\n'
                          '[materials.m]\nmodel = "lambert"\n')
    check(msg, "objects[0].scale", "a number > 0", "3 numbers > 0")


def test_missing_object_keys(tmp_path):
    mat = '[materials.m]\nmodel = "lambert"\n'
    check(error(tmp_path, '[[objects]]\nmaterial = "m"\n' + mat), "objects[0].mesh", "built-in mesh name")
    check(error(tmp_path, '[[objects]]\nmesh = "sphere"\n' + mat), "objects[0].material", "m")


def test_no_objects(tmp_path):
    check(error(tmp_path, '[materials.m]\nmodel = "lambert"\n'), "objects", "[[objects]]")
    check(error(tmp_path, 'objects = []\n[materials.m]\nmodel = "lambert"\n'), "objects", "[[objects]]")


def test_objects_as_single_table(tmp_path):
    check(error(tmp_path, '[objects]\nmesh = "sphere"\nmaterial = "m"\n[materials.m]\nmodel = "lambert"\n'),
          "objects", "[[objects]]")


def test_point_light_needs_position(tmp_path):
    check(error(tmp_path, BASE + "[[lights]]\nintensity = [1, 1, 1]\n"), "lights[0].position", "3 finite numbers")


def test_directional_light_needs_nonzero_direction(tmp_path):
    msg = error(tmp_path, BASE + '[[lights]]\ntype = "directional"\nirradiance = 1\n')
    check(msg, "lights[0].direction", "not all zero")
    msg = error(tmp_path, BASE + '[[lights]]\ntype = "directional"\ndirection = [0, 0, 0]\n')
    check(msg, "lights[0].direction", "not all zero", "toward the scene")


def test_unknown_material_lists_defined(tmp_path):
    msg = error(tmp_path, '[[objects]]\nmesh = "sphere"\nmaterial = "gold"\n'
                          '[materials.ball]\nmodel = "lambert"\n[materials.floor]\nmodel = "lambert"\n')
    check(msg, "objects[0].material", "ball, floor")
    assert "'gold'" in msg


def test_unknown_model_lists_registry(tmp_path):
    msg = error(tmp_path, '[[objects]]\nmesh = "sphere"\nmaterial = "m"\n[materials.m]\nmodel = "lamber"\n')
    check(msg, "materials.m.model", *brdf.names())


def test_missing_model(tmp_path):
    msg = error(tmp_path, '[[objects]]\nmesh = "sphere"\nmaterial = "m"\n[materials.m]\nalbedo = 0.5\n')
    check(msg, "materials.m.model", "lambert")


def test_bad_material_parameter_value(tmp_path):
    msg = error(tmp_path, BASE + "albedo = [0.5, 2.0, 0.5]\n")
    check(msg, "materials.m.albedo", "[0, 1]")


def test_camera_degenerate(tmp_path):
    check(error(tmp_path, BASE + "[camera]\nposition = [0, 0, 0]\n"), "camera.target", "different")
    check(error(tmp_path, BASE + "[camera]\nposition = [0, 4, 0]\n"), "camera.up", "not parallel")
    check(error(tmp_path, BASE + "[camera]\nup = [0, 0, 0]\n"), "camera.up", "not all zero")


def test_environment_map_missing_and_present(tmp_path):
    msg = error(tmp_path, BASE + '[environment]\nmap = "studio.hdr"\n')
    check(msg, "environment.map", "image file")
    assert "studio.hdr" in msg
    (tmp_path / "env").mkdir()
    (tmp_path / "env" / "studio.hdr").write_bytes(b"#?RADIANCE\n")
    s = load_scene(str(write(tmp_path, BASE + '[environment]\nmap = "env/studio.hdr"\nintensity = 2.0\n',
                             "env.toml")), load_meshes=False)
    assert s.environment.map == (tmp_path / "env" / "studio.hdr").absolute()
    assert s.environment.constant is None and s.environment.intensity == 2.0
    msg = error(tmp_path, BASE + '[environment]\nmap = "env"\n')  # a folder
    check(msg, "environment.map", "image file")
    msg = error(tmp_path, BASE + '[environment]\nmap = "env/studio.hdr"\nconstant = [1, 1, 1]\n')
    check(msg, "environment.map", "not both")


@pytest.mark.skipif(os.name != "posix" or os.geteuid() == 0, reason="root reads every file")
def test_environment_map_unreadable(tmp_path):
    f = tmp_path / "locked.hdr"
    f.write_bytes(b"x")
    f.chmod(0)
    try:
        check(error(tmp_path, BASE + '[environment]\nmap = "locked.hdr"\n'), "environment.map", "image file")
    finally:
        f.chmod(0o644)


def test_missing_mesh_file(tmp_path):
    pytest.importorskip("viewer.scene.mesh")
    p = write(tmp_path, '[[objects]]\nmesh = "meshes/gone.obj"\nmaterial = "m"\n[materials.m]\nmodel = "lambert"\n')
    with pytest.raises(ViewerError) as e:
        load_scene(str(p))
    msg = str(e.value)
    assert "bad.toml" in msg and "objects[0].mesh" in msg and "gone.obj" in msg


# ------------------------------------------------------------------ presets

def test_preset_merges_and_table_overrides(tmp_path, monkeypatch):
    monkeypatch.setitem(PRESETS, "test_clay", {"model": "lambert", "albedo": [0.7, 0.4, 0.3]})
    s = load_scene(str(write(tmp_path, '[[objects]]\nmesh = "sphere"\nmaterial = "a"\n'
                                       '[materials.a]\npreset = "test_clay"\n'
                                       '[materials.b]\npreset = "test_clay"\nalbedo = 0.25\n', "p.toml")),
                   load_meshes=False)
    assert s.materials["a"].model == "lambert"
    np.testing.assert_array_equal(s.materials["a"].albedo, [0.7, 0.4, 0.3])
    np.testing.assert_array_equal(s.materials["b"].albedo, [0.25, 0.25, 0.25])
    # an override of a preset material's parameter
    s = load_scene(str(tmp_path / "p.toml"), ["materials.a.albedo=0.1"], load_meshes=False)
    np.testing.assert_array_equal(s.materials["a"].albedo, [0.1, 0.1, 0.1])


def test_unknown_preset_lists_presets(tmp_path):
    msg = error(tmp_path, '[[objects]]\nmesh = "sphere"\nmaterial = "m"\n[materials.m]\npreset = "unobtainium"\n')
    check(msg, "materials.m.preset", *PRESETS)


def test_preset_bad_override_is_named(tmp_path):
    msg = error(tmp_path, '[[objects]]\nmesh = "sphere"\nmaterial = "m"\n'
                          '[materials.m]\npreset = "white_lambert"\nalbedo = 7\n')
    check(msg, "materials.m.albedo", "[0, 1]")


# ------------------------------------------------------------------ overrides

def test_override_nested_and_list_index():
    data = tomllib.loads(GOOD)
    apply_override(data, "materials.ball.albedo=[0.1, 0.2, 0.3]")
    apply_override(data, "lights.0.intensity=5")
    apply_override(data, "lights[1].irradiance=[1, 2, 3]")
    apply_override(data, "objects.1.translate.1=-2.5")
    apply_override(data, "camera.fov_y=60")
    apply_override(data, "render.ssr=true")
    apply_override(data, 'environment.map="x.hdr"')
    apply_override(data, "render.tonemap=aces")  # bare word: a string
    assert data["materials"]["ball"]["albedo"] == [0.1, 0.2, 0.3]
    assert data["lights"][0]["intensity"] == 5
    assert data["lights"][1]["irradiance"] == [1, 2, 3]
    assert data["objects"][1]["translate"] == [0.0, -2.5, 0.0]
    assert data["camera"]["fov_y"] == 60
    assert data["render"] == {"ssr": True, "tonemap": "aces"}  # created
    assert data["environment"] == {"map": "x.hdr"}


def test_overrides_reach_the_scene(tmp_path):
    p = write(tmp_path, GOOD, "good.toml")
    s = load_scene(str(p), ["materials.ball.albedo=0.2", "lights.0.position=[0, 5, 0]",
                            "camera.width=64", "render.msaa=0"], load_meshes=False)
    np.testing.assert_array_equal(s.materials["ball"].albedo, [0.2] * 3)
    np.testing.assert_array_equal(s.lights[0].position, [0, 5, 0])
    assert s.camera.width == 64 and s.render.msaa == 0
    assert s.data["camera"]["width"] == 64  # data is after overrides


@pytest.mark.parametrize("assignment,bad", [
    ("materials.bal.albedo=0.2", "materials.bal"),
    ("lights.7.intensity=1", "lights.7"),
    ("lights.x.intensity=1", "lights.x"),
    ("objectz.0.mesh=cube", "objectz"),
    ("camera.fov_y.x=3", "camera.fov_y.x"),
])
def test_override_typo_names_bad_part(assignment, bad):
    data = tomllib.loads(GOOD)
    with pytest.raises(ViewerError) as e:
        apply_override(data, assignment)
    msg = str(e.value)
    assert msg.startswith("--set ") and f": {bad}: " in msg and "allowed: " in msg, msg


def test_override_typo_lists_alternatives():
    data = tomllib.loads(GOOD)
    with pytest.raises(ViewerError) as e:
        apply_override(data, "materials.bal.albedo=0.2")
    assert "ball, floor" in str(e.value).split("allowed: ")[1]


def test_override_without_equals():
    with pytest.raises(ViewerError) as e:
        apply_override({}, "camera.fov_y")
    assert "KEY=VALUE" in str(e.value)


def test_override_of_unknown_leaf_is_caught_by_validation(tmp_path):
    p = write(tmp_path, GOOD, "good.toml")
    with pytest.raises(ViewerError) as e:
        load_scene(str(p), ["camera.fovy=30"], load_meshes=False)
    check(str(e.value), "camera.fovy", "fov_y", file="good.toml")
    with pytest.raises(ViewerError) as e:
        load_scene(str(p), ["camera.fov_y=500"], load_meshes=False)
    check(str(e.value), "camera.fov_y", "(0, 180)", file="good.toml")


# ------------------------------------------------------------------ saving

def _roundtrip(s: Scene):
    text = scene_to_toml(s)
    s2 = parse_scene(tomllib.loads(text), s.path, load_meshes=False)
    assert s2 == s
    assert scene_to_toml(s2) == text
    return s2


def test_round_trip(tmp_path, monkeypatch):
    monkeypatch.setitem(PRESETS, "test_clay", {"model": "lambert", "albedo": [0.7, 0.4, 0.3]})
    (tmp_path / "studio.hdr").write_bytes(b"#?RADIANCE\n")
    text = GOOD.replace('model = "lambert"\nalbedo = 0.5', 'preset = "test_clay"')
    text += '[environment]\nmap = "studio.hdr"\nrotation_deg = 90.0\n[render]\nssr = true\nexposure = -1.5\n'
    p = write(tmp_path, text, "rt.toml")
    s = load_scene(str(p), load_meshes=False)
    s2 = _roundtrip(s)
    assert s2.environment.map == s.environment.map
    assert 'map = "studio.hdr"' in scene_to_toml(s)
    # a changed scene is not equal
    s2.materials["ball"].albedo = np.array([0.1, 0.1, 0.1])
    assert s2 != s


def test_round_trip_of_edited_scene(tmp_path):
    s = load_scene(str(write(tmp_path, GOOD, "good.toml")), load_meshes=False)
    s.camera.fov_y = 55.0
    s.objects[0].scale = 2.0
    s.materials["ball"] = brdf.get("lambert").params(albedo=[0.2, 0.3, 0.4])
    s2 = _roundtrip(s)
    assert s2.camera.fov_y == 55.0 and s2.objects[0].scale == 2.0


def test_scene_to_toml_of_plain_data():
    data = tomllib.loads(GOOD)
    assert tomllib.loads(scene_to_toml(data)) == data


def test_builtin_scenes_round_trip():
    for name in builtin_scene_names():
        _roundtrip(load_scene(name, load_meshes=False))


# ------------------------------------------------------------------ built-in scenes

def test_builtin_scene_names():
    names = builtin_scene_names()
    assert names[0] == "default"
    assert {"default", "sphere", "cornell"} <= set(names)


@pytest.mark.parametrize("name", ["default", "sphere", "cornell"])
def test_every_builtin_scene_loads(name):
    pytest.importorskip("viewer.scene.mesh")
    s = load_scene(name)
    assert s.path is None and name in s.label
    assert s.objects and all(o.mesh_data is not None for o in s.objects)
    assert all(m.model in brdf.names() for m in s.materials.values())
    lo, hi = s.bounds()
    assert np.all(hi > lo - 1e-9) and np.all(np.isfinite(lo))


def test_default_scene_is_the_default():
    s = load_scene(None, load_meshes=False)
    assert s.label == "<built-in default>"
    assert load_scene("default", load_meshes=False) == s


def test_sphere_scene_is_the_analytic_one():
    s = load_scene("sphere", load_meshes=False)
    assert len(s.objects) == 1 and s.objects[0].mesh == "sphere"
    assert np.allclose(s.objects[0].model_matrix(), np.eye(4))
    assert math.isclose(np.linalg.norm(s.camera.position - s.camera.target), 4.0) and s.camera.fov_y == 40.0
    assert [l.type for l in s.lights] == ["point"]


def test_builtin_name_errors_use_builtin_label():
    with pytest.raises(ViewerError) as e:
        load_scene("default", ["camera.fov_y=-3"], load_meshes=False)
    check(str(e.value), "camera.fov_y", "(0, 180)", file="<built-in default>")


def test_file_named_like_builtin_with_suffix_is_a_file(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    write(tmp_path, BASE + "[camera]\nfov_y = 12.0\n", "sphere.toml")
    assert load_scene("sphere.toml", load_meshes=False).camera.fov_y == 12.0
    assert load_scene("sphere", load_meshes=False).camera.fov_y == 40.0


# ------------------------------------------------------------------ paths and transforms

def test_relative_mesh_path_resolves_against_scene_folder(tmp_path, monkeypatch):
    pytest.importorskip("viewer.scene.mesh")
    scene_dir = tmp_path / "scenes"
    (scene_dir / "meshes").mkdir(parents=True)
    (scene_dir / "meshes" / "tri.obj").write_text(
        "v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 0 1\nvn 0 0 1\nvn 0 0 1\nf 1//1 2//2 3//3\n")
    p = write(scene_dir, '[[objects]]\nmesh = "meshes/tri.obj"\nmaterial = "m"\nscale = 2.0\n'
                         'translate = [0.0, 0.0, -1.0]\n[materials.m]\nmodel = "lambert"\n', "rel.toml")
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    monkeypatch.chdir(elsewhere)
    s = load_scene(str(p))
    assert s.objects[0].mesh == "meshes/tri.obj"  # as written
    lo, hi = s.bounds()
    np.testing.assert_allclose(lo, [0, 0, -1], atol=1e-6)
    np.testing.assert_allclose(hi, [2, 2, -1], atol=1e-6)
    # the same through a relative scene path given from another folder
    monkeypatch.chdir(tmp_path)
    assert load_scene("scenes/rel.toml").objects[0].mesh_data is not None


def test_model_matrix():
    o = SceneObject(mesh="sphere", material="m", translate=np.array([1.0, 2.0, 3.0]), scale=2.0,
                    rotate_y_deg=90.0)
    m = o.model_matrix()
    assert m.shape == (4, 4) and m.dtype == np.float64
    # scale first: (1,0,0) -> (2,0,0); rotate +90 deg about +y: -> (0,0,-2); then translate.
    np.testing.assert_allclose(m @ [1.0, 0.0, 0.0, 1.0], [1.0, 2.0, 1.0, 1.0], atol=1e-12)
    np.testing.assert_allclose(m @ [0.0, 0.0, 1.0, 1.0], [3.0, 2.0, 3.0, 1.0], atol=1e-12)
    np.testing.assert_allclose(m @ [0.0, 1.0, 0.0, 1.0], [1.0, 4.0, 3.0, 1.0], atol=1e-12)
    # a non-uniform scale acts in object space, before the rotation
    o2 = SceneObject(mesh="sphere", material="m", scale=np.array([1.0, 1.0, 3.0]), rotate_y_deg=90.0)
    np.testing.assert_allclose(o2.model_matrix() @ [0.0, 0.0, 1.0, 1.0], [3.0, 0.0, 0.0, 1.0], atol=1e-12)
    # normals stay perpendicular to transformed tangents
    n = o2.normal_matrix() @ [1.0, 0.0, 1.0]
    t = o2.model_matrix()[:3, :3] @ [1.0, 0.0, -1.0]
    assert abs(n @ t) < 1e-12


@pytest.mark.parametrize("name", sorted(PRESETS))
def test_every_preset_loads_and_round_trips(name):
    if PRESETS[name].get("model") not in brdf.names():
        pytest.skip(f"model {PRESETS[name].get('model')!r} not registered yet")
    s = parse_scene({"objects": [{"mesh": "sphere", "material": "m"}], "materials": {"m": {"preset": name}}},
                    None, load_meshes=False)
    assert s.materials["m"].model == PRESETS[name]["model"]
    _roundtrip(s)


@pytest.mark.parametrize("name", sorted(PRESETS))
def test_every_preset_conserves_energy(name):
    """A preset is what students meet first: none may reflect more light than it receives.
    Directional albedo (reflected + transmitted) <= 1 at every incident angle. Tolerance 0.02:
    the albedo is a stratified Monte Carlo estimate (24 x 24 samples x 4 azimuths); its error for
    these smooth integrands is well below 1% (the furnace tests bound it)."""
    from viewer.brdf.albedo import directional_albedo

    s = parse_scene({"objects": [{"mesh": "sphere", "material": "m"}], "materials": {"m": {"preset": name}}},
                    None, load_meshes=False)
    p = s.materials["m"]
    cos_o = np.linspace(0.05, 1.0, 12)
    r, t = directional_albedo(brdf.get(p.model), p, cos_o, split=True)
    total = np.asarray(r) + np.asarray(t)
    # A tabulated metal's RGB reflectance is the spectral integral projected on linear Rec.709,
    # which may exceed 1 though R(lambda) < 1 at every wavelength (gold's red is 1.038: the red
    # matching function is negative where gold reflects little). The bound is then the table's
    # own largest RGB value, the furnace of a surface with that F everywhere.
    bound = 1.0
    if p.get("spectral") not in (None, "", "none"):
        from viewer.brdf import spectral_fresnel

        bound = max(bound, float(np.max(spectral_fresnel.table(p.spectral))))
    assert total.max() <= bound + 0.02, (name, total.max(axis=0), bound)


def test_dotted_key_turns_list_indices_into_path_parts():
    from viewer.scene import dotted_key

    assert dotted_key(" lobes[0].n ") == "lobes.0.n"
    assert dotted_key("lights[1].intensity") == "lights.1.intensity"
    assert dotted_key("materials.ball.alpha") == "materials.ball.alpha"


def test_save_scene_and_material_write_atomically_and_read_back(tmp_path, monkeypatch):
    """save_scene and save_material go through viewer.base.io's atomic writer; what they write loads
    back to the same scene and material."""
    from viewer.base import io as vio
    from viewer.scene import load_material_file, material_to_toml, save_material, save_scene

    written = []
    real = vio.atomic_write_bytes
    monkeypatch.setattr(vio, "atomic_write_bytes", lambda path, data: written.append(path) or real(path, data))
    s = load_scene("cornell", load_meshes=False)
    assert save_scene(s, tmp_path / "s.toml") == tmp_path / "s.toml"
    assert scene_to_toml(load_scene(tmp_path / "s.toml", load_meshes=False)) == scene_to_toml(s)
    name = sorted(s.materials)[0]
    save_material(name, s.materials[name], tmp_path / "m.toml")
    got, params = load_material_file(tmp_path / "m.toml")
    assert got == name and material_to_toml(got, params) == material_to_toml(name, s.materials[name])
    assert written == [tmp_path / "s.toml", tmp_path / "m.toml"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["m.toml", "s.toml"]  # no temporary left
