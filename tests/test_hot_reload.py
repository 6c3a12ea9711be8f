"""Shader hot reload: a watcher notices edited files, the renderer rebuilds the programs that
use them, a compile error names the included file and line it is really in while the last
good program keeps rendering, and a fixed file takes effect. Every edit is made in a
temporary copy of shaders/ (set_shader_root), never in the real files."""

import os
import shutil
import textwrap
import time

import numpy as np
import pytest

from viewer.scene.camera import OrbitCamera
from viewer.gl import shaders
from viewer.gl.hot_reload import ShaderWatcher
from viewer.gl.shaders import SHADER_ROOT_ENV, ShaderError, set_shader_root, shader_root
from viewer.base.resources import SHADER_DIR
from viewer.scene import load_scene

SCENE = """
[camera]
position = [0.0, 0.0, 4.0]
target = [0.0, 0.0, 0.0]
up = [0.0, 1.0, 0.0]
fov_y = 40.0
width = 64
height = 64

[render]
msaa = 0
shadows = false
ibl = "off"

[[lights]]
type = "point"
position = [2.0, 3.0, 4.0]
intensity = [10.0, 8.0, 6.0]

[[objects]]
mesh = "sphere"
material = "ball"

[materials.ball]
model = "{model}"
"""


def _scene(tmp_path, model="lambert"):
    p = tmp_path / f"{model}.toml"
    p.write_text(textwrap.dedent(SCENE.format(model=model)))
    return load_scene(p)


def _edit(path, text):
    """Write ``text`` and move the mtime a second on (mtime granularity can be coarse)."""
    st = path.stat()
    path.write_text(text)
    os.utime(path, ns=(st.st_atime_ns, max(path.stat().st_mtime_ns, st.st_mtime_ns) + 1_000_000_000))


def _insert_line(text, lineno, line):
    lines = text.splitlines()
    lines.insert(lineno - 1, line)
    return "\n".join(lines) + "\n"


def _poll_until_reload(hr, timeout=120.0):
    """Poll as the app does (once per 'frame') until a reload ran; returns (rebuilt, seconds)."""
    n = hr.reload_count
    t0 = time.perf_counter()
    while True:
        rebuilt = hr.poll()
        if hr.reload_count > n:
            return rebuilt, time.perf_counter() - t0
        assert time.perf_counter() - t0 < timeout, "no reload after the edit"   # a hang, not a latency
        time.sleep(0.005)


def _render(renderer, scene):
    return renderer.render_arrays(scene, OrbitCamera.from_scene(scene))[0]


# ------------------------------------------------------------------ no GL


def test_shader_root_default_env_and_override(monkeypatch, tmp_path):
    saved = set_shader_root(None)
    try:
        monkeypatch.delenv(SHADER_ROOT_ENV, raising=False)
        assert shader_root() == SHADER_DIR  # default: the package's folder
        monkeypatch.setenv(SHADER_ROOT_ENV, str(tmp_path))
        assert shader_root() == tmp_path.resolve()
        other = tmp_path / "other"
        other.mkdir()
        set_shader_root(other)  # the module setting wins over the environment
        assert shader_root() == other.resolve()
        (other / "a.glsl").write_text("float a() { return 1.0; }\n")
        src = shaders.preprocess('#version 410 core\n#include "a.glsl"\n', "<t>")
        assert "return 1.0" in src.text and src.files == ["<t>", "a.glsl"]
    finally:
        set_shader_root(saved)


def test_include_error_names_the_including_file_and_line(tmp_path):
    (tmp_path / "b.glsl").write_text('// b\n#include "missing.glsl"\n')
    with pytest.raises(ShaderError) as e:
        shaders.preprocess('#version 410 core\n#include "b.glsl"\n', "<t>", root=tmp_path)
    assert (e.value.file, e.value.line) == ("b.glsl", 2)
    assert e.value.summary().startswith("b.glsl:2: cannot include 'missing.glsl'")


def test_watcher_reports_modified_added_removed_and_rate_limits(tmp_path):
    (tmp_path / "common").mkdir()
    a = tmp_path / "common" / "a.glsl"
    a.write_text("x\n")
    (tmp_path / "notes.txt").write_text("not a shader\n")
    w = ShaderWatcher(tmp_path, interval=60.0)
    _edit(a, "y\n")
    assert w.poll() == []  # within the interval: no scan
    assert w.poll(force=True) == ["common/a.glsl"]
    assert w.poll(force=True) == []
    (tmp_path / "b.frag").write_text("z\n")
    (tmp_path / ".a.glsl.swp").write_text("editor state\n")  # hidden: ignored
    _edit(tmp_path / "notes.txt", "still not\n")  # not a shader: ignored
    assert w.poll(force=True) == ["b.frag"]
    a.unlink()
    assert w.poll(force=True) == ["common/a.glsl"]
    w.interval = 0.0
    _edit(tmp_path / "b.frag", "zz\n")
    assert w.poll() == ["b.frag"]


