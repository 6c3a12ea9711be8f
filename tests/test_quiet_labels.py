"""A quiet machine and labels that are true: the idle-time warm-up drains and the session then
reports no pending work, so the window's loop rests (no frame until input); every read-out
belongs to the view it was computed on; a ``.brdf`` file without a numpy twin gets its reference
from the gpu engine (or one line saying why there is none); a new scene opens in the raster view;
``--screenshot`` waits for the finished view; bools written 1 / 0; the keys that reach lecture
steps 11-15 and UI scale 1.5. Everything is checked on state: stand-in children and references
whose answers the test gives, no timing."""

from pathlib import Path

import numpy as np
import pytest

from viewer.app.compile_ahead import params_key
from viewer.app.input_keys import InputKeys
from viewer.app.main import App
from viewer.app.pacing import Pacing
from viewer.app.session import Session, scene_digest
from viewer.scene import load_scene

ROOT = Path(__file__).resolve().parents[1]
SIZE = (48, 36)
NO_TWIN = ROOT / "tests" / "brdfs" / "every_declaration.brdf"   # no every_declaration.py beside it
TWIN = ROOT / "tests" / "brdfs" / "lambert_twin.brdf"


class StandInChild:
    """A compile-ahead child whose answers the test gives: each request waits until ``answer``."""

    alive = True

    def __init__(self):
        self.compiled, self.tables, self.requests, self.answered_ids = set(), {}, [], set()
        self.texts = []  # each request's scene text, written when it was asked for

    def request(self, scene, urgent=True, text=None, **priority):
        from viewer.scene import scene_to_toml

        # a scene asked for again is not redone, as the child does; compared by the text written
        # at the time of asking, as the child's pipe carries it: the session edits its scene's
        # materials in place, so the scene object asked for earlier may read as today's scene
        text = scene_to_toml(scene)
        if text in self.texts:
            return self.texts.index(text)
        self.texts.append(text)
        self.requests.append((scene, urgent))
        return len(self.requests) - 1

    @property
    def outstanding(self):
        return len(self.requests) - len(self.answered_ids)

    def answered(self, rid):
        return rid in self.answered_ids

    def answer(self, rid):
        self.answered_ids.add(rid)

    def stop(self):
        pass


class StandInReference:
    """A reference view whose passes the test publishes (``publish``); its key follows the scene."""

    needs_frames = False
    busy = False
    preview = False
    error = ""
    engine_note = ""

    def __init__(self):
        self.key, self.spp, self.version, self.image = None, 0, 0, None

    def update(self, scene, camera, size, defer=False):
        key = f"{scene.label}|{len(scene.materials)}|{size}"
        if key != self.key:
            self.key, self.spp, self.image = key, 0, None
            self.version += 1

    def publish(self, image, spp):
        self.image, self.spp = image, spp
        self.version += 1

    def latest(self):
        return None if self.image is None else (self.image, self.spp)

    def take_notices(self):
        return []

    def texture_for_display(self):
        return None

    def stop(self, timeout=5.0):
        return True

    def close(self, timeout=None):
        pass


class NoReload:
    """A hot reloader with nothing to say."""
    noting = False


class LastInput:
    """A window's input with the last event long ago."""
    last_event = -1e9
    input_events = 0


class NoWindow:
    """What the loop's decision reads of the window, without one: the session, the last input long
    ago, no hot-reload note, the window's toast time."""
    TOAST_S = App.TOAST_S

    def __init__(self, session):
        self.session = session
        self.hot_reload = NoReload()
        self.keys = LastInput()


def Loop(session) -> Pacing:
    """The window's loop decision (``Pacing.loop_wait``) over a session, without a window."""
    return Pacing(NoWindow(session))


@pytest.fixture
def quiet(gl_ctx, renderer):
    s = Session(gl_ctx, "default", renderer=renderer, prefetch=False, compile_ahead=True)
    child = s.compile_ahead = StandInChild()
    yield s, child
    s.compile_ahead = None
    s.release()


