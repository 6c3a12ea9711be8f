"""Inputs that must not crash the window or cost memory before they are refused: a ``.brdf`` file
saved with other parameters into a running window (hot reload), a file with more parameter floats
than the material block holds, file names with quotes and other odd characters, window sizes and
state files that are not what the state file should hold, small files that ask for huge memory
(a TOML dotted key of 25,000 parts, PNG text chunks, sparse meshes of 2 GB) and scene numbers
that overflow the camera's and the objects' arithmetic. Each refusal is one line (exit status 2
from the CLI) and each is measured: the peak memory of the child that refused it."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest

from viewer import ViewerError, brdf
from viewer.brdf import brdffile

SHADER = ("::begin shader\nvec3 BRDF(vec3 L, vec3 V, vec3 N, vec3 X, vec3 Y)\n{{\n"
          "    return {} / 3.14159265;\n}}\n::end shader\n")


def brdf_text(params: str, expr: str) -> str:
    return "analytic\n::begin parameters\n" + params + "::end parameters\n" + SHADER.format(expr)


def save(path: Path, text: str) -> None:
    """Write ``text`` with a modification time one second later (a coarse clock sees it)."""
    path.write_text(text)
    st = path.stat()
    os.utime(path, ns=(st.st_atime_ns, st.st_mtime_ns + 10 ** 9))


def one_error(err: str) -> str:
    lines = [line for line in err.replace("\r", "\n").splitlines() if line.startswith("brdf-viewer: error:")]
    assert len(lines) == 1 and "Traceback" not in err, err
    return lines[0]


# The child's own peak: VmHWM of /proc/self/status (its memory since the exec), not ru_maxrss,
# which Linux carries over an exec from the forked parent (this test process, a few hundred MB).
PEAK = textwrap.dedent("""
    def peak_kb():
        try:
            with open("/proc/self/status") as f:
                return next(int(l.split()[1]) for l in f if l.startswith("VmHWM:"))
        except (OSError, StopIteration):
            import resource
            return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
