"""Programs compiled beside the window (viewer/app/compile_ahead.py): the child's answer (program
keys, tables equal to the window's own), and the session holding a changed material back
until the answer comes (driven with a stand-in child whose answer the test releases, so no
test waits on the timing of a process)."""

import math
import os
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest

from viewer.app.compile_ahead import CompileAhead, params_key, prepare
from viewer.gl.material_tables import MaterialTables
from viewer.scene import load_scene, material_from_name, scene_to_toml


def test_prepare_compiles_the_frames_programs_and_exports_tables_the_window_would_build(gl_ctx):
    from viewer.gl.renderer import Renderer

    scene = load_scene("default", overrides=["materials.ball.preset=glass"])
    r = Renderer(gl_ctx)
    try:
        out = prepare(r, scene)
        want = set(r.forward_keys(scene).values()) | set(r.forward_keys(scene, raytrace=False).values())
        assert set(out["keys"]) == want and want <= set(r.programs)
        mine = MaterialTables(gl_ctx)
        try:
            for name in ("ball", "floor"):
                p = scene.materials[name]
                theirs = MaterialTables(gl_ctx)
                theirs.adopt(p, out["tables"][params_key(p)])
                assert theirs.ready(p)
                for a, b in zip(theirs.tables(p), mine.tables(p)):
                    assert np.array_equal(a, b)  # the same estimator on the same points
                for a, b in zip(theirs.ms_terms(p), mine.ms_terms(p)):
                    assert np.array_equal(a, b)
        finally:
            mine.release()
    finally:
        r.release()


def _wait(cond, what, limit=300.0):
    # a generous bound for a child process on a loaded two-core machine; no speed is asserted
    t0 = time.monotonic()
    while not cond():
        if time.monotonic() - t0 > limit:
            pytest.fail(f"no answer after {limit:.0f} s: {what}")
        time.sleep(0.05)


def test_the_child_answers_with_the_programs_and_tables_and_reports_a_bad_scene():
    ca = CompileAhead()
    try:
        scene = load_scene("sphere")
        rid = ca.request(scene)
        assert ca.request(scene) == rid  # asked twice, done once
        _wait(lambda: ca.answered(rid), "sphere")
        ans = ca.done[rid]
        assert ans["ok"], ans
        assert ans["keys"] and set(ans["keys"]) <= ca.compiled
        assert {params_key(p) for p in scene.materials.values()} <= set(ca.tables)
        broken = load_scene("sphere")
        broken.base_dir = None
        broken.objects[0].mesh = "/no/such/mesh.obj"
        bad = ca.request(broken)
        _wait(lambda: ca.answered(bad), "a scene whose mesh is missing")
        assert not ca.done[bad]["ok"] and "mesh" in ca.done[bad]["error"].lower()
    finally:
        ca.stop()
    assert not ca.alive


class StandIn:
    """A compile-ahead child whose answer the test releases."""

    alive = True

    def __init__(self):
        self.compiled, self.tables, self.requests, self.released = set(), {}, [], False

    def request(self, scene, urgent=True, text=None, **priority):
        self.requests.append((scene, urgent))
        return len(self.requests)  # a request's id, as the child numbers them

    def answered(self, rid):
        return self.released

    def stop(self):
        pass


def test_a_changed_material_is_drawn_as_before_until_its_programs_are_ready(gl_ctx):
    from viewer.app.session import Session
    from viewer.gl.renderer import Renderer

    renderer = Renderer(gl_ctx)  # its own: the soap bubble's program not compiled by another test

    s = Session(gl_ctx, "default", renderer=renderer, prefetch=False, compile_ahead=True)
    stand_in = s.compile_ahead = StandIn()
    try:
        stand_in.released = True  # the scene as it opens, with its own programs
        s.render_view((96, 64))
        assert s.frame_source.form == "own"
        stand_in.released = False
        before = renderer.read_linear(s.hdr).copy()
        s.set_material("ball", material_from_name("soap_bubble"))
        key = renderer.forward_keys(s.scene)["ball"]
        assert key not in renderer.programs
        s.render_view((96, 64))
        # the soap bubble lets light through: the floor now takes the glass-shadow variant too
        assert s.compiling and s.pending == ["ball", "floor"]
        assert "compiling ball" in s.status
        assert key not in renderer.programs  # nothing compiled on this thread
        assert np.array_equal(renderer.read_linear(s.hdr), before)  # the ball as it was
        assert stand_in.requests and stand_in.requests[-1][1] is True
        drawn = s.raster_version
        s.render_view((96, 64))  # nothing changed: the view is not drawn again while waiting
        assert s.raster_version == drawn
        stand_in.released = True
        s.render_view((96, 64))
        assert not s.compiling and s.pending == []
        assert key in renderer.programs
        assert not np.array_equal(renderer.read_linear(s.hdr), before)
    finally:
        s.compile_ahead = None
        s.release()
        renderer.release()


