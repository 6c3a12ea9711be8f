"""A scene's first frame prepared over several frames (viewer/app/view_prep.py): the first frame
defers every costly part and shows no image, each frame after makes at most one part (counted
on the renderer's own state, not on the preparation's bookkeeping), the label says what is ready
and what comes next, true of the state at every frame, and the frame drawn at the end is the one
drawn without any preparation. Also the disk-cached DFG table (a corrupt file is recomputed) and
the quick prefilter's SH9 from the map's mip level. No timing is asserted."""

import re
import time

import numpy as np
import pytest

from viewer.app.view_prep import PREPARING

SIZE = (64, 48)


def _session(gl_ctx, scene="default", prepare=True, budget_s=0.0):
    from viewer.app.session import Session
    from viewer.gl.renderer import Renderer

    s = Session(gl_ctx, scene, renderer=Renderer(gl_ctx), prefetch=False, compile_ahead=False,
                prepare_frames=prepare)
    s.frames.prep.budget_s = budget_s   # 0: one part per frame, whatever each costs
    return s


def _state(s, scene):
    """What the renderer holds of the parts of a frame of ``scene``, read from the renderer
    itself: {part: built}."""
    from viewer.gl.program_set import frame_switches
    from viewer.gl.shadow import casts_shadows

    r = s.renderer
    ssr_on, env_on = frame_switches(scene, False if r.traces(scene) else None)[:2]
    env = scene.environment
    out = {"dfg": r.ibl().dfg_tex is not None, "targets": r.output.holds(*SIZE, scene.render.msaa),
           "mips": r.ibl().map_tex is not None, "environment": r.ibl().prefiltered is not None}
    if casts_shadows(scene):
        out["shadows"] = r.shadows_ready(scene)
    for name in dict.fromkeys(o.material for o in scene.objects):
        out[f"tables {name}"] = not (ssr_on or env_on) or r.tables.built(scene.materials[name], True)
    for name, key in r.forward_keys(scene, raytrace=False if r.traces(scene) else None).items():
        out[f"program {name}"] = key in r.programs
    if env.map is not None:
        out["sky"] = "background" in r.programs
    return out


def _prepare(s):
    """Frames until the view shows its frame; per frame (state, label, hdr shown)."""
    frames = []
    deadline = time.monotonic() + 120  # a bound against a hang, not a timing
    while time.monotonic() < deadline:
        s.render_view(SIZE)
        if s.frame_source is None or s.frame_source.form != PREPARING:
            return frames
        frames.append((_state(s, s.scene), s.trace_status, s.hdr))
        time.sleep(0.002)  # the map's worker thread's turn
    raise AssertionError("the preparation did not end")


def _settle(s, limit=400):
    """Frames until the view rests (a traced view's strips, tiles)."""
    for _ in range(limit):
        s.render_view(SIZE)
        if not (s.dirty or s.refining):
            return
    raise AssertionError("the view did not settle")


def _glass_traced(s):
    """The default scene's ball made glass and traced, the view prepared."""
    from viewer.scene import material_from_name

    ball = next(o.material for o in s.scene.objects if o.mesh != "plane")
    s.set_material(ball, material_from_name("glass"))
    s.set_reflection_mode("ray traced")
    _prepare(s)


def _assert_traced_as_at_once(gl_ctx, s):
    """The view shows the trace of the same view made in one piece."""
    from viewer.gl import raytrace

    pt = raytrace.ProgressiveTrace(gl_ctx)
    try:
        pt.start(s.renderer, s.scene, s.camera, *SIZE)
        pt.finish()
        assert np.array_equal(s.renderer.read_linear(s.hdr), pt.image())
    finally:
        pt.release()


def test_the_first_frame_defers_the_costly_parts(gl_ctx):
    s = _session(gl_ctx)
    try:
        s.render_view(SIZE)
        r = s.renderer
        assert s.frame_source.form == PREPARING and s.frame_source.scene is s.scene
        assert s.hdr is None and s.dirty and not s.view_finished  # no image; the next frame follows
        built = _state(s, s.scene)
        assert not any(built.values()), built  # the DFG table, targets, tables, programs: none made
        kinds = [p.kind for p in s.frames.prep.plan(s.scene, None, SIZE)]
        assert kinds[:2] == ["dfg", "targets"] and {"environment", "tables", "program"} <= set(kinds)
        assert kinds.index("mips") + 1 == kinds.index("environment")  # the mip chain, then the prefilter
        # the shadow atlas before the trial draws (each would draw it in its own frame)
        assert kinds.index("shadows") < kinds.index("program")
        assert s.trace_status == f"preparing the view: 0 of {len(kinds)} parts ready; next: the DFG table"
        assert r.ibl().dfg_tex is None
    finally:
        s.release()