# ---------------------------------------------------------------------- a quiet machine
def test_the_warm_up_drains_and_the_loop_then_rests(quiet):
    from viewer.brdf.presets import PRESETS

    s, child = quiet
    assert s.warm == []   # with the child the presets warm up there, not a list of models here
    loop = Loop(s)
    assert loop.loop_wait()[0] == "draw"   # the first frame
    s.render_view(SIZE)
    for rid in range(len(child.requests)):   # the first frame's own programs, if it asked
        child.answer(rid)
    if child.requests:   # drawn with stand-ins meanwhile: the answer's frame draws its own
        assert loop.loop_wait()[0] == "draw"
        s.render_view(SIZE)
    first = len(child.requests)
    assert s.pending_work() == ["warm-up"] and loop.loop_wait()[0] == "warm"   # no frame for it
    while s.warming:
        s.warm_one()
    from viewer.scene import material_from_name

    ahead = child.requests[first:]   # each preset on the ball once (equal ones are one request)
    assert ahead and not any(urgent for _, urgent in ahead)
    assert {params_key(sc.materials["ball"]) for sc, _ in child.requests} >= {
        params_key(material_from_name(n)) for n in PRESETS}
    assert child.outstanding == len(ahead)
    # the child works through them; the window waits on events meanwhile (nothing to draw)
    assert s.pending_work() == ["compile ahead"] and loop.loop_wait()[0] == "rest"
    assert not loop.settled()
    for rid in range(first, len(child.requests) - 1):
        child.answer(rid)
    assert s.pending_work() == ["compile ahead"]
    child.answer(len(child.requests) - 1)
    # every request answered: nothing pending, the loop's wait is the resting one
    assert child.outstanding == 0 and s.pending_work() == []
    assert loop.loop_wait() == ("rest", Pacing.POLL_S) and loop.settled() and loop.idle()
    s.warm_one()   # more idle turns send nothing again
    assert len(child.requests) == first + len(ahead) and s.pending_work() == []


def test_what_keeps_the_loop_drawing_and_what_slows_it(quiet):
    s, child = quiet
    loop = Loop(s)
    s.presets_ahead = False
    s.render_view(SIZE)
    for rid in range(len(child.requests)):   # the first frame's own programs, if it asked
        child.answer(rid)
    s.render_view(SIZE)
    assert loop.loop_wait()[0] == "rest"
    s.notify("saved it")   # a toast fades: a frame at least every IDLE_FRAME_S
    assert loop.loop_wait() == ("frames", Pacing.IDLE_FRAME_S) and loop.idle() and not loop.settled()
    s.messages.clear()
    assert loop.loop_wait()[0] == "rest"
    s.changed()   # a change: draw now
    assert loop.loop_wait()[0] == "draw" and not loop.idle() and s.pending_work() == ["raster"]
    s.render_view(SIZE)
    rv = s.reference = StandInReference()
    rv.busy = True   # the cpu reference renders: frames on its passes and every IDLE_FRAME_S
    assert loop.loop_wait()[0] == "frames" and "reference" in s.pending_work()
    # a pass just after a frame waits until REFERENCE_FRAME_S after it (the frames would take the
    # workers' cores); input does not wait
    import time

    now = time.perf_counter()
    loop.drawn = (0, now, rv.version, "frames")
    rv.version += 1
    assert not loop.wants_frame()
    loop.drawn = (0, now - Pacing.REFERENCE_FRAME_S, rv.version - 1, "frames")
    assert loop.wants_frame()
    loop.drawn = (-1, now, rv.version, "frames")
    assert loop.wants_frame()   # an input event since the frame
    rv.busy, rv.needs_frames = False, True   # the gpu engine renders in the frames: draw
    assert loop.loop_wait()[0] == "draw"
    rv.needs_frames = False
    assert loop.loop_wait()[0] == "rest" and loop.settled()


