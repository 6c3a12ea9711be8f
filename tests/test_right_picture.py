"""The right picture, always: after any step change (next, back, a digit, wrap-around) and any
scene change, every frame the window draws is drawn from the scene shown (its own objects and
materials, or grey stand-ins of the materials whose programs still compile, or the scene
untraced), never from the scene before. Driven on state with compile-ahead and tiled frames on
and a stand-in child whose answers the test releases (no timing)."""

import pytest

SIZE = (32, 24)
FORMS_WHILE_COMPILING = ("own", "untraced", "stand-in")


class StandIn:
    """A compile-ahead child whose answers the test releases."""

    alive = True

    def __init__(self):
        self.compiled, self.tables, self.requests, self.released = set(), {}, [], False

    def request(self, scene, urgent=True, text=None, **priority):
        self.requests.append((scene, urgent))
        return len(self.requests)

    def answered(self, rid):
        return self.released

    def stop(self):
        pass


def _session(gl_ctx, renderer):
    from viewer.app.session import Session

    s = Session(gl_ctx, "default", renderer=renderer, prefetch=False, compile_ahead=True, tiled_frames=True)
    s.compile_ahead = StandIn()
    return s


def _frames_are_of_this_scene(s, n=2):
    """``n`` frames; each drawn from the scene the session shows (never another's)."""
    for _ in range(n):
        s.render_view(SIZE)
        src = s.frame_source
        assert src is not None and src.scene is s.scene, (s.lecture_step, s.status)
        assert set(src.materials) == set(s.scene.materials)
        assert src.form in FORMS_WHILE_COMPILING, src.form
        for name, p in src.materials.items():  # a material as the scene has it, or a grey stand-in
            assert p is s.scene.materials[name] or (src.form == "stand-in" and p.model == "lambert"), name


def _settle(s, limit=400):
    s.compile_ahead.released = True
    for _ in range(limit):
        s.render_view(SIZE)
        if not (s.compiling or s.tracing or s.tiling):
            break
    assert s.frame_source.scene is s.scene and s.frame_source.form == "own"
    s.compile_ahead.released = False


def test_every_step_forwards_and_backwards_shows_its_own_scene(gl_ctx, renderer):
    from viewer.scene.lecture import TOUR

    s = _session(gl_ctx, renderer)
    try:
        _settle(s)
        s.lecture(0)
        for i in range(len(TOUR)):  # forwards, each step first drawn while its programs compile beside
            assert s.lecture_step == i
            _frames_are_of_this_scene(s)
            _settle(s)
            s.lecture_next()
        assert s.lecture_step == 0  # wrapped around
        for i in reversed(range(len(TOUR))):  # backwards, wrapping at once to the last step
            s.lecture_back()
            assert s.lecture_step == i
            _frames_are_of_this_scene(s)
    finally:
        s.compile_ahead = None
        s.release()


def test_the_class_route_never_shows_the_step_before(gl_ctx):
    # default scene, L, 9, 0, Right with nothing compiled yet and the child never answering:
    # every frame of every step is drawn from that step's scene
    from viewer.gl.renderer import Renderer

    renderer = Renderer(gl_ctx)
    s = _session(gl_ctx, renderer)
    try:
        _frames_are_of_this_scene(s)
        for action in (lambda: s.lecture(0), lambda: s.lecture(8), lambda: s.lecture(9), s.lecture_next):
            before = s.scene
            action()
            assert s.scene is not before
            _frames_are_of_this_scene(s, n=3)
        assert s.lecture_step == 10 and s.compiling and "in the background" in s.status
        # the view's own label says what it shows, whatever the status line said since
        assert s.frame_source.form in ("stand-in", "untraced")
        assert s.trace_status.startswith("compiling ") and "until ready" in s.trace_status
        s.notify("lecture 11/15: Complex IOR (0.4 s)")
        assert "until ready" in s.trace_status
    finally:
        s.compile_ahead = None
        s.release()
        renderer.release()


def test_a_scene_opened_while_compiling_is_drawn_itself(gl_ctx, renderer):
    from viewer.scene import load_scene

    s = _session(gl_ctx, renderer)
    try:
        _settle(s)
        for text in ("materials.ball.model=oren_nayar", "materials.ball.preset=soap_bubble"):
            s.scene = load_scene("default", [text])
            s.changed()
            _frames_are_of_this_scene(s)
    finally:
        s.compile_ahead = None
        s.release()


