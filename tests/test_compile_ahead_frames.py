"""The compile-ahead child draws every kind of frame the window's view draws (viewer/app/compile_ahead.py,
``window_frames``): llvmpipe makes a program's machine code at its first draw for the state in use
(sample count, a scissor, traced chains) and keys Mesa's disk cache by it, so a kind of frame the
child never drew is compiled on the window's thread. The window's kinds are recorded from a real
session driven through a scene change, its tiles, a drag and a traced view; no timing is asserted."""

import inspect
import sys

import pytest

from viewer.app.compile_ahead import prepare, window_frames
from viewer.scene import load_scene
from viewer.scene.lecture import tour_scene


def _recorder(renderer, kinds: set):
    """Wrap ``renderer``'s draws so that each adds its kind to ``kinds``: ("frame", samples, traced,
    scissored) or ("mask",)."""
    render, mask = renderer.render, renderer.traced_mask
    sig = inspect.signature(render)

    def recorded(*args, **kwargs):
        a = sig.bind(*args, **kwargs).arguments
        scene = a["scene"]
        samples = scene.render.msaa if a.get("msaa") is None else a["msaa"]
        rt = a.get("raytrace")
        traced = renderer.traces(scene) and (bool(scene.render.raytrace) if rt is None else bool(rt))
        region = a.get("region")
        w, h = a.get("width") or scene.camera.width, a.get("height") or scene.camera.height
        scissored = region is not None and tuple(region[2:]) != (w, h)
        kinds.add(("frame", int(samples), traced, scissored))
        return render(*args, **kwargs)

    def masked(*args, **kwargs):
        kinds.add(("mask",))
        return mask(*args, **kwargs)

    renderer.render, renderer.traced_mask = recorded, masked


def _settle(s, size, limit=400):
    for _ in range(limit):
        s.render_view(size)
        if not (s.dirty or s.refining):
            return
    raise AssertionError("the view did not settle")


@pytest.mark.slow  # a session through a raster and a traced scene's tiles and strips, twice: a minute on 2 loaded cores
def test_the_child_draws_the_kinds_of_frame_the_window_draws(gl_ctx):
    from viewer.app.session import Session
    from viewer.gl.renderer import Renderer

    window, child = Renderer(gl_ctx), Renderer(gl_ctx)
    # prepared as the window's view is (its quarter-resolution preview then has no MSAA)
    s = Session(gl_ctx, "default", renderer=window, prefetch=False, compile_ahead=False, tiled_frames=True,
                prepare_frames=True)
    try:
        size = (96, 64)
        _settle(s, size)  # a whole frame: the next scene's cost is not known, so it is tiled
        drawn: set = set()
        _recorder(window, drawn)
        for scene in (load_scene("sphere"), tour_scene(2)):  # a raster scene, then one traced in strips
            s.scene = scene
            s.changed()
            _settle(s, size)
            s.render_view(size, interacting=True)  # dragged
            _settle(s, size)
        assert any(k[0] == "frame" and k[2] for k in drawn) and ("mask",) in drawn  # it traced
        assert any(k[0] == "frame" and k[3] for k in drawn)  # and drew tiles
        ahead: set = set()
        _recorder(child, ahead)
        for scene in (load_scene("sphere"), tour_scene(2)):
            window_frames(child, scene)
        assert drawn <= ahead, f"drawn by the window only: {sorted(drawn - ahead, key=str)}"
    finally:
        s.release()
        window.release()
        child.release()


@pytest.mark.slow  # every kind of frame drawn twice, with the albedo tables built: 20-40 s on 2 loaded cores
def test_the_echo_draws_the_same_frames_with_the_tables_adopted(gl_ctx):
    """``prepare``'s second renderer (its programs link from Mesa's cache, as the window's do)
    draws what the first drew, with the tables the first exported, as the window adopts them."""
    from viewer.gl.renderer import Renderer

    first, echo = Renderer(gl_ctx), Renderer(gl_ctx)
    try:
        scene = load_scene("default", overrides=["materials.ball.preset=gold"])
        kinds_first: set = set()
        kinds_echo: set = set()
        _recorder(first, kinds_first)
        _recorder(echo, kinds_echo)
        made = []
        out = prepare(first, scene, echo=lambda: made.append(1) or echo)
        assert made == [1]  # made once the first renderer has drawn
        assert kinds_echo == kinds_first and kinds_first
        for name in ("ball", "floor"):
            assert echo.tables.ready(scene.materials[name])
        assert set(out["keys"]) <= set(echo.programs)  # the echo drew with the same programs
    finally:
        first.release()
        echo.release()