# ------------------------------------------------------------------ GL


@pytest.fixture(scope="module")
def shader_copy(tmp_path_factory):
    root = tmp_path_factory.mktemp("hot") / "shaders"
    shutil.copytree(SHADER_DIR, root)
    saved = set_shader_root(root)
    yield root
    set_shader_root(saved)


@pytest.fixture(scope="module")
def hot(gl_ctx, shader_copy):
    from viewer.app.shader_overlay import HotReload
    from viewer.gl.renderer import Renderer

    r = Renderer(gl_ctx)
    hr = HotReload(r, root=shader_copy)
    yield r, hr, shader_copy
    r.release()


def test_deep_include_error_keeps_last_image_and_a_fix_takes_effect(tmp_path, hot):
    renderer, hr, root = hot
    scene = _scene(tmp_path)
    before = _render(renderer, scene)
    assert before.max() > 0.05
    n_before = len(renderer.programs)

    math_glsl = root / "common" / "math.glsl"
    lambert = root / "brdf" / "lambert.glsl"
    math_ok, lambert_ok = math_glsl.read_text(), lambert.read_text()
    try:
        # an error two includes deep (forward.frag -> common/math.glsl, also via ibl.glsl ...)
        _edit(math_glsl, _insert_line(math_ok, 3, "const float HOT_RELOAD_PROBE = no_such_symbol;"))
        rebuilt, t_err = _poll_until_reload(hr)
        assert not rebuilt and renderer.last_reloaded == []
        errs = hr.errors
        assert errs, "the broken include was not reported"
        assert {(e.file, e.line) for e in errs} == {("common/math.glsl", 3)}, [e.summary() for e in errs]
        assert "no_such_symbol" in errs[0].summary() and errs[0].summary().startswith("common/math.glsl:3:")
        # the last good programs keep rendering: the very same image
        again = _render(renderer, scene)
        assert np.array_equal(again, before)
        assert len(renderer.programs) == n_before

        # a touch with no change of content rebuilds nothing and keeps the error
        _edit(math_glsl, math_glsl.read_text())
        _poll_until_reload(hr)
        assert renderer.last_reloaded == [] and hr.errors

        # fix the include and make a visible change in the Lambert BRDF at once
        _edit(math_glsl, math_ok)
        nonce = 1.0 + (time.time_ns() % 999983) * 1e-12  # new source each run; 1 in float32
        halved = lambert_ok.replace("vec3 lambert_eval(", "vec3 lambert_eval_unscaled(") + (
            "\nvec3 lambert_eval(lambert_params p, vec3 wi, vec3 wo) {\n"
            f"    return 0.5 * {nonce!r} * lambert_eval_unscaled(p, wi, wo);\n}}\n")
        _edit(lambert, halved)
        rebuilt, t_fix = _poll_until_reload(hr)
        assert rebuilt and hr.errors == [] and renderer.shader_errors == []
        assert any(k.startswith("forward:lambert") for k in renderer.last_reloaded)
        t0 = time.perf_counter()
        after = _render(renderer, scene)  # software GL JIT-compiles at the first draw
        t_frame = time.perf_counter() - t0
        lit = before > 1e-3
        assert np.allclose(after[lit], 0.5 * before[lit], rtol=1e-4, atol=1e-6)

        # a deep edit that every program including math.glsl must be rebuilt for: reload latency
        # (a new constant each run: no compiler cache can serve it)
        _edit(math_glsl, math_ok + f"\nconst float HOT_RELOAD_NONCE = {time.time_ns() % 999983}.0;\n")
        rebuilt, t_all = _poll_until_reload(hr)
        assert rebuilt and hr.errors == []
        programs = list(renderer.last_reloaded)
        t0 = time.perf_counter()
        assert np.allclose(_render(renderer, scene)[lit], 0.5 * before[lit], rtol=1e-4, atol=1e-6)
        t_frame_all = time.perf_counter() - t0
        print(f"\nreload latency from the edit (waits for the {hr.watcher.interval} s scan included): error "
              f"reported {t_err * 1000:.0f} ms; fix + Lambert change: programs {t_fix * 1000:.0f} ms, "
              f"+ first frame {t_frame * 1000:.0f} ms; math.glsl edit ({len(programs)} programs: "
              f"{', '.join(programs)}): programs {t_all * 1000:.0f} ms (reload {hr.last_reload_ms:.0f} ms), "
              f"+ first frame {t_frame_all * 1000:.0f} ms")
        # figures belong in the report, not in assertions (no timing assertions); a hang is caught
        # by _poll_until_reload's deadline
    finally:
        _edit(math_glsl, math_ok)
        _edit(lambert, lambert_ok)
        _poll_until_reload(hr)
    assert hr.errors == []
    assert np.allclose(_render(renderer, scene), before, rtol=1e-5, atol=1e-7)