# a constant sky; a sky map read beside with traced glass (slow: its traced programs compile and two
# traced views settle, ~30 s on 2 loaded cores)
@pytest.mark.parametrize("scene", ["default", pytest.param("lecture:2", marks=pytest.mark.slow)])
def test_one_part_per_frame_with_a_true_label_then_the_frame_itself(gl_ctx, scene):
    s = _session(gl_ctx, scene)
    plain = _session(gl_ctx, scene, prepare=False)
    try:
        frames = _prepare(s)
        assert len(frames) >= 5  # the placeholder, the DFG table, targets, environment, tables, programs
        before = {k: False for k in frames[0][0]}
        for state, label, hdr in frames:
            assert hdr is None  # never an image while it prepares
            made = [k for k, v in state.items() if v and not before.get(k)]
            assert len(made) <= 1, made  # at most one part per frame
            before = state
            m = re.fullmatch(r"preparing the view: (\d+) of (\d+) parts ready; (?:next: (.+)|the view comes next)", label)
            assert m, label
            ready, total, nxt = int(m.group(1)), int(m.group(2)), m.group(3)
            assert ready <= total
            # the next part named is one the renderer does not hold yet
            if nxt and nxt.startswith("the DFG table"):
                assert not state["dfg"]
            elif nxt == "the view's targets":
                assert not state["targets"]
            elif nxt == "the environment map's mip chain":
                assert not state["mips"]
            elif nxt == "the environment light":
                assert not state["environment"]
            elif nxt and nxt.startswith("the program of "):
                names = nxt[len("the program of "):].split(", ")
                assert all(not state[f"program {n}"] for n in names)
            elif nxt and nxt.startswith("the tables of "):
                assert not state["tables " + nxt[len("the tables of "):]]
        assert all(frames[-1][0].values()), frames[-1][0]  # everything made before the frame
        if s.scene.environment.map is not None:
            assert any(label.endswith("next: the sky's program") for _, label, _ in frames)
        assert s.frame_source.form == "own" and s.hdr is not None
        assert not s.frames.prep.active and "preparing" not in s.trace_status
        _settle(s)
        _settle(plain)
        assert plain.frame_source.form == "own"
        # the same picture as a frame drawn at once (same programs, same driver: bit for bit)
        assert np.array_equal(s.renderer.read_linear(s.hdr), plain.renderer.read_linear(plain.hdr))
    finally:
        s.release()
        plain.release()


def test_the_mip_chain_and_the_prefilter_have_a_frame_each(gl_ctx):
    """However much time a frame may spend on parts, the environment map's mip chain ends its
    frame (its first draws make its program's code, a cost not known before): the prefilter
    comes in the next. The light made in two equals the one made at once."""
    from viewer.gl.ibl import IBL

    s = _session(gl_ctx, budget_s=1e9)
    try:
        frames = _prepare(s)
        firsts = [next((i for i, f in enumerate(frames) if f[0][k]), None) for k in ("mips", "environment")]
        assert None not in firsts and firsts[0] < firsts[1], firsts
        ibl = s.renderer.ibl()
        once = IBL(gl_ctx, use_cache=False)
        twice = IBL(gl_ctx, use_cache=False)
        try:
            c = np.asarray(s.scene.environment.constant, float)
            twice.upload_map(None, constant=c)
            assert twice.map_uploaded(None, constant=c) and not once.map_uploaded(None, constant=c)
            tex = twice.map_tex
            twice.set_environment(None, constant=c)
            once.set_environment(None, constant=c)
            assert twice.map_tex is tex  # not uploaded again
            assert np.array_equal(once.prefiltered_data, twice.prefiltered_data) and np.array_equal(once.sh, twice.sh)
            assert once.map_tex.read(level=1) == twice.map_tex.read(level=1)
            assert ibl.map_uploaded(None, constant=c)
        finally:
            once.release()
            twice.release()
    finally:
        s.release()


