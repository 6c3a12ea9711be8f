"""The traced-frame cache (viewer/gl/trace_cache.py), Prepare lecture (viewer/app/lecture_prep.py)
and ``brdf-viewer bake --lecture --width W --height H``; the window's screenshot of a traced view
and the trace's reported time."""

import os
import subprocess
import sys

import numpy as np
import pytest

SIZE = (40, 30)  # small: the checks are about identity and bookkeeping, not about detail


def _step(key):
    from viewer.scene.lecture import TOUR

    return [s.key for s in TOUR].index(key)


@pytest.fixture
def cache_dir(tmp_path, monkeypatch):
    monkeypatch.setenv("BRDF_VIEWER_CACHE", str(tmp_path))
    return tmp_path / "traced"


@pytest.fixture
def session(gl_ctx, renderer):
    from viewer.app.session import Session

    s = Session(gl_ctx, "default", renderer=renderer, prefetch=False)
    s.warm = []
    yield s
    s.release()


def test_cache_hit_is_the_live_trace(renderer, gl_ctx, cache_dir):
    # A trace read from the cache is the live one bit for bit (linear float32 texels), done at once
    from viewer.gl.raytrace import ProgressiveTrace
    from viewer.scene.lecture import tour_scene

    scene = tour_scene(_step("tir"))
    live, again = ProgressiveTrace(gl_ctx), ProgressiveTrace(gl_ctx)
    try:
        live.start(renderer, scene, None, *SIZE, cache=True, store=True)
        assert not live.from_cache and not live.done and live.cache_message == ""
        while not live.done:
            live.step(budget_s=0.02)
        assert live.stored is not None and live.stored.parent == cache_dir and live.stored.is_file()
        assert not list(cache_dir.glob(".*.part"))
        traced = live.image()
        calls = []
        real = renderer.render
        renderer.render = lambda *a, **k: calls.append(k) or real(*a, **k)
        try:
            again.start(renderer, scene, None, *SIZE, cache=True)
        finally:
            del renderer.render
        assert again.from_cache and again.done and again.progress == 1.0 and again.steps == 0
        assert calls == []  # at once: no frame rendered
        assert np.array_equal(again.image(), traced)
        # and both are the composition of one traced frame (no MSAA) and the untraced view
        one_shot = renderer.read_linear(renderer.render(scene, None, *SIZE, msaa=0))
        untraced = renderer.read_linear(renderer.render(scene, None, *SIZE, raytrace=False))
        mask = renderer.traced_mask(scene, None, *SIZE)[::-1]
        assert np.array_equal(traced, np.where(mask[..., None], one_shot, untraced))
        # without cache=True nothing is read
        again.start(renderer, scene, None, *SIZE)
        assert not again.from_cache and not again.done
    finally:
        live.release()
        again.release()


def test_key_follows_size_scene_camera_and_view(renderer):
    from viewer.scene.camera import OrbitCamera
    from viewer.gl.trace_cache import frame_key
    from viewer.scene.lecture import tour_scene

    scene = tour_scene(_step("fresnel"))
    cam = OrbitCamera.from_scene(scene)
    key = frame_key(scene, cam, 64, 48)
    assert key == frame_key(tour_scene(_step("fresnel")), OrbitCamera.from_scene(scene), 64, 48)  # content, not identity
    assert key != frame_key(scene, cam, 64, 49) and key != frame_key(scene, cam, 65, 48)
    # one entry serves every view of its height and width parity (narrower ones are its centre)
    assert key == frame_key(scene, cam, 40, 48) == frame_key(scene, cam, 128, 48)
    assert key != frame_key(scene, cam, 64, 48, view_mode=1) and key != frame_key(scene, cam, 64, 48, msaa=0)
    assert key != frame_key(scene, cam, 64, 48, gl_renderer="another driver")
    moved = OrbitCamera.from_scene(scene)
    moved.orbit(3.0, 0.0, 48)
    assert key != frame_key(scene, moved, 64, 48)
    glass = next(n for n, p in scene.materials.items() if p.model == "dielectric")
    scene.materials[glass]["ior"] = float(scene.materials[glass]["ior"]) + 0.01
    assert key != frame_key(scene, cam, 64, 48)
    other = tour_scene(_step("tir"))
    assert key != frame_key(other, OrbitCamera.from_scene(other), 64, 48)


