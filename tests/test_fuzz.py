"""Fuzzed inputs: mutated scene files, broken meshes, broken HDR / EXR maps.

Each case must load cleanly or fail with exactly one ``ViewerError`` whose message is one line
(no traceback, no other exception type, nothing else printed); through the command line, exit
status 2 and no output file. The generators live in ``tests/fuzz_cases.py``; the default run
uses a fixed seed and moderate counts (a few seconds), ``benchmarks/hardening.py`` runs many
more seeds and prints the counts.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from viewer import ViewerError

sys.path.insert(0, str(Path(__file__).parent))
import fuzz_cases as fc  # noqa: E402

SEED = 20240611
ROOT = Path(__file__).resolve().parents[1]


def _run(which, n, tmp_path):
    counts, failures = fc.run_fuzz(which, n, SEED, tmp_path / which)
    assert not failures, f"{len(failures)} failures, first:\n" + "\n\n".join(failures[:3])
    kinds = {k for k, _ in counts}
    expected = {"scene": fc.SCENE_KINDS, "mesh": fc.MESH_KINDS, "env": fc.ENV_KINDS}[which]
    assert kinds == set(expected)
    assert sum(counts.values()) == n
    return counts


def test_fuzzed_scene_files(tmp_path):
    counts = _run("scene", 1500, tmp_path)
    # most mutations break the file, some keep it valid (both outcomes are exercised)
    assert sum(v for (k, o), v in counts.items() if o == "ok") > 50
    assert sum(v for (k, o), v in counts.items() if o == "error") > 1000


def test_fuzzed_meshes(tmp_path, capfd):
    counts = _run("mesh", 640, tmp_path)
    assert capfd.readouterr() == ("", ""), "a library printed beside the ViewerError"
    for kind in ("empty", "garbage", "nan_coords", "inf_coords", "index_out_of_range", "no_faces"):
        assert counts[(kind, "ok")] == 0, kind
    for kind in ("nan_normals", "zero_normals", "non_manifold"):
        assert counts[(kind, "error")] == 0, kind   # repaired (normals) or accepted as is


def test_fuzzed_environment_maps(tmp_path, capfd):
    counts = _run("env", 650, tmp_path)
    assert capfd.readouterr() == ("", ""), "a library printed beside the ViewerError"
    for kind in ("empty", "garbage", "truncate", "tiny"):
        assert counts[(kind, "ok")] == 0, kind
    # NaN / inf / negative texels are sanitized (set to 0, with a warning), not refused
    for kind in ("nan_texels", "inf_texels", "negative_texels"):
        assert counts[(kind, "ok")] >= counts[(kind, "error")], kind


# ----------------------------------------------------------------------------- the bugs fuzzing found

def _error(fn, *args, **kwargs) -> str:
    with pytest.raises(ViewerError) as info:
        fn(*args, **kwargs)
    msg = str(info.value)
    assert len(msg.splitlines()) == 1, msg
    return msg


def _scene_file(tmp_path, text, name="s.toml"):
    p = tmp_path / name
    p.write_text(text, encoding="utf-8")
    return p


MINIMAL = '[[objects]]\nmesh = "sphere"\nmaterial = "m"\n[materials.m]\nmodel = "lambert"\n'


def test_huge_integers_and_deep_nesting_are_clean_errors(tmp_path):
    from viewer.scene import load_scene

    digits = "9" * 400
    # used to raise OverflowError (float() of a huge int) and, for 5000 digits, ValueError
    assert "not a finite number" in _error(load_scene, "default", [f"camera.fov_y={digits}"])
    assert "materials.ball.kd" in _error(load_scene, "default", [f"materials.ball.kd=[1, 0, {digits}]"])
    assert "allowed" in _error(load_scene, _scene_file(tmp_path, MINIMAL + f"[camera]\nfov_y = {'9' * 5000}\n"))
    # used to raise RecursionError inside tomllib, or in copy.deepcopy for moderate depths
    assert "nested" in _error(load_scene, _scene_file(tmp_path, MINIMAL + "x = " + "[" * 5000 + "]" * 5000))
    assert "nested" in _error(load_scene, _scene_file(tmp_path, MINIMAL + "x = " + "[" * 200 + "]" * 200))
    assert "nested" in _error(load_scene, "default", ["camera.fov_y=" + "[" * 200 + "]" * 200])


def test_float32_range_and_camera_limits(tmp_path):
    from viewer.scene import load_scene

    for assignment in ("lights.0.intensity=1e300", "objects.0.scale=1e39", "camera.position=[1e308, 0, 0]",
                       "environment.constant=3.5e38"):
        assert "float32" in _error(load_scene, "default", [assignment]), assignment
    assert "at least" in _error(load_scene, "default", ["camera.position=[1e-7, 0.75, 0]"])
    # a tiny but valid up / light direction: normalized without underflow (used to give NaN)
    s = load_scene("default", ["camera.up=[0, 1e-300, 0]",
                               'lights.0={type="directional", direction=[1e-300, -1e-300, 0]}'])
    assert np.allclose(s.camera.up, [0, 1, 0]) and np.allclose(s.lights[0].direction, [2 ** -0.5, -2 ** -0.5, 0])


def test_messages_stay_one_line_for_keys_with_line_breaks(tmp_path):
    from viewer.scene import load_scene

    for key in ('"a\\nb"', '"c\\rd"', '"e\\u2028f"', '"g\\u0085h"', '"' + "k" * 5000 + '"'):
        msg = _error(load_scene, _scene_file(tmp_path, MINIMAL + f"[render]\n{key} = 1\n"))
        assert "render." in msg and len(msg) < 400, msg
        msg = _error(load_scene, _scene_file(tmp_path, MINIMAL.replace('model = "lambert"', f'model = "lambert"\n{key} = 1')))
        assert "materials.m." in msg and len(msg) < 400, msg


def test_odd_paths_are_clean_errors(tmp_path):
    from viewer.environment.io import load_environment
    from viewer.scene.mesh import load_mesh
    from viewer.scene import load_scene

    odd = ["a\x00.obj", "~nobody_xyz_/a.obj", "x" * 300 + ".obj", "line\nbreak.obj", "/dev/null.obj"]
    for ref in odd:  # NUL used to raise ValueError, ~user RuntimeError, a long name OSError
        _error(load_mesh, ref)
        _error(load_environment, ref.replace(".obj", ".hdr"))
        _error(load_scene, ref.replace(".obj", ".toml"))
        _error(load_scene, _scene_file(tmp_path, MINIMAL.replace('"sphere"', repr(ref).replace("'", '"'))))
    pipe = tmp_path / "pipe.toml"
    os.mkfifo(pipe)  # reading it would block for ever
    assert "regular file" in _error(load_scene, pipe)
    assert "regular file" in _error(load_environment, "/dev/zero")


def test_corrupt_exr_gives_our_message_only(tmp_path, capfd):
    import struct

    from viewer.environment.io import load_environment, save_environment

    p = tmp_path / "m.exr"
    save_environment(p, np.ones((6, 12, 3), np.float32))
    data = p.read_bytes()
    capfd.readouterr()
    p.write_bytes(data[: len(data) * 2 // 3])     # the OpenEXR library printed two lines of its own here
    assert "corrupt OpenEXR" in _error(load_environment, p)
    i = data.find(b"dataWindow\0box2i\0") + len(b"dataWindow\0box2i\0") + 4
    p.write_bytes(data[:i] + struct.pack("<4i", 0, 0, 99999, 99999) + data[i + 16:])
    assert "100000 x 100000" in _error(load_environment, p)  # refused before a 37 GiB allocation
    out, err = capfd.readouterr()
    assert out == "" and err == "", (out, err)


def test_hdr_with_absurd_size_or_exposure(tmp_path):
    from viewer.environment.io import load_environment, save_environment

    p = tmp_path / "m.hdr"
    save_environment(p, np.ones((4, 8, 3), np.float32))
    data = p.read_bytes()
    end = data.index(b"\n\n") + 2
    nl = data.index(b"\n", end)
    p.write_bytes(data[:end] + b"-Y 99999 +X 99999" + data[nl:])
    assert "texels" in _error(load_environment, p)
    first = data.index(b"\n") + 1
    for exposure in (b"0", b"-2", b"nan", b"inf"):   # ignored with a warning
        p.write_bytes(data[:first] + b"EXPOSURE=" + exposure + b"\n" + data[first:])
        assert np.allclose(load_environment(p), 1.0, rtol=0.02)
    p.write_bytes(data[:first] + b"EXPOSURE=1e-320\n" + data[first:])
    img = load_environment(p)                        # overflows to inf: set to 0 like any bad texel
    assert np.all(np.isfinite(img)) and img.min() >= 0


def test_scene_equality_ignores_loaded_meshes():
    import tomllib

    from viewer.scene import load_scene, parse_scene, scene_to_toml

    s = load_scene("default")
    again = parse_scene(tomllib.loads(scene_to_toml(s)), s.path, label=s.label, base_dir=s.base_dir,
                        load_meshes=False)
    assert again == s   # SceneObject skips mesh_data inside a Scene too (it did only on its own)


# ----------------------------------------------------------------------------- through the CLI

def _cli(args, cwd):
    env = dict(os.environ, PYTHONPATH=str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    return subprocess.run([sys.executable, "-m", "viewer", *args], cwd=cwd, env=env, capture_output=True,
                          text=True, timeout=120)


@pytest.fixture(scope="module")
def cli_folder(tmp_path_factory):
    from viewer.environment.io import save_environment

    d = tmp_path_factory.mktemp("cli")
    save_environment(d / "good.exr", np.ones((8, 16, 3), np.float32))
    data = (d / "good.exr").read_bytes()
    (d / "cut.exr").write_bytes(data[: len(data) // 2])
    (d / "garbage.toml").write_bytes(b"[camera\n\xff\xfe\x00 = = [[")
    (d / "cut_map.toml").write_text(MINIMAL + '[environment]\nmap = "cut.exr"\n[camera]\nwidth = 8\nheight = 8\n')
    (d / "bad.obj").write_text("v 0 0 0\nv 1 0 0\nv nan 1 0\nf 1 2 3\n")
    (d / "bad_mesh.toml").write_text(MINIMAL.replace('"sphere"', '"bad.obj"'))
    return d


@pytest.mark.parametrize("args, outputs", [
    (["render", "garbage.toml", "--out", "o.png"], ["o.png"]),
    (["render", "cut_map.toml", "--out", "o.png", "--linear", "o.npy"], ["o.png", "o.npy"]),
    (["reference", "bad_mesh.toml", "--spp", "1", "--workers", "0", "--out", "r.png", "--linear", "r.npy"],
     ["r.png", "r.npy"]),
    (["compare", "default", "--spp", "1", "--out", "cmp", "--set", "materials.ball.kd=[nan, 0, 0]"], ["cmp"]),
], ids=["garbage-scene", "truncated-exr", "nan-mesh", "nan-override"])
def test_cli_bad_input_exit_2_one_line_no_output(cli_folder, args, outputs):
    r = _cli(args, cli_folder)
    assert r.returncode == 2, (r.returncode, r.stdout, r.stderr)
    lines = r.stderr.splitlines()
    assert len(lines) == 1 and lines[0].startswith("brdf-viewer: error: "), r.stderr
    assert "Traceback" not in r.stderr and r.stdout == ""
    for name in outputs:
        assert not (cli_folder / name).exists(), name
    assert not [p for p in cli_folder.iterdir() if p.name.startswith(".") and ".part" in p.name]