def test_another_scene_never_shows_the_last_ones_frame(gl_ctx):
    s = _session(gl_ctx)
    try:
        _prepare(s)
        assert s.hdr is not None
        first = s.scene
        s.open_scene("default")  # another scene object: its first frame is prepared too
        assert s.scene is not first
        s.render_view(SIZE)
        src = s.frame_source
        if src.form == PREPARING:  # parts to make (the environment light of the new scene)
            assert s.hdr is None and src.scene is s.scene
        else:  # nothing to make: drawn at once, of the new scene
            assert src.scene is s.scene and s.hdr is not None
        _prepare(s)
        assert s.frame_source.scene is s.scene and s.hdr is not None
    finally:
        s.release()


def test_the_stand_in_note_is_not_shown_over_the_placeholder(gl_ctx):
    """A note about a frame drawn with grey stand-ins is true only while that frame is shown."""
    s = _session(gl_ctx)
    try:
        s.render_view(SIZE)
        s.notify("compiling ball in the background: drawn with grey stand-ins until ready",
                 frame=(s.scene, "stand-in"))
        assert s.last_message is None and s.status != "compiling ball in the background: drawn with grey stand-ins until ready"
        assert s.trace_status.startswith("preparing the view")
    finally:
        s.release()


def test_a_map_that_fails_to_read_is_reported_not_raised(gl_ctx, tmp_path):
    """The environment map is read on a worker thread: a bad file's error comes back to the
    window's thread, which reports it in one line and draws the scene as always."""
    from viewer.scene import load_scene

    s = _session(gl_ctx)
    try:
        bad = tmp_path / "bad.hdr"
        bad.write_bytes(b"not an image")
        import dataclasses

        scene = load_scene("default")
        env = dataclasses.replace(scene.environment, map=str(bad))
        with pytest.raises(Exception):
            env.radiance_map()  # the file is bad indeed
        s.scene = dataclasses.replace(scene, environment=dataclasses.replace(scene.environment, map=str(bad)))
        deadline = time.monotonic() + 60  # a bound against a hang, not a timing: the read is milliseconds
        while not any(m.error for m in s.messages) and time.monotonic() < deadline:
            s.render_view(SIZE)
            time.sleep(0.005)  # the worker thread's turn
        assert any(m.error and "bad.hdr" in m.text for m in s.messages), [m.text for m in s.messages]
        assert not s.frames.prep.active
    finally:
        s.release()


def test_a_corrupt_dfg_cache_file_is_recomputed(gl_ctx, tmp_path, monkeypatch):
    from viewer.environment import cache
    from viewer.gl.ibl import IBL

    monkeypatch.setenv("BRDF_VIEWER_CACHE", str(tmp_path))
    first = IBL(gl_ctx)
    first.ensure_dfg()
    files = list(tmp_path.glob("dfg-*.npz"))
    assert len(files) == 1
    want = first.dfg.copy()
    first.release()
    files[0].write_bytes(b"PK\x03\x04 truncated")  # a zip header and nothing after it
    again = IBL(gl_ctx)
    try:
        again.ensure_dfg()  # no crash: read as a miss and computed again
        assert np.array_equal(again.dfg, want)
        with np.load(files[0]) as z:  # stored again, whole (atomically)
            assert np.array_equal(z["dfg"], want)
    finally:
        again.release()
    assert cache.cache_dir() == tmp_path


