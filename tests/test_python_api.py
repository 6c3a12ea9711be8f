"""The Python API (docs/python-api.md): ``viewer.render`` and ``viewer.reference`` give exactly the
arrays the command line writes with ``--linear``, take a path, a built-in name or TOML text, and
explain bad input and an unguarded spawning script in one line."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import viewer
from viewer import ViewerError
from viewer.commands.cli import main

ROOT = Path(__file__).resolve().parent.parent

SPHERE_TOML = """
[camera]
position = [0.0, 0.0, 4.0]
target = [0.0, 0.0, 0.0]
fov_y = 30.0
width = 20
height = 14

[[lights]]
type = "point"
position = [2.0, 3.0, 4.0]
intensity = [10.0, 10.0, 10.0]

[[objects]]
mesh = "sphere"
material = "ball"

[materials.ball]
model = "microfacet"
alpha = 0.3
"""


def _env():
    env = dict(os.environ)
    env["PYTHONPATH"] = str(ROOT) + os.pathsep + env.get("PYTHONPATH", "")
    return env


def test_render_equals_the_cli_bit_for_bit(tmp_path):
    over = ["materials.ball.albedo=[0.2,0.5,0.8]"]
    assert main(["render", "sphere", "--out", str(tmp_path / "a.png"), "--linear", str(tmp_path / "a.npy"),
                 "--width", "40", "--height", "30", "--set", over[0]]) == 0
    cli = np.load(tmp_path / "a.npy")
    api = viewer.render("sphere", width=40, height=30, overrides=over)
    assert api.dtype == np.float32 and api.shape == (30, 40, 3)
    assert api.mean() > 0.01
    np.testing.assert_array_equal(api, cli)
    # a second call reuses the renderer and gives the same bits; a Path works like a str
    np.testing.assert_array_equal(viewer.render(ROOT / "viewer" / "scenes" / "sphere.toml", width=40,
                                                height=30, overrides=over), cli)


def test_render_after_reference_gives_the_same_image():
    """A notebook's reference call in between (its engine choice makes and releases a GL context
    of its own) must not change what render returns."""
    before = viewer.render("sphere", width=24, height=16)
    viewer.reference("sphere", spp=1, width=8, height=6, workers=0, max_depth=1)
    np.testing.assert_array_equal(viewer.render("sphere", width=24, height=16), before)


def test_render_takes_toml_text_like_a_file(tmp_path):
    f = tmp_path / "s.toml"
    f.write_text(SPHERE_TOML)
    assert main(["render", str(f), "--out", str(tmp_path / "a.png"), "--linear", str(tmp_path / "a.npy")]) == 0
    api = viewer.render(SPHERE_TOML)
    assert api.shape == (14, 20, 3)
    np.testing.assert_array_equal(api, np.load(tmp_path / "a.npy"))


def test_reference_equals_the_cli_for_the_same_seed(tmp_path):
    assert main(["reference", "sphere", "--spp", "2", "--seed", "5", "--width", "16", "--height", "12",
                 "--out", str(tmp_path / "r.png"), "--linear", str(tmp_path / "r.npy")]) == 0
    cli = np.load(tmp_path / "r.npy")
    api = viewer.reference("sphere", spp=2, seed=5, width=16, height=12)
    assert api.dtype == np.float32 and api.shape == (12, 16, 3) and api.mean() > 0
    np.testing.assert_array_equal(api, cli)
    # in-process rendering (no pool) gives the same image; another seed another one
    np.testing.assert_array_equal(viewer.reference("sphere", spp=2, seed=5, width=16, height=12, workers=0), cli)
    assert not np.array_equal(viewer.reference("sphere", spp=2, seed=6, width=16, height=12, workers=0), cli)


@pytest.mark.parametrize("call, needle", [
    (lambda: viewer.reference("sphere", spp=1, engine="gpu-fast"), "engine: 'gpu-fast' is not a reference engine; allowed: cpu, gpu, auto"),
    (lambda: viewer.reference("sphere", spp=0), "spp: 0 is out of range"),
    (lambda: viewer.reference("sphere", spp=1, max_depth=0), "max_depth: 0 is out of range"),
    (lambda: viewer.render("no_such_scene"), "no such built-in scene or file"),
    (lambda: viewer.render("sphere", overrides=["camera.fov_y=200"]), "camera.fov_y: 200 is out of range"),
    (lambda: viewer.render("[camera\nwidth = 3"), "<scene text>"),
    (lambda: viewer.render(42), "int is not a scene"),
])
def test_bad_input_is_one_viewer_error(call, needle):
    with pytest.raises(ViewerError) as e:
        call()
    assert needle in str(e.value) and "\n" not in str(e.value)


def test_reference_engine_choice():
    from viewer.api import REFERENCE_ENGINES, reference_engine

    from viewer.reference_common.select import choose_engine

    # the CLI's choice (cpu on software OpenGL, gpu on a hardware GPU)
    assert reference_engine("auto") == choose_engine("auto")[0] and reference_engine("cpu") == "cpu"
    assert reference_engine("gpu") == "gpu"
    assert set(REFERENCE_ENGINES) == {"cpu", "gpu", "auto"}


SCRIPT = """
import viewer
{body}
"""


def _run_script(tmp_path, text, name="script.py"):
    f = tmp_path / name
    f.write_text(text)
    return subprocess.run([sys.executable, str(f)], cwd=tmp_path, env=_env(), capture_output=True, text=True,
                          timeout=300)


def test_unguarded_script_gets_one_line_naming_the_fix(tmp_path):
    # glass (transmission: the numpy steps) renders on worker processes, which an unguarded
    # script cannot start; the sphere alone would render on threads, which need no guard
    body = 'img = viewer.reference("sphere", spp=1, width=8, height=8, overrides=["materials.ball.preset=glass"])'
    r = _run_script(tmp_path, SCRIPT.format(body=body))
    assert r.returncode == 1
    last = r.stderr.strip().splitlines()[-1]
    assert last.startswith("viewer.ViewerError: script.py, line 3:") and 'if __name__ == "__main__":' in last
    assert "bootstrapping phase" not in r.stderr  # no worker ever started


def test_guarded_script_and_notebook_style_code_run(tmp_path):
    guarded = SCRIPT.format(body='def main():\n    print(viewer.reference("sphere", spp=1, width=8, height=8).shape)\n'
                                 'if __name__ == "__main__":\n    main()')
    r = _run_script(tmp_path, guarded)
    assert r.returncode == 0 and "(8, 8, 3)" in r.stdout, r.stderr
    # code with no file behind it (a Jupyter cell, the REPL, python -c) needs no guard: the spawned
    # workers have no main script to re-import
    r = subprocess.run([sys.executable, "-c", 'import viewer; print(viewer.reference("sphere", spp=1, width=8, '
                        'height=8).shape)'], cwd=tmp_path, env=_env(), capture_output=True, text=True, timeout=300)
    assert r.returncode == 0 and "(8, 8, 3)" in r.stdout, r.stderr


def test_version_is_the_packages(capsys):
    with pytest.raises(SystemExit) as e:
        main(["--version"])
    assert e.value.code == 0
    out = capsys.readouterr().out.strip()
    assert out == f"brdf-viewer {viewer.__version__}"
    try:  # pyproject.toml is the one place the version is written; installed metadata repeats it
        import tomllib
    except ModuleNotFoundError:
        import tomli as tomllib
    declared = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["version"]
    assert viewer.__version__ == declared
