"""The record of what the driver's shader cache holds of the viewer's programs
(viewer/app/driver_cache.py): programs a compile-ahead child answered for, per driver, per cache
and per drawing state (the sample count, the environment map, the lights), kept across sessions
in a file written atomically; a file that cannot be read, another driver or a cache made anew is
an empty record. And the children's answers feed it (``CompileControl``), with the drawing state
of the scene asked for."""

import json
import time

import pytest

from viewer.app import driver_cache
from viewer.app.driver_cache import DriverCacheRecord


@pytest.fixture
def cache_id(monkeypatch):
    ident = {"now": "index#1"}
    monkeypatch.setattr(driver_cache, "cache_identity", lambda: ident["now"])
    return ident


def test_a_record_holds_what_was_added_in_its_drawing_state_across_sessions(tmp_path, cache_id):
    path = tmp_path / "record.json"
    rec = DriverCacheRecord("llvmpipe|4.5", path)
    assert not rec.holds(["forward:lambert:env"], "msaa=4")
    rec.add(["forward:lambert:env", "forward:ggx:env"], "msaa=4")
    assert rec.holds(["forward:lambert:env", "forward:ggx:env"], "msaa=4")
    assert not rec.holds(["forward:lambert:env"], "msaa=8")  # another state is other machine code
    assert not rec.holds(["forward:lambert:env", "forward:mirror:env:rt"], "msaa=4")  # all of them, or not
    assert not rec.holds([], "msaa=4")  # nothing asked: nothing to read from the cache
    again = DriverCacheRecord("llvmpipe|4.5", path)  # the next session
    assert again.holds(["forward:ggx:env"], "msaa=4")
    assert not DriverCacheRecord("radeonsi|4.6", path).holds(["forward:ggx:env"], "msaa=4")  # another driver
    cache_id["now"] = "index#2"  # the cache removed and made anew
    assert not DriverCacheRecord("llvmpipe|4.5", path).holds(["forward:ggx:env"], "msaa=4")
    rec.add(["forward:phong:env"], "msaa=4")  # the record learns of the new cache: the old entries go
    assert rec.holds(["forward:phong:env"], "msaa=4") and not rec.holds(["forward:ggx:env"], "msaa=4")
    data = json.loads(path.read_text())
    assert data["cache"] == "index#2" and data["programs"] == ["forward:phong:env@msaa=4"]


def test_a_drawing_state_tells_apart_what_llvmpipe_makes_other_code_for():
    """The lecture's Lambert floor has one program key in steps 2, 9 and 11 and three drawing
    states (the sky and no light, the studio map and a point light, the sky and a point light);
    steps 2 and 3 share theirs, step 10's absorbing glass adds the thickness pass; the scene's
    materials are not part of it otherwise."""
    from viewer.scene import load_scene
    from viewer.scene.lecture import tour_scene

    state = {i: driver_cache.drawing_state(tour_scene(i - 1, load_meshes=False)) for i in (2, 3, 9, 10, 11)}
    assert len({state[2], state[9], state[11]}) == 3 and state[2] == state[3]
    assert state[10] != state[2]  # the same map and no light, but absorbing glass: the thickness pass
    gold = load_scene("default", overrides=["materials.ball.preset=gold"])
    assert driver_cache.drawing_state(gold) == driver_cache.drawing_state(load_scene("default"))
    assert driver_cache.drawing_state(load_scene("default", overrides=["render.msaa=8"])) != \
        driver_cache.drawing_state(gold)


def test_a_broken_record_is_empty_and_a_cache_that_is_off_holds_nothing(tmp_path, cache_id, monkeypatch):
    path = tmp_path / "record.json"
    for text in ("{not json", "[1, 2]", '{"driver": "d", "cache": "index#1", "programs": 7}', "\x00" * 9):
        path.write_text(text)
        assert not DriverCacheRecord("d", path).holds(["k"], "s")
    path.write_text(json.dumps({"driver": "d", "cache": "index#1", "programs": ["k@s", 3, None]}))
    assert DriverCacheRecord("d", path).holds(["k"], "s")
    with open(path, "ab") as f:  # the same record, still valid JSON, grown past MAX_BYTES: not ours, never read
        f.write(b" " * driver_cache.MAX_BYTES)
    assert not DriverCacheRecord("d", path).holds(["k"], "s")
    cache_id["now"] = None  # no cache (MESA_SHADER_CACHE_DISABLE, or none written yet)
    rec = DriverCacheRecord("d", path)
    rec.add(["k"], "s")
    assert not rec.holds(["k"], "s")


def test_the_cache_index_follows_mesa_s_settings(tmp_path, monkeypatch):
    monkeypatch.delenv("MESA_SHADER_CACHE_DISABLE", raising=False)
    monkeypatch.setenv("MESA_SHADER_CACHE_DIR", str(tmp_path / "mesa"))
    assert driver_cache.shader_cache_index() == tmp_path / "mesa" / "index"
    assert driver_cache.cache_identity() is None  # none written yet
    (tmp_path / "mesa").mkdir()
    (tmp_path / "mesa" / "index").write_bytes(b"")
    assert driver_cache.cache_identity().startswith(str(tmp_path / "mesa" / "index"))
    monkeypatch.delenv("MESA_SHADER_CACHE_DIR")
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    assert driver_cache.shader_cache_index() == tmp_path / "xdg" / "mesa_shader_cache" / "index"
    monkeypatch.setenv("MESA_SHADER_CACHE_DISABLE", "true")
    assert driver_cache.shader_cache_index() is None and driver_cache.cache_identity() is None