def test_a_dfg_table_not_on_disk_is_drawn_a_band_of_rows_a_frame(gl_ctx, tmp_path, monkeypatch):
    """On a disk cache miss the DFG table's pass is made over frames of its own: one links its
    program, each later one draws the next band of rows (``DFG_BAND_ROWS``), the label counting
    them, and the table made so equals the table drawn in one piece, texel for texel; it is then
    stored, so the next view reads it in one frame."""
    from viewer.app.view_prep import DFG_BAND_ROWS
    from viewer.gl.ibl import DFG_SIZE, IBL, render_dfg

    monkeypatch.setenv("BRDF_VIEWER_CACHE", str(tmp_path))
    s = _session(gl_ctx, "default", budget_s=1e9)
    try:
        frames = _prepare(s)
        labels = [label for _, label, _ in frames]
        bands = DFG_SIZE // DFG_BAND_ROWS
        assert bands >= 2
        want = ["next: the DFG table"] + [f"next: the DFG table ({k * DFG_BAND_ROWS} of {DFG_SIZE} rows drawn)"
                                          for k in range(bands)]
        got = [label.split("; ", 1)[1] for label in labels[: bands + 1]]
        assert got == want, labels
        assert not any(state["dfg"] for state, _, _ in frames[: bands + 1])
        assert frames[bands + 1][0]["dfg"]  # the last band's frame made the table
        assert all(label.startswith("preparing the view: 0 of ") for label in labels[: bands + 1])
        one = IBL(gl_ctx, use_cache=False)
        try:
            assert np.array_equal(s.renderer.ibl().dfg, render_dfg(one))
        finally:
            one.release()
        assert len(list(tmp_path.glob("dfg-*.npz"))) == 1
    finally:
        s.release()
    again = _session(gl_ctx, "default", budget_s=1e9)
    try:
        frames = _prepare(again)
        assert frames[1][0]["dfg"]  # read from the disk in the first frame that makes a part
    finally:
        again.release()


def test_a_quick_prefilters_sh_comes_from_the_maps_mip_level(gl_ctx, tmp_path, monkeypatch):
    """SH9 of the map's first mip level at most 256 wide: its texels are solid-angle weighted
    means of the map's, so the integral (l = 0) is the map's up to float32 rounding; the l = 1, 2
    bands see each texel's light at the texel's centre, at most half a texel's diagonal (about 1
    degree at 256 x 128) from where it was, which moves a sun's cosine-weighted irradiance by at
    most sin(1 degree) = 1.7 % of the largest irradiance: the bound below is 2 %."""
    from viewer.environment.sh import irradiance, project_latlong
    from viewer.gl.ibl import IBL
    from viewer.scene import load_scene

    monkeypatch.setenv("BRDF_VIEWER_CACHE", str(tmp_path))
    img = load_scene("lecture:2").environment.radiance_map()
    assert img.shape[1] > 256
    ibl = IBL(gl_ctx)
    ibl.defer = True
    try:
        ibl.set_environment(img)
        assert ibl.stats["provisional"]
        full = project_latlong(img)
        assert np.abs(ibl.sh[0] - full[0]).max() < 1e-4 * np.abs(full[0]).max()  # the mean: kept
        rng = np.random.default_rng(3)
        n = rng.normal(size=(2000, 3))
        n /= np.linalg.norm(n, axis=1, keepdims=True)
        e_full, e_quick = irradiance(full, n), irradiance(ibl.sh, n)
        assert np.abs(e_quick - e_full).max() < 0.02 * e_full.max()
        assert not np.array_equal(ibl.sh, full)  # from the mip level indeed, not the map
    finally:
        ibl.release()


class _Child:
    """The compile-ahead child as the preparation sees it: asked for a scene, answered or not."""

    alive = True

    def __init__(self):
        self.asked, self.finished, self.done = [], False, {}
        self.compiled, self.tables = set(), {}

    def request(self, scene, urgent=True, batch=0, ahead=False, lead=False, text=None):
        self.asked.append((scene, urgent, lead))
        return 7

    def answered(self, rid):
        return self.finished


def test_a_program_waits_for_the_compile_ahead_child_then_is_made(gl_ctx, monkeypatch):
    """A program part the driver's cache does not hold waits (the placeholder, saying so) for the
    child, asked for the scene as drawn ahead of its other requests, however long it takes, and
    is made on the window's thread once the child answered; a program the driver's cache holds
    (``viewer.app.driver_cache``, as recorded) is made at once, the child not asked."""
    from viewer.app import driver_cache

    monkeypatch.setattr(driver_cache, "cache_identity", lambda: "a shader cache")  # whatever Mesa's is here
    s = _session(gl_ctx)
    child = s.compiles.child = _Child()
    try:
        for _ in range(20):
            s.render_view(SIZE)
            if "waiting for the background compile" in s.trace_status:
                break
        m = re.search(r"next: the program of (.+) \(waiting for the background compile\)$", s.trace_status)
        assert m, s.trace_status
        scene, urgent, lead = child.asked[0]
        assert scene.objects == s.scene.objects and urgent and lead  # the scene shown, first of its batch
        every = s.renderer.forward_keys(s.scene)
        keys = {every[n] for n in m.group(1).split(", ")}
        for _ in range(30):  # still waiting, as long as no answer comes: the program is not made here
            s.render_view(SIZE)
            assert s.frame_source.form == PREPARING and not keys & set(s.renderer.programs)
        child.finished = True
        s.render_view(SIZE)  # answered: made on this thread now
        assert keys <= set(s.renderer.programs) and s.frame_source.form == PREPARING
        _prepare(s)  # the other program (the child answered that request too), then the frame
        assert s.frame_source.form == "own" and s.hdr is not None
    finally:
        s.compiles.child = None
        s.release()
    s = _session(gl_ctx)
    child = s.compiles.child = _Child()
    try:
        s.compiles.record().add(s.renderer.forward_keys(s.scene).values(), driver_cache.drawing_state(s.scene))
        _prepare(s)
        assert not child.asked and s.frame_source.form == "own" and s.hdr is not None
    finally:
        s.compiles.child = None
        s.release()


