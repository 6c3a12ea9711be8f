"""The package as a new user installs it: an sdist and a wheel built from a copy of the source
tree, the wheel installed (not editable) into a fresh virtual environment outside the checkout,
and the console script run from another folder. It proves that the wheel carries the shaders and
the built-in meshes (setup.py copies them into the package) and that ``viewer.base.resources`` finds
them there, with nothing read from the checkout or the working folder.

Dependencies are not installed again: a ``.pth`` line lets the fresh environment see the test
interpreter's site-packages (a bare path line adds that folder to ``sys.path`` without running
the ``.pth`` hooks in it, so an editable install of this checkout there cannot take over), and
the test asserts that ``viewer`` is imported from the fresh environment. The build runs without
build isolation when the running environment can build wheels (setuptools >= 70.1 or the
``wheel`` package); otherwise pip fetches the build requirements from PyPI.
"""

from __future__ import annotations

import importlib.util
import json
import os
import shutil
import subprocess
import sys
import sysconfig
import tarfile
import time
import zipfile
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parent.parent
JUNK = shutil.ignore_patterns(".git", ".venv", "venv", "build", "dist", "*.egg-info", "__pycache__",
                              ".pytest_cache", "out", ".gl", ".whl", ".cache", "*.pyc")
TIMINGS: dict[str, float] = {}


def _run(cmd, cwd, env=None, timeout=300):
    r = subprocess.run([str(c) for c in cmd], cwd=cwd, env=env, capture_output=True, text=True,
                       timeout=timeout)
    assert r.returncode == 0, f"{' '.join(map(str, cmd))} failed ({r.returncode}):\n{r.stdout[-3000:]}\n{r.stderr[-3000:]}"
    return r


def _can_build_wheels_here() -> bool:
    """setuptools with a bdist_wheel command (its own since 70.1, else the wheel package): the
    test extra installs both, so the build needs no network."""
    if importlib.util.find_spec("setuptools") is None:
        return False
    return (importlib.util.find_spec("wheel") is not None
            or importlib.util.find_spec("setuptools.command.bdist_wheel") is not None)


def _clean_env() -> dict:
    env = {k: v for k, v in os.environ.items()
           if k not in ("PYTHONPATH", "PYTHONHOME", "BRDF_VIEWER_SHADERS", "VIRTUAL_ENV", "PYTHONSTARTUP")}
    env["PIP_DISABLE_PIP_VERSION_CHECK"] = "1"
    return env


@pytest.fixture(scope="module")
def installed(tmp_path_factory):
    """(venv python, venv bin folder, a run folder outside the checkout, the wheel, the sdist)."""
    if importlib.util.find_spec("setuptools") is None:
        pytest.skip("setuptools is not installed (the test extra has it: pip install -e '.[test]')")
    base = tmp_path_factory.mktemp("wheel")
    env = _clean_env()
    t0 = time.perf_counter()
    src = base / "src"
    shutil.copytree(ROOT, src, ignore=JUNK)
    dist = base / "dist"
    dist.mkdir()
    # the sdist through setuptools' PEP 517 hook (what `python -m build --sdist` calls)
    _run([sys.executable, "-c", "import sys; from setuptools import build_meta; "
          "print(build_meta.build_sdist(sys.argv[1]))", dist], cwd=src, env=env)
    (sdist,) = dist.glob("*.tar.gz")
    unpacked = base / "sdist"
    with tarfile.open(sdist) as tf:
        tf.extractall(unpacked)
    (sdist_root,) = unpacked.iterdir()
    isolation = ["--no-build-isolation"] if _can_build_wheels_here() else []  # else: from PyPI
    _run([sys.executable, "-m", "pip", "wheel", "--no-deps", *isolation, "-q", "-w", dist, sdist_root],
         cwd=base, env=env)
    (wheel,) = dist.glob("*.whl")
    TIMINGS["build"] = time.perf_counter() - t0

    venv = base / "venv"
    _run([sys.executable, "-m", "venv", "--without-pip", venv], cwd=base, env=env)
    vpy = venv / "bin" / "python"
    site = Path(_run([vpy, "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])"],
                     cwd=base, env=env).stdout.strip())
    outer = {sysconfig.get_paths()["purelib"], sysconfig.get_paths()["platlib"]}
    (site / "outer-site-packages.pth").write_text("".join(p + "\n" for p in sorted(outer)))
    _run([sys.executable, "-m", "pip", "--python", vpy, "install", "--no-deps", "--no-index", "-q", wheel],
         cwd=base, env=env)
    TIMINGS["install"] = time.perf_counter() - t0 - TIMINGS["build"]
    run_dir = base / "elsewhere"
    run_dir.mkdir()
    return vpy, venv / "bin", run_dir, wheel, sdist, env


