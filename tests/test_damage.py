"""Damage that must not lose work or block a class: damaged reference-cache entries, killed
parents, caches and output folders that cannot be written, screenshots opened from another
folder, scenes of 10,000 objects, hostile ``--set`` values. Each test reproduces the damage and
checks the one-line outcome and what is (or is not) left on disk."""

from __future__ import annotations

import errno
import io
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from viewer.commands import cli
from viewer.pathtracer import ReferenceRenderer
from viewer.reference_common import cache
from viewer.reference_common.setup import RenderSetup
from viewer.scene import load_scene, load_scene_text, parse_scene

try:  # Python >= 3.11
    import tomllib
except ModuleNotFoundError:  # pragma: no cover - Python 3.10
    import tomli as tomllib

BAKE = ["bake", "sphere", "--width", "12", "--height", "8", "--engine", "cpu", "--workers", "0"]


def run_main(args, capsys):
    """cli.main in this process: (exit status, stdout, stderr)."""
    rc = cli.main(list(args))
    out = capsys.readouterr()
    return rc, out.out, out.err


def entry_file(folder: Path) -> Path:
    files = list((folder / "references").glob("*.npz"))
    assert len(files) == 1, files
    return files[0]


def one_error(err: str) -> str:
    """The one error line of ``err`` (progress bars aside), which must hold no traceback."""
    lines = [line for line in err.replace("\r", "\n").splitlines() if line.startswith("brdf-viewer: error:")]
    assert len(lines) == 1 and "Traceback" not in err, err
    return lines[0]


def leftovers(folder: Path) -> list[str]:
    return sorted(p.name for p in Path(folder).rglob("*") if ".part" in p.name)


# ------------------------------------------------------------------ damaged cache entries

def _rewrite(path: Path, **changes):
    """Rewrite the entry at ``path`` with some arrays replaced (a structurally valid file)."""
    with np.load(path) as z:
        arrays = {k: z[k] for k in z.files}
    arrays.update(changes)
    buf = io.BytesIO()
    np.savez(buf, **arrays)
    path.write_bytes(buf.getvalue())