# ---------------------------------------------------------------------- labels that are true
def test_metrics_belong_to_the_reference_view_they_were_taken_on(gl_ctx, renderer):
    s = Session(gl_ctx, "default", renderer=renderer, prefetch=False)
    s.warm = []
    rv = s.reference = StandInReference()
    try:
        s.set_image_mode("split")
        s.render_view(SIZE)
        s.update_reference(SIZE)
        rv.publish(np.full((SIZE[1], SIZE[0], 3), 0.5, np.float32), 35)
        s.update_reference(SIZE)
        s.compare.settle()   # measured on the worker thread: this snapshot's metrics
        text = s.metrics_text()
        assert text.startswith("RMSE") and "(35 spp)" in text
        assert s.compare.metrics_for == rv.key
        assert s.compare.metrics_text("another view") == ""   # never beside another view's reference
        # another scene: its reference has 4 spp, its raster is not drawn yet
        assert s.open_scene("sphere")
        s.update_reference(SIZE)   # the reference's key is the new scene's, no raster frame yet
        rv.publish(np.full((SIZE[1], SIZE[0], 3), 0.2, np.float32), 4)
        s.quality = "refining"     # the raster still coming (tiles): no metrics from it
        s.update_reference(SIZE)
        assert s.metrics_text() == "" and s.compare.metrics is None
        assert s.compare.heat_texture(relative=False) is None   # no heat map of the old pair either
        labels = [t for _, t in s.compare.overlay_labels((0, 0, 400, 300), rv.spp)]
        assert labels == ["raster", "reference (4 spp)"]
        s.render_view(SIZE)
        s.update_reference(SIZE)
        s.compare.settle()
        assert "(4 spp)" in s.metrics_text() and s.compare.metrics_for == rv.key
    finally:
        s.reference = None
        s.release()


def test_metrics_are_measured_on_a_worker_and_a_left_view_s_are_never_adopted(gl_ctx, renderer, monkeypatch):
    """The RMSE and the difference view's heat map are computed on the worker thread (the
    window's thread only reads the raster back); a measurement asked for on a view of the
    reference that has since changed is dropped when it finishes, never shown."""
    import threading

    from viewer.app import compare_view

    gate, threads = threading.Event(), []
    measure = compare_view.measure

    def held(*args):
        threads.append(threading.current_thread().name)
        assert gate.wait(10)
        return measure(*args)

    monkeypatch.setattr(compare_view, "measure", held)
    s = Session(gl_ctx, "default", renderer=renderer, prefetch=False)
    s.warm = []
    rv = s.reference = StandInReference()
    try:
        s.set_image_mode("difference")
        s.render_view(SIZE)
        s.update_reference(SIZE)
        rv.publish(np.full((SIZE[1], SIZE[0], 3), 0.5, np.float32), 35)
        s.update_reference(SIZE)   # asked for; held on the worker: this call returned meanwhile
        assert s.compare.metrics is None and s.metrics_text() == ""
        assert s.compare.heat_texture(relative=False) is None
        assert s.open_scene("sphere")   # another view of the reference: what is under way is the old one's
        s.update_reference(SIZE)
        gate.set()
        s.compare.settle()
        assert s.compare.metrics is None and s.compare.heat_texture(relative=False) is None
        rv.publish(np.full((SIZE[1], SIZE[0], 3), 0.25, np.float32), 8)
        s.render_view(SIZE)
        s.update_reference(SIZE)
        s.compare.settle()
        assert "(8 spp)" in s.metrics_text() and s.compare.metrics_for == rv.key
        assert s.compare.heat_texture(relative=False) is not None   # measured with the metrics
        assert threads and all(t.startswith("brdf-viewer-metrics") for t in threads)
    finally:
        s.reference = None
        s.release()


def test_a_file_brdf_without_a_twin_takes_the_gpu_engine_in_the_window(gl_ctx, trust_twins):
    from viewer.app.reference_view import ReferenceView
    from viewer.reference_common.select import without_twin

    def scene_with(path):
        return load_scene("sphere", [f"materials.{m}.file={path}" for m in load_scene("sphere").materials])

    assert "not run (not trusted)" in without_twin(scene_with(TWIN))  # an untrusted twin counts as none
    trust_twins(TWIN)

    no_twin, twin = scene_with(NO_TWIN), scene_with(TWIN)
    assert "numpy twin" in without_twin(no_twin) and without_twin(twin) is None
    assert without_twin(load_scene("sphere")) is None
    rv = ReferenceView(gl_ctx, engine="auto")
    try:
        assert rv.engine_for(no_twin) == "gpu" and ".brdf" in rv.engine_note
        assert rv.engine_for(twin) == rv.engine and rv.engine_note == ""
        assert rv.engine_for(load_scene("sphere")) == rv.engine
        rv.gpu_failed = "GLError: no program"   # then neither engine can: one line says why
        assert rv.engine_for(no_twin) is None and "gpu engine failed" in rv.engine_note
    finally:
        rv.close()
    asked = ReferenceView(gl_ctx, engine="cpu")   # the cpu engine asked for: its own refusal shows
    try:
        assert asked.engine_for(no_twin) == "cpu"
    finally:
        asked.close()


