"""Output files are written atomically: screenshots and renders (PNG),
linear images (.npy), reference outputs, metrics.json, saved scenes, environment maps and
meshes reach their name only through ``os.replace`` of a complete, fsynced temporary file in
the same folder; a writer killed at any moment leaves the destination absent or a complete old
or new file, never a part of one."""

from __future__ import annotations

import builtins
import io
import json
import os
import random
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

import viewer.base.io as vio

ROOT = Path(__file__).resolve().parents[1]


class WriteSpy:
    """Records os.replace calls and fails on any open() of a watched name for writing."""

    def __init__(self, monkeypatch, watched):
        self.replaced: dict[Path, Path] = {}
        self.watched = {Path(p).resolve() for p in watched}
        real_replace, real_open = os.replace, builtins.open

        def replace(src, dst, *a, **k):
            self.replaced[Path(dst).resolve()] = Path(src).resolve()
            return real_replace(src, dst, *a, **k)

        def guarded_open(file, mode="r", *a, **k):
            if isinstance(file, (str, os.PathLike)) and any(c in mode for c in "wax+") \
                    and Path(file).resolve() in self.watched:
                raise AssertionError(f"{file} opened for writing in place (mode {mode!r})")
            return real_open(file, mode, *a, **k)

        monkeypatch.setattr(os, "replace", replace)
        monkeypatch.setattr(builtins, "open", guarded_open)
        monkeypatch.setattr(io, "open", guarded_open)

    def check(self, path):
        path = Path(path).resolve()
        assert path in self.replaced, f"{path.name} was not renamed into place"
        src = self.replaced[path]
        assert src.parent == path.parent and src.name.startswith(f".{path.name}.") and ".part" in src.name, src
        assert not src.exists()
        assert path.stat().st_mode & 0o777 == 0o666 & ~_umask(), oct(path.stat().st_mode)  # not mkstemp's 0600


def _umask():
    m = os.umask(0o022)
    os.umask(m)
    return m


def _leftovers(folder):
    return [p.name for p in Path(folder).iterdir() if ".part" in p.name]


def test_library_writers_rename_a_complete_temporary_file(tmp_path, monkeypatch):
    from viewer.environment.io import load_environment, save_environment
    from viewer.scene.mesh import load_mesh, write_ply
    from viewer.scene import load_scene, scene_to_toml

    names = ["a.png", "a.npy", "metrics.json", "scene.toml", "m.hdr", "m.exr", "m.ply"]
    spy = WriteSpy(monkeypatch, [tmp_path / n for n in names])
    img = np.random.default_rng(0).random((6, 8, 3)).astype(np.float32)
    vio.write_png(tmp_path / "a.png", (img * 255).astype(np.uint8), {"k": "v"})
    vio.write_npy(tmp_path / "a.npy", img)
    vio.atomic_write_bytes(tmp_path / "metrics.json", b'{"rmse": 0.1}\n')
    vio.atomic_write_bytes(tmp_path / "scene.toml", scene_to_toml(load_scene("default")).encode())  # as the GUI saves
    save_environment(tmp_path / "m.hdr", img)
    save_environment(tmp_path / "m.exr", img)
    write_ply(tmp_path / "m.ply", [[0, 0, 0], [1, 0, 0], [0, 1, 0]], [[0, 0, 1]] * 3, [[0, 1, 2]])
    for n in names:
        spy.check(tmp_path / n)
    assert np.array_equal(np.load(tmp_path / "a.npy"), img)
    assert vio.read_png_text(tmp_path / "a.png") == {"k": "v"}
    assert scene_to_toml(load_scene(tmp_path / "scene.toml", load_meshes=False)) == \
        scene_to_toml(load_scene("default", load_meshes=False))
    assert load_environment(tmp_path / "m.exr").shape == (6, 8, 3) and len(load_mesh(tmp_path / "m.ply").indices) == 1
    assert _leftovers(tmp_path) == []


def test_reference_command_outputs_are_renamed_into_place(tmp_path, monkeypatch, capsys):
    from viewer.commands.cli import main

    out, lin = tmp_path / "r.png", tmp_path / "r.npy"
    spy = WriteSpy(monkeypatch, [out, lin])
    assert main(["reference", "sphere", "--spp", "1", "--workers", "0", "--width", "8", "--height", "6",
                 "--max-depth", "1", "--out", str(out), "--linear", str(lin)]) == 0
    spy.check(out)
    spy.check(lin)
    assert np.load(lin).shape == (6, 8, 3)


def test_compare_outputs_and_metrics_are_renamed_into_place(tmp_path, monkeypatch, capsys):
    from viewer.commands.cli import main

    d = tmp_path / "cmp"
    names = ["raster.npy", "reference.npy", "raster.png", "reference.png", "diff_abs.png", "diff_rel.png",
             "metrics.json"]
    spy = WriteSpy(monkeypatch, [d / n for n in names])
    assert main(["compare", "sphere", "--spp", "1", "--workers", "0", "--width", "8", "--height", "6",
                 "--max-depth", "1", "--supersample", "1", "--out", str(d)]) == 0
    for n in names:
        spy.check(d / n)
    assert "rmse" in json.loads((d / "metrics.json").read_text())