def test_parts_within_the_budget_share_a_frame_but_each_costly_one_has_its_own(gl_ctx):
    """With a budget no part passes, the cheap parts (the view's targets, a material's tables)
    share a frame with the costly part after them; a costly part (its first draws make a
    program's code, a cost not known before it: the DFG table's pass, the environment map's mip
    chain, its prefilter, the shadow atlas, each program's trial draw) ends its frame, so each has a frame of its
    own: the placeholder, one frame per costly part, then the frame itself."""
    from viewer.gl.ibl import IBL

    warm = IBL(gl_ctx)
    warm.ensure_dfg()  # the DFG table in this test's disk cache: one frame (a miss takes a band a frame)
    warm.release()
    s = _session(gl_ctx, "default", budget_s=1e9)
    try:
        programs = len(set(s.renderer.forward_keys(s.scene).values()))
        frames = _prepare(s)
        costly = {"dfg", "mips", "environment", "shadows"}
        assert programs == 2 and len(frames) == 1 + len(costly) + programs, [label for _, label, _ in frames]
        assert not any(frames[0][0].values())  # the placeholder: nothing made
        for before, after in zip(frames, frames[1:]):
            made = {k for k, v in after[0].items() if v and not before[0][k]}
            assert len({k for k in made if k in costly or k.startswith("program")}) == 1, made
        assert all(frames[-1][0].values()), frames[-1][0]  # the cheap parts too, within those frames
        assert s.hdr is not None and s.frame_source.scene is s.scene
    finally:
        s.release()


def test_a_traced_views_bvh_is_made_beside_and_the_untraced_frame_stays_meanwhile(gl_ctx, monkeypatch):
    # the soup and BVH of a traced scene (0.3-1.5 s of numpy and Python for the gallery) are made
    # on a thread of their own, held here on a gate: meanwhile no traced tile is drawn and the
    # view shows the scene's untraced frame; then the trace ends as the one made at once
    import threading

    from viewer.gl import raytrace

    gate, entered, where = threading.Event(), threading.Event(), []
    made = raytrace.cached_flat_scene

    def held(geom):
        where.append(threading.current_thread().name)
        entered.set()
        assert gate.wait(60)
        return made(geom)

    monkeypatch.setattr(raytrace, "cached_flat_scene", held)
    s = _session(gl_ctx, budget_s=10.0)
    try:
        _glass_traced(s)
        for _ in range(5):
            s.render_view(SIZE)
            assert s.tracing and s.frames.trace.steps == 0 and s.hdr is not None
            assert s.frame_source.scene is s.scene and s.frame_source.form == "own"
        assert entered.wait(60) and where == ["brdf-viewer-bvh"]   # on its own thread, at the gate
        s.render_view(SIZE)
        assert s.tracing and s.frames.trace.steps == 0
        gate.set()
        deadline = time.monotonic() + 60  # a bound against a hang, not a timing
        while s.tracing and time.monotonic() < deadline:
            s.render_view(SIZE)
            time.sleep(0.002)
        assert not s.tracing and s.frames.trace.steps > 0
        _assert_traced_as_at_once(gl_ctx, s)   # the same view traced in one piece
    finally:
        gate.set()
        s.release()