def test_the_view_says_why_there_is_no_reference_instead_of_waiting(gl_ctx):
    from viewer.app.compare_view import PENDING, CompareView

    cv = CompareView(gl_ctx)
    try:
        cv.mode = "split"
        assert [t for _, t in cv.overlay_labels((0, 0, 400, 300), 0)][1] == PENDING
        why = "x.brdf: the cpu engine evaluates numpy twins and this file has none"
        assert [t for _, t in cv.overlay_labels((0, 0, 400, 300), 0, error=why)][1] == f"reference: {why}"
        cv.mode = "difference"
        assert why in cv.overlay_labels((0, 0, 400, 300), 0, error=why)[0][1]
    finally:
        cv.release()


def test_a_new_scene_opens_in_the_raster_view_the_last_one_as_it_was_left(gl_ctx, renderer):
    last = load_scene("default")
    state = {"compare_mode": "split", "view_mode": 1, "split": 0.3, "scene_digest": scene_digest(last)}
    same = Session(gl_ctx, "default", renderer=renderer, prefetch=False, state=state)
    try:
        assert same.same_scene and same.image_mode == "split" and same.view_mode == 1
    finally:
        same.release()
    other = Session(gl_ctx, "sphere", renderer=renderer, prefetch=False, state=state)
    try:
        assert not other.same_scene and other.image_mode == "raster" and other.view_mode == 0
        assert other.compare.split == 0.3   # the divider is the window's, not the scene's
        assert other.state_entries()["scene_digest"] == scene_digest(other.scene)
    finally:
        other.release()
    # an orbit is the same scene; a material edited is not
    moved = load_scene("default", ["camera.position=[1, 2, 3]"])
    assert scene_digest(moved) == scene_digest(last)
    assert scene_digest(load_scene("default", ["materials.ball.preset=gold"])) != scene_digest(last)


@pytest.fixture
def tiled(monkeypatch):
    import viewer.app.session as session
    import viewer.app.view_frames as frames

    monkeypatch.setattr(frames, "TILE_BUDGET_S", 0.0)  # every frame is over the budget
    return session


def test_the_screenshot_waits_for_the_finished_view(gl_ctx, renderer, tiled):
    s = tiled.Session(gl_ctx, "default", renderer=renderer, prefetch=False, tiled_frames=True)
    s.warm = []
    try:
        s.render_view(SIZE)   # the view's first frame, in tiles (its cost is not known yet)
        assert s.tiling and not s.view_finished
        while s.tiling:
            s.render_view(SIZE)
        assert s.view_finished
        s.set_material_param("ball", "kd", [0.2, 0.6, 0.3])
        assert not s.view_finished   # a change: not drawn yet
        s.render_view(SIZE)
        assert s.tiling and not s.view_finished and s.pending_work() == ["raster"]
        while s.tiling:
            s.render_view(SIZE)
        assert s.view_finished
        rv = s.reference = StandInReference()
        s.set_image_mode("side by side")
        s.render_view(SIZE)
        while s.tiling:
            s.render_view(SIZE)
        s.update_reference(SIZE)
        assert not s.view_finished   # the view shows the reference: a pass of it first
        rv.publish(np.full((SIZE[1], SIZE[0], 3), 0.5, np.float32), 4)
        assert not s.view_finished   # and its metrics
        s.update_reference(SIZE)     # asked for on the worker thread
        s.compare.settle()
        assert s.view_finished
        rv.spp, rv.error = 0, "no reference: why, in one line"
        assert s.view_finished   # none will come: the line says why
        s.reference = None
    finally:
        s.release()


