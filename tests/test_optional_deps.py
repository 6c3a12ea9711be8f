"""A missing optional package gives one line naming it (the parts without a GUI):
the numba kernel without numba, the Embree kernel without embreex (also inside the worker
processes), .hdr / .exr maps without OpenCV / OpenEXR, mesh files without trimesh, and the
benchmark's Mitsuba comparison (``viewer.base.optional`` knows every one)."""

from __future__ import annotations

import importlib.util
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from viewer import ViewerError
from viewer.base.optional import PACKAGES, require

ROOT = Path(__file__).resolve().parents[1]


def _hide(monkeypatch, name):
    """Make ``name`` look not installed: import raises, find_spec gives None."""
    monkeypatch.setitem(sys.modules, name, None)
    real = importlib.util.find_spec
    monkeypatch.setattr(importlib.util, "find_spec", lambda n, *a, **k: None if n == name else real(n, *a, **k))


@pytest.mark.parametrize("name", sorted(PACKAGES))
def test_require_names_the_package_and_how_to_install_it(monkeypatch, name):
    _hide(monkeypatch, name)
    for load in (True, False):
        with pytest.raises(ViewerError) as e:
            require(name, load=load)
        msg = str(e.value)
        assert msg.startswith(name) and "not installed" in msg and "pip install" in msg, msg
        assert len(msg.splitlines()) == 1


def test_numba_kernel_without_numba(monkeypatch):
    from viewer.pathtracer import ReferenceRenderer
    from viewer.scene import load_scene

    _hide(monkeypatch, "numba")
    scene = load_scene("sphere", ["camera.width=4", "camera.height=4"])
    for workers in (0, 2):  # checked before any worker process starts
        with pytest.raises(ViewerError, match=r"^numba is not installed; .*pip install numba"):
            ReferenceRenderer(scene, kernel="numba", workers=workers)
    with pytest.raises(ViewerError, match="allowed: embree, numba"):
        ReferenceRenderer(scene, kernel="optix", workers=0)


def test_maps_and_meshes_without_their_readers(monkeypatch, tmp_path):
    from viewer.environment.io import load_environment, save_environment
    from viewer.scene.mesh import clear_cache, load_mesh, write_ply

    for suffix in (".hdr", ".exr"):
        save_environment(tmp_path / f"m{suffix}", np.ones((2, 4, 3), np.float32))
    write_ply(tmp_path / "t.ply", np.eye(3), np.eye(3), [[0, 1, 2]])
    _hide(monkeypatch, "cv2")
    _hide(monkeypatch, "OpenEXR")
    _hide(monkeypatch, "trimesh")
    with pytest.raises(ViewerError, match=r"cv2 \(opencv-python-headless\) is not installed"):
        load_environment(tmp_path / "m.hdr")
    with pytest.raises(ViewerError, match="OpenEXR is not installed"):
        load_environment(tmp_path / "m.exr")
    clear_cache()
    with pytest.raises(ViewerError, match=r"t\.ply: trimesh is not installed; .*pip install trimesh"):
        load_mesh(tmp_path / "t.ply")
    clear_cache()


def test_broken_embreex_in_the_workers_gives_one_line(tmp_path):
    """A package that is there but fails to import (here: embreex, in the spawned workers too)
    gives the CLI's one line and exit status 2, not a traceback per worker and BrokenProcessPool."""
    block = tmp_path / "block" / "embreex"
    block.mkdir(parents=True)
    (block / "__init__.py").write_text("raise ModuleNotFoundError(\"No module named 'embreex'\", name='embreex')\n")
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(tmp_path / "block"), str(ROOT),
                                                       os.environ.get("PYTHONPATH", "")]))
    out = tmp_path / "r.png"
    r = subprocess.run([sys.executable, "-m", "viewer", "reference", "sphere", "--spp", "1", "--width", "4",
                        "--height", "4", "--workers", "2", "--out", str(out)], env=env, capture_output=True,
                       text=True, timeout=120)
    assert r.returncode == 2, r.stderr
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1 and "embreex is not installed" in lines[0] and "pip install embreex" in lines[0], r.stderr
    assert not out.exists()
