"""A .brdf file's GLSL cannot hang or exhaust the viewer (viewer/brdf/glsl_guard.py,
viewer/gl/file_probe.py), and the window's helper processes are on a leash
(viewer/app/compile_ahead.py, viewer/app/prefetch.py): sizes refused before anything is read or
compiled, loops that never end refused, every loop under a budget, the compile and a 4x4 render
in a child with a time and a memory limit, ``check`` ending at once on a signal with no child
left, and a silent child replaced. Time limits here are small ones set through the environment
or an argument, against children that never finish; no test asserts how long anything took."""

from __future__ import annotations

import math
import os
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import numpy as np
import pytest

from viewer import ViewerError
from viewer.brdf import glsl_guard
from viewer.brdf.brdffile import parse

ROOT = Path(__file__).resolve().parent.parent


def _file(tmp_path, name, body, params=""):
    p = tmp_path / name
    p.write_text(f"analytic\n::begin parameters\n{params}::end parameters\n::begin shader\n{body}\n"
                 f"::end shader\n")
    return p


def _brdf(code):
    return f"vec3 BRDF(vec3 L, vec3 V, vec3 N, vec3 X, vec3 Y)\n{{\n{code}\n}}"


def _bomb(depth: int) -> str:
    """A BRDF of 16,000 loop steps (within the budget) over a call tree 4**depth wide: its
    compile and render grow fourfold with each level (a few seconds at 6, minutes at 8)."""
    fs = ["float f0(float x) { return sin(x) * cos(x * 1.3) + exp(-x * x); }"]
    for k in range(1, depth + 1):
        fs.append(f"float f{k}(float x) {{ return f{k-1}(x) + f{k-1}(x + 0.1) + f{k-1}(x + 0.2) + f{k-1}(x + 0.3); }}")
    return "\n".join(fs) + "\n" + _brdf(f"    float s = L.z;\n    for (int i = 0; i < 16000; i++) {{ s = 1e-3 * f{depth}(s); }}\n"
                                        "    return vec3(abs(s) * 1e-3);")


def _env(**extra):
    return dict(os.environ, PYTHONPATH=str(ROOT), **extra)


def _check(path, **env):
    return subprocess.run([sys.executable, "-m", "viewer", "check", str(path)], capture_output=True, text=True,
                          env=_env(**env), timeout=600)


def _one_error_line(r) -> str:
    lines = [x for x in r.stderr.strip().splitlines() if x.strip()]
    assert len(lines) == 1 and "Traceback" not in r.stderr, r.stderr
    return lines[0]


# ------------------------------------------------------------------ sizes

def test_a_huge_file_is_refused_by_its_size_before_it_is_read_in_little_memory(tmp_path):
    big = tmp_path / "huge.brdf"
    with open(big, "w") as f:
        f.write("analytic\n::begin shader\n")
        line = "float pad_%d = 1.0;\n"
        for i in range(400_000):  # about 10 MB
            f.write(line % i)
        f.write(_brdf("return vec3(0.1);") + "\n::end shader\n")
    assert big.stat().st_size > 8_000_000
    # the RSS of the check process alone: a fresh parent whose only child it is
    code = textwrap.dedent(f"""
        import resource, subprocess, sys
        r = subprocess.run([sys.executable, "-m", "viewer", "check", {str(big)!r}], capture_output=True, text=True)
        print(r.returncode, resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss)
        sys.stderr.write(r.stderr)
    """)
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=_env(), timeout=600)
    rc, maxrss_kb = (int(x) for x in r.stdout.split())
    assert rc == 2
    line = _one_error_line(r)
    assert "huge.brdf" in line and "at most 256 KB" in line, line
    assert maxrss_kb < 200 * 1024, f"check used {maxrss_kb / 1024:.0f} MB refusing a file by its size"


@pytest.mark.parametrize("text, words", [
    ("analytic\n" + "# a comment\n" * (glsl_guard.MAX_LINES + 1) + "::begin shader\n" + _brdf("return vec3(0.1);")
     + "\n::end shader\n", "lines"),
    ("analytic\n::begin shader\n" + "\n".join(f"const float c{i} = {i}.0 + 1.0 + 2.0 + 3.0 + 4.0 + 5.0 + 6.0 + 7.0 + 8.0;"
                                               for i in range(1500))
     + "\n" + _brdf("return vec3(0.1);") + "\n::end shader\n", "GLSL has"),
    ("analytic\n::begin shader\nfloat table[100000];\n" + _brdf("return vec3(0.1);") + "\n::end shader\n",
     "3: an array of 100,000 elements"),
])
def test_files_over_a_limit_are_refused_in_one_line_naming_the_limit(text, words):
    with pytest.raises(ViewerError) as e:
        parse("over.brdf", text=text)
    msg = str(e.value)
    assert msg.startswith("over.brdf") and words in msg and "\n" not in msg, msg