@pytest.mark.parametrize("fail_at", ["write", "fsync", "replace"])
def test_a_failed_write_keeps_the_old_file_and_no_temporary(tmp_path, monkeypatch, fail_at):
    dst = tmp_path / "out.npy"
    vio.write_npy(dst, np.zeros((4, 4, 3)))
    old = dst.read_bytes()

    def boom(*a, **k):
        raise OSError(28, "No space left on device")

    if fail_at == "write":
        monkeypatch.setattr(vio, "atomic_write_file",
                            lambda path, write, suffix="": _real_atomic(path, lambda tmp: (write(tmp), boom())))
    else:
        monkeypatch.setattr(os, fail_at, boom)
    with pytest.raises(OSError):
        vio.write_npy(dst, np.ones((64, 64, 3)))
    assert dst.read_bytes() == old and _leftovers(tmp_path) == []


_real_atomic = vio.atomic_write_file


def test_no_writer_in_the_package_bypasses_viewer_io():
    """Every file the package writes goes through viewer.base.io (or writes its own temporary file):
    no open(..., "w"), write_text / write_bytes, np.save to a path, image.save(path) elsewhere."""
    allowed = {
        "viewer/base/io.py": "the implementation",
        "viewer/pathtracer/progressive.py": "the workers' temporary setup file (mkstemp, not an output)",
        "viewer/environment/io.py": "cv2.imwrite / OpenEXR write to atomic_write_file's temporary name",
    }
    pattern = re.compile(r"""open\([^)]*["'][wax]b?\+?["']|\.write_text\(|\.write_bytes\(|np\.save[z]?\((?!buf)"""
                         r"""|(?<!bparam)\.save\((?!buf)[^)]*\)|imwrite\(|\.tofile\(""")
    offenders = []
    for path in sorted((ROOT / "viewer").rglob("*.py")):
        rel = path.relative_to(ROOT).as_posix()
        if rel in allowed:
            continue
        for i, line in enumerate(path.read_text(encoding="utf-8").splitlines(), 1):
            code = line.split("#", 1)[0]
            if pattern.search(code) and "os.fdopen" not in code:
                offenders.append(f"{rel}:{i}: {line.strip()}")
    assert not offenders, "direct writes:\n" + "\n".join(offenders)


# ----------------------------------------------------------------------------- SIGKILL mid-write

WRITER = r"""
import json, sys, numpy as np
from viewer.base.io import atomic_write_bytes, write_npy, write_png
kind, dst, size = sys.argv[1], sys.argv[2], int(sys.argv[3])
print("ready", flush=True)
i = 0
while True:
    i += 1
    if kind == "npy":      # 4 * size^2 * 3 bytes, every element = i
        write_npy(dst, np.full((size, size, 3), float(i), np.float32))
    elif kind == "png":    # incompressible noise seeded by i, version i in a text chunk
        rgb = np.random.default_rng(i).integers(0, 256, (size, size, 3), dtype=np.uint8)
        write_png(dst, rgb, {"version": str(i)})
    else:                  # metrics.json of a compare run
        atomic_write_bytes(dst, (json.dumps({"version": i, "pad": "x" * size * size}) + "\n").encode())
"""


def check_complete(kind, dst: Path, size: int):
    """The file is absent or one complete version; returns its version number (0: absent)."""
    if not dst.exists():
        return 0
    if kind == "npy":
        a = np.load(dst)
        assert a.shape == (size, size, 3) and np.all(a == a.flat[0]), "partial or mixed .npy"
        return int(a.flat[0])
    if kind == "png":
        from PIL import Image

        with Image.open(dst) as im:
            im.load()
            version = int(im.text["version"])
            got = np.asarray(im)
        want = np.random.default_rng(version).integers(0, 256, (size, size, 3), dtype=np.uint8)
        assert np.array_equal(got, want), "partial or mixed .png"
        return version
    d = json.loads(dst.read_text())
    assert d["pad"] == "x" * size * size
    return d["version"]