def test_idle_frames_send_the_presets_ahead_one_at_a_time(gl_ctx, renderer):
    from viewer.brdf.presets import PRESETS
    from viewer.app.session import Session

    s = Session(gl_ctx, "default", renderer=renderer, prefetch=False, compile_ahead=True)
    stand_in = s.compile_ahead = StandIn()
    stand_in.released = True   # the view's own programs, if it asks for them
    try:
        s.warm_one()
        assert stand_in.requests == []   # the view not drawn yet: no warm-up
        while s.dirty or s.refining or s.quality != "full":
            s.render_view((48, 36))
        stand_in.requests.clear()
        s.warm_one()
        assert len(stand_in.requests) == 1
        for _ in range(len(PRESETS) + 3):
            s.warm_one()
        assert len(stand_in.requests) == len(PRESETS)
        assert all(urgent is False for _, urgent in stand_in.requests)
        ball = {params_key(sc.materials["ball"]) for sc, _ in stand_in.requests}
        # each preset on the ball, the rest of the scene as it is (some presets are equal)
        assert ball == {params_key(material_from_name(n)) for n in PRESETS}
        assert all(sc.materials["floor"] is s.scene.materials["floor"] for sc, _ in stand_in.requests)
    finally:
        s.compile_ahead = None
        s.release()


def test_another_scene_is_never_drawn_with_the_last_scenes_materials(gl_ctx, renderer, tmp_path):
    """A new scene (a lecture step, a file opened) with programs still to compile is drawn
    itself at once, the materials not ready as grey stand-ins, never with materials of the
    scene before; its own programs once the child has them."""
    from viewer.app.session import STAND_IN_ALBEDO, Session
    from viewer.gl.renderer import Renderer

    renderer = Renderer(gl_ctx)  # its own: no program of the new scene compiled by another test
    s = Session(gl_ctx, "default", renderer=renderer, prefetch=False, compile_ahead=True)
    stand_in = s.compile_ahead = StandIn()
    try:
        stand_in.released = True
        s.render_view((96, 64))
        stand_in.released = False
        old_ball = s.scene.materials["ball"]
        s.scene = load_scene("default", overrides=["materials.ball.model=oren_nayar"])  # a program not built
        s.changed()
        key = renderer.forward_keys(s.scene)["ball"]
        s.render_view((96, 64))
        assert s.pending == ["ball"] and s.compiling and "grey stand-ins" in s.status
        src = s.frame_source
        assert src.scene is s.scene and src.form == "stand-in"
        assert src.materials["ball"] is not old_ball and src.materials["ball"].model == "lambert"
        assert np.allclose(src.materials["ball"]["albedo"], STAND_IN_ALBEDO)
        assert key not in renderer.programs  # nothing compiled on the window's thread
        stand_in.released = True
        s.render_view((96, 64))
        assert s.pending == [] and not s.compiling and s.frame_source.form == "own"
        assert renderer.forward_keys(s.scene)["ball"] in renderer.programs
    finally:
        s.compile_ahead = None
        s.release()
        renderer.release()


def test_the_viewer_command_can_turn_it_off(capsys):
    from viewer.commands import cli
    with pytest.raises(SystemExit):
        cli.main(["--help"])
    assert "--no-compile-ahead" in capsys.readouterr().out


def _req(rid, tier, batch=0, lead=None):
    return {"id": rid, "scene": "", "priority": [tier, batch] + ([] if lead is None else [lead])}


def test_the_child_draws_the_scene_shown_first_its_untraced_copy_before_its_traced_programs():
    """The child's queue (``WorkQueue``): the scene the window shows before the next lecture
    step's and the warm-up's; of the scenes shown the latest first, a scene's requests in the
    order sent (a traced scene's untraced copy, then its traced programs)."""
    from viewer.app.compile_ahead import AHEAD, IDLE, URGENT, WorkQueue

    q = WorkQueue()
    for r in (_req(0, IDLE), _req(1, AHEAD), _req(2, URGENT, 1), _req(3, URGENT, 1), _req(4, URGENT, 2),
              _req(5, URGENT, 2), _req(6, IDLE)):
        q.put(r)
    q.close()
    order = []
    while (r := q.take()) is not None:
        order.append(r["id"])
        q.finished()
    assert order == [4, 5, 2, 3, 1, 0, 6]