def test_the_plan_of_two_glasses_with_absorption_colours(gl_ctx):
    # two materials of one model whose parameters hold arrays (the absorbing glass step, two
    # glasses of the same values): the plan compares their values (== on the parameters has no
    # single truth value) and the two share one part for their tables
    from viewer.scene.lecture import TOUR, tour_scene

    s = _session(gl_ctx)
    try:
        scene = tour_scene([t.key for t in TOUR].index("absorbing_glass"))
        parts = s.frames.prep.plan(scene, False, SIZE)
        assert scene.materials["glass_big"].to_plain() == scene.materials["glass_small"].to_plain()
        assert sorted(p.materials[0] for p in parts if p.kind == "tables") == ["floor", "glass_big"]
    finally:
        s.release()


def test_the_loop_sleeps_while_the_placeholder_waits_for_the_child(gl_ctx, monkeypatch):
    """While the view's preparation waits for the compile-ahead child, the window's loop draws the
    placeholder no more than once an ``IDLE_FRAME_S`` (its frames would take the CPU the child
    needs); the child's answer (which wakes the loop) makes it draw at once. On state: the loop's
    ``loop_wait``, no timing."""
    import types

    from viewer.app import driver_cache
    from viewer.app.pacing import Pacing

    monkeypatch.setattr(driver_cache, "cache_identity", lambda: "a shader cache")
    s = _session(gl_ctx)
    child = s.compiles.child = _Child()
    app = types.SimpleNamespace(session=s, keys=types.SimpleNamespace(last_event=-1e9))
    pacing = Pacing(app)
    try:
        assert pacing.loop_wait() == ("draw", 0.0)  # the first frame of a new scene
        for _ in range(20):
            s.render_view(SIZE)
            if s.frames.prep.waits_on_child:
                break
        assert s.dirty and s.frame_source.form == PREPARING
        assert pacing.loop_wait() == ("frames", Pacing.IDLE_FRAME_S)
        child.finished = True  # answered
        assert not s.frames.prep.waits_on_child and pacing.loop_wait() == ("draw", 0.0)
    finally:
        s.compiles.child = None
        s.release()


def test_a_program_drawn_for_another_scene_is_prepared_again_in_a_new_drawing_state(gl_ctx):
    """llvmpipe makes a program's code for the state it is drawn in (the sample count, the
    environment map's and the shadow atlas's kinds of texture: ``driver_cache.drawing_state``):
    a scene whose programs the renderer linked for another scene in another state gets their
    parts (a trial draw each) all the same; one in the same state does not."""
    from viewer.scene import load_scene

    s = _session(gl_ctx)
    try:
        _prepare(s)
        keys = set(s.renderer.forward_keys(s.scene).values())
        gold = load_scene("default", overrides=["materials.floor.albedo=[0.3, 0.3, 0.3]"])  # the same state
        eight = load_scene("default", overrides=["render.msaa=8"])  # another
        assert set(s.renderer.forward_keys(eight).values()) == keys <= set(s.renderer.programs)
        for scene, parts in ((gold, False), (eight, True)):
            s.scene = scene
            s.changed()
            labels = [label for _, label, _ in _prepare(s)]
            assert any("the program of" in label for label in labels) is parts, labels
            assert s.frame_source.form == "own"
    finally:
        s.release()


def _until(s, done, bound_s=120):
    """Frames until ``done()`` (a bound against a hang, not a timing: the map is read on a thread)."""
    deadline = time.monotonic() + bound_s
    while not done():
        assert time.monotonic() < deadline, s.trace_status
        s.render_view(SIZE)
        time.sleep(0.002)


class _Answering:
    """A compile-ahead child whose answers the test gives (``answer``), keeping a scene's id when
    it is asked for again, as the child does."""

    alive = True

    def __init__(self):
        self.compiled, self.tables, self.requests, self.done, self.states = set(), {}, [], {}, {}

    def request(self, scene, urgent=True, batch=0, ahead=False, lead=False, text=None):
        from viewer.scene import scene_to_toml

        text = scene_to_toml(scene)
        for i, (t, _, _) in enumerate(self.requests):
            if t == text:
                return i + 1
        self.requests.append((text, scene, lead))
        return len(self.requests)

    def answered(self, rid):
        return rid in self.done

    def answer(self, rid):
        self.done[rid] = {"id": rid, "ok": True}

    def stop(self):
        pass