def test_the_shipped_and_test_files_are_far_inside_the_limits():
    files = sorted((ROOT / "viewer" / "brdfs").glob("*.brdf")) + sorted((ROOT / "tests" / "brdfs").glob("*.brdf"))
    assert files
    for f in files:
        if f.name == "syntax_error.brdf":
            continue
        text = f.read_text()
        assert len(text) * 10 < glsl_guard.MAX_FILE_BYTES and text.count("\n") * 10 < glsl_guard.MAX_LINES
        parse(f)


# ------------------------------------------------------------------ loops

@pytest.mark.parametrize("loop, line, shown", [
    ("while (true) { s += 1.0; }", 8, "while (true)"),
    ("for (;;) { s += 1.0; }", 8, "for (;;)"),
    ("for (int i = 0; ; i++) { s += 1.0; }", 8, "for (;;)"),
    ("do { s += 1.0; } while (1);", 8, "while (1)"),
    ("while (\n  true\n) { s += 1.0; }", 8, "while"),
])
def test_a_loop_that_never_ends_is_refused_with_its_line(tmp_path, loop, line, shown):
    p = _file(tmp_path, "forever.brdf", _brdf(f"    float s = 0.0;\n    {loop}\n    return vec3(s);"))
    r = _check(p)
    assert r.returncode == 2
    msg = _one_error_line(r)
    assert f"forever.brdf:{line}:" in msg and shown in msg and "never ends" in msg, msg


def test_loops_keep_their_lines_and_a_comment_is_no_loop(tmp_path):
    p = _file(tmp_path, "ok.brdf", _brdf(
        "    float s = 0.0; // while (true) is only a comment\n"
        "    for (int i = 0; i < 8; i++) { for (int j = 0; j < 8; j++) s += 1.0 / 64.0; }\n"
        "    int k = 0;\n    while (k < 3) k++;\n    do { k++; } while (k < 5);\n"
        "    return vec3(s * 0.3 / 3.14159265) * float(k) / 5.0;"))
    f = parse(p)
    block = f.glsl_block()
    assert len(block.splitlines()) == len(f.lines)
    assert block.count("bxf_0step() && (") == 4
    from viewer import brdf

    m = brdf.load(p)
    wi = np.array([[0.0, 0.0, 1.0], [0.6, 0.0, 0.8]])
    f_val = m.eval(m.params(), wi, wi[::-1].copy())
    assert np.allclose(f_val, 0.3 / np.pi, rtol=1e-5)  # the guarded loops ran to their end


@pytest.mark.parametrize("body", [
    "    float s = 0.0;\n    for (int i = 0; i < 1000000000; i++) { s += 1e-12; }\n    return vec3(0.3 + s);",
    "    float s = 1.0;\n    while (s > 0.0) { s += 1.0; }\n    return vec3(0.3);",
    "    float s = 0.0;\n    for (int i = 0; i < 200; i++) for (int j = 0; j < 200; j++) s += 1e-9;\n    return vec3(0.3 + s);",
])
def test_a_loop_past_the_budget_fails_check_instead_of_passing_it(tmp_path, body):
    """llvmpipe ends any loop at 65,535 steps by itself, so without the budget a 1e9-step loop
    passes the card here (and hangs a real GPU); nested loops count together."""
    p = _file(tmp_path, "long.brdf", _brdf(body))
    r = _check(p)
    assert r.returncode == 2, r.stdout + r.stderr
    msg = _one_error_line(r)
    assert "long.brdf" in msg and "16,384 steps" in msg, msg


# ------------------------------------------------------------------ the probe

def test_a_file_whose_test_render_does_not_finish_is_refused_and_its_child_killed(tmp_path, monkeypatch):
    from lifecycle import children

    from viewer import brdf

    monkeypatch.setenv("BRDF_VIEWER_PROBE_TIMEOUT", "1.5")
    p = _file(tmp_path, "slow.brdf", _bomb(8))
    with pytest.raises(ViewerError) as e:
        brdf.load(p)
    assert str(e.value) == ("slow.brdf: its GLSL did not finish a 4x4 test render within 1.5 s "
                            "(an unbounded loop?)")
    assert not [c for c in children().values() if "file_probe" in c]