def test_the_form_the_view_waits_for_goes_first_in_its_batch_and_preempts_the_rest():
    """A request marked ``lead`` (the view's preparation waits for it: the grey stand-ins, or the
    untraced copy) goes before the requests of its scene sent earlier (its traced programs), and
    one of them being drawn is put back at its next kind of frame; a later scene still goes
    first."""
    from viewer.app.compile_ahead import URGENT, Preempted, WorkQueue

    q = WorkQueue()
    q.put(_req(0, URGENT, 1, 0))
    q.put(_req(1, URGENT, 1, 0))
    assert q.take()["id"] == 0  # the traced programs being drawn ...
    q.put(_req(2, URGENT, 1, 1))
    with pytest.raises(Preempted):  # ... put back for the stand-ins the view waits for
        q.check()
    q.put_back()
    q.put(_req(3, URGENT, 2, 0))  # a later scene shown
    q.close()
    order = []
    while (r := q.take()) is not None:
        order.append(r["id"])
        q.finished()
    assert order == [3, 2, 0, 1]


def test_the_childs_renderers_draw_a_new_map_with_the_quick_prefilter_as_the_window(gl_ctx):
    from viewer.app.compile_ahead import child_renderer
    from viewer.app.session import Session

    r = child_renderer(gl_ctx)
    s = Session(gl_ctx, "default", renderer=r, prefetch=True)  # the window's renderer, as it opens
    try:
        assert r.ibl().defer is True and s.renderer.ibl().defer is True
    finally:
        s.release()
        r.release()


def test_a_request_asked_for_again_moves_up_and_outranks_the_one_drawn():
    """The next step's scene, sent ahead, then shown: promoted over the warm-up, and the warm-up
    request being drawn is put back at its next kind of frame (``check`` raises), to be drawn
    after it."""
    from viewer.app.compile_ahead import AHEAD, IDLE, URGENT, Preempted, WorkQueue

    q = WorkQueue()
    q.put(_req(0, IDLE))
    q.put(_req(1, AHEAD))
    q.put(_req(2, IDLE))
    assert q.take()["id"] == 1
    q.finished()
    assert q.take()["id"] == 0  # the warm-up drawn ...
    q.check()                   # ... nothing outranks it yet
    q.put(_req(3, IDLE))
    q.check()                   # another warm-up request waits its turn
    q.put({"promote": 2, "priority": [URGENT, 5]})  # ... until the scene shown asks for request 2 again
    with pytest.raises(Preempted):
        q.check()
    q.put_back()
    assert q.take()["id"] == 2
    q.put({"promote": 2, "priority": [IDLE, 0]})  # a lower priority never demotes one
    q.put(_req(4, URGENT, 4))   # an earlier scene's request does not preempt a later one's
    q.check()
    q.finished()
    q.close()
    assert [q.take()["id"] for _ in range(3)] == [4, 0, 3]


def test_the_window_asks_for_a_traced_steps_untraced_copy_first_and_a_later_scene_in_a_later_batch(gl_ctx):
    from viewer.app.session import STAND_IN_ALBEDO, Session
    from viewer.scene import scene_to_toml
    from viewer.gl.renderer import Renderer
    from viewer.scene.lecture import tour_scene

    class Child(StandIn):
        def request(self, scene, urgent=True, text=None, **priority):
            # a text the window gives is the scene's own (written once per scene and state)
            assert text is None or text == scene_to_toml(scene, absolute_paths=True)
            self.requests.append((scene, urgent, priority))
            return len(self.requests)

    def grey(scene):
        return all(p.model == "lambert" and np.allclose(p["albedo"], STAND_IN_ALBEDO) for p in scene.materials.values())

    renderer = Renderer(gl_ctx)
    s = Session(gl_ctx, "default", renderer=renderer, prefetch=False, compile_ahead=True)
    child = s.compiles.child = Child()
    try:
        s.tour.lecture(1)  # mirror and glass, traced; asks for step 3 ahead, in the order it needs them:
        ahead = [(sc, pr) for sc, urgent, pr in child.requests if not urgent]
        assert [pr for _, pr in ahead] == [{"ahead": True}] * 3
        (stand_in, _), (flat, _), (traced, _) = ahead
        assert grey(stand_in) and stand_in.objects is traced.objects  # its first frame's grey stand-ins
        assert not flat.render.raytrace and traced.render.raytrace  # its untraced programs, its own
        child.requests.clear()
        # what the view draws while the step's programs compile (no frame drawn: none is needed)
        assert s.compiles.held_back(None, False, True) is not None
        (flat, u1, p1), (nxt, u2, p2), (traced, u3, p3) = child.requests[:3]
        assert u1 and u2 and u3 and p1 == p2 == p3
        assert not flat.render.raytrace and traced is s.scene
        assert nxt is stand_in  # the next step's stand-ins (cheap) before this step's traced programs
        s.tour.lecture(2)
        child.requests.clear()
        s.compiles.held_back(None, False, True)
        assert child.requests[0][2]["batch"] > p1["batch"]  # the later scene goes first
    finally:
        s.compiles.child = None
        s.release()
        renderer.release()