def test_a_new_form_of_the_scene_shown_is_prepared_under_the_image_it_replaces(gl_ctx, monkeypatch):
    """A traced step opens on its grey stand-ins (prepared behind the placeholder once the child
    answered them); when its untraced programs are answered, the view keeps the stand-ins' image
    while their trial draws are made, one program a frame, under a label that says so, and
    only then draws the step untraced: never the placeholder again, never another scene."""
    from viewer.app import driver_cache
    from viewer.app.session import Session
    import viewer.app.view_frames as frames
    from viewer.gl.renderer import Renderer
    from viewer.scene.lecture import TOUR

    monkeypatch.setattr(driver_cache, "cache_identity", lambda: "a shader cache")
    # one tile a frame, however fast this machine draws them (the tiles below are read frame by frame)
    monkeypatch.setattr(frames, "TILE_BUDGET_S", 0.0)
    s = Session(gl_ctx, "default", renderer=Renderer(gl_ctx), prefetch=False, compile_ahead=True,
                tiled_frames=True, prepare_frames=True)
    child = s.compile_ahead = _Answering()
    try:
        s.lecture([t.key for t in TOUR].index("fresnel"))
        _until(s, lambda: s.frames.prep.waits_on_child)  # the placeholder, waiting for the stand-ins
        lead = [i + 1 for i, (_, sc, first) in enumerate(child.requests) if first]
        assert lead and all(getattr(child.requests[i - 1][1], "stand_in", False) for i in lead)
        child.answer(lead[0])
        _until(s, lambda: s.frame_source.form == "stand-in")
        assert s.frame_source.form == "stand-in" and s.hdr is not None
        flat = next(i + 1 for i, (_, sc, first) in enumerate(child.requests)
                    if not first and sc.objects is s.scene.objects and not sc.render.raytrace)
        child.answer(flat)
        untraced = set(s.renderer.forward_keys(s.scene, raytrace=False).values()) - set(s.renderer.programs)
        assert untraced
        kept = 0
        for _ in range(60):
            before = set(s.renderer.programs)
            s.render_view(SIZE)
            src = s.frame_source
            assert src.scene is s.scene and src.form in ("stand-in", "untraced"), src.form
            if src.form == "untraced":
                break
            assert s.hdr is not None and s.trace_status.startswith("drawn with grey stand-ins; preparing the view")
            assert len(set(s.renderer.programs) - before) <= 1  # one program a frame
            kept += 1
        assert s.frame_source.form == "untraced" and kept >= len(untraced)
        assert untraced <= set(s.renderer.programs)
        # its tiles drawn over the stand-ins' image: no note says "drawn untraced" of that view,
        # the status line says both
        tiled = 0
        while s.frames.under_form == "stand-in":
            m = s.last_message
            assert m is None or "drawn untraced" not in m.text, m.text
            assert "drawn untraced until ready (in tiles: " in s.trace_status and "the rest grey stand-ins" in s.trace_status
            tiled += 1
            s.render_view(SIZE)
        assert tiled and s.frame_source.form == "untraced"
        if s.compiling:  # the traced programs still compile: the note is true of the whole view now
            assert "drawn untraced until ready" in s.status
    finally:
        s.compile_ahead = None
        s.release()


def test_the_placeholder_s_label_stands_over_a_note_but_not_over_an_error(gl_ctx, monkeypatch):
    """While the view shows its placeholder, its label (what is prepared, what it waits for) is
    what the view says: a note (the environment light's) is not shown over it; an error is."""
    from viewer.app import driver_cache
    from viewer.app.panels.overlays import toast

    monkeypatch.setattr(driver_cache, "cache_identity", lambda: "a shader cache")
    s = _session(gl_ctx)
    s.compiles.child = _Child()
    try:
        _until(s, lambda: s.frames.prep.waits_on_child)
        assert s.frame_source.form == PREPARING and "waiting for the background compile" in s.trace_status
        s.notify("environment light: a quick low-resolution prefilter until the full one is ready")
        assert toast(s, 60.0) is None
        s.notify("a shader did not compile", error=True)
        assert toast(s, 60.0) is not None and toast(s, 60.0).error
        s.compiles.child.finished = True
        _until(s, lambda: s.frame_source.form != PREPARING)  # the view itself: notes show again
        s.notify("opened default")
        assert toast(s, 60.0).text == "opened default"
    finally:
        s.compiles.child = None
        s.release()