# ---------------------------------------------------------------------- small items
def test_bools_written_1_and_0_as_in_a_brdf_file(tmp_path):
    from viewer import ViewerError
    from viewer.scene import material_from_name

    f = tmp_path / "s.toml"
    f.write_text(f'[[objects]]\nmesh = "sphere"\nmaterial = "m"\n[materials.m]\nmodel = "custom"\nfile = "{NO_TWIN}"\n')
    for text, want in (("0", False), ("1", True), ("true", True), ("false", False)):
        assert load_scene(f, [f"materials.m.use_fresnel={text}"]).materials["m"]["use_fresnel"] is want
    for bad in ("2", "0.0", '"yes"'):
        with pytest.raises(ViewerError, match="use_fresnel: expected true or false"):
            load_scene(f, [f"materials.m.use_fresnel={bad}"])
    assert material_from_name(str(NO_TWIN), ["halve=1"])["halve"] is True   # brdf-viewer plot X.brdf --set
    with pytest.raises(ViewerError, match="render.shadows"):   # the scene's own switches stay true / false
        load_scene("default", ["render.shadows=0"])


def test_ui_scale_steps_reach_1_5_and_2():
    from viewer.app.layout import UI_SCALES, step_ui_scale

    up = [1.0]
    while up[-1] < UI_SCALES[-1]:
        up.append(step_ui_scale(up[-1], up=True))
    assert up[:5] == [1.0, 1.25, 1.5, 1.75, 2.0]
    assert step_ui_scale(1.5, up=False) == 1.25 and step_ui_scale(1.3, up=True) == 1.5
    assert step_ui_scale(3.0, up=True) == 3.0 and step_ui_scale(0.5, up=False) == 0.5


class Keys(InputKeys):
    """``InputKeys.key_action`` over a stand-in session that records the steps asked for."""

    class _Session:
        lecture_step = 0

        def __init__(self):
            self.asked = []

        def lecture(self, step):
            self.asked.append(step)

    class _Window:  # no window: the session alone
        def __init__(self, session):
            self.session = session

    def __init__(self):
        super().__init__(self._Window(self._Session()))
        self.session = self.app.session


def test_every_lecture_step_has_a_key_and_the_docs_count_them():
    from viewer.app.panels.lecture import step_keys_text
    from viewer.scene.lecture import TOUR

    app = Keys()
    for key in ("1", "9", "0", "shift+1", "shift+5", "shift+6"):
        app.key_action(key)
    assert len(TOUR) == 15 and app.session.asked == [0, 8, 9, 10, 14]   # Shift 6: no step 16
    assert "Shift 1-5 = 11-15" in step_keys_text(len(TOUR))
    n = len(TOUR)
    for doc in ("README.md", "docs/window.md", "docs/commands.md"):
        text = (ROOT / doc).read_text()
        assert f"lecture:{n}" in text and f"lecture:{n - 1}`" not in text and f"lecture:{n - 1})" not in text, doc
    assert f"tour of {n} steps" in (ROOT / "README.md").read_text()
    assert "Shift 1`-`Shift 5" in (ROOT / "docs/window.md").read_text()


def test_the_compiling_note_goes_with_the_compile(quiet, renderer):
    from viewer import brdf

    s, child = quiet
    s.presets_ahead = False
    s.render_view(SIZE)
    for rid in range(len(child.requests)):
        child.answer(rid)
    s.render_view(SIZE)
    for name in brdf.names():
        if name in ("custom", "measured", "layered"):
            continue
        s.set_material("ball", brdf.get(name).params())
        if renderer.forward_keys(s.scene)["ball"] not in renderer.programs:
            break
    else:
        pytest.skip("every model's program is compiled already in this test session")
    s.render_view(SIZE)
    assert s.compiling and "compiling ball" in s.last_message.text
    assert "compiling ball" in s.status and s.frame_source.form in ("stand-in", "held")
    child.answer(len(child.requests) - 1)
    assert s.last_message is None   # the compile is over: its note is no longer shown
    s.render_view(SIZE)
    assert not s.compiling and s.pending_work() == []
    assert s.frame_source.form == "own" and "compiling" not in s.status, s.status  # nor in the status line