# ------------------------------------------------------------------ the two children

# A stand-in child: the module's own main() (its command line, its niceness) around a serve()
# that answers each request at once with its process id (as a program key and a table's key);
# but the child behind the window (--nice above 0) holds a request whose base_dir is named "held"
# until told to drop it, and then answers it all the same (a child that was drawing it when the
# other child answered).
TWO_CHILDREN = [sys.executable, "-c", (
    "import json, os, sys\n"
    "import viewer.app.compile_ahead as ca\n"
    "def serve():\n"
    "    print(json.dumps({'ready': True}), flush=True)\n"
    "    for line in sys.stdin:\n"
    "        msg = json.loads(line)\n"
    "        held = 'scene' in msg and os.path.basename(msg['base_dir'] or '') == 'held' and sys.argv[-1] != '0'\n"
    "        if 'drop' in msg or ('scene' in msg and not held):\n"
    "            me = str(os.getpid())\n"
    "            rid = msg['drop'] if 'drop' in msg else msg['id']\n"
    "            print(json.dumps({'id': rid, 'ok': True, 'keys': ['pid ' + me], 'tables': {me: {}}}), flush=True)\n"
    "    return 0\n"
    "ca.serve = serve\n"
    "sys.exit(ca.main())\n")]


def _niceness(pid: int) -> int:
    with open(f"/proc/{pid}/stat") as f:  # field 19; the name (field 2) may hold spaces
        return int(f.read().rsplit(")", 1)[1].split()[16])


def _scene(name, held=False, preset=None):
    scene = load_scene(name, overrides=[f"materials.ball.preset={preset}"] if preset else ())
    if held:
        scene.base_dir = Path("/nowhere/held")  # the stand-in holds it (its meshes are built in)
    return scene


def _answered_by(ca, rid) -> int:
    _wait(lambda: ca.answered(rid), f"request {rid}", 60)
    ans = ca.done[rid]
    assert ans["ok"], ans
    return int(ans["keys"][0].split()[1])


@pytest.mark.skipif(not os.path.isdir("/proc/self"), reason="reads the children's niceness from Linux /proc")
def test_the_scene_shown_compiles_at_the_windows_priority_and_the_work_ahead_behind_it():
    from viewer.app.compile_ahead import AHEAD_NICE

    mine = _niceness(os.getpid())
    behind = min(mine + AHEAD_NICE, 19)
    if behind == mine:
        pytest.skip("this process already has the lowest priority: the children's cannot differ")
    ca = CompileAhead(command=TWO_CHILDREN, leash=math.inf)
    try:
        shown = _answered_by(ca, ca.request(_scene("sphere"), urgent=True, batch=1))
        assert ca.ahead_pid is None  # a window that never warms anything runs one child
        assert shown == ca.pid and _niceness(shown) == mine
        nxt = _answered_by(ca, ca.request(_scene("default"), urgent=False, ahead=True))
        warm = _answered_by(ca, ca.request(_scene("cornell"), urgent=False))
        assert nxt == warm == ca.ahead_pid != shown
        assert _niceness(nxt) == behind
        assert ca.outstanding == 0
        pids = (shown, nxt)
    finally:
        ca.stop()
    assert not ca.alive and not any(os.path.exists(f"/proc/{p}") for p in pids)  # both ended and reaped