def kill_writers(folder: Path, kind: str, kills: int, size: int, seed: int, max_delay: float = 0.25):
    """Start a writer that rewrites one file in a loop, SIGKILL it after a random delay, check
    the file; ``kills`` times. Returns (versions seen, kills that found a temporary file, i.e.
    landed mid-write)."""
    rng = random.Random(seed)
    dst = folder / {"npy": "img.npy", "png": "shot.png", "json": "metrics.json"}[kind]
    env = dict(os.environ, PYTHONPATH=str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    versions, mid_write = [], 0
    for _ in range(kills):
        p = subprocess.Popen([sys.executable, "-c", WRITER, kind, str(dst), str(size)], stdout=subprocess.PIPE,
                             env=env)
        assert p.stdout.readline().strip() == b"ready"
        time.sleep(rng.random() * max_delay)
        os.kill(p.pid, signal.SIGKILL)
        p.wait()
        p.stdout.close()
        if [n for n in _leftovers(folder) if n.startswith(f".{dst.name}.{p.pid}.")]:
            mid_write += 1
        versions.append(check_complete(kind, dst, size))
    return versions, mid_write


# A writer that pauses inside its own write, at a named point, until it is killed: the kill lands
# there by construction, not by luck of timing. Versions 1 .. N-1 are written whole first (so
# the destination holds an old version); version N pauses at PHASE:
#   data     half of the bytes are in the temporary file (flushed to disk)
#   fsync    every byte is written, the temporary file is not yet fsynced
#   replace  fsynced, not yet renamed over the destination
PAUSING_WRITER = r"""
import builtins, json, os, sys, time
import numpy as np
from viewer.base.io import atomic_write_bytes, write_npy, write_png
kind, dst, size, phase, last = sys.argv[1], sys.argv[2], int(sys.argv[3]), sys.argv[4], int(sys.argv[5])
armed = False

def pause(where):
    if armed and where == phase:
        print("paused", flush=True)
        while True:
            time.sleep(60)   # until the SIGKILL

class Halves:
    def __init__(self, f):
        self.f = f
    def __enter__(self):
        return self
    def __exit__(self, *exc):
        return self.f.__exit__(*exc)
    def write(self, data):
        half = len(data) // 2
        n = self.f.write(data[:half])
        self.f.flush()
        real_fsync(self.f.fileno())   # the half on disk, as a slow disk would have it
        pause("data")
        return n + self.f.write(data[half:])

real_open, real_fsync, real_replace = builtins.open, os.fsync, os.replace

def hooked_open(file, mode="r", *a, **k):
    f = real_open(file, mode, *a, **k)
    return Halves(f) if armed and ".part" in str(file) and mode == "r+b" else f

def hooked_fsync(fd):
    pause("fsync")
    return real_fsync(fd)

def hooked_replace(src, dst_):
    pause("replace")
    return real_replace(src, dst_)

builtins.open, os.fsync, os.replace = hooked_open, hooked_fsync, hooked_replace
for i in range(1, last + 1):
    armed = i == last
    if kind == "npy":      # 4 * size^2 * 3 bytes, every element = i
        write_npy(dst, np.full((size, size, 3), float(i), np.float32))
    elif kind == "png":    # incompressible noise seeded by i, version i in a text chunk
        rgb = np.random.default_rng(i).integers(0, 256, (size, size, 3), dtype=np.uint8)
        write_png(dst, rgb, {"version": str(i)})
    else:                  # metrics.json of a compare run
        atomic_write_bytes(dst, (json.dumps({"version": i, "pad": "x" * size * size}) + "\n").encode())
print("not paused", flush=True)
"""

PHASES = ("data", "fsync", "replace")
DEADLINE_S = 120.0   # for the writer to reach its pause (interpreter start, numpy import); generous


def kill_paused_writer(folder: Path, kind: str, size: int, phase: str, version: int):
    """Run PAUSING_WRITER up to its pause in ``version``, SIGKILL it there. Returns (version
    found at the destination, the temporary files it left)."""
    dst = folder / {"npy": "img.npy", "png": "shot.png", "json": "metrics.json"}[kind]
    env = dict(os.environ, PYTHONPATH=str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    p = subprocess.Popen([sys.executable, "-c", PAUSING_WRITER, kind, str(dst), str(size), phase, str(version)],
                         stdout=subprocess.PIPE, env=env)
    try:
        line = p.stdout.readline().strip()   # blocks until the writer pauses (or ends)
        assert line == b"paused", (phase, line, p.poll())
        os.kill(p.pid, signal.SIGKILL)
        p.wait(DEADLINE_S)
    finally:
        if p.poll() is None:
            p.kill()
            p.wait()
        p.stdout.close()
    left = [n for n in _leftovers(folder) if n.startswith(f".{dst.name}.{p.pid}.")]
    return check_complete(kind, dst, size), left


@pytest.mark.parametrize("kind, size", [("npy", 256), ("png", 128), ("json", 256)])
def test_sigkill_mid_write_leaves_a_complete_file(tmp_path, kind, size):
    """Killed at each point of a write, with no old file and with one: the destination is absent
    or the complete old version, and the next writer removes the killed writer's temporary file."""
    full = {"npy": 4 * size * size * 3 + 128}.get(kind)   # .npy: data + its header (128 bytes here)
    for version in (1, 2):
        for phase in PHASES:
            folder = tmp_path / f"{phase}-{version}"
            folder.mkdir()
            found, left = kill_paused_writer(folder, kind, size, phase, version)
            assert found == version - 1, (phase, version, found)   # 0: absent
            assert len(left) == 1, (phase, left)                   # it died inside the write
            if full is not None:
                written = (folder / left[0]).stat().st_size
                assert written == (full // 2 if phase == "data" else full), (phase, written)
            name = {"npy": "img.npy", "png": "shot.png", "json": "metrics.json"}[kind]
            vio.atomic_write_bytes(folder / name, b"x")   # the next writer cleans up
            assert _leftovers(folder) == []