@pytest.mark.slow
def test_a_file_whose_compile_exceeds_the_memory_limit_is_refused(tmp_path, monkeypatch):
    from viewer import brdf

    monkeypatch.setenv("BRDF_VIEWER_PROBE_MEMORY_MB", "1024")
    monkeypatch.setenv("BRDF_VIEWER_PROBE_TIMEOUT", "300")
    p = _file(tmp_path, "fat.brdf", _bomb(8))
    with pytest.raises(ViewerError, match=r"fat\.brdf: .* more than 1,024 MB of memory"):
        brdf.load(p)


def test_a_verdict_is_kept_per_content_in_the_process_and_on_disk(tmp_path):
    from viewer.gl import file_probe
    from viewer.base.io import cache_root

    a = _file(tmp_path, "a.brdf", _brdf(f"return vec3({time.time_ns() % 1000} * 1e-4);"))
    before = file_probe.started
    file_probe.probe(parse(a))
    assert file_probe.started == before + 1
    assert len(list((cache_root() / "brdf_probe").glob("*.ok"))) == 1
    (tmp_path / "b").mkdir()
    b = (tmp_path / "b" / "a.brdf")
    b.write_text(a.read_text())
    file_probe.probe(parse(b))  # the same content elsewhere: no second child
    assert file_probe.started == before + 1


def test_load_asks_the_probe_set_for_the_process(tmp_path):
    from viewer import brdf
    from viewer.brdf import file_model

    seen = []

    def refuse(bfile):
        seen.append(bfile.path.name)
        raise ViewerError(f"{bfile.path.name}: refused by the stand-in")

    p = _file(tmp_path, "vetted.brdf", _brdf("return vec3(0.1);"))
    file_model.set_file_probe(refuse)
    try:
        with pytest.raises(ViewerError, match="vetted.brdf: refused by the stand-in"):
            brdf.load(p)
    finally:
        file_model.set_file_probe(None)
    assert seen == ["vetted.brdf"]
    brdf.load(p)  # the default probe again: it passes


@pytest.mark.skipif(not os.path.isdir("/proc/self"), reason="reads the process tree from Linux /proc")
def test_cancel_all_ends_a_running_test_render_without_a_verdict(tmp_path, monkeypatch):
    import threading

    from lifecycle import children

    from viewer.gl import file_probe

    monkeypatch.setenv("BRDF_VIEWER_PROBE_TIMEOUT", "600")
    bfile = parse(_file(tmp_path, "waited.brdf", _bomb(8)))
    out = []
    # a probe child of an earlier test may still be ending: wait for this probe's own
    before = {pid for pid, c in children(zombies=False).items() if "file_probe" in c}

    def run():
        try:
            file_probe.probe(bfile)
            out.append("passed")
        except ViewerError as e:
            out.append(str(e))

    t = threading.Thread(target=run)
    t.start()
    _wait(lambda: any("file_probe" in c and pid not in before for pid, c in children(zombies=False).items()) or out,
          "the probe's child")
    file_probe.cancel_all()  # also when the child is not yet registered (the probe sees the cancel)
    t.join(120)  # a hang detector
    assert out == ["waited.brdf: the test render of its GLSL was stopped"]
    assert not [c for c in children(zombies=False).values() if "file_probe" in c]


def test_a_compile_error_passes_the_probe_and_is_reported_on_its_line():
    from viewer import brdf
    from viewer.gl.file_brdf import FileBrdfError

    m = brdf.load(ROOT / "tests" / "brdfs" / "syntax_error.brdf")
    with pytest.raises(FileBrdfError, match=r"syntax_error\.brdf:\d+:"):
        m.eval(m.params(), np.array([[0.0, 0.0, 1.0]]), np.array([[0.0, 0.0, 1.0]]))


def _wait(cond, what, limit=300.0):
    t0 = time.monotonic()  # a generous bound on a loaded machine; no speed is asserted
    while not cond():
        if time.monotonic() - t0 > limit:
            pytest.fail(f"not after {limit:.0f} s: {what}")
        time.sleep(0.05)


def _alive(pid: int) -> bool:
    try:
        with open(f"/proc/{pid}/stat") as f:
            return f.read().rsplit(")", 1)[1].split()[0] != "Z"
    except (OSError, IndexError):
        return False