@pytest.mark.parametrize("damage", ["garbage", "truncated", "other size", "not finite"])
def test_damaged_entry_is_set_aside_and_traced_again(renderer, gl_ctx, cache_dir, damage):
    from viewer.gl import trace_cache
    from viewer.gl.raytrace import ProgressiveTrace
    from viewer.scene.lecture import tour_scene

    scene = tour_scene(_step("tir"))
    pt = ProgressiveTrace(gl_ctx)
    try:
        pt.start(renderer, scene, None, *SIZE, cache=True, store=True, coarse=False)
        pt.finish()
        path = pt.stored
        good = pt.image()
        if damage == "garbage":
            path.write_bytes(b"not an npz file")
        elif damage == "truncated":
            path.write_bytes(path.read_bytes()[:200])
        elif damage == "other size":  # a well-formed entry of another view under this key
            path.unlink()
            trace_cache.store(pt.cache_key, np.zeros((SIZE[1] + 1, SIZE[0], 4), np.float32))
        else:
            trace_cache.store(pt.cache_key, np.full((SIZE[1], SIZE[0], 4), np.nan, np.float32))
        pt.start(renderer, scene, None, *SIZE, cache=True, store=True, coarse=False)
        assert not pt.from_cache and "set aside" in pt.cache_message and "\n" not in pt.cache_message
        assert path.with_name(path.name + ".damaged").is_file()
        pt.finish()
        assert pt.stored == path and np.array_equal(pt.image(), good)
        pt.start(renderer, scene, None, *SIZE, cache=True)
        assert pt.from_cache and np.array_equal(pt.image(), good)
    finally:
        pt.release()