@pytest.mark.slow  # two lecture steps' first frames, their maps and tables made here: about a minute on 2 loaded cores
def test_a_steps_timing_message_says_it_is_drawn_with_stand_ins(gl_ctx):
    """The status line shows the step's timing over the compile's own message: while the step's
    programs compile beside, that message says how its first frame is drawn."""
    from viewer.app.session import Session
    from viewer.gl.renderer import Renderer

    class Child:  # a compile-ahead child that has not answered yet
        alive = True

        def __init__(self):
            self.compiled, self.tables, self.done, self.released = set(), {}, {}, False

        def request(self, scene, urgent=True, text=None, **priority):
            return id(scene)

        def answered(self, rid):
            return self.released

        def stop(self):
            pass

    renderer = Renderer(gl_ctx)  # its own: step 2's programs not compiled by another test
    # lecture step 1 (Lambert: the fixed stand-in program's model) is the scene compiled here
    s = Session(gl_ctx, "lecture:1", renderer=renderer, prefetch=False, compile_ahead=True)
    child = s.compiles.child = Child()
    try:
        child.released = True
        s.render_view((96, 64))
        child.released = False
        s.tour.lecture(1)  # mirror and glass: programs not built here
        s.render_view((96, 64))
        assert s.frame_source.form in ("stand-in", "untraced") and s.pending
        words = "grey stand-ins" if s.frame_source.form == "stand-in" else "untraced"
        msg = s.status
        assert msg.startswith("lecture 2/15") and words in msg and "compile in the background" in msg, msg
        assert s.last_message.text == msg  # on the toast while compiling ...
        child.released = True
        s.render_view((96, 64))
        assert not s.compiling and s.last_message is None  # ... and gone once it is over
        assert s.frame_source.form == "own" and words not in s.status and "background" not in s.status
        assert s.status.startswith("lecture 2/15"), s.status  # the step's timing stands, said plainly
        # ready: the next step's first frame is its own, said plainly
        s.tour.lecture(0)
        s.render_view((96, 64))
        msg = s.status
        assert msg.startswith("lecture 1/15") and "background" not in msg, msg
    finally:
        s.compiles.child = None
        s.release()
        renderer.release()


# a child that says it is working every 0.1 s for 3 s (sleeping: no CPU time), then answers
WORKS_THEN_ANSWERS = [sys.executable, "-c", (
    "import json, sys, time\n"
    "print(json.dumps({'ready': True}), flush=True)\n"
    "req = json.loads(sys.stdin.readline())\n"
    "for _ in range(30):\n"
    "    time.sleep(0.1)\n"
    "    print(json.dumps({'working': req['id']}), flush=True)\n"
    "print(json.dumps({'id': req['id'], 'ok': True, 'keys': [], 'tables': {}}), flush=True)\n"
    "sys.stdin.readline()\n")]


def test_a_child_that_says_it_is_working_is_not_replaced():
    """The child's line after each kind of frame is heard: a long request (a traced scene on a
    loaded machine) is not taken for silence, though the child sleeps past the leash between
    its lines in total; the answer is the request's."""
    import time

    from viewer.app.compile_ahead import CompileAhead

    ca = CompileAhead(command=WORKS_THEN_ANSWERS, leash=1.0)
    try:
        rid = ca.request(load_scene("sphere"))
        t0 = time.monotonic()
        while not ca.answered(rid):
            assert time.monotonic() - t0 < 120, "no answer"
            time.sleep(0.05)
        assert ca.replaced == 0 and ca.done[rid]["ok"]
    finally:
        ca.stop()


_CHILD = """
import sys
from viewer.app.compile_ahead import child_renderer, prepare, window_frames
from viewer.app.driver_cache import CacheWriters
from viewer.gl.context import create_offscreen_context
from viewer.scene import load_scene
ctx = create_offscreen_context()
scene = load_scene("lecture:" + sys.argv[2])
r = child_renderer(ctx)
if sys.argv[1] == "child":      # the child's work for one request: compiled, then the echo
    prepare(r, scene, lambda: child_renderer(ctx))
else:                           # a process that links every program from the cache, as the window
    window_frames(r, scene)
ctx.finish()
CacheWriters().wait()           # every file written (the writer runs at the lowest priority)
"""


def test_a_process_linking_from_the_cache_reads_every_kind_of_frame_the_child_made(tmp_path):
    """The oracle of the echo: after the child's work for lecture step 10 (absorbing glass, traced)
    in an empty Mesa cache, a fresh process whose programs link from that cache, as the window's
    do, draws every kind of frame the window draws and adds no file to the cache: all its code
    was made by the child. Drawn by an echo on the same programs throughout (not linked anew for
    each kind), the floor's traced tiles made new code here (1 file, 0.3 s)."""
    import os
    import subprocess

    env = dict(os.environ, XDG_CACHE_HOME=str(tmp_path))
    env.pop("MESA_SHADER_CACHE_DIR", None)
    if env.get("MESA_SHADER_CACHE_DISABLE", "").lower() in ("1", "true", "yes"):
        pytest.skip("the driver's cache is disabled here")
    root = tmp_path / "mesa_shader_cache"

    def files():
        return {p.relative_to(root) for p in root.rglob("*") if p.is_file() and p.name != "index"}

    def run(role):
        out = subprocess.run([sys.executable, "-c", _CHILD, role, "10"], env=env, capture_output=True, text=True,
                             timeout=600)
        assert out.returncode == 0, out.stderr[-2000:]

    run("child")
    made = files()
    if not made:
        pytest.skip("this driver keeps no disk cache")
    run("window")
    assert files() == made