@pytest.mark.skipif(not os.path.isdir("/proc/self"), reason="reads the process tree from Linux /proc")
@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGINT, signal.SIGKILL], ids=["TERM", "INT", "KILL"])
def test_a_signal_to_check_during_the_probe_ends_it_with_no_child_left(tmp_path, sig):
    from lifecycle import children

    p = _file(tmp_path, "busy.brdf", _bomb(8))
    proc = subprocess.Popen([sys.executable, "-m", "viewer", "check", str(p)], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, env=_env(BRDF_VIEWER_PROBE_TIMEOUT="600"))
    probes: list[int] = []
    try:
        def probing():
            probes[:] = [pid for pid, c in children(proc.pid, zombies=False).items() if "file_probe" in c]
            return bool(probes) or proc.poll() is not None

        _wait(probing, "the probe's child to start")
        assert probes, proc.communicate()
        time.sleep(0.5)  # the child is compiling, not starting
        proc.send_signal(sig)
        rc = proc.wait(timeout=120)  # a hang detector: it ends at once
        assert rc == (128 + sig if sig != signal.SIGKILL else -sig)
        _wait(lambda: not any(_alive(c) for c in probes), "the probe's child to end with its parent", 60)
        assert "Traceback" not in proc.stderr.read()
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
        for c in probes:
            if _alive(c):
                os.kill(c, signal.SIGKILL)


def test_saving_a_file_with_a_loop_that_cannot_end_into_a_window_keeps_the_last_good_program(gl_ctx, renderer,
                                                                                                 tmp_path):
    from viewer.app.session import Session
    from viewer.app.shader_overlay import HotReload

    s = Session(gl_ctx, "default", renderer=renderer, prefetch=False)
    s.warm = []
    try:
        src = tmp_path / "live.brdf"
        src.write_text("analytic\n::begin shader\n" + _brdf("    return vec3(0.2);") + "\n::end shader\n")
        assert s.load_brdf_file(str(src))
        hr = HotReload(s.renderer)

        def image():
            s.changed()
            s.render_view((48, 36))
            return s.renderer.read_linear(s.hdr).astype(np.float64)

        good = image()
        hr.poll(force=True)  # the first look only learns the files
        for n, (code, words) in enumerate([
                ("    float s = 0.0;\n    while (true) { s += 1.0; }\n    return vec3(s);", "live.brdf:6: the loop"),
                ("    float s = 0.0;\n    for (int i = 0; i < 1000000000; i++) s += 1e-9;\n    return vec3(s);",
                 "16,384 steps")]):
            src.write_text("analytic\n::begin shader\n" + _brdf(code) + "\n::end shader\n")
            st = src.stat()
            os.utime(src, ns=(st.st_atime_ns, st.st_mtime_ns + (n + 1) * 10 ** 9))
            hr.poll(force=True)
            errs = [e.summary() for e in hr.errors]
            assert any(words in e and e.startswith("live.brdf") for e in errs), errs
            np.testing.assert_allclose(image(), good, atol=1e-7)  # the last good program keeps drawing
    finally:
        s.release()


def test_a_file_the_scene_let_go_leaves_no_error_behind(gl_ctx, renderer, tmp_path):
    """A saved file whose loop ran past the budget, then another file opened on the material:
    the overlay lists no error of the file no longer in the scene (its program is dropped) and
    hot reload stops watching it; the other file draws."""
    from viewer.app.session import Session
    from viewer.app.shader_overlay import HotReload

    s = Session(gl_ctx, "default", renderer=renderer, prefetch=False)
    s.warm = []
    try:
        src = tmp_path / "live.brdf"
        src.write_text("analytic\n::begin shader\n" + _brdf("    return vec3(0.2);") + "\n::end shader\n")
        assert s.load_brdf_file(str(src))
        hr = HotReload(s.renderer)

        def image():
            s.changed()
            s.render_view((48, 36))
            return s.renderer.read_linear(s.hdr).astype(np.float64)

        image()
        hr.poll(force=True)  # the first look only learns the files
        src.write_text("analytic\n::begin shader\n" + _brdf(
            "    float s = 0.0;\n    for (int i = 0; i < 1000000000; i++) s += 1e-9;\n    return vec3(s);")
            + "\n::end shader\n")
        st = src.stat()
        os.utime(src, ns=(st.st_atime_ns, st.st_mtime_ns + 10 ** 9))
        hr.poll(force=True)
        assert any("16,384 steps" in e.summary() for e in hr.errors), [e.summary() for e in hr.errors]
        other = tmp_path / "other.brdf"
        other.write_text("analytic\n::begin shader\n" + _brdf("    return vec3(0.3);") + "\n::end shader\n")
        assert s.load_brdf_file(str(other))
        img = image()
        assert not s.renderer.shader_errors, [e.summary() for e in s.renderer.shader_errors]
        assert img.max() > 0
        watched = s.renderer.file_brdfs()
        assert str(other.resolve()) in watched and str(src.resolve()) not in watched, watched
        hr.poll(force=True)
        assert not hr.errors, [e.summary() for e in hr.errors]
        assert not s.load_brdf_file(str(src))  # the looping file itself is still refused
    finally:
        s.release()