def test_one_entry_serves_every_narrower_view_of_its_height(renderer, gl_ctx, cache_dir):
    # traced once at a window's full width, the entry is every narrower view of that height (of
    # the same width parity): its centre columns, equal to a live trace of that width up to
    # float rounding in the projection
    from viewer.gl import trace_cache
    from viewer.gl.raytrace import ProgressiveTrace
    from viewer.scene.lecture import tour_scene

    scene = tour_scene(_step("tir"))
    W, H = 64, 30
    pt = ProgressiveTrace(gl_ctx)
    try:
        pt.start(renderer, scene, None, W, H, cache=True, store=True, coarse=False)
        pt.finish()
        wide = pt.image()
        for w in (40, 22):
            live = ProgressiveTrace(gl_ctx)
            try:
                live.start(renderer, scene, None, w, H, coarse=False)  # no cache: traced here
                live.finish()
                truth = live.image()
            finally:
                live.release()
            pt.start(renderer, scene, None, w, H, cache=True, store=True)
            assert pt.from_cache and pt.done and pt.cache_message == ""
            got = pt.image()
            assert got.shape == truth.shape and np.array_equal(got, wide[:, (W - w) // 2:(W + w) // 2])
            close = np.abs(got - truth) <= 1e-4 * np.maximum(np.abs(truth), 1.0)
            # float rounding of another aspect's projection flips the odd edge pixel, no more
            assert close.all(axis=2).mean() > 0.995, close.all(axis=2).mean()
        assert trace_cache.entry_width(trace_cache.path_for(pt.cache_key)) == W  # never replaced by a narrower one
        pt.start(renderer, scene, None, W + 2, H, cache=True)  # wider than prepared: traced live
        assert not pt.from_cache and pt.cache_message == ""
    finally:
        pt.release()


def test_every_layout_of_a_prepared_window_opens_traced(renderer, gl_ctx, cache_dir):
    # prepared for a window size, every view the window lays out at that size (strip or side
    # panel, plots docked or not, UI scale 1 to 2, the interface hidden) finds its entry
    from viewer.app.layout import view_columns, window_layout
    from viewer.app.lecture_prep import LecturePrep, view_size
    from viewer.gl.raytrace import ProgressiveTrace
    from viewer.scene.lecture import tour_scene

    step = _step("tir")
    win = (961, 24)  # odd: the prepared view is 960 wide
    prep = LecturePrep(gl_ctx, renderer, win, [step])
    prep.run()
    assert prep.size == view_size(win) == (960, 24) and [r.step for r in prep.results] == [step]
    assert "every view 24 pixels high up to 960 wide" in prep.progress_text()
    widths = set()
    for scale in (1.0, 1.25, 1.5, 2.0):
        for lecture in (True, False):
            for plots in (True, False):
                for panel_open in (True, False):
                    for show_ui in (True, False):
                        v = window_layout(win[0], win[1], scale, show_ui=show_ui, lecture=lecture, plots=plots,
                                          panel_open=panel_open)["view"]
                        widths.add(view_columns(v, 1.0, win[0])[1])  # as the window's viewport
    assert len(widths) > 4 and all(w % 2 == 0 for w in widths)
    scene = tour_scene(step)
    pt = ProgressiveTrace(gl_ctx)
    try:
        for w in sorted(widths):
            pt.start(renderer, scene, None, w, win[1], cache=True)
            assert pt.from_cache, w
    finally:
        pt.release()


def test_prepare_lecture_runs_beside_the_window_then_the_step_opens_traced(session, cache_dir, monkeypatch):
    # Prepare lecture runs bake --lecture in a child process for the window's size: the
    # window's frames never trace for it; the step then opens fully traced in a narrower view
    step = _step("tir")
    session.window_px = (56, 30)
    session.render_view(SIZE)
    calls = []
    real = session.renderer.render
    session.renderer.render = lambda *a, **k: calls.append(a[0]) or real(*a, **k)
    assert session.prepare_lecture(steps=[step]) and session.preparing
    assert "preparing lecture for a 56x30 window in the background" in session.status
    assert session.prep.wait(timeout=280)
    session.render_view(SIZE)
    assert not session.preparing and not session.prep.error, session.prep.error
    assert all(sc is session.scene for sc in calls)  # the window drew its own scene only
    del session.renderer.render
    assert "lecture prepared for a 56x30 window" in session.status
    assert [r.step for r in session.prep.results] == [step] and not session.prep.results[0].cached
    assert len(list(cache_dir.glob("*.npz"))) == 1
    session.lecture(step)
    session.render_view(SIZE)  # 40 wide: the centre of the 56-wide entry
    assert not session.tracing and session.quality == "full"
    assert any("from the prepared cache" in m.text for m in session.messages[-3:])


def test_prepare_twice_cancels(session, cache_dir, monkeypatch):
    assert not session.prepare_lecture()  # no view drawn yet: nothing to size it by
    assert session.last_message.error and "no view" in session.status
    assert session.prepare_lecture(SIZE, steps=[_step("tir")]) and session.preparing
    prep = session.prep
    assert prep.running
    assert not session.prepare_lecture(SIZE) and not session.preparing and "cancelled" in session.status
    assert not prep.running  # the child is gone


def test_prepare_with_an_unwritable_cache_says_so_once(session, tmp_path, monkeypatch):
    blocker = tmp_path / "file"
    blocker.write_text("")
    monkeypatch.setenv("BRDF_VIEWER_CACHE", str(blocker))
    assert session.prepare_lecture((24, 16), steps=[_step("tir")])
    assert session.prep.wait(timeout=120)
    session.render_view((24, 16))
    assert not session.preparing
    assert session.last_message.error and "cannot be written" in session.status and "\n" not in session.status


def test_screenshot_of_a_traced_view_neither_waits_nor_restarts(session, cache_dir, tmp_path, monkeypatch):
    # F12 while the view traces: the image as shown, no traced frame rendered for it, and the
    # trace goes on where it was
    from PIL import Image

    import viewer.app.view_frames as smod

    monkeypatch.setattr(smod, "TRACE_BUDGET_S", 1e-9)
    session.lecture(_step("tir"))
    session.render_view(SIZE)
    session.render_view(SIZE)
    assert session.tracing
    steps, progress = session.trace.steps, session.trace.progress
    calls = []
    real = session.renderer.render
    monkeypatch.setattr(session.renderer, "render", lambda *a, **k: calls.append(k) or real(*a, **k))
    shown = session.renderer.read_srgb(session.hdr, session.scene.render.exposure, session.scene.render.tonemap)
    path = session.take_screenshot(tmp_path / "shot.png", size=SIZE)
    assert path is not None and calls == []
    assert np.array_equal(np.asarray(Image.open(path).convert("RGB")), shown)
    assert session.tracing and not session.dirty
    session.render_view(SIZE)
    assert session.trace.steps == steps + 1 and session.trace.progress >= progress


def test_reported_time_is_the_wall_clock(session, cache_dir, monkeypatch):
    # the time the trace reports runs from the still view's first frame to the last tile,
    # frames between included: here 0.05 s of other work between frames
    import time

    import viewer.app.view_frames as smod

    monkeypatch.setattr(smod, "TRACE_BUDGET_S", 1e-9)
    session.lecture(_step("tir"))
    t0 = time.perf_counter()
    session.render_view(SIZE)
    frames = 0
    while session.tracing:
        time.sleep(0.05)
        session.render_view(SIZE)
        frames += 1
    wall = time.perf_counter() - t0
    t = session.trace
    assert 0.05 * frames <= t.elapsed_s <= wall
    assert t.elapsed_s > t.trace_s
    assert f"ray traced in {t.elapsed_s:.1f} s" in session.status


def run_cli(*args, env):
    return subprocess.run([sys.executable, "-m", "viewer", *args], capture_output=True, text=True, env=env,
                          timeout=300)


def test_bake_lecture_refuses_bad_sizes_in_one_line(tmp_path):
    env = dict(os.environ, BRDF_VIEWER_CACHE=str(tmp_path))
    for args, said in ((("--width", "0", "--height", "10"), "--width: 0 is out of range"),
                       (("--width", "64"), "give both --width and --height"),
                       (("--height", "-3", "--width", "8"), "--height: -3 is out of range")):
        r = run_cli("bake", "--lecture", *args, env=env)
        assert r.returncode == 2 and said in r.stderr and r.stderr.count("\n") == 1, r.stderr
    r = run_cli("bake", "sphere", env=env)
    assert r.returncode == 2 and "--spp N is required" in r.stderr and r.stderr.count("\n") == 1
    for steps, said in (("0", "out of range"), ("2-x", "not a step or a range"), ("99", "out of range")):
        r = run_cli("bake", "--lecture", "--steps", steps, env=env)
        assert r.returncode == 2 and said in r.stderr and r.stderr.count("\n") == 1, r.stderr
    r = run_cli("bake", "sphere", "--lecture", "--width", "8", "--height", "8", env=env)
    assert r.returncode == 2 and "need --spp" in r.stderr
    blocker = tmp_path / "file"
    blocker.write_text("")
    r = run_cli("bake", "--lecture", "--width", "8", "--height", "8", env=dict(env, BRDF_VIEWER_CACHE=str(blocker)))
    assert r.returncode == 1 and "cannot be written" in r.stderr and r.stderr.count("\n") == 1, r.stderr
    assert not (tmp_path / "traced").exists()


def test_bake_lecture_fills_the_cache(cache_dir, monkeypatch, capsys):
    # in-process, one step (the CLI's own code path; all steps: the slow test below)
    import viewer.app.lecture_prep as prep_mod
    from viewer.commands import cli
    monkeypatch.setattr(prep_mod, "traced_steps", lambda: [_step("tir")])
    assert cli.main(["bake", "--lecture", "--width", "25", "--height", "16"]) == 0
    out = capsys.readouterr().out.splitlines()
    assert out[0].startswith("preparing lecture for a 25x16 window (every view 16 pixels high up to 24 wide")
    assert out[1].startswith(f"lecture step {_step('tir') + 1}: traced 24x16 in ") and str(cache_dir) in out[1]
    assert out[-1].startswith("lecture prepared for a 25x16 window") and "1 traced steps in " in out[-1]
    assert len(list(cache_dir.glob("*.npz"))) == 1
    assert cli.main(["bake", "--lecture", "--width", "24", "--height", "16"]) == 0
    assert "24x16 already prepared" in capsys.readouterr().out


def test_bake_lecture_without_a_size_prepares_the_last_sessions_window(cache_dir, monkeypatch, capsys, tmp_path):
    from viewer.commands import cli
    from viewer.app.state import save_state

    state = tmp_path / "state.toml"
    save_state({"window_width": 70, "window_height": 64}, state)
    monkeypatch.setenv("BRDF_VIEWER_STATE", str(state))
    assert cli.main(["bake", "--lecture", "--steps", str(_step("tir") + 1)]) == 0
    out = capsys.readouterr().out.splitlines()
    assert out[0].startswith("preparing lecture for a 70x64 window") and "traced 70x64 in" in out[1]


def test_bake_lecture_without_a_size_prepares_the_framebuffer_the_last_session_drew(cache_dir, monkeypatch,
                                                                                    capsys, tmp_path):
    """Full screen, or a HiDPI screen (framebuffer twice the window): the last session's window
    size is not what it drew; the framebuffer it saved is what Prepare lecture prepares."""
    from viewer.commands import cli
    from viewer.app.state import save_state

    state = tmp_path / "state.toml"
    save_state({"window_width": 64, "window_height": 64, "framebuffer_width": 40, "framebuffer_height": 18}, state)
    monkeypatch.setenv("BRDF_VIEWER_STATE", str(state))
    assert cli.main(["bake", "--lecture", "--steps", str(_step("tir") + 1)]) == 0
    out = capsys.readouterr().out.splitlines()
    assert out[0].startswith("preparing lecture for a 40x18 window") and "traced 40x18 in" in out[1]


def test_the_window_saves_the_framebuffer_it_drew_into():
    """What the window writes at exit (``viewer.app.main.window_state``, which ``App.save_state``
    writes): full screen on a HiDPI screen, the framebuffer it drew into beside the windowed size
    it will reopen at; a size that failed is not saved, the framebuffer still is."""
    from viewer.app.main import window_state

    st = window_state(1.5, True, False, (10, 20, 1280, 720), False, (3840, 2160))
    assert (st["window_width"], st["window_height"], st["window_x"], st["window_y"]) == (1280, 720, 10, 20)
    assert (st["framebuffer_width"], st["framebuffer_height"]) == (3840, 2160)
    assert st["ui_scale"] == 1.5 and st["show_ui"] and not st["plots_visible"]
    failed = window_state(1.0, True, True, (10, 20, 1280, 720), True, (1280, 720))
    assert "window_width" not in failed and failed["framebuffer_width"] == 1280
    assert "framebuffer_width" not in window_state(1.0, True, True, (0, 0, 800, 600), False, None)


@pytest.mark.slow(reason="traces every traced lecture step (about a minute on two software-GL cores)")
def test_bake_lecture_cli_every_traced_step(tmp_path):
    from viewer.app.lecture_prep import traced_steps

    env = dict(os.environ, BRDF_VIEWER_CACHE=str(tmp_path))
    r = run_cli("bake", "--lecture", "--width", "32", "--height", "18", env=env)
    assert r.returncode == 0, r.stderr
    lines = r.stdout.splitlines()
    steps = traced_steps()
    assert len(lines) == len(steps) + 2 and all("traced 32x18 in" in x for x in lines[1:-1])
    assert len(list((tmp_path / "traced").glob("*.npz"))) == len(steps)
    r = run_cli("bake", "--lecture", "--width", "32", "--height", "18", env=env)
    assert r.returncode == 0 and r.stdout.count("already prepared") == len(steps)


def test_prepare_lecture_child_ends_with_the_window(tmp_path):
    # the window's bake child watches the window's pid: killed with SIGKILL, the window leaves
    # no bake running (here a stand-in parent process that starts BackgroundPrep, then dies)
    import signal
    import textwrap

    script = tmp_path / "parent.py"
    script.write_text(textwrap.dedent(f"""
        import sys, time
        from viewer.app.lecture_prep import BackgroundPrep
        p = BackgroundPrep((1920, 1080), steps=[{_step("tir")}])
        print(p.child_pid, flush=True)
        time.sleep(600)
    """))
    env = dict(os.environ, BRDF_VIEWER_CACHE=str(tmp_path / "cache"))
    parent = subprocess.Popen([sys.executable, str(script)], stdout=subprocess.PIPE, text=True, env=env)
    child = int(parent.stdout.readline())
    with open(f"/proc/{child}/cmdline", "rb") as f:
        assert b"bake" in f.read()  # running, not ended by itself
    os.kill(parent.pid, signal.SIGKILL)
    parent.wait()
    # it checks its parent every PARENT_CHECK_S once its imports are done, which at the
    # background children's priority on a loaded machine take tens of seconds: a generous
    # bound (no speed is asserted; a quiet machine leaves the loop within a second or two)
    for _ in range(2400):
        try:
            os.kill(child, 0)
        except ProcessLookupError:
            break
        with open(f"/proc/{child}/stat") as f:
            if f.read().split(") ")[-1].startswith("Z"):
                break
        import time

        time.sleep(0.05)
    else:
        os.kill(child, signal.SIGKILL)
        raise AssertionError("the bake child outlived its window")


def test_prepare_lecture_runs_behind_the_windows_frames():
    """The bake child runs at the background children's priority (CHILD_NICE), as the prefetch
    and the compile-ahead child: at the window's own it would take half the window's cores."""
    from viewer.app.lecture_prep import BackgroundPrep
    from viewer.app.prefetch import CHILD_NICE

    p = BackgroundPrep((64, 36), steps=[0], command=[sys.executable, "-c", "import time; time.sleep(60)"])
    try:
        assert os.getpriority(os.PRIO_PROCESS, p.child_pid) == max(CHILD_NICE, os.getpriority(os.PRIO_PROCESS, 0))
    finally:
        p.cancel()


def test_a_state_file_cannot_ask_bake_for_a_frame_larger_than_its_options_allow(tmp_path, monkeypatch):
    """A framebuffer in the state file past what --width allows (16384) is dropped on reading,
    so `bake --lecture` falls back to the window size instead of allocating a huge frame."""
    from viewer.app.state import load_state

    path = tmp_path / "state.toml"
    path.write_text("framebuffer_width = 65536\nframebuffer_height = 65536\nwindow_width = 800\nwindow_height = 600\n")
    st = load_state(path)
    assert "framebuffer_width" not in st and "framebuffer_height" not in st
    assert (st["window_width"], st["window_height"]) == (800, 600)