def _truncate(path: Path):
    path.write_bytes(path.read_bytes()[: len(path.read_bytes()) // 2])


def _bad_crc(path: Path):
    data = bytearray(path.read_bytes())
    data[len(data) // 2] ^= 0xFF   # inside the stored (uncompressed) sums: the member's CRC-32 fails
    path.write_bytes(bytes(data))


DAMAGE = {
    "truncated": _truncate,
    "bad CRC": _bad_crc,
    "wrong shape": lambda p: _rewrite(p, sum=np.zeros((10, 10, 3), np.float32), sum2=np.zeros((10, 10, 3), np.float32)),
    "spp 2^62": lambda p: _rewrite(p, spp=np.int64(2 ** 62)),
    "NaN sums": lambda p: _rewrite(p, sum=np.full((8, 12, 3), np.nan, np.float32)),
    "negative sums": lambda p: _rewrite(p, sum=np.full((8, 12, 3), -1.0, np.float32)),
    "not an npz": lambda p: p.write_bytes(b"broken"),
}


@pytest.mark.parametrize("damage", list(DAMAGE))
def test_bake_sets_a_damaged_entry_aside_and_renders_it_afresh(damage, tmp_path, monkeypatch, capsys):
    monkeypatch.setenv("BRDF_VIEWER_CACHE", str(tmp_path))
    rc, out, err = run_main(BAKE + ["--spp", "2"], capsys)
    assert rc == 0, err
    entry = entry_file(tmp_path)
    DAMAGE[damage](entry)
    rc, out, err = run_main(BAKE + ["--spp", "4"], capsys)
    assert rc == 0, err                                     # no traceback, no exit 1 on every rerun
    said = [line for line in err.splitlines() if "reference cache" in line]
    assert len(said) == 1 and entry.name in said[0] and "damaged" in said[0] and "rendering afresh" in said[0], err
    assert "Traceback" not in err and len(said[0]) < 400
    assert (entry.parent / (entry.name + ".damaged")).is_file()   # set aside, not lost to inspection
    e = cache.load(entry.stem, tmp_path / "references")
    assert e is not None and e.spp == 4 and e.sum.shape == (8, 12, 3)   # rebuilt from scratch at 4 spp
    rc, out, err = run_main(BAKE + ["--spp", "4"], capsys)
    assert "already cached at 4 spp" in out and "reference cache" not in err


def test_load_checks_the_shape_it_is_asked_for(tmp_path):
    sc = load_scene("sphere")
    with ReferenceRenderer(sc, width=12, height=8, max_depth=2, workers=0) as r:
        r.step(1)
        s, s2, spp = r.state()
    key = cache.setup_key(RenderSetup.from_scene(sc, None, 12, 8, 2))
    assert cache.store(key, cache.Entry(s, s2, spp, "cpu", 0), tmp_path)
    said = []
    assert cache.load(key, tmp_path, shape=(8, 12, 3), report=said.append) is not None and said == []
    assert cache.load(key, tmp_path, shape=(9, 12, 3), report=said.append) is None
    assert len(said) == 1 and "shape" in said[0] and not cache.path_for(key, tmp_path).exists()


def test_window_reference_repairs_a_damaged_entry(tmp_path, monkeypatch):
    """The reference view: one notification naming the entry, then it renders afresh and stores
    a good entry again."""
    from viewer.app.reference_view import ReferenceView
    from viewer.scene.camera import OrbitCamera

    monkeypatch.setenv("BRDF_VIEWER_CACHE", str(tmp_path))
    scene = load_scene("sphere")
    cam = OrbitCamera.from_scene(scene)

    def run_view(until_spp):
        rv = ReferenceView(None, scale=0.1, max_depth=2, workers=0, engine="cpu")
        notices = []
        try:
            rv.update(scene, cam, (120, 80))
            deadline = time.monotonic() + 120
            while rv.spp < until_spp and time.monotonic() < deadline:
                notices += rv.take_notices()
                time.sleep(0.02)
            notices += rv.take_notices()
            return rv.spp, rv.error, notices
        finally:
            rv.close()

    spp, error, notices = run_view(1)
    assert spp >= 1 and not error and notices == []
    entry = entry_file(tmp_path)
    _truncate(entry)
    spp, error, notices = run_view(1)
    assert spp >= 1 and not error                       # rendered afresh, not a flat grey view
    assert len(notices) == 1, notices
    text, is_error = notices[0]
    assert entry.name in text and "damaged" in text and not is_error
    assert cache.load(entry.stem, tmp_path / "references") is not None   # stored again at close


def test_window_reference_says_when_the_cache_cannot_store(tmp_path, monkeypatch):
    from viewer.app.reference_view import ReferenceView
    from viewer.scene.camera import OrbitCamera

    blocker = tmp_path / "a_file"
    blocker.write_text("")
    monkeypatch.setenv("BRDF_VIEWER_CACHE", str(blocker / "cache"))   # under a regular file: never writable
    scene = load_scene("sphere")
    rv = ReferenceView(None, scale=0.1, max_depth=2, workers=0, engine="cpu")
    try:
        rv.update(scene, OrbitCamera.from_scene(scene), (120, 80))
        deadline = time.monotonic() + 120
        while rv.spp < 1 and time.monotonic() < deadline:
            time.sleep(0.02)
        assert rv.spp >= 1
        rv.stop()
    finally:
        rv.close()
    notices = rv.take_notices()
    assert len(notices) == 1 and notices[0][1] and "not" in notices[0][0] and "cannot be written" in notices[0][0]


# ------------------------------------------------------------------ bake that cannot store

def test_bake_into_an_unwritable_cache_says_so_and_fails(tmp_path, monkeypatch, capsys):
    blocker = tmp_path / "a_file"
    blocker.write_text("")
    monkeypatch.setenv("BRDF_VIEWER_CACHE", str(blocker / "cache"))   # ENOTDIR, also as root
    rc, out, err = run_main(BAKE + ["--spp", "2"], capsys)
    assert rc == 1 and "->" not in out
    line = one_error(err)
    assert "cannot be written" in line and "BRDF_VIEWER_CACHE" in line, err


def _enospc(*_a, **_k):
    raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))


def test_bake_into_a_full_cache_says_so_and_fails(tmp_path, monkeypatch, capsys):
    """A full disk: the entry's write fails (injected at the fsync every atomic write makes)."""
    monkeypatch.setenv("BRDF_VIEWER_CACHE", str(tmp_path))
    monkeypatch.setattr(os, "fsync", _enospc)
    rc, out, err = run_main(BAKE + ["--spp", "2"], capsys)
    assert rc == 1 and "->" not in out
    assert "No space left on device" in one_error(err)
    assert not list((tmp_path / "references").glob("*.npz")) and leftovers(tmp_path) == []


def test_store_failure_is_an_error_not_false(tmp_path, monkeypatch):
    e = cache.Entry(np.zeros((2, 2, 3)), np.zeros((2, 2, 3)), 1, "cpu", 0)
    monkeypatch.setattr(os, "fsync", _enospc)
    with pytest.raises(cache.CacheError, match="No space left on device"):
        cache.store("k" * 64, e, tmp_path)
    assert leftovers(tmp_path) == []


# ------------------------------------------------------------------ full or unwritable outputs

OUTPUTS = {
    "render": ["render", "sphere", "--width", "16", "--height", "12"],
    "reference": ["reference", "sphere", "--spp", "1", "--width", "8", "--height", "6", "--engine", "cpu",
                  "--workers", "0"],
    "plot": ["plot", "lambert", "--kind", "polar", "--width", "200", "--height", "150"],
}


@pytest.mark.parametrize("command", list(OUTPUTS))
def test_a_full_disk_gives_one_line_exit_1_and_no_file(command, tmp_path, monkeypatch, capsys):
    out = tmp_path / "out.png"
    monkeypatch.setattr(os, "fsync", _enospc)
    rc, stdout, err = run_main(OUTPUTS[command] + ["--out", str(out)], capsys)
    assert rc == 1, err
    line = one_error(err)
    assert str(out) in line and "No space left on device" in line, err
    assert not out.exists() and leftovers(tmp_path) == []      # nothing partial: the temporary file is gone


@pytest.mark.parametrize("command", ["render", "reference"])
def test_a_failed_png_takes_the_commands_npy_with_it(command, tmp_path, monkeypatch, capsys):
    """--linear is written first; when the PNG then meets a full disk, the .npy goes too."""
    if not os.path.isdir("/proc/self/fd"):
        pytest.skip("tells the files apart through /proc/self/fd")
    real = os.fsync

    def fsync(fd):
        if ".png." in os.readlink(f"/proc/self/fd/{fd}"):
            _enospc()
        return real(fd)

    monkeypatch.setattr(os, "fsync", fsync)
    out, lin = tmp_path / "out.png", tmp_path / "out.npy"
    rc, stdout, err = run_main(OUTPUTS[command] + ["--out", str(out), "--linear", str(lin)], capsys)
    assert rc == 1 and "No space left on device" in one_error(err)
    assert sorted(p.name for p in tmp_path.iterdir()) == []


@pytest.mark.parametrize("command", list(OUTPUTS))
def test_an_unwritable_folder_gives_one_line_exit_1(command, capsys):
    """/proc refuses new files for every user, root included (chmod would not stop root)."""
    if not os.path.isdir("/proc/self"):
        pytest.skip("needs Linux /proc")
    rc, stdout, err = run_main(OUTPUTS[command] + ["--out", "/proc/brdf-viewer-test.png"], capsys)
    assert rc == 1 and "cannot be written" in one_error(err), err


def test_a_read_only_folder_gives_one_line_exit_1(tmp_path, capsys):
    if os.geteuid() == 0:
        pytest.skip("root writes into read-only folders (the /proc test covers the error path)")
    folder = tmp_path / "ro"
    folder.mkdir()
    folder.chmod(0o500)
    try:
        rc, stdout, err = run_main(OUTPUTS["render"] + ["--out", str(folder / "x.png")], capsys)
    finally:
        folder.chmod(0o700)
    assert rc == 1 and "Permission denied" in one_error(err), err
    assert list(folder.iterdir()) == []


def test_a_screenshot_to_a_full_disk_is_a_notification(gl_ctx, renderer, tmp_path, monkeypatch):
    from viewer.app.session import Session

    s = Session(gl_ctx, "sphere", renderer=renderer, prefetch=False)
    s.warm = []
    try:
        monkeypatch.setattr(os, "fsync", _enospc)
        path = tmp_path / "shot.png"
        assert s.take_screenshot(path, size=(32, 24)) is None
        assert s.last_message.error and "No space left on device" in s.last_message.text
        assert not path.exists() and leftovers(tmp_path) == []
    finally:
        s.release()


# ------------------------------------------------------------------ screenshots reopen from anywhere

TRI_SCENE = """version = 1
[camera]
position = [0, 0, 4]
target = [0, 0, 0]
width = 32
height = 24
[[lights]]
type = "point"
position = [0, 1, 4]
intensity = [10, 10, 10]
[[objects]]
mesh = "tri.obj"
material = "m"
[materials.m]
model = "lambert"
"""


def test_a_png_reopens_from_another_folder(tmp_path, monkeypatch, capsys):
    a, b, c = (tmp_path / n for n in "abc")
    for d in (a, b, c):
        d.mkdir()
    (a / "tri.obj").write_text("v -1 -1 0\nv 1 -1 0\nv 0 1 0\nf 1 2 3\n")
    (a / "scene.toml").write_text(TRI_SCENE)
    monkeypatch.chdir(a)
    rc, out, err = run_main(["render", "scene.toml", "--out", str(b / "shot.png")], capsys)
    assert rc == 0, err
    monkeypatch.chdir(c)                                    # elsewhere: the mesh is not beside the PNG
    rc, out, err = run_main(["render", "../b/shot.png", "--out", "again.png"], capsys)
    assert rc == 0, err
    from PIL import Image

    first, again = (np.asarray(Image.open(p)) for p in (b / "shot.png", c / "again.png"))
    assert first.std() > 0 and np.array_equal(first, again)
    # the PNG copied with its mesh to another machine (the original folder gone): the file beside it
    d = tmp_path / "d"
    d.mkdir()
    (d / "shot.png").write_bytes((b / "shot.png").read_bytes())
    (a / "tri.obj").rename(d / "tri.obj")
    rc, out, err = run_main(["render", str(d / "shot.png"), "--out", str(d / "again.png")], capsys)
    assert rc == 0, err
    assert np.array_equal(first, np.asarray(Image.open(d / "again.png")))


# ------------------------------------------------------------------ 10,000 objects

def _grid_scene(objects_toml: str) -> str:
    return f"""version = 1
[camera]
position = [0.3, 9, 7]
target = [0, 0, 0]
width = 96
height = 72
[render]
msaa = 0
[[lights]]
type = "directional"
direction = [-0.3, -1, -0.4]
irradiance = [3, 3, 3]
[materials.m]
model = "lambert"
albedo = [0.7, 0.5, 0.3]
[materials.m2]
model = "lambert"
albedo = [0.2, 0.5, 0.8]
{objects_toml}"""


def test_ten_thousand_objects_render_as_the_same_triangles_in_one_mesh(renderer, tmp_path):
    """10,000 objects (cubes and prisms with two materials: four instanced draws; turned and
    scaled unevenly, so the prisms' slanted normals check the normal matrix) against the same
    triangles baked into one mesh file per material, drawn as two objects: the same image. The
    instanced path transforms in float32 in the vertex shader, the baked meshes in float64
    before rounding, so vertex positions differ by a float32 ulp and an edge pixel may flip;
    hence 99.5% of pixels equal, not all."""
    from viewer.scene.camera import OrbitCamera
    from viewer.scene.mesh import load_mesh, write_ply

    rng = np.random.default_rng(7)
    n, k = 10_000, 100
    shapes = {"cube": "m", "prism": "m2"}
    meshes = {name: load_mesh(name) for name in shapes}
    objs = []
    baked = {name: ([], [], []) for name in shapes}
    for i in range(n):
        name = "cube" if i % 2 else "prism"
        t = np.array([(i % k - k / 2 + 0.5) * 0.08, 0.0, (i // k - k / 2 + 0.5) * 0.08])
        sc = rng.uniform(0.015, 0.03, 3)
        rot = float(rng.uniform(0, 90))
        objs.append({"mesh": name, "material": shapes[name], "translate": [float(t[0]), 0.0, float(t[2])],
                     "scale": [float(x) for x in sc], "rotate_y_deg": rot})
        a = np.radians(rot)
        r = np.array([[np.cos(a), 0, np.sin(a)], [0, 1, 0], [-np.sin(a), 0, np.cos(a)]])
        m = meshes[name]
        P, N, F = baked[name]
        F.append(m.indices + len(m.positions) * len(P))
        P.append(m.positions.astype(np.float64) @ (r * sc).T + t)
        nrm = m.normals.astype(np.float64) @ (r / sc).T      # the inverse transpose of R S
        N.append(nrm / np.linalg.norm(nrm, axis=1, keepdims=True))
    for name, (P, N, F) in baked.items():
        write_ply(tmp_path / f"{name}s.ply", np.concatenate(P), np.concatenate(N), np.concatenate(F))
    base = tomllib.loads(_grid_scene(""))        # the scene as data: parsing 10,000 tables of TOML is not the point
    many = parse_scene(dict(base, objects=objs), None)
    one = parse_scene(dict(base, objects=[{"mesh": "cubes.ply", "material": "m"},
                                          {"mesh": "prisms.ply", "material": "m2"}]), None, base_dir=tmp_path)
    assert len(many.objects) == n and many.size_note() == "10,000 objects, 100,000 triangles"
    a = renderer.render_arrays(many, OrbitCamera.from_scene(many))[0]
    b = renderer.render_arrays(one, OrbitCamera.from_scene(one))[0]
    if os.environ.get("BRDF_VIEWER_TEST_IMAGES"):   # to look at them
        from viewer.base.io import write_npy

        write_npy(Path(os.environ["BRDF_VIEWER_TEST_IMAGES"]) / "many.npy", a)
        write_npy(Path(os.environ["BRDF_VIEWER_TEST_IMAGES"]) / "baked.npy", b)
    lit = a.max(axis=2) > 0.05
    assert 0.2 < lit.mean() < 0.95, lit.mean()              # the grid fills much of the view, with gaps
    same = np.all(np.abs(a - b) <= 1e-4 * np.maximum(1.0, np.abs(b)), axis=2)
    assert same.mean() > 0.995, same.mean()


def test_absurd_counts_are_refused_in_one_line():
    objs = '[[objects]]\nmesh = "sphere"\nmaterial = "m"\n' * 1_500     # 1,500 x 20,480 triangles
    with pytest.raises(Exception) as e:
        load_scene_text(_grid_scene(objs))
    assert "30,720,000 triangles" in str(e.value) and "docs/scene-format.md" in str(e.value)
    from viewer import ViewerError

    assert isinstance(e.value, ViewerError)


def test_a_large_scene_says_how_large_on_stderr(tmp_path, capsys, monkeypatch):
    objs = "".join(f'[[objects]]\nmesh = "cube"\nmaterial = "m"\ntranslate = [{i % 40 * 0.1}, 0, {i // 40 * 0.1}]\n'
                   f'scale = 0.03\n' for i in range(1_200))
    (tmp_path / "many.toml").write_text(_grid_scene(objs))
    rc, out, err = run_main(["render", str(tmp_path / "many.toml"), "--out", str(tmp_path / "m.png"),
                             "--width", "32", "--height", "24"], capsys)
    assert rc == 0, err
    # one line before the load (it takes seconds at 10,000 objects) and one after it
    assert err.count("\n") == 2, err
    before, after = err.splitlines()
    assert "loading about 1,200 objects" in before
    assert "1,200 objects, 14,400 triangles" in after


# ------------------------------------------------------------------ orphaned workers

def _children(pid: int) -> dict[int, str]:
    """pid -> command line of the live (not zombie) processes whose parent is ``pid``."""
    from lifecycle import children

    return children(pid, zombies=False)


def _alive(pid: int, cmdline: str) -> bool:
    """``pid`` still runs the same program (not a zombie, not a reused number)."""
    try:
        with open(f"/proc/{pid}/stat") as f:
            state = f.read().rsplit(")", 1)[1].split()[0]
        with open(f"/proc/{pid}/cmdline", "rb") as f:
            now = f.read().replace(b"\0", b" ").decode(errors="replace").strip()  # as lifecycle.children
    except (OSError, IndexError):
        return False
    return state != "Z" and now == cmdline


@pytest.mark.skipif(not os.path.isdir("/proc/self"), reason="reads the process tree from Linux /proc")
@pytest.mark.parametrize("sig", [signal.SIGKILL, signal.SIGTERM], ids=["kill-9", "kill-TERM"])
def test_killing_the_parent_ends_its_workers_and_the_resource_tracker(sig, tmp_path):
    env = dict(os.environ, PYTHONPATH=str(Path(__file__).resolve().parent.parent))
    proc = subprocess.Popen([sys.executable, "-m", "viewer", "reference", "gallery", "--spp", "100000",
                             "--width", "96", "--height", "64", "--engine", "cpu", "--workers", "2",
                             "--out", str(tmp_path / "ref.png")], env=env, stdout=subprocess.DEVNULL,
                            stderr=subprocess.DEVNULL)
    try:
        deadline = time.monotonic() + 120      # imports and two spawned workers on a loaded machine
        kids: dict[int, str] = {}
        while time.monotonic() < deadline and proc.poll() is None:
            kids = _children(proc.pid)
            if sum("multiprocessing.spawn" in c for c in kids.values()) >= 2:
                break
            time.sleep(0.1)
        workers = {p: c for p, c in kids.items() if "multiprocessing.spawn" in c}
        assert len(workers) == 2, f"the reference's workers never started: {kids}"
        assert any("resource_tracker" in c for c in kids.values()), kids
        time.sleep(0.5)                          # let them take chunks: they are busy, not idle, when it dies
        proc.send_signal(sig)
        proc.wait(timeout=30)
        deadline = time.monotonic() + 30         # generous: they check their parent every 0.5 s
        while time.monotonic() < deadline and any(_alive(p, c) for p, c in kids.items()):
            time.sleep(0.1)
        left = {p: c for p, c in kids.items() if _alive(p, c)}
        assert left == {}, f"still running after their parent died: {left}"
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
        for p, c in kids.items():    # never leave them behind, whatever the assertion said
            if _alive(p, c):
                os.kill(p, signal.SIGKILL)


def test_a_worker_exits_when_its_parent_is_gone():
    """watch_parent in isolation: a parent pid that is not ours (the parent 'died' at once)."""
    code = ("import os, time\nfrom viewer.pathtracer.progressive import watch_parent\n"
            "watch_parent(os.getppid() + 1, every_s=0.05)\ntime.sleep(60)\n")
    env = dict(os.environ, PYTHONPATH=str(Path(__file__).resolve().parent.parent))
    r = subprocess.run([sys.executable, "-c", code], env=env, timeout=60)
    assert r.returncode == 0


# ------------------------------------------------------------------ the minor items

def test_a_killed_writers_part_file_is_removed_when_the_cache_opens(tmp_path):
    folder = tmp_path / "references"
    folder.mkdir()
    dead = subprocess.run([sys.executable, "-c", "import os; print(os.getpid())"], capture_output=True,
                          text=True).stdout.strip()           # a pid that has ended
    stale = folder / f".{'a' * 64}.npz.{dead}.abcd1234.part"
    stale.write_bytes(b"x" * 1000)
    mine = folder / f".{'b' * 64}.npz.{os.getpid()}.abcd1234.part"   # a live writer's: kept
    mine.write_bytes(b"x")
    # a pid that exists but started after the file was written (the number was reused): stale
    later = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(60)"])
    try:
        reused = folder / f".{'c' * 64}.npz.{later.pid}.abcd1234.part"
        reused.write_bytes(b"x")
        os.utime(reused, (1.0, 1.0))
        assert cache.load("d" * 64, folder) is None
    finally:
        later.kill()
        later.wait()
    assert not stale.exists() and mine.exists() and not reused.exists()


def test_error_lines_quote_a_short_prefix_of_a_huge_value(tmp_path, capsys):
    big = "9" * 100_000
    for assignment in (f"camera.width={big}", f"materials.ball.model=x{big}", f"materials.ball.preset=x{big}",
                       f"lights.99.x={big}", f"novalue{big}", f"lights.0.type=x{big}"):
        rc, out, err = run_main(["render", "sphere", "--out", str(tmp_path / "x.png"), "--set", assignment], capsys)
        assert rc == 2 and len(one_error(err)) < 1200, (assignment[:40], len(err))


def test_a_set_camera_size_replaced_by_width_is_still_checked(tmp_path, capsys):
    out = str(tmp_path / "x.png")
    rc, _, err = run_main(["render", "sphere", "--out", out, "--width", "32", "--height", "24",
                           "--set", "camera.width=" + "9" * 5000], capsys)
    assert rc == 2 and "camera.width" in err and "--width" in err and len(err) < 600, err
    assert not Path(out).exists()
    rc, _, err = run_main(["render", "sphere", "--out", out, "--width", "32", "--height", "24",
                           "--set", "camera.width=64"], capsys)
    assert rc == 0, err                                      # a valid value: --width wins, as documented