""")


def run_cli(args, tmp_path, env=None):
    """``brdf-viewer ARGS`` in a child: (exit status, stdout, stderr, the child's peak RSS in MB),
    which the child reports on a line of its own as it ends."""
    code = PEAK + textwrap.dedent("""
        import sys
        from viewer.commands.cli import main
        try:
            rc = main(sys.argv[1:])
        except SystemExit as e:
            rc = e.code if isinstance(e.code, int) else 1
        print("MAXRSS_KB", peak_kb(), file=sys.stderr)
        sys.exit(rc)
    """)
    full_env = dict(os.environ)
    full_env.update(env or {})
    full_env["PYTHONPATH"] = str(Path(__file__).resolve().parent.parent) + os.pathsep + full_env.get("PYTHONPATH", "")
    r = subprocess.run([sys.executable, "-c", code, *args], capture_output=True, text=True, cwd=tmp_path,
                       env=full_env, timeout=600)
    lines = r.stderr.splitlines()
    kb = [int(l.split()[1]) for l in lines if l.startswith("MAXRSS_KB")]
    err = "\n".join(l for l in lines if not l.startswith("MAXRSS_KB"))
    return r.returncode, r.stdout, err, (kb[-1] / 1024 if kb else float("nan"))


# ------------------------------------------------------------------ hot reload of a .brdf file


@pytest.fixture
def file_session(gl_ctx, renderer):
    from viewer.app.session import Session

    s = Session(gl_ctx, "default", renderer=renderer, prefetch=False)
    s.warm = []
    yield s
    s.release()


def _image(s, size=(40, 30)):
    s.changed()
    s.render_view(size)
    return s.renderer.read_linear(s.hdr).astype(np.float64)


def test_saving_a_brdf_file_with_other_parameters_keeps_the_session_and_carries_values(file_session, tmp_path):
    from viewer.app.shader_overlay import HotReload

    s = file_session
    src = tmp_path / "edit.brdf"
    src.write_text(brdf_text("float k 0 1 0.5\nfloat gone 0 1 0.5\n", "vec3(k)"))
    name = s.scene.objects[s.mesh_target].material
    hr = HotReload(s.renderer)  # as the window does: before any file is drawn
    assert s.load_brdf_file(str(src))
    assert s.set_material_param(name, "k", 0.25)
    _image(s)
    hr.poll(force=True)  # the first look learns the files
    steps = [
        # one parameter more, one removed: k kept, the new one at its default
        (brdf_text("float k 0 1 0.5\nfloat extra 0 2 1.5\n", "vec3(k * extra)"), {"k": 0.25, "extra": 1.5}),
        # k renamed: the new name starts at its default
        (brdf_text("float kk 0 1 0.5\nfloat extra 0 2 1.5\n", "vec3(kk * extra)"), {"kk": 0.5, "extra": 1.5}),
        # extra retyped float -> bool -> color: each at its default, never the old value
        (brdf_text("float kk 0 1 0.5\nbool extra 1\n", "vec3(extra ? kk : 0.0)"), {"kk": 0.5, "extra": True}),
        (brdf_text("float kk 0 1 0.5\ncolor extra 0.2 0.4 0.6\n", "extra * kk"),
         {"kk": 0.5, "extra": [0.2, 0.4, 0.6]}),
        # kk's range narrowed below its value: clamped into it
        (brdf_text("float kk 0 0.3 0.1\ncolor extra 0.2 0.4 0.6\n", "extra * kk"),
         {"kk": 0.3, "extra": [0.2, 0.4, 0.6]}),
    ]
    for text, want in steps:
        save(src, text)
        hr.poll(force=True)  # rebuilds the programs when the GLSL changed (not for a range alone)
        # the renderer draws before the session fits the material: the file's defaults stand in
        assert np.all(np.isfinite(_image(s)))
        assert s.refit_file_materials() == [name]
        p = s.scene.materials[name]
        assert set(p) == {"file", *want}, dict(p)
        for k, v in want.items():
            assert np.allclose(p[k], v) and type(p[k] if not isinstance(v, list) else v) is type(v), (k, p[k], v)
        assert not hr.errors, [e.summary() for e in hr.errors]
        img = _image(s)
        assert np.all(np.isfinite(img)) and img.max() > 0
        assert s.refit_file_materials() == []  # fitted once
    # the material's sliders edit the new parameters
    assert s.set_material_param(name, "extra", [0.1, 0.1, 0.1])


def test_carry_over_keeps_a_material_that_fits_and_one_whose_file_no_longer_parses(tmp_path):
    from viewer.brdf.file_carry import carry_over

    src = tmp_path / "c.brdf"
    src.write_text(brdf_text("float k 0 1 0.5\n", "vec3(k)"))
    p = brdf.load(src).params(k=0.75)
    assert carry_over(p) is p
    save(src, "analytic\n::begin parameters\nfloat k 0 1\n::end parameters\n")  # a mistake
    assert carry_over(p) is p  # the last good file's material; the hot reloader shows the error


# the real window's path of the edits above (its hot-reload watcher, the editor fitting what it
# draws): 17-19 s of the default run for what the session's test covers, so with -m slow
@pytest.mark.slow
@pytest.mark.skipif(shutil.which("Xvfb") is None, reason="needs Xvfb")
def test_the_window_survives_a_brdf_file_saved_with_one_parameter_more(display, tmp_path):
    from gui_harness import run_py

    src = tmp_path / "win.brdf"
    src.write_text(brdf_text("float k 0 1 0.5\n", "vec3(k)"))
    edits = (brdf_text("float k 0 1 0.5\nfloat more 0 1 0.75\n", "vec3(k * more)"),
             brdf_text("bool k 1\ncolor more 1 0.5 0.5\n", "k ? more : vec3(0.0)"))
    r = run_py(f"""
        import os
        from viewer.app.main import App
        app = App("default", size=(900, 600), restore_state=False)
        app.session.warm = []
        s = app.session
        assert s.load_brdf_file({str(src)!r})
        name = s.scene.objects[s.mesh_target].material
        s.set_material_param(name, "k", 0.25)
        for _ in range(2):
            app.frame()
        print("FIRST", list(s.scene.materials)[0] == name)
        for i, text in enumerate({edits!r}):
            if i == 1:  # the material editor fits what it draws by itself (the panel's own path)
                s.refit_file_materials = lambda: []
            with open({str(src)!r}, "w") as f:
                f.write(text)
            st = os.stat({str(src)!r})
            os.utime({str(src)!r}, ns=(st.st_atime_ns, st.st_mtime_ns + 10 ** 9))
            app.hot_reload.watcher.interval = 0.0
            for _ in range(3):
                app.frame()
            print("PARAMS", sorted((k, str(v)) for k, v in s.scene.materials[name].items() if k != "file"))
        app.close()
    """, display)
    assert r.returncode == 0, r.stdout + r.stderr
    seen = [line for line in r.stdout.splitlines() if line.startswith("PARAMS")]
    assert "FIRST True" in r.stdout, r.stdout + r.stderr  # the first material's editor starts open
    assert seen == ["PARAMS [('k', '0.25'), ('more', '0.75')]",
                    "PARAMS [('k', 'True'), ('more', '[1.  0.5 0.5]')]"], r.stdout + r.stderr


# ------------------------------------------------------------------ parameter floats


def test_the_limit_leaves_the_material_block_room_for_the_samplers_smallest_table():
    from viewer.brdf import file_sampler
    from viewer.gl.constants import MAT_FLOATS

    room = MAT_FLOATS - brdffile.MAX_PARAM_FLOATS
    assert file_sampler.sizes_for(room) is not None
    assert file_sampler.size(file_sampler.SMALL[-1]) <= room < file_sampler.size(file_sampler.SMALL[-1]) + 8


def _many(n_floats: int, colours: int = 0) -> str:
    lines = [f"color c{i} 0.5 0.5 0.5\n" for i in range(colours)]
    lines += [f"float p{i} 0 1 0.5\n" for i in range(n_floats - 3 * colours)]
    return brdf_text("".join(lines), "vec3(0.5)")


def test_a_file_at_the_limit_loads_and_one_float_more_is_one_line(tmp_path):
    ok = tmp_path / "at.brdf"
    ok.write_text(_many(brdffile.MAX_PARAM_FLOATS, colours=10))
    assert len(brdf.load(ok).bfile.declarations) == brdffile.MAX_PARAM_FLOATS - 20
    over = tmp_path / "over.brdf"
    over.write_text(_many(brdffile.MAX_PARAM_FLOATS + 1, colours=10))
    with pytest.raises(ViewerError) as e:
        brdf.load(over)
    assert str(e.value) == ("over.brdf: its parameters are 225 floats (a color is 3); a .brdf file may declare "
                            "at most 224")


def test_a_file_at_the_limit_renders(tmp_path, renderer):
    from viewer import api
    from viewer.scene import load_scene

    ok = tmp_path / "at.brdf"
    ok.write_text(_many(brdffile.MAX_PARAM_FLOATS))
    img = api.render(load_scene("sphere", ["camera.width=24", "camera.height=16",
                                           f'materials.ball={{model="custom", file="{ok}"}}']))
    assert np.all(np.isfinite(img))


def test_check_render_and_the_window_refuse_too_many_floats_alike(tmp_path, file_session):
    over = tmp_path / "over.brdf"
    over.write_text(_many(230))
    want = "over.brdf: its parameters are 230 floats (a color is 3); a .brdf file may declare at most 224"
    rc, _, err, _ = run_cli(["check", str(over)], tmp_path)
    assert rc == 2 and one_error(err).endswith(want), err
    rc, _, err, _ = run_cli(["render", "sphere", "--out", "o.png", "--width", "16", "--height", "12",
                             "--set", f'materials.ball={{model="custom", file="{over}"}}'], tmp_path)
    assert rc == 2 and one_error(err).endswith(want), err
    said = []
    file_session.notify = lambda text, error=False: said.append((text, error))
    file_session.open_files([str(over)])
    assert said == [(want, True)]


# ------------------------------------------------------------------ odd file names

ODD = ['quo"te', "apos'trophe", "back\\slash", "new\nline", "ünïcödé", "sp ace", "semi;colon"]


@pytest.mark.parametrize("stem", ODD, ids=lambda s: s.encode("unicode_escape").decode())
def test_a_brdf_file_with_an_odd_name_works_in_the_session(stem, tmp_path, file_session):
    src = tmp_path / f"{stem}.brdf"
    src.write_text(brdf_text("float k 0 1 0.5\n", "vec3(k)"))
    said = []
    file_session.notify = lambda text, error=False: said.append((text, error))
    file_session.open_files([str(src)])
    assert not any(e for _, e in said), said
    img = _image(file_session)
    assert np.all(np.isfinite(img)) and img.max() > 0
    assert not file_session.renderer.shader_errors


def test_odd_names_check_and_render_from_the_cli(tmp_path):
    import tomli_w

    for stem in ('quo"te', "back\\slash", "new\nline"):
        src = tmp_path / f"{stem}.brdf"
        src.write_text(brdf_text("float k 0 1 0.25\n", "vec3(k)"))
        rc, out, err, _ = run_cli(["check", str(src)], tmp_path)
        assert rc in (0, 1) and "Traceback" not in err and "reciprocity" in out, (stem, err)
        value = tomli_w.dumps({"file": str(src)}).strip()  # file = "..." with the quotes escaped
        rc, out, err, _ = run_cli(["render", "sphere", "--out", "o.png", "--width", "16", "--height", "12",
                                   "--set", f'materials.ball={{model="custom", {value}}}'], tmp_path)
        assert rc == 0 and "Traceback" not in err, (stem, err)


def test_include_names_are_plain_and_distinct():
    from viewer.gl.file_brdf_glsl import include_name

    assert include_name("plain-name_1.2.brdf") == "plain-name_1.2.brdf"
    odd = [include_name(f"{s}.brdf") for s in ODD + ['quo_te']]
    assert len(set(odd)) == len(odd)
    assert all(n.endswith(".brdf") and n.isascii() and not set(n) & set("\"'\\\n ;") for n in odd), odd


# ------------------------------------------------------------------ the window's state


def run_child(code: str, *args, env=None):
    """``code`` in a child Python: (exit status, stdout, stderr, its peak RSS in MB)."""
    full_env = dict(os.environ)
    full_env.update(env or {})
    full_env["PYTHONPATH"] = str(Path(__file__).resolve().parent.parent) + os.pathsep + full_env.get("PYTHONPATH", "")
    code = PEAK + textwrap.dedent(code) + textwrap.dedent("""
        import sys as _s
        print("MAXRSS_KB", peak_kb(), file=_s.stderr)
    """)
    r = subprocess.run([sys.executable, "-c", code, *args], capture_output=True, text=True, env=full_env,
                       timeout=600)  # a hang detector: a FIFO used to block the read forever
    lines = r.stderr.splitlines()
    kb = [int(l.split()[1]) for l in lines if l.startswith("MAXRSS_KB")]
    err = "\n".join(l for l in lines if not l.startswith("MAXRSS_KB"))
    return r.returncode, r.stdout, err, (kb[-1] / 1024 if kb else float("nan"))


LOAD_STATE = """
    import sys
    from viewer.app.state import load_state
    print("STATE", load_state(sys.argv[1]))
"""


def _fifo(p: Path):
    os.mkfifo(p)


def _dev_zero(p: Path):
    p.symlink_to("/dev/zero")


def _huge(p: Path):
    with open(p, "wb") as f:
        f.truncate(2 * 1024 ** 3)  # sparse: no disk spent


def _deep(p: Path):
    p.write_text("a" + ".a" * 8000 + " = 1\n")  # 16 KB: within the size, not the key depth


STATE_DAMAGE = {"FIFO": (_fifo, "a FIFO"), "link to /dev/zero": (_dev_zero, "a character device"),
                "2 GB sparse": (_huge, "2147483648 bytes"), "key of 8001 parts": (_deep, "dotted parts")}


@pytest.mark.parametrize("damage", list(STATE_DAMAGE))
def test_a_state_file_that_is_not_a_small_file_is_ignored_in_one_line_unread(damage, tmp_path):
    make, words = STATE_DAMAGE[damage]
    p = tmp_path / "state.toml"
    make(p)
    rc, out, err, mb = run_child(LOAD_STATE, str(p))
    assert rc == 0 and "STATE {}" in out, err
    lines = err.strip().splitlines()
    assert len(lines) == 1 and "window state ignored" in lines[0] and words in lines[0], err
    print(f"state file, {damage}: refused at {mb:.0f} MB peak")
    assert mb < 200, mb


def test_a_small_state_file_and_a_link_to_one_still_load(tmp_path):
    from viewer.app.state import load_state

    real = tmp_path / "real.toml"
    real.write_text("window_width = 800\nui_scale = 1.5\n")
    link = tmp_path / "state.toml"
    link.symlink_to(real)
    assert load_state(link) == {"window_width": 800, "ui_scale": 1.5}
    assert load_state(tmp_path / "absent.toml") == {}


def test_window_sizes_are_fitted_to_the_display_and_the_context(capsys):
    from viewer.app import window_size

    assert window_size.fit((8192, 8192), (1600, 1000), "the display") == (1600, 1000)
    said = capsys.readouterr().err.strip().splitlines()
    assert said == ["brdf-viewer: window 8192x8192 does not fit the display (1600x1000); opening it at 1600x1000"]
    assert window_size.fit((1280, 720), (1600, 1000), "the display") == (1280, 720)
    assert window_size.fit((10, 20000), None, "") == (64, 20000)
    assert capsys.readouterr().err == ""
    info = {"GL_MAX_TEXTURE_SIZE": 16384, "GL_MAX_RENDERBUFFER_SIZE": 8192, "GL_MAX_VIEWPORT_DIMS": (16384, 4096)}
    assert window_size.gl_bound(info) == 4096
    assert window_size.gl_bound({}) == window_size.NO_MONITOR_MAX

    class NoMonitor:
        @staticmethod
        def get_primary_monitor():
            return None

    assert window_size.monitor_bound(NoMonitor)[0] == (window_size.NO_MONITOR_MAX,) * 2


@pytest.mark.skipif(shutil.which("Xvfb") is None, reason="needs Xvfb")
def test_a_state_file_too_large_for_the_display_opens_a_window_that_fits_and_a_failed_size_is_not_saved(display):
    from gui_harness import run_py

    r = run_py("""
        import os
        from viewer.app import state
        from viewer.app.main import App
        path = state.state_path()
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text("window_width = 16384\\nwindow_height = 16384\\n")
        app = App("sphere")
        app.session.warm = []
        print("SIZE", *app.glfw.get_window_size(app.window))
        app.frame()
        app.close()
        print("SAVED", state.load_state().get("window_width"), state.load_state().get("window_height"))
        # a frame that raises: the window's size is not saved for the next start
        path.write_text("window_width = 640\\nwindow_height = 400\\n")
        app = App("sphere")
        app.session.warm = []
        def broken(*a, **k):
            raise RuntimeError("a frame that fails")
        app.frame = broken
        try:
            app.run(frames=1)
        except RuntimeError:
            pass
        print("AFTER", state.load_state().get("window_width"), state.load_state().get("ui_scale"))
    """, display)
    assert r.returncode == 0, r.stdout + r.stderr
    size = [line.split()[1:] for line in r.stdout.splitlines() if line.startswith("SIZE")][0]
    assert [int(v) for v in size] == [1600, 1000], r.stdout + r.stderr  # the display fixture's screen
    assert "SAVED 1600 1000" in r.stdout and "does not fit the display" in r.stderr, r.stdout + r.stderr
    assert "AFTER None 1.0" in r.stdout, r.stdout + r.stderr


# ------------------------------------------------------------------ small files, huge memory


def _png(chunks: list[tuple[bytes, bytes]]) -> bytes:
    import struct
    import zlib

    def chunk(kind, data):
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF)

    ihdr = struct.pack(">IIBBBBB", 4, 4, 8, 2, 0, 0, 0)
    idat = zlib.compress(b"".join(b"\0" + b"\0" * 12 for _ in range(4)))
    return (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", ihdr) + b"".join(chunk(k, d) for k, d in chunks)
            + chunk(b"IDAT", idat) + chunk(b"IEND", b""))


DEEP_KEY = "a" + ".a" * 25000 + " = 1\n"  # 50 KB: used to cost the TOML reader 3.5 GB


def _deep_toml(tmp_path):
    p = tmp_path / "deep.toml"
    p.write_text(DEEP_KEY)
    return p


def _deep_png(tmp_path):
    p = tmp_path / "deep.png"
    p.write_bytes(_png([(b"tEXt", b"brdf-viewer:scene\0" + DEEP_KEY.encode())]))
    return p


def _big_ztxt(tmp_path):
    import zlib

    p = tmp_path / "big.png"  # 33 MB of text in a chunk of 33 KB
    p.write_bytes(_png([(b"zTXt", b"brdf-viewer:scene\0\0" + zlib.compress(b"#" * (33 * 1024 * 1024)))]))
    return p


SCENE_PROBES = {
    "TOML key of 25,001 parts": (_deep_toml, "a key of more than 64 dotted parts"),
    "PNG scene with that key": (_deep_png, "a key of more than 64 dotted parts"),
    "PNG zTXt of 33 MB": (_big_ztxt, "a text chunk larger than"),
}


@pytest.mark.parametrize("probe", list(SCENE_PROBES))
def test_small_scene_files_asking_for_huge_memory_are_refused_in_one_line(probe, tmp_path):
    make, words = SCENE_PROBES[probe]
    path = make(tmp_path)
    rc, out, err, mb = run_cli(["render", str(path), "--out", "o.png"], tmp_path)
    assert rc == 2 and words in one_error(err) and path.name in one_error(err), err
    print(f"{probe}: refused at {mb:.0f} MB peak")
    assert mb < 200, mb


def test_a_png_text_chunk_over_a_megabyte_of_scene_still_reopens(tmp_path):
    """Pillow's own bound (1 MB) is raised to the scene's: a big scene's screenshot reopens."""
    import zlib

    from viewer.scene import load_scene

    text = 'version = 1\n[materials.m]\nmodel = "lambert"\n' + "#" * (2 * 1024 * 1024) + \
        '\n[[objects]]\nmesh = "sphere"\nmaterial = "m"\n'
    p = tmp_path / "shot.png"
    p.write_bytes(_png([(b"zTXt", b"brdf-viewer:scene\0\0" + zlib.compress(text.encode()))]))
    assert load_scene(p, load_meshes=False).objects[0].mesh == "sphere"


def test_a_toml_value_or_key_of_many_parts_in_set_is_one_line(tmp_path):
    from viewer.scene import load_scene

    with pytest.raises(ViewerError) as e:
        load_scene("sphere", ["render.x={" + "a." * 5000 + "b=1}"])
    assert "dotted parts" in str(e.value) and "\n" not in str(e.value)
    assert load_scene("sphere", ["materials.ball.albedo=[0.5,0.5,0.5]"]).materials["ball"].albedo[0] == 0.5


def _sparse(path: Path, head: bytes = b"", size: int = 2 * 1024 ** 3) -> Path:
    with open(path, "wb") as f:
        f.write(head)
        f.truncate(size)  # sparse: no disk spent
    return path


PLY_HEAD = ("ply\nformat binary_little_endian 1.0\nelement vertex {v}\nproperty float x\nproperty float y\n"
            "property float z\nelement face {f}\nproperty list uchar int vertex_indices\nend_header\n")

MESH_PROBES = {
    "2 GB sparse PLY": (lambda d: _sparse(d / "big.ply"), "a mesh file holds at most"),
    "2 GB sparse OBJ": (lambda d: _sparse(d / "big.obj"), "a mesh file holds at most"),
    "PLY header of 2 GB": (lambda d: _sparse(d / "hdr.ply", PLY_HEAD.format(v=10 ** 8, f=1).encode()),
                           "a mesh file holds at most"),
    "PLY of 500,000,000 faces": (lambda d: _sparse(d / "faces.ply", PLY_HEAD.format(v=3, f=5 * 10 ** 8).encode(),
                                                   64 * 1024 ** 2), "face elements; at most"),
    "PLY header past its bytes": (lambda d: _sparse(d / "short.ply", PLY_HEAD.format(v=10 ** 7, f=1).encode(),
                                                    64 * 1024 ** 2), "the file has"),
    "900 MB sparse OBJ": (lambda d: _sparse(d / "zeros.obj", b"", 900 * 1024 ** 2), "NUL byte"),
}


@pytest.mark.parametrize("probe", list(MESH_PROBES))
def test_mesh_files_asking_for_huge_memory_are_refused_before_they_are_parsed(probe, tmp_path):
    make, words = MESH_PROBES[probe]
    mesh = make(tmp_path)
    rc, out, err, mb = run_cli(["render", "sphere", "--out", "o.png", "--width", "16", "--height", "12",
                                "--set", f'objects.0.mesh="{mesh}"'], tmp_path)
    assert rc == 2 and words in one_error(err) and mesh.name in one_error(err), err
    print(f"{probe}: refused at {mb:.0f} MB peak")
    assert mb < 200, mb


def test_real_meshes_pass_the_bounds(tmp_path):
    from viewer.base.input_bounds import mesh_problem, ply_problem
    from viewer.scene.mesh import load_mesh
    from viewer.base.resources import MODEL_DIR

    for p in sorted(Path(MODEL_DIR).glob("*.ply")):
        assert mesh_problem(p, p.stat().st_size) is None, p
    obj = tmp_path / "tri.obj"
    obj.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    assert len(load_mesh(str(obj)).indices) == 1
    text = PLY_HEAD.replace("binary_little_endian", "ascii").format(v=3, f=1) + "0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n"
    assert ply_problem(text.encode(), len(text)) is None
    assert "the file has" in ply_problem(text.encode(), 20)


# ------------------------------------------------------------------ numbers that overflow


@pytest.mark.parametrize("assignment, words", [
    ("objects.0.translate=[1e20,0,0]", "objects[0].translate"),
    ("camera.position=[3e38,0,0]", "camera.position"),
    ("camera.target=[0,2e6,0]", "camera.target"),
    ("lights.0.position=[0,0,-1e30]", "lights[0].position"),
    ("objects.0.scale=1e-30", "objects[0].scale"),
    ("objects.0.scale=[1,1,1e9]", "objects[0].scale"),
])
def test_numbers_past_the_scenes_bounds_are_one_line(assignment, words):
    from viewer.scene import load_scene

    with pytest.raises(ViewerError) as e:
        load_scene("sphere", [assignment])
    msg = str(e.value)
    assert words in msg and "allowed:" in msg and "\n" not in msg, msg


def test_the_bounds_render(renderer):
    from viewer import api
    from viewer.scene import load_scene

    sc = load_scene("sphere", ["camera.width=16", "camera.height=12", "objects.0.translate=[1e6,0,0]",
                               "camera.target=[1e6,0,0]", "camera.position=[1e6,0,4]", "objects.0.scale=1e-6"])
    assert np.all(np.isfinite(api.render(sc)))


def test_a_camera_at_3e38_is_refused_by_render(tmp_path):
    rc, out, err, _ = run_cli(["render", "sphere", "--out", "o.png", "--set", "camera.position=[3e38,0,0]"], tmp_path)
    assert rc == 2 and "camera.position" in one_error(err), err


@pytest.mark.skipif(shutil.which("Xvfb") is None, reason="needs Xvfb")
def test_a_camera_at_3e38_is_refused_before_the_window_opens(display, tmp_path):
    state = tmp_path / "state.toml"
    rc, out, err, _ = run_cli(["sphere", "--frames", "1", "--set", "camera.position=[3e38,0,0]"], tmp_path,
                              env={"DISPLAY": display, "BRDF_VIEWER_STATE": str(state)})
    assert rc == 2 and "camera.position" in one_error(err), err
    assert not state.exists()  # no window, no state written