def test_program_first_compiled_after_a_broken_edit(tmp_path, hot):
    """A model whose program was never built while its file is broken: hot-reload mode leaves
    the object out and reports the error; strict mode (CLI, tests) raises; the fix builds it."""
    renderer, hr, root = hot
    scene = _scene(tmp_path, "phong")
    phong = root / "brdf" / "phong.glsl"
    ok = phong.read_text()
    try:
        _edit(phong, _insert_line(ok, 5, "float broken_phong = missing_helper(1.0);"))
        _poll_until_reload(hr)
        assert not any(k.startswith("forward:phong") for k in renderer.programs)

        img = _render(renderer, scene)  # no exception: the sphere is left out
        assert float(np.abs(img).max()) == 0.0
        errs = hr.errors
        assert [(e.file, e.line) for e in errs] == [("brdf/phong.glsl", 5)], [e.summary() for e in errs]
        assert errs[0].program.startswith("forward:phong")

        renderer.hot_reload = False
        try:
            with pytest.raises(ShaderError) as e:
                _render(renderer, scene)
            assert (e.value.file, e.value.line) == ("brdf/phong.glsl", 5)
        finally:
            renderer.hot_reload = True

        _edit(phong, ok)
        rebuilt, _ = _poll_until_reload(hr)
        assert rebuilt and hr.errors == []
        assert _render(renderer, scene).max() > 0.05
    finally:
        _edit(phong, ok)
        _poll_until_reload(hr)
    assert hr.errors == []


SSR_SCENE = SCENE.replace('ibl = "off"', 'ibl = "split_sum"\nssr = true') + """
[environment]
constant = [0.4, 0.5, 0.6]

[[objects]]
mesh = "plane"
material = "floor"
translate = [0.0, -1.0, 0.0]
scale = 4.0

[materials.floor]
model = "mirror"
"""


def test_ibl_and_ssr_programs_reload_through_the_passes(tmp_path, hot):
    """The IBL and SSR passes' programs are rebuilt through their own interface
    (``program_recipes`` / ``replace_program``): an edit of the SSR composite takes effect, an
    edit of the IBL prefilter rebuilds the prefiltered environment (the same result here)."""
    renderer, hr, root = hot
    p = tmp_path / "ssr.toml"
    p.write_text(textwrap.dedent(SSR_SCENE.format(model="lambert")))
    scene = load_scene(p)
    before = _render(renderer, scene)
    assert before.max() > 0.05
    assert set(renderer.ssr().program_recipes()) == {"trace", "background", "hiz"}
    assert "ibl_prefilter" in renderer.ibl().program_recipes()
    ssr_frag, prefilter = root / "passes" / "ssr.frag", root / "passes" / "ibl_prefilter.frag"
    ssr_ok, prefilter_ok = ssr_frag.read_text(), prefilter.read_text()
    assert "frag_color = vec4(base + ssr, 1.0);" in ssr_ok
    try:
        _edit(ssr_frag, ssr_ok.replace("frag_color = vec4(base + ssr, 1.0);", "frag_color = vec4(0.5 * (base + ssr), 1.0);"))
        nonce = time.time_ns() % 999983  # a new source each run: no compiler cache serves it
        _edit(prefilter, prefilter_ok + f"\nconst float HOT_RELOAD_NONCE = {nonce}.0;\n")
        rebuilt, _ = _poll_until_reload(hr)
        assert rebuilt and hr.errors == []
        assert {"ssr:trace", "ibl:ibl_prefilter"} <= set(renderer.last_reloaded), renderer.last_reloaded
        assert not renderer.ibl().use_cache  # results of edited shaders never go to the disk cache
        after = _render(renderer, scene)
        np.testing.assert_allclose(after, 0.5 * before, rtol=1e-5, atol=1e-7)
    finally:
        _edit(ssr_frag, ssr_ok)
        _edit(prefilter, prefilter_ok)
        _poll_until_reload(hr)
    assert hr.errors == []
    np.testing.assert_allclose(_render(renderer, scene), before, rtol=1e-5, atol=1e-7)