@pytest.mark.slow
@pytest.mark.skipif(not os.path.isdir("/proc/self"), reason="reads the process tree from Linux /proc")
def test_sigterm_to_a_window_waiting_on_a_saved_files_test_render_closes_it_and_saves_its_state(display, tmp_path):
    """A file saved into a running window whose test render would take minutes: SIGTERM ends the
    wait (the child killed) and the window closes as always, saving its state."""
    from gui_harness import window_env
    from lifecycle import children

    src = tmp_path / "live.brdf"
    src.write_text("analytic\n::begin shader\n" + _brdf("    return vec3(0.2);") + "\n::end shader\n")
    scene = tmp_path / "scene.toml"
    scene.write_text((ROOT / "viewer" / "scenes" / "sphere.toml").read_text().replace(
        'model  = "lambert"\nalbedo = [0.8, 0.8, 0.8]', f'model = "custom"\nfile = "{src}"'))
    env = window_env(display)
    env.update(PYTHONPATH=str(ROOT), BRDF_VIEWER_PROBE_TIMEOUT="600")
    state = Path(env["BRDF_VIEWER_STATE"])
    p = subprocess.Popen([sys.executable, "-m", "viewer", str(scene)], env=env, stderr=subprocess.PIPE,
                         stdout=subprocess.PIPE, text=True, cwd=tmp_path)
    probes: list[int] = []
    try:
        line = ""
        t0 = time.monotonic()
        while "first frame" not in line and time.monotonic() - t0 < 600:
            line = p.stderr.readline()
            if not line and p.poll() is not None:
                break
        assert "first frame" in line, line + p.stderr.read()
        src.write_text("analytic\n::begin shader\n" + _bomb(8) + "\n::end shader\n")

        def probing():
            probes[:] = [pid for pid, c in children(p.pid, zombies=False).items() if "file_probe" in c]
            return bool(probes) or p.poll() is not None

        _wait(probing, "the saved file's test render to start")
        assert probes
        assert not state.exists()
        p.send_signal(signal.SIGTERM)
        rc = p.wait(120)  # a hang detector
        err = p.stderr.read()
        assert rc == 0 and "Traceback" not in err, err
        assert state.is_file() and "window_width" in state.read_text()
        _wait(lambda: not any(_alive(c) for c in probes), "the test render's child to end", 60)
    finally:
        if p.poll() is None:
            p.kill()
            p.wait()
        for c in probes:
            if _alive(c):
                os.kill(c, signal.SIGKILL)


# ------------------------------------------------------------------ the leash

NEVER_ANSWERS = [sys.executable, "-c", "import sys; print('{\"ready\": true}', flush=True); sys.stdin.read()"]


def test_a_compile_ahead_child_that_never_answers_is_replaced_with_a_notice():
    from viewer.app.compile_ahead import CompileAhead
    from viewer.scene import load_scene

    notes = []
    ca = CompileAhead(on_notice=notes.append, command=NEVER_ANSWERS, leash=0.3)
    try:
        first = ca.pid
        rid = ca.request(load_scene("sphere"))
        assert rid is not None and not ca.answered(rid)
        _wait(lambda: ca.answered(rid), "the leash")
        assert ca.replaced == 1 and ca.alive and ca.pid != first
        assert not ca.done[rid]["ok"] and "no answer within 0.3 s" in ca.done[rid]["error"]
        assert len(notes) == 1 and "did not answer within 0.3 s" in notes[0]
        _wait(lambda: not _alive(first), "the silent child to be gone", 30)
    finally:
        ca.stop()