def test_sdist_and_wheel_hold_the_resources(installed):
    _, _, _, wheel, sdist, _ = installed
    with tarfile.open(sdist) as tf:
        names = {n.split("/", 1)[1] for n in tf.getnames() if "/" in n}
    for rel in ("shaders/passes/forward.frag", "shaders/brdf/lambert.glsl", "models/sphere.ply",
                "models/generate.py", "setup.py", "viewer/scenes/default.toml"):
        assert rel in names, f"the sdist lacks {rel}"
    with zipfile.ZipFile(wheel) as zf:
        names = set(zf.namelist())
    shaders = sorted(p.relative_to(ROOT / "shaders").as_posix() for p in (ROOT / "shaders").rglob("*")
                     if p.is_file() and p.suffix in (".glsl", ".vert", ".frag", ".geom"))
    assert shaders, "no shaders in the checkout"
    for rel in shaders:
        assert f"viewer/shaders/{rel}" in names, f"the wheel lacks shaders/{rel}"
    for p in (ROOT / "models").glob("*.ply"):
        assert f"viewer/models/{p.name}" in names, f"the wheel lacks models/{p.name}"
    assert "viewer/scenes/default.toml" in names
    assert not any(n.startswith(("shaders/", "models/", "tests/")) for n in names), \
        "resources belong inside the package, not at the top level of site-packages"
    print(f"wheel {wheel.name}: {wheel.stat().st_size / 1024:.0f} KiB; sdist {sdist.stat().st_size / 1024:.0f} KiB")


def test_installed_wheel_runs_from_another_folder(installed):
    vpy, bindir, run_dir, wheel, _, env = installed
    t0 = time.perf_counter()
    info = json.loads(_run([vpy, "-c", "import json, viewer, viewer.pathtracer, viewer.base.resources as r; print(json.dumps("
                            "[viewer.__file__, str(r.SHADER_DIR), str(r.MODEL_DIR), viewer.__version__]))"],
                           cwd=run_dir, env=env).stdout)
    venv = vpy.parent.parent
    for p in info[:3]:  # the wheel's files, not the checkout's
        assert Path(p).resolve().is_relative_to(venv.resolve()), f"{p} is not inside the fresh environment"
    version = wheel.name.split("-")[1]
    assert info[3] == version

    exe = bindir / "brdf-viewer"
    out = _run([exe, "--version"], cwd=run_dir, env=env).stdout
    assert out.strip() == f"brdf-viewer {version}"
    out = _run([exe, "models"], cwd=run_dir, env=env).stdout
    assert "lambert" in out and "dielectric" in out
    _run([exe, "render", "default", "--width", "48", "--height", "27", "--out", "r.png", "--linear", "r.npy"],
         cwd=run_dir, env=env)
    img = np.load(run_dir / "r.npy")
    assert img.shape == (27, 48, 3) and np.isfinite(img).all() and img.mean() > 0.01
    _run([exe, "plot", "lambert", "--kind", "polar", "--out", "p.png", "--width", "300", "--height", "200"],
         cwd=run_dir, env=env)
    assert (run_dir / "p.png").stat().st_size > 0
    # BRDF_VIEWER_SHADERS still wins over the package's copy: an empty folder there breaks the
    # render that just worked, with one line naming the missing file
    bad = run_dir / "no-shaders"
    bad.mkdir()
    r = subprocess.run([str(exe), "render", "default", "--width", "8", "--height", "8", "--out", "x.png"],
                       cwd=run_dir, env={**env, "BRDF_VIEWER_SHADERS": str(bad)}, capture_output=True, text=True,
                       timeout=120)
    assert r.returncode == 2 and "lambert.glsl" in r.stderr and len(r.stderr.splitlines()) == 1, r.stderr
    TIMINGS["commands"] = time.perf_counter() - t0
    print("wheel smoke test: " + ", ".join(f"{k} {v:.1f} s" for k, v in TIMINGS.items()))


# slow: the installed copy has no numba cache of its own, so its first reference compiles the CPU
# reference's kernels (about 80 CPU s on two cores, a sixth of the default suite); the default test
# above imports the reference's package from the installed copy, this one runs it
@pytest.mark.slow
def test_installed_wheel_renders_a_reference(installed):
    vpy, bindir, run_dir, wheel, _, env = installed
    _run([bindir / "brdf-viewer", "reference", "sphere", "--spp", "1", "--width", "12", "--height", "8",
          "--workers", "1", "--out", "ref.png", "--linear", "ref.npy"], cwd=run_dir, env=env)
    ref = np.load(run_dir / "ref.npy")
    assert ref.shape == (8, 12, 3) and np.isfinite(ref).all() and ref.mean() > 0.0
