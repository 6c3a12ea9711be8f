"""Tiled frames: a still view whose whole frame takes longer than a frame's budget is drawn over
several frames, in tiles, over the view as it was (or its half-resolution preview), and ends
exactly as the whole frame. The budget is set to 0 here so that every frame tiles whatever this
machine's speed; the cost the window meets is benchmarks/preset_switch.py's."""

import dataclasses

import numpy as np
import pytest

from viewer.gl.raytrace import upscale
from viewer.scene import material_from_name

SIZE = (120, 80)


def _whole(renderer, scene, camera, size):
    return renderer.read_linear(renderer.render(scene, camera, size[0], size[1], raytrace=False)).copy()


def test_a_raster_frame_in_tiles_is_the_whole_frame_and_shows_the_meantime_until_then(gl_ctx, renderer):
    from viewer.gl.raytrace import ProgressiveTrace
    from viewer.scene import load_scene

    scene = load_scene("default")
    w, h = SIZE
    whole = _whole(renderer, scene, None, SIZE)
    under = np.full((h, w, 4), 7.0, np.float32)  # a value no pixel of the view has
    pt = ProgressiveTrace(gl_ctx)
    try:
        pt.start(renderer, scene, None, w, h, traced=False, under=under, rows=4, max_pixels=w * 8)
        assert not pt.done
        assert np.array_equal(pt.image(), under[::-1, :, :3])  # the meantime, before any tile
        pt.step(0.0)  # one tile (a step draws at least one)
        img = pt.image()
        drawn = np.all(img != 7.0, axis=2)
        assert 0 < drawn.mean() < 1
        assert drawn[0].all() and not drawn[-1].any()  # from the top
        assert np.array_equal(img[drawn], whole[drawn])
        while not pt.done:
            pt.step(0.0)
        assert pt.steps > 2
        # the tiles are scissors of the whole frame (MSAA 4 included): the same texels
        assert np.array_equal(pt.image(), whole)
        # the same view again, its tiles sized by the last frame's rows: the same texels
        gold = dict(scene.materials, ball=material_from_name("gold"))
        scene2 = dataclasses.replace(scene, materials=gold)
        pt.start(renderer, scene2, None, w, h, traced=False, under=pt.texture, like_last=True, rows=4,
                 max_pixels=w * 8)
        assert np.array_equal(pt.image(), whole)  # the old frame stays until its tiles come
        while not pt.done:
            pt.step(0.0)
        assert np.array_equal(pt.image(), _whole(renderer, scene2, None, SIZE))
        # without an image for the meantime: the half-resolution view, enlarged by bilinear
        # interpolation (smooth silhouettes; the same values up to the rounding of the other
        # row order: the texture's rows run from the bottom)
        pt.start(renderer, scene, None, w, h, traced=False)
        preview = renderer.read_linear(renderer.render(scene, None, w // 2, h // 2, msaa=0, raytrace=False))
        assert np.allclose(pt.image(), upscale(preview, 2, h, w), rtol=1e-5, atol=1e-6)
        pt.finish()
        assert np.array_equal(pt.image(), whole)
    finally:
        pt.release()


@pytest.fixture
def tiled(monkeypatch):
    import viewer.app.session as session
    import viewer.app.view_frames as frames

    monkeypatch.setattr(frames, "TILE_BUDGET_S", 0.0)  # every frame is over the budget
    # the preview at half the resolution, as the tests compare: a coarser one is chosen where the
    # last tiles' time per pixel says a half-resolution one would take over the frame's goal,
    # which a loaded machine's timings did (a quarter-resolution preview: a failure under load)
    monkeypatch.setattr(frames, "FRAME_GOAL_S", 1e9)
    return session


def test_a_change_is_drawn_over_the_old_view_in_tiles_then_whole(gl_ctx, renderer, tiled):
    s = tiled.Session(gl_ctx, "default", renderer=renderer, prefetch=False, tiled_frames=True)
    try:
        s.render_view(SIZE)  # the view's first frame: in tiles too (no cost known yet)
        assert s.tiling
        while s.quality != "full":
            s.render_view(SIZE)
        before = renderer.read_linear(s.hdr).copy()
        s.set_material("ball", material_from_name("gold"))
        s.render_view(SIZE)
        assert s.quality == "refining" and s.tiling and s.refining
        first = renderer.read_linear(s.hdr).copy()
        # tiles from the top; below them the view as it was (same scene, same size), not a
        # preview: the bottom row is the old frame's, texel for texel
        assert np.array_equal(first[-1], before[-1])
        frames = 1
        while s.quality != "full":
            s.render_view(SIZE)
            frames += 1
            assert frames < 500
        assert frames > 2 and not s.tiling
        final = renderer.read_linear(s.hdr)
        assert not np.array_equal(final, before)  # gold, not the terracotta
        assert np.array_equal(final, _whole(renderer, s.scene, s.camera, SIZE))
        # nothing changed: no frame is drawn again
        version = s.raster_version
        s.render_view(SIZE)
        assert s.raster_version == version
    finally:
        s.release()


def test_a_drag_stops_the_tiles_and_its_end_tiles_over_the_preview(gl_ctx, renderer, tiled):
    s = tiled.Session(gl_ctx, "default", renderer=renderer, prefetch=False, tiled_frames=True)
    try:
        s.render_view(SIZE)
        s.set_material("ball", material_from_name("copper"))
        s.render_view(SIZE)
        assert s.tiling
        s.camera.orbit(20.0, 0.0, SIZE[1])
        s.dirty = True
        s.render_view(SIZE, interacting=True)
        assert s.quality == "preview" and not s.tiling
        s.render_view(SIZE)  # the drag paused: tiles over the preview just shown
        assert s.quality == "refining"
        while s.quality != "full":
            s.render_view(SIZE)
        assert np.array_equal(renderer.read_linear(s.hdr), _whole(renderer, s.scene, s.camera, SIZE))
        # the camera reset (no drag): not the old view under the tiles, a preview of the new one
        s.camera.reset()
        s.dirty = True
        s.render_view(SIZE)
        assert s.quality == "refining"
        shown = renderer.read_linear(s.hdr)
        preview = renderer.read_linear(renderer.render(s.scene, s.camera, SIZE[0] // 2, SIZE[1] // 2, msaa=0,
                                                       raytrace=False))
        assert np.allclose(shown, upscale(preview, 2, SIZE[1], SIZE[0]), rtol=1e-5, atol=1e-6)  # see the first test
    finally:
        s.release()


def test_frames_that_read_the_whole_frame_or_average_frames_are_never_tiled(gl_ctx, renderer, tiled):
    from viewer.scene import load_scene

    for name, setting in (("ssr", ("ssr", True)), ("brute force", ("ibl", "brute_force"))):
        scene = load_scene("default")
        setattr(scene.render, *setting)
        s = tiled.Session(gl_ctx, scene=scene, renderer=renderer, prefetch=False, tiled_frames=True)
        try:
            s.render_view(SIZE)
            s.set_material("ball", material_from_name("gold"))
            s.render_view(SIZE)
            assert not s.tiling, name
        finally:
            s.release()


def test_without_tiled_frames_a_change_is_drawn_whole_at_once(gl_ctx, renderer, tiled):
    s = tiled.Session(gl_ctx, "default", renderer=renderer, prefetch=False)
    try:
        s.render_view(SIZE)
        s.set_material("ball", material_from_name("gold"))
        s.render_view(SIZE)
        assert s.quality == "full" and not s.tiling
        assert np.array_equal(renderer.read_linear(s.hdr), _whole(renderer, s.scene, s.camera, SIZE))
    finally:
        s.release()


def test_changing_the_frames_size_or_samples_and_tiling_raise_no_gl_error(gl_ctx, renderer):
    """Each change of the frame's sample count or size remakes its framebuffers; releasing the
    bound one used to leave moderngl to bind a deleted name again (GL_INVALID_OPERATION)."""
    from viewer.gl.raytrace import ProgressiveTrace
    from viewer.scene import load_scene

    scene = load_scene("default")
    gl_ctx.error  # noqa: B018 - reading clears the flag: only this test's calls count
    steps = [dict(), dict(msaa=0), dict(msaa=0, region=(0, 0, 32, 8)), dict(region=(0, 0, 32, 8)),
             dict(width=60, height=40), dict()]
    for kw in steps:
        kw = {"width": SIZE[0], "height": SIZE[1], **kw}
        renderer.render(scene, None, kw.pop("width"), kw.pop("height"), **kw)
        assert gl_ctx.error == "GL_NO_ERROR", kw
    pt = ProgressiveTrace(gl_ctx)
    pt.start(renderer, scene, None, SIZE[0], SIZE[1], traced=False)
    pt.finish()
    pt.release()
    assert gl_ctx.error == "GL_NO_ERROR"


def test_another_scene_tiles_over_a_quarter_resolution_preview_then_is_whole(gl_ctx, renderer):
    """A scene opened at the view's size has no known cost (a lecture step's soap bubbles cost
    tens of times the step before): its first still frame tiles over a preview at a quarter of
    the resolution (with the view's MSAA, as the tiles), whatever the budget, and ends as the
    whole frame."""
    from viewer.app.session import Session
    from viewer.scene import load_scene

    s = Session(gl_ctx, "default", renderer=renderer, prefetch=False, tiled_frames=True)
    try:
        s.render_view(SIZE)  # the session's first frame: in tiles (no cost known yet), then whole
        assert s.tiling
        while s.quality != "full":
            s.render_view(SIZE)
        s.scene = load_scene("sphere")
        s.changed()
        s.render_view(SIZE)
        assert s.quality == "refining" and s.tiling
        assert "drawing the view in tiles" in s.trace_status
        w, h = SIZE
        preview = renderer.read_linear(renderer.render(s.scene, s.camera, (w + 3) // 4, (h + 3) // 4,
                                                       raytrace=False)).copy()  # with the view's MSAA
        shown = renderer.read_linear(s.hdr)
        bottom = shown[-(h // 2):]  # below the first tile: the preview, enlarged 4 times (bilinear)
        expect = upscale(preview, 4, h, w)[-(h // 2):]
        assert np.allclose(bottom, expect, rtol=1e-5, atol=1e-6)  # rounding: see the first test
        while s.quality != "full":
            s.render_view(SIZE)
        assert np.array_equal(renderer.read_linear(s.hdr), _whole(renderer, s.scene, s.camera, SIZE))
    finally:
        s.release()


@pytest.mark.parametrize("goal_s, scale", [(0.0, 16), (1e9, 2)])
def test_a_preview_at_another_framing_is_as_coarse_as_the_scenes_known_cost_needs(gl_ctx, renderer, tiled,
                                                                                 monkeypatch, goal_s, scale):
    """The view at another framing (lecture mode left: the strip gone) has no frame of its own to
    tile over: its preview is drawn anew, at half the resolution for a scene whose tiles showed
    what a pixel costs, and coarser (up to a 16th) where that cost over the preview's pixels
    exceeds a frame's goal. A goal of 0 s: every known cost is over it; an unbounded one: none is.
    A scene whose cost is not known (none of its tiles drawn) keeps the quarter resolution."""
    import viewer.app.view_frames as frames
    from viewer.gl.raytrace import ProgressiveTrace
    from viewer.scene import load_scene

    monkeypatch.setattr(frames, "FRAME_GOAL_S", goal_s)
    s = tiled.Session(gl_ctx, "default", renderer=renderer, prefetch=False, tiled_frames=True)
    other = (160, 60)  # another aspect: not the same framing
    try:
        while s.quality != "full" or s.hdr is None:
            s.render_view(SIZE)
        drawn = []
        render = renderer.render
        renderer.render = lambda *a, **k: drawn.append(tuple(a[2:4])) or render(*a, **k)
        try:
            s.render_view(other)
        finally:
            renderer.render = render
        assert drawn[0] == ((other[0] + scale - 1) // scale, (other[1] + scale - 1) // scale), drawn
    finally:
        s.release()
    # the cost is known only of the scene whose tiles were drawn: another keeps its base scale
    scene, other_scene = load_scene("default"), load_scene("sphere")
    pt = ProgressiveTrace(gl_ctx)
    try:
        assert pt.raster_cost_px(scene) is None and pt.preview_scale(scene, 160, 60, 4, goal_s) == 4
        pt.start(renderer, scene, None, *SIZE, traced=False, rows=4, max_pixels=SIZE[0] * 8)
        pt.step(0.0)
        assert pt.raster_cost_px(scene) > 0 and pt.raster_cost_px(other_scene) is None
        assert pt.preview_scale(scene, 160, 60, 2, goal_s) == scale
        assert pt.preview_scale(other_scene, 160, 60, 4, goal_s) == 4
    finally:
        pt.release()


def test_a_traced_view_over_the_budget_tiles_its_untraced_frame_before_tracing(gl_ctx, renderer, tiled):
    """Ray tracing turned on where the untraced frame is over the budget: no whole frame at
    once; the untraced frame is drawn in tiles, then traced from it, and the end is the
    trace of a whole untraced frame."""
    from viewer.gl.raytrace import ProgressiveTrace
    from viewer.scene.lecture import TOUR, tour_scene

    scene = tour_scene([t.key for t in TOUR].index("absorbing_glass"))
    scene.render.raytrace = False
    s = tiled.Session(gl_ctx, scene=scene, renderer=renderer, prefetch=False, tiled_frames=True)
    try:
        s.render_view(SIZE)
        s.render_view(SIZE)
        while s.quality != "full":
            s.render_view(SIZE)
        s.set_reflection_mode("ray traced")
        assert renderer.traces(s.scene)
        s.render_view(SIZE)
        assert s.tiling and not s.tracing and s.quality == "tracing"
        seen_tracing = False
        for _ in range(2000):
            if s.quality == "full":
                break
            s.render_view(SIZE)
            seen_tracing |= s.tracing
        assert s.quality == "full" and seen_tracing
        pt = ProgressiveTrace(gl_ctx)
        try:
            pt.start(renderer, s.scene, s.camera, SIZE[0], SIZE[1])
            pt.finish()
            assert np.array_equal(renderer.read_linear(s.hdr), pt.image())
        finally:
            pt.release()
    finally:
        s.release()


def test_a_compare_view_switch_keeps_the_raster_shown(gl_ctx, renderer):
    """Switching to the split or difference view draws no raster frame again (on a traced scene
    it would restart the trace); side by side draws it at its own size, and the raster after the
    reference alone (which draws none) is drawn anew."""
    from viewer.app.session import Session

    s = Session(gl_ctx, "default", renderer=renderer, prefetch=False)
    try:
        s.render_view(SIZE)
        version = s.raster_version
        for mode in ("split", "difference", "raster"):
            s.set_image_mode(mode)
            assert not s.dirty
            s.render_view(SIZE)
            assert s.raster_version == version, mode
        s.set_image_mode("side by side")
        s.render_view((SIZE[0] // 2, SIZE[1]))  # the raster's half of the view
        assert s.raster_version > version
        s.set_image_mode("reference")
        s.set_image_mode("raster")
        assert s.dirty
    finally:
        s.release()


def test_the_view_at_another_size_of_its_framing_tiles_over_its_last_frame_resampled(gl_ctx, renderer, tiled):
    """A compare view's half and the whole view again (the same framing at another size): the
    tiles start over the frame shown, resampled on the GPU (a 2 x 2 box going down, the preview's
    bilinear weights going up), never over a preview drawn anew."""
    from viewer.gl import raytrace

    s = tiled.Session(gl_ctx, "default", renderer=renderer, prefetch=False, tiled_frames=True)
    half = (SIZE[0] // 2, SIZE[1] // 2)
    try:
        while s.quality != "full" or s.hdr is None:
            s.render_view(SIZE)
        whole = renderer.read_linear(s.hdr).copy()
        drawn = []
        render = renderer.render
        renderer.render = lambda *a, **k: drawn.append(tuple(a[2:4])) or render(*a, **k)
        try:
            s.render_view(half)
            first = renderer.read_linear(s.hdr).copy()
            assert s.tiling
            # the bottom row is under the tiles: the whole frame's two bottom rows, boxed 2 x 2
            boxed = whole.reshape(half[1], 2, half[0], 2, 3).mean(axis=(1, 3))
            np.testing.assert_allclose(first[-1], boxed[-1], rtol=1e-5, atol=1e-6)
            while s.quality != "full":
                s.render_view(half)
            small = renderer.read_linear(s.hdr).copy()
            s.render_view(SIZE)
            again = renderer.read_linear(s.hdr).copy()
            grown = raytrace.upscale(np.ascontiguousarray(small[::-1]), 2, SIZE[1], SIZE[0])[::-1]
            np.testing.assert_allclose(again[-1], grown[-1], rtol=1e-5, atol=1e-6)
        finally:
            renderer.render = render
        # no preview was drawn: every render was a tile of the view's own size
        assert set(drawn) == {half, SIZE}, drawn
        while s.quality != "full":
            s.render_view(SIZE)
        assert np.array_equal(renderer.read_linear(s.hdr), _whole(renderer, s.scene, s.camera, SIZE))
    finally:
        s.release()


def test_a_raster_tile_ends_where_an_object_begins_and_probes_it_alone(gl_ctx, renderer):
    """A new scene's tiles (no cost known) stop above the row where an object's projected box
    begins, and the block of 4 rows where it begins is a tile of its own, whose time sizes the
    next: a tile sized at the sky's cost that ran into the soap bubbles took 0.6-0.8 s. The
    frame is still the whole frame, texel for texel."""
    from viewer.gl.raytrace import ProgressiveTrace
    from viewer.scene import load_scene
    from viewer.scene.camera import OrbitCamera, screen_boxes

    scene = load_scene("sphere", ["camera.fov_y=100"])
    w, h = 96, 160   # tall, the ball small in the middle: the sky above it spans 14 blocks
    cam = OrbitCamera.from_scene(scene)
    ball = next(o for o in scene.objects if o.mesh == "sphere")
    top = int(screen_boxes(cam, w, h, [ball])[0][3]) // 4
    assert 4 < top < h // 4 - 2   # the ball begins well inside the frame
    pt = ProgressiveTrace(gl_ctx)
    regions = []   # each tile's (x, y, w, h), from the bottom
    render = renderer.render
    renderer.render = lambda *a, **k: (k.get("region") and regions.append(k["region"])) or render(*a, **k)
    try:
        pt.start(renderer, scene, cam, w, h, 0, traced=False, rows=4, max_pixels=w * h)
        while not pt.done:
            pt.step(0.3)   # tiles grow over the cheap sky (a third of the budget each)
        renderer.render = render
        spans = [(y // 4, (y + th - 1) // 4) for _, y, _, th in regions]   # (lowest, highest) block
        assert max(hi - lo for lo, hi in spans if lo > top) > 0   # over the sky: tiles of several blocks
        assert (top, top) in spans   # the block where the ball begins: a tile of its own
        assert not any(lo < top < hi or (lo < top and hi == top) for lo, hi in spans)
        whole = _whole(renderer, scene, cam, (w, h))
        assert np.array_equal(pt.image(), whole)
    finally:
        renderer.render = render
        pt.release()


def test_a_preview_is_enlarged_without_steps():
    """A preview's pixels are interpolated between their centres: a ramp stays a ramp (no
    stairs), the borders hold their pixel's value, a constant stays exactly constant."""
    ramp = np.tile(np.arange(6, dtype=np.float32)[None, :, None], (2, 1, 4))
    big = upscale(ramp, 4, 8, 24)
    assert big.shape == (8, 24, 4) and big.dtype == np.float32
    row = big[0, :, 0]
    assert np.allclose(np.diff(row[2:-2]), 0.25)  # between the first and last centres: even steps of 1/4
    assert row[0] == row[1] == 0.0 and row[-1] == row[-2] == 5.0
    assert np.array_equal(upscale(np.full((3, 5, 4), 0.3, np.float32), 4, 12, 20), np.full((12, 20, 4), 0.3, np.float32))


def test_a_scene_drawn_with_stand_ins_stays_under_the_tiles_of_its_own_frame(gl_ctx, tiled):
    """Once the child has a new scene's programs, its own frame is drawn in tiles over the
    stand-in frame shown (full resolution, the view's MSAA), not over a new quarter-resolution
    preview: the view never drops back to a coarser picture of the same scene. Every frame is
    over the tile budget (``tiled``): whether the own frame tiles must not hang on how long the
    stand-in frame took on this machine."""
    from viewer.app.session import Session
    from viewer.gl.renderer import Renderer
    from viewer.scene import load_scene

    class Child:  # a compile-ahead child whose answer the test releases
        alive, released = True, False

        def __init__(self):
            self.compiled, self.tables, self.done = set(), {}, {}

        def request(self, scene, urgent=True, text=None, **priority):
            return id(scene)

        def answered(self, rid):
            return self.released

        def stop(self):
            pass

    renderer = Renderer(gl_ctx)  # its own: the new scene's programs not compiled by another test
    s = Session(gl_ctx, "default", renderer=renderer, prefetch=False, compile_ahead=True, tiled_frames=True)
    child = s.compiles.child = Child()
    try:
        child.released = True
        for _ in range(400):  # the first frame, in tiles (its cost not known yet)
            s.render_view(SIZE)
            if s.quality == "full":
                break
        child.released = False
        s.scene = load_scene("default", overrides=["materials.ball.model=oren_nayar"])
        s.changed()
        for _ in range(400):
            s.render_view(SIZE)
            if not s.tiling:
                break
        assert s.frame_source.form == "stand-in" and s.quality == "full"
        stand_in = renderer.read_linear(s.hdr).copy()
        child.released = True
        s.render_view(SIZE)  # the scene's own frame: its first tile over the stand-in frame
        assert s.frame_source.form == "own" and s.tiling
        shown = renderer.read_linear(s.hdr)
        h = SIZE[1]
        assert np.array_equal(shown[-(h // 2):], stand_in[-(h // 2):])  # below the first tile
        while s.tiling:
            s.render_view(SIZE)
        assert not np.array_equal(renderer.read_linear(s.hdr), stand_in)  # the ball with its own program
    finally:
        s.compiles.child = None
        s.release()
        renderer.release()


def test_a_tile_draws_only_the_objects_over_it_and_equals_the_whole_frame_there(gl_ctx, renderer):
    # the gallery's objects, each tile drawing only those whose projected box reaches it: every
    # tile's pixels are the whole frame's, bit for bit, and a tile over one corner leaves most
    # objects out (their vertex work was a tile's whole fixed cost on software OpenGL)
    from viewer.gl.frame_passes import Frame
    from viewer.gl.object_draws import in_region
    from viewer.scene import load_scene
    from viewer.scene.camera import OrbitCamera

    scene = load_scene("gallery")
    w, h = SIZE
    cam = OrbitCamera.from_scene(scene)
    whole = _whole(renderer, scene, cam, SIZE)

    def kept(region):
        def frame(cull):
            return Frame(w, h, cam, None, 0, False, 0, [], False, np.zeros(3), None, False, False, region, cull=cull)
        assert in_region(scene.objects, frame(False)) == list(enumerate(scene.objects))
        return len(in_region(scene.objects, frame(True)))

    assert kept(None) == len(scene.objects)
    assert kept((0, 0, 6, 6)) < len(scene.objects) // 2
    for region in [(0, 0, 6, 6), (w // 2 - 10, h // 2 - 7, 20, 14), (0, h - 8, w, 8), (w - 9, 0, 9, h)]:
        x, y, rw, rh = region
        img = renderer.read_linear(renderer.render(scene, cam, w, h, region=region, raytrace=False))
        rows = slice(h - y - rh, h - y)  # read_linear: row 0 at the top, GL's region from the bottom
        assert np.array_equal(img[rows, x:x + rw], whole[rows, x:x + rw]), region


def test_a_trace_sizes_its_tiles_from_a_probe_of_their_fixed_cost(gl_ctx, renderer):
    # the first traced tile is a 16-pixel probe: its time is the fixed part of a tile, not a
    # tile's whole time over glass, which sized the next tiles to a second each
    from viewer.gl.raytrace import PROBE_PIXELS, ProgressiveTrace
    from viewer.scene.lecture import TOUR, tour_scene

    scene = tour_scene([s.key for s in TOUR].index("absorbing_glass"))
    pt = ProgressiveTrace(gl_ctx)
    try:
        pt.start(renderer, scene, None, *SIZE)
        assert pt.pixels == PROBE_PIXELS
        pt.step(0.0)
        assert pt.steps == 1 and pt.overhead_s > 0 and pt.pixels > PROBE_PIXELS
        while not pt.done:
            pt.step(0.05)
        assert pt.progress == 1.0
    finally:
        pt.release()


@pytest.mark.parametrize("s, h, w", [(4, 37, 50), (2, 30, 41)])
def test_the_preview_is_enlarged_on_the_gpu_as_upscale_does(gl_ctx, renderer, s, h, w):
    # shaders/passes/enlarge.frag against the numpy enlargement (the same weights, the borders
    # clamped), on random texels; sizes not multiples of the factor, as a view's rarely are
    from viewer.gl.raytrace import ProgressiveTrace

    rng = np.random.default_rng(3)
    hs, ws = (h + s - 1) // s, (w + s - 1) // s
    small = rng.random((hs, ws, 4)).astype(np.float32)
    src = gl_ctx.texture((ws, hs), 4, dtype="f4")
    src.write(small.tobytes())
    pt = ProgressiveTrace(gl_ctx)
    try:
        tex = pt.enlarge(renderer, src, s, w, h)
        got = np.frombuffer(tex.read(), np.float32).reshape(h, w, 4)
        np.testing.assert_allclose(got, upscale(small, s, h, w), rtol=1e-6, atol=1e-6)  # float32 rounding
    finally:
        pt.release()
        src.release()


def test_a_tile_is_planned_under_a_fixed_most_however_dear_its_fixed_part():
    # a tile's fixed part (every triangle through the vertex stage) is a third of its time at
    # most; where that part is large (the gallery beside two busy processes:
    # 0.15 s) the tile stays within TILE_MOST_S, not three times that part
    from viewer.gl.raytrace import TILE_MOST_S, RasterTileSizes, _Pass, planned_tile_s

    assert planned_tile_s(0.07, 0.07, 0.01) == pytest.approx(0.07)
    assert planned_tile_s(0.07, 0.07, 0.04) == pytest.approx(0.12)   # the fixed part a third
    assert planned_tile_s(0.07, 0.07, 0.15) == TILE_MOST_S            # not 0.45 s
    assert planned_tile_s(1e9, 1e9, 0.15) == pytest.approx(1e9)       # a bake's tiles: whole
    w, h = 1344, 1080
    sizes = RasterTileSizes()
    sizes.start(w, h, like_last=False, contacts=frozenset())
    p = _Pass(w, h, np.ones((h, w), bool), 1)
    p.block -= 1                       # the top block was drawn: 4 rows at 0.2 us a pixel
    per_px = 2e-7                      # the whole frame: 0.29 s, over the most
    for overhead in (0.01, 0.05, 0.15, 0.3):
        pixels = sizes.next_pixels(p, h - 4, 4, per_px, 0.07, 4 * w, overhead)
        assert pixels >= 4 * w         # a block at least, always
        if pixels > 4 * w:             # more than one block only within the plan
            assert sizes.next_s <= planned_tile_s(0.07 / 3, 0.07, overhead) + 1e-12
        assert sizes.next_s <= max(TILE_MOST_S, 0.9 * overhead + per_px * 4 * w) + 1e-12
    assert sizes.next_s > 0.9 * 0.3    # the dearest: one block, its fixed part alone over the most