def test_tiles_of_a_new_scene_are_never_drawn_over_the_last_scenes_preview(gl_ctx, renderer, monkeypatch):
    # a preview of scene A (drawn while the view moved), then scene B drawn in tiles: the part
    # not tiled yet shows B's own preview, not A's
    import viewer.app.view_frames as smod
    from viewer.scene import load_scene

    monkeypatch.setattr(smod, "TILE_BUDGET_S", 1e-6)  # every still frame in tiles, one at a time
    monkeypatch.setattr(smod, "FRAME_GOAL_S", 1e-6)
    s = _session(gl_ctx, renderer)
    try:
        _settle(s)
        s.camera.orbit(2.0, 0.0, SIZE[1])  # a drag: A's preview
        s.changed()
        s.render_view(SIZE, interacting=True)
        assert s.quality == "preview"
        a = s.scene
        s.scene = load_scene("default", ["materials.floor.albedo=[0.2, 0.6, 0.2]"])  # then B, still
        s.changed()
        s.render_view(SIZE)
        assert s.tiling and s.scene is not a and s.frame_source.scene is s.scene
        assert s.frame_source.under is s.scene, "tiles over the last scene's image"
        s.camera.orbit(2.0, 0.0, SIZE[1])  # B's own preview stays under B's tiles
        s.changed()
        s.render_view(SIZE, interacting=True)
        s.render_view(SIZE)
        assert s.tiling and s.frame_source.under is s.scene
    finally:
        s.compile_ahead = None
        s.release()


class AnsweringChild(StandIn):
    """A child whose answers the test gives one request at a time (``answer(rid)``)."""

    def __init__(self):
        super().__init__()
        self.done = {}

    def request(self, scene, urgent=True, text=None, **priority):  # a scene asked for again keeps its id, as the child's
        for i, (sc, _) in enumerate(self.requests):
            if sc is scene:
                return i + 1
        return super().request(scene, urgent)

    def answered(self, rid):
        return rid in self.done

    def answer(self, rid):
        self.done[rid] = {"id": rid, "ok": True}


def test_a_traced_step_is_drawn_untraced_once_its_untraced_programs_are_ready(gl_ctx, monkeypatch):
    # the untraced programs are asked for first: once they are answered the step is drawn
    # untraced (its own materials), long before the traced ones
    import viewer.app.view_frames as frames
    from viewer.gl.renderer import Renderer
    from viewer.scene.lecture import TOUR

    # one tile a frame, however fast this machine draws them (the tiles of this small view fit
    # one frame's budget on a quiet machine, and the frames below would not see them)
    monkeypatch.setattr(frames, "TILE_BUDGET_S", 0.0)

    renderer = Renderer(gl_ctx)
    s = _session(gl_ctx, renderer)
    child = s.compile_ahead = AnsweringChild()
    try:
        s.lecture([t.key for t in TOUR].index("fresnel"))
        s.render_view(SIZE)
        assert s.frame_source.form == "stand-in"
        mine = [(i + 1, sc) for i, (sc, _) in enumerate(child.requests)
                if sc is s.scene or sc.objects is s.scene.objects]  # not the next step's, asked ahead
        flat = [rid for rid, sc in mine if not sc.render.raytrace]
        traced = [rid for rid, sc in mine if sc.render.raytrace]
        assert flat and traced and flat[0] < traced[0]  # the untraced first
        child.answer(flat[0])
        s.render_view(SIZE)
        # its untraced frame's tiles over the stand-ins: the label says what the rest still shows
        assert s.frame_source.form == "untraced" and s.tiling
        assert "drawn untraced until ready (in tiles: " in s.trace_status
        assert s.trace_status.endswith("%, the rest grey stand-ins)")
        while s.tiling:
            s.render_view(SIZE)
        _frames_are_of_this_scene(s)
        assert s.frame_source.form == "untraced" and s.trace_status.endswith("drawn untraced until ready")
        for rid in traced:
            child.answer(rid)
        for _ in range(400):
            s.render_view(SIZE)
            if not (s.compiling or s.tracing or s.tiling):
                break
        assert s.frame_source.form == "own" and s.frame_source.scene is s.scene
    finally:
        s.compile_ahead = None
        s.release()
        renderer.release()