class _Answers:
    """A compile-ahead child's bookkeeping as ``CompileControl`` reads it."""
    alive = True

    def __init__(self):
        self.done, self.states = {}, {}

    def answered(self, rid):
        return rid in self.done


def test_the_children_s_answers_are_recorded_with_their_scenes_drawing_states(gl_ctx, cache_id):
    from viewer.app.session import Session
    from viewer.gl.renderer import Renderer
    from viewer.scene import load_scene

    s = Session(gl_ctx, "default", renderer=Renderer(gl_ctx), prefetch=False, compile_ahead=False)
    eight = load_scene("default", overrides=["render.msaa=8"])
    try:
        ca = s.compiles.child = _Answers()
        ca.states.update({1: driver_cache.drawing_state(s.scene), 2: driver_cache.drawing_state(eight),
                          3: driver_cache.drawing_state(s.scene)})
        ca.done[1] = {"id": 1, "ok": True, "keys": ["forward:lambert:env"]}
        ca.done[2] = {"id": 2, "ok": True, "keys": ["forward:ggx:env"]}
        ca.done[3] = {"id": 3, "ok": False, "error": "ShaderError: no"}  # failed there: nothing is cached
        s.compiles.poll()
        assert s.compiles.in_driver_cache(["forward:lambert:env"], s.scene)
        assert s.compiles.in_driver_cache(["forward:ggx:env"], eight)
        assert not s.compiles.in_driver_cache(["forward:ggx:env"], s.scene)
        ca.done[4] = {"id": 4, "ok": True, "keys": ["forward:phong:env"]}
        ca.states[4] = driver_cache.drawing_state(s.scene)
        s.compiles.poll()  # a later answer
        assert s.compiles.in_driver_cache(["forward:phong:env", "forward:lambert:env"], s.scene)
    finally:
        s.compiles.child = None
        s.release()


def test_the_window_s_programs_are_linked_again_once_after_the_child_s_first_answer(gl_ctx, cache_id, monkeypatch):
    """llvmpipe keys a program's machine code apart for a program compiled afresh and the same
    program linked from the driver's cache, which is how the child's echo links it: the window
    links its programs again (once each, a few a frame) from the time a child has answered."""
    from viewer.app import compile_control
    from viewer.app.session import Session
    from viewer.gl.renderer import Renderer

    r = Renderer(gl_ctx)
    s = Session(gl_ctx, "default", renderer=r, prefetch=False, compile_ahead=False)
    try:
        r.render(s.scene, width=32, height=24)  # the fixed passes, the forward programs, the IBL's
        keys = r.program_keys()
        assert any(k.startswith("forward") for k in keys) and "shadow" in keys
        assert not any(k.startswith(("ibl:", "ssr:")) for k in keys)  # a pass's own would redo its work
        before = dict(r.programs)
        ca = s.compiles.child = _Answers()
        s.compiles.poll()  # no answer yet: nothing linked again
        assert all(r.programs[k] is p for k, p in before.items())
        monkeypatch.setattr(compile_control, "RELINK_S", 0.0)  # one a frame
        ca.done[1] = {"id": 1, "ok": True, "keys": []}

        def relinked():
            return sum(r.programs[k] is not p for k, p in before.items())

        deadline = time.monotonic() + 60  # a bound against a hang: the cache writers go quiet first
        while relinked() == 0:
            assert time.monotonic() < deadline
            s.compiles.poll()
            time.sleep(0.03)
        assert relinked() == 1  # one a frame
        monkeypatch.setattr(compile_control, "RELINK_S", 1e9)
        while relinked() < len(before):
            assert time.monotonic() < deadline
            s.compiles.poll()  # the rest
            time.sleep(0.03)
        again = dict(r.programs)
        for _ in range(5):
            s.compiles.poll()  # once each
            time.sleep(0.03)
        assert all(r.programs[k] is p for k, p in again.items())
        r.render(s.scene, width=32, height=24)  # and they draw
    finally:
        s.compiles.child = None
        s.release()
        r.release()


def test_the_cache_writers_are_idle_once_asleep_with_their_cpu_time_unchanged(monkeypatch):
    """``CacheWriters`` on a stand-in /proc: busy while a writer runs or its CPU time moves,
    idle after two looks at an asleep writer with the same CPU time, idle with no writer."""
    from viewer.app.driver_cache import CacheWriters

    state = {"threads": [7], 7: ("R", 10)}

    def fake_open(path, *a, **k):
        import io

        tid = int(path.split("/")[4])
        if path.endswith("comm"):
            return io.StringIO("python:disk$0\n")
        st, ticks = state[tid]
        return io.StringIO(f"{tid} (python:disk$0) {st} " + " ".join(["0"] * 10) + f" {ticks} 0 0\n")

    monkeypatch.setattr(driver_cache.os, "listdir", lambda p: [str(t) for t in state["threads"]])
    monkeypatch.setattr("builtins.open", fake_open)
    monkeypatch.setattr(CacheWriters, "QUIET_S", 0.0)
    w = CacheWriters()
    assert w.threads() == [7]
    assert not w.idle()           # running
    state[7] = ("S", 12)
    assert not w.idle()           # asleep, but its CPU time moved since the last look
    assert w.idle()               # asleep and unchanged
    state[7] = ("S", 13)
    assert not w.idle()           # woke for another write
    state["threads"] = []
    assert w.idle()               # no writer at all (or not Linux)