def test_a_traced_views_tiles_come_once_each_program_is_drawn_in_their_state_one_a_frame(gl_ctx):
    # a traced tile draws its programs without MSAA in the traced frame's state, which llvmpipe
    # makes code for apart from the untraced frame's: each program of that state is drawn first
    # into one pixel, one a frame, before any tile; the trace then ends as the one made at once
    from viewer.app.view_prep import PIXEL

    s = _session(gl_ctx, budget_s=10.0)
    try:
        _glass_traced(s)
        calls = []
        render = s.renderer.render

        def logged(*a, **k):
            calls.append((a[2:4], k.get("msaa"), k.get("raytrace"), k.get("region"), k.get("only")))
            return render(*a, **k)

        s.renderer.render = logged
        trials, frames = [], 0
        deadline = time.monotonic() + 120  # a bound against a hang, not a timing
        while s.tracing and time.monotonic() < deadline:
            calls.clear()
            steps = s.frames.trace.steps
            s.render_view(SIZE)
            mine = [c for c in calls if c[3] == PIXEL]
            assert len(mine) <= 1   # one program a frame
            if mine:
                assert s.frames.trace.steps == steps   # no tile in that frame
                assert steps == 0                      # every one before the first tile
                trials.append(mine[0])
            frames += 1
            time.sleep(0.002)
        assert not s.tracing and s.frames.trace.steps > 0
        keys = s.renderer.forward_keys(s.scene, raytrace=None)
        assert len(trials) == len(set(keys.values())) >= 2
        half = ((SIZE[0] + 1) // 2, (SIZE[1] + 1) // 2)   # the coarse pass's size, the first tiles'
        for size, msaa, rt, region, only in trials:
            assert size == half and msaa == 0 and rt is None
        assert {keys[n] for t in trials for n in t[4]} == set(keys.values())
        s.renderer.render = render
        _assert_traced_as_at_once(gl_ctx, s)   # the trial draws left no trace in the image
    finally:
        s.release()


def test_a_prepared_traced_step_opens_from_the_cache_while_its_programs_compile_beside(gl_ctx, tmp_path, monkeypatch):
    """A traced lecture step prepared for this view (its traced frame in the cache, as ``bake
    --lecture`` leaves it) opens from the cache in the first frame that can read it (once its
    map is read on the preparation's thread), though none of its programs is made and the
    compile-ahead child never answers: never grey stand-ins or a placeholder waiting for
    programs it does not need, no "compiling" read-out over it, and the image is the prepared
    one. (The soap bubbles' step, prepared, showed stand-ins for 5 s and more beside two busy
    processes while its traced programs compiled.)"""
    from viewer.app.session import Session
    from viewer.gl.raytrace import ProgressiveTrace
    from viewer.gl.renderer import Renderer
    from viewer.scene.lecture import TOUR, tour_scene

    monkeypatch.setenv("BRDF_VIEWER_CACHE", str(tmp_path))
    step = [t.key for t in TOUR].index("tir")
    other, pt = Renderer(gl_ctx), ProgressiveTrace(gl_ctx)
    try:  # prepared by another renderer, as the bake's process does
        pt.start(other, tour_scene(step), None, *SIZE, store=True)
        while not pt.done:
            pt.step(0.05)
        assert pt.stored is not None
        want = pt.image()
    finally:
        pt.release()
        other.release()
    s = Session(gl_ctx, "default", renderer=Renderer(gl_ctx), prefetch=False, compile_ahead=True,
                prepare_frames=True)
    s.compiles.child = _Child()
    try:
        s.lecture(step)
        forms = []
        deadline = time.monotonic() + 120  # a bound against a hang, not a timing (the map is read beside)
        while time.monotonic() < deadline:
            s.render_view(SIZE)
            forms.append(getattr(s.frame_source, "form", None))
            if forms[-1] == "own":
                break
            time.sleep(0.002)
        assert forms[-1] == "own", forms
        assert set(forms[:-1]) <= {PREPARING}, forms  # the placeholder while the map is read, nothing else
        assert s.quality == "full" and not s.tracing and not s.dirty
        assert np.array_equal(s.renderer.read_linear(s.hdr), want)
        assert not s.pending and "compiling" not in s.trace_status and "preparing" not in s.trace_status
        assert any("from the prepared cache" in m.text for m in s.messages[-3:])
        assert not s.frames.prep.active
    finally:
        s.compiles.child = None
        s.release()