def test_the_status_line_says_what_the_frame_shown_was_drawn_from():
    """On state: a note about a frame drawn while programs compile (its scene and form, as
    ``FrameSource`` records them) is the status while that frame is shown and the compile runs;
    once the frame is drawn another way its plain text stands (the step's timing without "grey
    stand-ins"), or, with none, the message before it; never the stand-ins' wording over a
    frame drawn with the real programs."""
    import types

    from viewer.app.session import FrameSource, Message

    scene, other = object(), object()
    ns = types.SimpleNamespace(compiling=True, frame_source=FrameSource(scene, {}, "stand-in"),
                               frames=types.SimpleNamespace(under_form=None), messages=[
        Message("opened lecture:11", False, 0.0),
        Message("compiling gold in the background: drawn with grey stand-ins until ready", False, 1.0,
                (scene, "stand-in")),
        Message("lecture 11/15: Complex IOR (0.30 s; its first frame with grey stand-ins while gold compile in the "
                "background)", False, 2.0, (scene, "stand-in"), "lecture 11/15: Complex IOR (0.30 s)")])
    ns.message_true = lambda m: Session.message_true(ns, m)
    status = lambda: Session.status.fget(ns)  # noqa: E731
    toast = lambda: Session.last_message.fget(ns)  # noqa: E731
    assert "grey stand-ins" in status() and toast() is ns.messages[-1]
    for src, compiling in ((FrameSource(scene, {}, "untraced"), True), (FrameSource(scene, {}, "own"), False),
                           (FrameSource(other, {}, "stand-in"), True), (FrameSource(scene, {}, "stand-in"), False)):
        ns.frame_source, ns.compiling = src, compiling
        assert status() == "lecture 11/15: Complex IOR (0.30 s)" and toast() is None, (src.form, compiling)
    ns.messages.pop()  # a compile note has no plain text: the message before it stands
    assert status() == "opened lecture:11" and toast() is None
    ns.frame_source, ns.compiling = FrameSource(scene, {}, "stand-in"), True
    assert status().startswith("compiling gold") and toast() is ns.messages[-1]
    # tiles of that form over another (an untraced frame's tiles over the stand-ins' image): the
    # note is not true of the view yet (the status line says both); over its own preview it is
    ns.frame_source = FrameSource(scene, {}, "untraced")
    ns.messages[-1] = Message("compiling gold in the background: drawn untraced until ready", False, 3.0,
                              (scene, "untraced"))
    for under, true in (("stand-in", False), ("preview", True), ("untraced", True), (None, True)):
        ns.frames.under_form = under
        assert (toast() is ns.messages[-1]) == true and status().startswith("compiling gold") == true, under


def test_without_the_child_the_models_warm_up_after_frames_then_the_loop_rests(gl_ctx, renderer):
    s = Session(gl_ctx, "sphere", renderer=renderer, prefetch=False)
    try:
        loop = Loop(s)
        s.render_view(SIZE)
        s.warm = s.warm[:1]   # one model left to compile here: one more frame, then the warm-up
        assert s.warming and not s.warms_beside and loop.loop_wait()[0] == "draw"
        s.warm_one()
        assert s.warm == [] and s.pending_work() == [] and loop.loop_wait()[0] == "rest" and loop.settled()
    finally:
        s.release()


def test_the_warm_up_waits_for_a_finished_view(gl_ctx, renderer, tiled):
    """A frame that still tiles the view sends no preset to the child (each is a scene's text:
    20-30 ms for the gallery, on top of the frame's tile); the first finished one does."""
    s = tiled.Session(gl_ctx, "default", renderer=renderer, prefetch=False, compile_ahead=True,
                      tiled_frames=True)
    child = s.compile_ahead = StandInChild()
    try:
        s.render_view(SIZE)
        for rid in range(len(child.requests)):
            child.answer(rid)
        s.render_view(SIZE)
        sent, turns = len(child.requests), 0
        assert s.tiling and s.warming
        while s.refining or s.quality != "full":
            s.warm_one()
            assert len(child.requests) == sent   # nothing sent while the view is tiled
            s.render_view(SIZE)
            turns += 1
        assert turns > 1
        s.warm_one()
        assert len(child.requests) == sent + 1   # the finished view: one preset a turn
    finally:
        s.compile_ahead = None
        s.release()