def test_a_request_sent_ahead_then_shown_is_drawn_by_the_urgent_child_and_answered_once():
    from viewer.app.driver_cache import drawing_state

    calls = []
    ca = CompileAhead(on_done=lambda: calls.append(sorted(ca.done)), command=TWO_CHILDREN, leash=math.inf)
    try:
        scene = _scene("sphere", held=True)
        rid = ca.request(scene, urgent=False, ahead=True)  # the next step, held by the ahead child
        assert not ca.answered(rid) and ca.outstanding == 1
        assert ca.request(scene, urgent=False, ahead=True) == rid  # asked again ahead: nothing new
        assert ca.request(scene, urgent=True, batch=2) == rid       # now shown: the same request
        assert ca.states[rid] == drawing_state(scene)  # the state its answer puts in the driver's cache
        assert _answered_by(ca, rid) == ca.pid
        # the ahead child, told to drop it, answers all the same: merged, not counted again
        _wait(lambda: str(ca.ahead_pid) in ca.tables and calls, "the ahead child's late answer", 60)
        assert ca.done[rid]["keys"] == [f"pid {ca.pid}"] and ca.outstanding == 0
        later = ca.request(_scene("default"), urgent=False)  # answered after the late one, in order
        _wait(lambda: calls and later in calls[-1], "the warm-up request", 60)
        assert calls == [[rid], [rid, later]]
    finally:
        ca.stop()


@pytest.mark.skipif(not os.path.isdir("/proc/self"), reason="the leash reads a child's CPU time from Linux /proc")
def test_replacing_a_silent_child_leaves_the_other_serving():
    import signal

    notes = []
    ca = CompileAhead(on_notice=notes.append, command=TWO_CHILDREN, leash=0.3)
    try:
        urgent = ca.pid
        held = ca.request(_scene("sphere", held=True), urgent=False, ahead=True)
        ahead = ca.ahead_pid
        _wait(lambda: ca.answered(held), "the ahead child's leash", 60)
        assert not ca.done[held]["ok"] and "no answer within 0.3 s" in ca.done[held]["error"]
        assert ca.replaced == 1 and ca.pid == urgent and ca.ahead_pid not in (None, ahead)
        assert len(notes) == 1 and "did not answer within 0.3 s" in notes[0]
        ca.leash = math.inf  # a loaded machine's pause is not taken for silence from here on
        assert _answered_by(ca, ca.request(_scene("default"), urgent=True)) == urgent
        ahead = ca.ahead_pid
        ca.leash = 0.3
        os.kill(urgent, signal.SIGSTOP)  # the other way round: the urgent child stops
        stuck = ca.request(_scene("cornell"), urgent=True)
        _wait(lambda: ca.answered(stuck), "the urgent child's leash", 60)
        assert ca.replaced == 2 and ca.alive and ca.pid != urgent and ca.ahead_pid == ahead
        ca.leash = math.inf
        assert _answered_by(ca, ca.request(_scene("default", preset="glass"), urgent=False)) == ahead
        assert _answered_by(ca, ca.request(_scene("default", preset="gold"), urgent=True)) == ca.pid
    finally:
        ca.stop()


def test_the_childs_command_line_says_its_niceness():
    from viewer.app.compile_ahead import AHEAD_NICE, main, niceness

    assert niceness([]) == AHEAD_NICE and niceness(["--nice", "0"]) == 0 and niceness(["--nice", "10"]) == 10
    for bad in (["--nice", "x"], ["--nice", "-3"], ["--nice"], ["--fast"]):
        with pytest.raises(ValueError):
            niceness(bad)
    assert main(["--nice", "twenty"]) == 2  # one line, before any priority is changed


def test_a_request_answered_by_the_other_child_is_dropped_from_the_queue():
    from viewer.app.compile_ahead import AHEAD, IDLE, WorkQueue

    q = WorkQueue()
    for r in (_req(0, AHEAD), _req(1, AHEAD), _req(2, IDLE)):
        q.put(r)
    assert q.take()["id"] == 0
    q.put({"drop": 0})  # being drawn: it finishes
    q.put({"drop": 1})
    q.finished()
    q.close()
    assert q.take()["id"] == 2 and q.take() is None