@pytest.mark.skipif(not os.path.isdir("/proc/self"), reason="reads the process state from Linux /proc")
def test_a_stopped_compile_ahead_child_is_replaced():
    from viewer.app.compile_ahead import CompileAhead
    from viewer.scene import load_scene

    ca = CompileAhead(leash=1.0)
    try:
        _wait(lambda: ca.ready or not ca.alive, "the child's start")
        assert ca.alive, ca.error
        stopped = ca.pid
        os.kill(stopped, signal.SIGSTOP)
        rid = ca.request(load_scene("sphere"))
        _wait(lambda: ca.answered(rid), "the leash")
        assert ca.replaced == 1 and ca.alive and ca.pid != stopped
        _wait(lambda: not _alive(stopped), "the stopped child to be killed", 30)
    finally:
        ca.stop()


BUSY_NEVER_ANSWERS = [sys.executable, "-c", "import sys; print('{\"ready\": true}', flush=True); "
                      "sys.stdin.readline()\nwhile True: pass"]


@pytest.mark.skipif(not os.path.isdir("/proc/self"), reason="reads the process's CPU time from Linux /proc")
def test_a_child_that_works_without_answering_is_given_time_then_replaced():
    # a child using CPU is compiling (a traced program takes tens of seconds on a loaded
    # machine): not replaced at the first leash, only after BUSY_LEASHES of them
    import time

    from viewer.app.compile_ahead import CompileAhead
    from viewer.app.prefetch import BUSY_LEASHES
    from viewer.scene import load_scene

    ca = CompileAhead(command=BUSY_NEVER_ANSWERS, leash=1.0)
    try:
        rid = ca.request(load_scene("sphere"))
        t0 = time.monotonic()
        while time.monotonic() - t0 < 3.0:  # three leashes of silence while it works
            assert not ca.answered(rid) and ca.replaced == 0
            time.sleep(0.1)
        _wait(lambda: ca.answered(rid), "the busy child's last leash", BUSY_LEASHES * 3)
        assert ca.replaced == 1
    finally:
        ca.stop()


def test_the_window_compiles_a_change_itself_when_the_child_never_answers(gl_ctx):
    """The silent child is replaced once its leash runs out, and the window compiles the change
    itself. The leash is endless until the held frame has been seen, then 0.5 s: with a leash of
    0.5 s from the start, a first frame (or the held one) longer than 0.5 s on a loaded machine
    let the leash run out on the first request already, and the change's request went to the
    second child, replaced in turn (two replacements)."""
    from viewer.app.compile_ahead import CompileAhead
    from viewer.app.session import Session
    from viewer.gl.renderer import Renderer
    from viewer.scene import material_from_name

    renderer = Renderer(gl_ctx)  # its own: the soap bubble's program not compiled by another test

    s = Session(gl_ctx, "default", renderer=renderer, prefetch=False, compile_ahead=True)
    s.compile_ahead = CompileAhead(on_notice=s.notify, command=NEVER_ANSWERS, leash=math.inf)
    try:
        s.render_view((96, 64))
        s.set_material("ball", material_from_name("soap_bubble"))
        key = renderer.forward_keys(s.scene)["ball"]
        s.render_view((96, 64))
        assert s.compiling and key not in renderer.programs  # held: drawn as before
        assert s.compile_ahead.replaced == 0 and s.compile_ahead.outstanding == 2  # the first frame's, the change's
        s.compile_ahead.leash = 0.5  # from now on the silence counts: both requests are failed at once

        def drawn():
            s.render_view((96, 64))
            return not s.compiling

        _wait(drawn, "the leash")
        s.render_view((96, 64))
        assert key in renderer.programs  # compiled here
        assert "did not answer within 0.5 s" in s.status
        assert s.compile_ahead.replaced == 1
    finally:
        s.compile_ahead.stop()
        s.compile_ahead = None
        s.release()
        renderer.release()


def test_a_prefetch_child_that_stays_silent_is_restarted_once_then_given_up():
    from viewer.app.prefetch import Prefetch

    silent = [sys.executable, "-c", "import time; print('total 3', flush=True); time.sleep(600)"]
    pf = Prefetch(command=silent, leash=0.3)
    try:
        first = pf.pid
        _wait(lambda: pf.done, "the leash, twice")
        assert pf.replaced == 1 and "did not answer within 0.3 s" in pf.error
        assert pf.total == 3
        assert "not prepared" in pf.progress_text()
        _wait(lambda: not _alive(first), "the first child to be gone", 30)
    finally:
        pf.stop()
