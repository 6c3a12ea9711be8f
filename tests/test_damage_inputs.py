"""Inputs that must not crash the window or cost memory before they are refused: a ``.brdf`` file
saved with other parameters into a running window (hot reload), a file with more parameter floats
than the material block holds, file names with quotes and other odd characters, window sizes and
state files that are not what the state file should hold, small files that ask for huge memory
(a TOML dotted key of 25,000 parts, PNG text chunks, sparse meshes of 2 GB) and scene numbers
that overflow the camera's and the objects' arithmetic. Each refusal is one line (exit status 2
from the CLI) and each is measured: the peak memory of the child that refused it."""

from __future__ import annotations

import os
import resource
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


def run_cli(args, tmp_path, env=None):
    """``brdf-viewer ARGS`` in a child: (exit status, stdout, stderr, the child's peak RSS in MB).
    The child reports its own peak (ru_maxrss of RUSAGE_SELF, kB on Linux) on a line of its own."""
    code = textwrap.dedent("""
        import resource, sys
        from viewer.cli import main
        try:
            rc = main(sys.argv[1:])
        except SystemExit as e:
            rc = e.code if isinstance(e.code, int) else 1
        print("MAXRSS_KB", resource.getrusage(resource.RUSAGE_SELF).ru_maxrss, file=sys.stderr)
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
        for text in {edits!r}:
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
    assert seen == ["PARAMS [('k', '0.25'), ('more', '0.75')]",
                    "PARAMS [('k', 'True'), ('more', '[1.  0.5 0.5]')]"], r.stdout + r.stderr


# ------------------------------------------------------------------ parameter floats


def test_the_limit_is_the_material_block_less_the_samplers_table():
    from viewer.gl.brdf_glsl import HALF_TABLE
    from viewer.gl.constants import MAT_FLOATS

    assert brdffile.MAX_PARAM_FLOATS == MAT_FLOATS - HALF_TABLE


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