def test_a_scene_s_text_for_the_child_is_written_once_per_state(gl_ctx):
    """``held_back`` asks for the shown scene's programs every frame while they compile: the
    scene's text is written once per scene object and state, and again after any change in place
    (anything that changes the view marks it ``dirty``)."""
    from viewer.app.session import Session
    from viewer.gl.renderer import Renderer
    from viewer.scene import scene_to_toml

    renderer = Renderer(gl_ctx)
    s = Session(gl_ctx, "default", renderer=renderer, prefetch=False)
    try:
        text = s.compiles.scene_text(s.scene)
        assert text == scene_to_toml(s.scene, absolute_paths=True)
        assert s.compiles.scene_text(s.scene) is text       # the same state: not written again
        s.set_reflection_mode("ray traced")                 # the scene's render settings, in place
        again = s.compiles.scene_text(s.scene)
        assert again != text and again == scene_to_toml(s.scene, absolute_paths=True)
        other = s.compiles.untraced_copy(s.scene)           # another scene object: its own text
        assert s.compiles.scene_text(other) == scene_to_toml(other, absolute_paths=True) != again
    finally:
        s.release()
        renderer.release()


# a stand-in child that gets ready, then dies on its first request as a driver crash would
# (a message on stderr, a non-zero status)
CRASHES_ON_WORK = [sys.executable, "-c", (
    "import sys\n"
    "print('{\"ready\": true}', flush=True)\n"
    "sys.stdin.readline()\n"
    "sys.stderr.write('Segmentation fault in the driver\\n')\n"
    "sys.exit(139)\n")]
NEVER_READY = [sys.executable, "-c", "import sys; sys.stderr.write('no EGL display\\n'); sys.exit(1)"]


def test_a_child_that_ends_by_itself_is_started_again_a_few_times_with_a_notice():
    """A child that was serving and ended by itself (a crash) is started again, so the window
    does not make every later program itself; what it held fails (the window makes it). After
    ``RESTARTS`` such ends it stays down with its reason, and a child that never got ready (no
    context) is not started again at all."""
    from viewer.app.compile_ahead import RESTARTS

    notes = []
    ca = CompileAhead(on_notice=notes.append, command=CRASHES_ON_WORK, leash=math.inf)
    try:
        pids = []
        for k in range(RESTARTS + 1):
            _wait(lambda: ca.ready, "the child to be ready", 60)
            assert ca.alive and ca.pid not in pids
            pids.append(ca.pid)
            rid = ca.request(_scene("default", preset=["glass", "gold", "copper", "silver"][k]), urgent=True)
            assert rid is not None
            _wait(lambda: ca.answered(rid), "the crash's answer", 60)
            assert not ca.done[rid]["ok"] and ca.done[rid]["error"] == "Segmentation fault in the driver"
            if k < RESTARTS:
                _wait(lambda: len(notes) == k + 1, "the notice", 60)
                assert "ended (Segmentation fault in the driver): restarted it" in notes[k]
        _wait(lambda: not ca.alive, "the last end", 60)
        assert ca.error == "Segmentation fault in the driver" and len(notes) == RESTARTS
        assert ca.ended == ["Segmentation fault in the driver"] * (RESTARTS + 1)
        assert ca.request(_scene("sphere")) is None  # the window compiles from here on
    finally:
        ca.stop()
    never = CompileAhead(command=NEVER_READY, leash=math.inf)
    try:
        _wait(lambda: not never.alive, "the child that cannot start", 60)
        assert never.error == "no EGL display" and never.ended == []
    finally:
        never.stop()


# a stand-in child that gets ready and then never reads its input (as a child's reader thread
# cannot while its main thread holds the interpreter lock through a long GL call)
NEVER_READS = [sys.executable, "-c", "import sys, time; print('{\"ready\": true}', flush=True); time.sleep(600)"]


def test_the_window_never_waits_on_a_child_that_does_not_read():
    """Requests to a child that reads nothing fill its pipe (64 KB: sixteen gallery scenes);
    asking must not wait for it, however many are asked. Run on a thread with a bound that
    only catches a hang: the old write from the window's thread never returned here."""
    ca = CompileAhead(command=NEVER_READS, leash=math.inf)
    try:
        _wait(lambda: ca.ready, "the child to be ready", 60)
        got = []

        gallery = load_scene("gallery")
        text = scene_to_toml(gallery, absolute_paths=True)

        def ask():
            for k in range(40):  # 40 different requests of about 4 KB each
                got.append(ca.request(gallery, urgent=False, text=f"{text}\n# request {k}\n"))
        t = threading.Thread(target=ask, daemon=True)
        t.start()
        t.join(120)
        assert not t.is_alive(), "a request waited on the child's full pipe"
        assert len(got) == 40 and None not in got and ca.outstanding == len(set(got))
    finally:
        ca.stop(timeout=5)
