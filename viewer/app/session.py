"""The classroom session without a window: the scene, the camera, the renderer and every action a
student or lecturer can take (open and save scenes, edit materials, load meshes, materials and
environment maps, step the lecture, switch the compare and reflection modes, take screenshots,
keep the window's state), each reporting through one path, ``notify(text, error=False)``.

``Session`` is the facade the window and the tests use; each of its jobs is a part of its own,
held and passed the session: ``files`` (``viewer.app.file_actions``: scenes, materials, meshes,
environment maps), ``frames`` (``viewer.app.view_frames``: what the view draws, whole, in tiles
or traced in strips, and what each frame was drawn from), ``compiles``
(``viewer.app.compile_control``: programs compiled beside the window and what is drawn
meanwhile, the idle-time warm-up), ``tour`` (``viewer.app.lecture_control``: lecture mode and
Prepare lecture), ``env`` (``viewer.app.environment_watch``: the environment map's background
prefilter) and ``view`` (``viewer.app.view_state``: image, view and reflection modes, the
camera, screenshots, the saved state). The parts' attributes and actions the window reads are
the session's too (``Part``).

The window (``App`` in ``viewer/app/main.py``) draws it with imgui and forwards input; tests drive it
in-process on an offscreen EGL context. Nothing here imports imgui or glfw."""

from __future__ import annotations

import dataclasses
import os
import time
from pathlib import Path

import numpy as np

from viewer.app.compile_control import STAND_IN_ALBEDO, CompileControl  # noqa: F401 - the session's names
from viewer.app.environment_watch import EnvironmentWatch
from viewer.app.file_actions import FileActions
from viewer.app.lecture_control import LectureControl
from viewer.app.parts import Part
from viewer.app.view_frames import FrameSource, ViewFrames  # noqa: F401 - the session's names
from viewer.app.view_state import ViewState, scene_digest
from viewer.gl.shadow import unshadowed_note

#: "0": the window prefilters a new environment map in the frame, as offscreen rendering does
#: (tests that compare the window with offscreen images); else a quick prefilter meanwhile
DEFER_ENV = "BRDF_VIEWER_DEFER_PREFILTER"


@dataclasses.dataclass(frozen=True)
class Message:
    """One notification: its text, whether it reports a problem, when (perf_counter seconds).
    ``frame``: (scene, form) of the frame it describes (``FrameSource``: one drawn while its
    programs compile beside), it is true while that frame is shown and they compile; after it
    says ``plain`` (None: nothing)."""
    text: str
    error: bool
    time: float
    frame: tuple | None = None
    plain: str | None = None


class Session:
    """The state and the actions of one viewing session on the OpenGL context ``ctx``.

    ``scene``: a loaded Scene, else ``scene_ref`` / ``overrides`` are loaded (``lecture:N``
    starts lecture mode at step N). ``state``: the saved window state (``viewer.app.state``)
    whose compare mode, divider and view mode are restored. ``prefetch``: prefilter the lecture's
    environment maps in a background process when lecture mode starts. ``compile_ahead``:
    compile a changed material's programs in a background process (viewer/app/compile_ahead.py)
    and keep drawing it as it was meanwhile; the scene's presets compile ahead while idle.
    ``tiled_frames``: a still view whose whole frame takes longer than ``TILE_BUDGET_S``
    (``viewer.app.view_frames``) is drawn in tiles over the next frames, over the view as it was
    or its half-resolution preview (``quality`` "refining" meanwhile). ``prepare_frames``: the
    first frame of a scene the view has not drawn is prepared over several frames, one costly
    part each, under a labelled placeholder (``viewer.app.view_prep``)."""

    # files: scenes, materials, meshes, environment maps
    set_material = Part("files")
    set_material_param = Part("files")
    save_material = Part("files")
    load_material = Part("files")
    open_scene = Part("files")
    save_scene = Part("files")
    mesh_target = Part("files")
    load_mesh = Part("files")
    file_action = Part("files")
    open_files = Part("files")
    open_brdf_library = Part("files")
    load_brdf_file = Part("files")
    refit_file_materials = Part("files")
    set_environment = Part("files")
    # frames: what the view draws and what it was drawn from
    hdr = Part("frames")
    quality = Part("frames")
    raster_version = Part("frames")
    render_ms = Part("frames")
    frame_rest_s = Part("frames")
    bf_count = Part("frames")
    nonfinite = Part("frames")
    frame_source = Part("frames")
    refining = Part("frames")
    tiling = Part("frames")
    trace = Part("frames")
    tracing = Part("frames")
    trace_status = Part("frames")
    tile_budget_s = Part("frames")
    render_view = Part("frames", "draw")
    # compiles: programs compiled beside the window, the idle-time warm-up
    compile_ahead = Part("compiles", "child")
    pending = Part("compiles")
    warm = Part("compiles")
    presets_ahead = Part("compiles")
    compiling = Part("compiles")
    compile_ready = Part("compiles")
    warming = Part("compiles")
    warms_beside = Part("compiles")
    warm_one = Part("compiles")
    # tour: lecture mode and Prepare lecture
    lecture_step = Part("tour")
    step_listeners = Part("tour")
    prefetch = Part("tour")
    prep = Part("tour")
    lecture = Part("tour")
    lecture_next = Part("tour")
    lecture_previous = Part("tour")
    lecture_back = Part("tour")
    lecture_title = Part("tour")
    step_plot = Part("tour")
    preparing = Part("tour")
    prepare_lecture = Part("tour")
    # env: the environment map's background prefilter
    environment_provisional = Part("env", "provisional")
    # view: image, view and reflection modes, the camera, screenshots, the saved state
    screenshot_dir = Part("view")
    reset_camera = Part("view")
    fit_camera = Part("view")
    image_mode = Part("view")
    set_image_mode = Part("view")
    cycle_image_mode = Part("view")
    set_view_mode = Part("view")
    reflection_mode = Part("view")
    set_reflection_mode = Part("view")
    take_screenshot = Part("view")
    state_entries = Part("view")
    save_state = Part("view")

    def __init__(self, ctx, scene_ref=None, overrides=(), *, scene=None, renderer=None,
                 state: dict | None = None, prefetch: bool = True, compile_ahead: bool = False,
                 tiled_frames: bool = False, prepare_frames: bool = False):
        from viewer.app.compare_view import MODES, CompareView
        from viewer.app.monte_carlo import MonteCarloPanel
        from viewer.scene.camera import OrbitCamera
        from viewer.gl.renderer import VIEW_MODES, Renderer
        from viewer.scene import LECTURE_NAME, load_scene

        self.ctx = ctx
        self.files = FileActions(self)
        self.frames = ViewFrames(self, tiled_frames, prepare_frames)
        self.compiles = CompileControl(self, compile_ahead)
        self.tour = LectureControl(self, prefetch)
        self.env = EnvironmentWatch(self)
        self.view = ViewState(self)
        self.scene = scene if scene is not None else load_scene(scene_ref, overrides)
        self.state = dict(state or {})
        self._own_renderer = renderer is None
        self.renderer = renderer if renderer is not None else Renderer(ctx)
        self.camera = OrbitCamera.from_scene(self.scene)
        self.compare = CompareView(ctx)
        self.monte_carlo = MonteCarloPanel(ctx)  # reference settings, error views, convergence
        # the last session's compare view, term view and plots belong to the scene it ended on:
        # another scene opens in the raster view
        self.same_scene = self.state.get("scene_digest") == scene_digest(self.scene)
        if self.state.get("compare_mode") in MODES and self.same_scene:
            self.compare.mode = self.state["compare_mode"]
        self.compare.split = float(self.state.get("split", 0.5))
        self.view_mode = 0
        if 0 <= self.state.get("view_mode", 0) < len(VIEW_MODES) and self.same_scene:
            self.view_mode = self.state.get("view_mode", 0)
        self.messages: list[Message] = []
        self.edits = 0             # times the view was marked to be drawn again (``dirty``)
        self.dirty = True          # the raster image must be rendered again
        self.reference = None      # the ReferenceView, made on first use
        self.wake = None           # called from any thread when the reference has a new image
        # a map the disk cache lacks: drawn at once with a quick prefilter, its full prefilter in
        # a child process (viewer.app.prefetch.MapPrefilter), never on this thread
        if prefetch and os.environ.get(DEFER_ENV, "1") != "0":
            self.renderer.ibl().defer = True
        self.window_px = None      # the window's framebuffer size (w, h), set by the window each frame
        self._extents_for = None
        m = LECTURE_NAME.fullmatch(str(scene_ref)) if scene_ref is not None else None
        if m is not None:  # opened as lecture:N: lecture mode at that step
            self.tour.enter_step(int(m.group(1)) - 1)
        note = self.scene.size_note()   # a large scene: its first frame takes a while; say why
        if note:
            self.notify(f"{self.scene.label}: {note}")
        note = unshadowed_note(self.scene)   # lights beyond the shadow atlas
        if note:
            self.notify(f"{self.scene.label}: {note}")
        from viewer.app.twin_question import TwinQuestion

        self.twins = TwinQuestion(self)  # a .brdf file's numpy twin runs only when the user says so

    # ------------------------------------------------------------------ notifications
    def notify(self, text: str, error: bool = False, frame: tuple | None = None, plain: str | None = None) -> None:
        """The one way anything reports to the user: the window shows the latest as a toast
        (red for an error) and in the panel. ``frame``, ``plain``: a message about the frame
        drawn while programs compile beside (``Message``)."""
        self.messages.append(Message(str(text), bool(error), time.perf_counter(), frame, plain))
        del self.messages[:-50]

    def message_true(self, m: Message) -> bool:
        """``m`` is true of the view now: it is about no frame, or about the frame shown (the
        frame's provenance, ``frame_source``: the same scene, drawn the same way, the whole view:
        not tiles of it over another form, which the status line says) while the programs it
        waits for compile."""
        if m.frame is None:
            return True
        src = self.frame_source
        return self.compiling and src is not None and src.scene is m.frame[0] and src.form == m.frame[1] \
            and self.frames.under_form in (None, "preview", src.form)

    @property
    def status(self) -> str:
        """The latest message's text as it holds now: a message about a frame drawn while
        programs compiled beside says its ``plain`` text once another frame is shown, or, with
        none, gives way to the message before it."""
        for m in reversed(self.messages):
            if self.message_true(m):
                return m.text
            if m.plain:
                return m.plain
        return ""

    @property
    def last_message(self) -> Message | None:
        """The latest message, as the window shows it (its toast); one about the frame drawn
        while programs compile goes once that frame is not shown any more (it is not true)."""
        m = self.messages[-1] if self.messages else None
        return m if m is None or self.message_true(m) else None

    def release(self) -> None:
        """Stop the reference and the prefetch, free the GL objects this session made."""
        self.twins.release()
        if self.reference is not None:
            self.reference.close()
        self.tour.release()
        self.env.release()
        if self.compile_ahead is not None:
            self.compile_ahead.stop()
        self.compare.release()
        self.monte_carlo.release()
        self.frames.release()
        if self._own_renderer:
            self.renderer.release()

    # ------------------------------------------------------------------ the reference
    def update_reference(self, size, interacting: bool = False):
        """Advance the reference for a view of ``size`` when a compare mode or an error view
        shows it; returns its texture to display (or None), and refreshes the metrics.
        ``interacting``: a change restarts the reference only once the drag pauses."""
        if not (self.compare.uses_reference or self.monte_carlo.active) or size[0] <= 0 or size[1] <= 0:
            return None
        rv = self.reference_view()
        rv.update(self.scene, self.camera, size, defer=interacting)
        for line, error in rv.take_notices():   # a damaged cache entry repaired, a cache that cannot store
            self.notify(line, error=error)
        tex = rv.texture_for_display()
        self.compare.follow(rv.key)  # metrics taken on another scene or view: gone with it
        # the raster as the scene now is: whole, at full quality, no material drawn as it was
        if self.compare.mode != "reference" and self.quality == "full" and self.hdr is not None \
                and self.compiles.awaiting is None and not self.pending:
            self.compare.update_metrics(self.renderer, self.hdr, self.raster_version, rv)
        return tex

    def metrics_text(self) -> str:
        """The RMSE read-out of the view shown (``CompareView.metrics_text``), empty unless its
        metrics were taken on the reference's view as it is now."""
        return self.compare.metrics_text(None if self.reference is None else self.reference.key)

    def render_image(self, width: int, height: int) -> np.ndarray:
        """The raster image of the scene as seen, rendered afresh: (H, W, 3) uint8 sRGB."""
        hdr = self.renderer.render(self.scene, self.camera, width, height, self.view_mode)
        return self.renderer.read_srgb(hdr, self.scene.render.exposure, self.scene.render.tonemap)

    @property
    def view_finished(self) -> bool:
        """The view is as it will stay until something changes (what ``--screenshot`` waits for):
        the raster whole at full quality (no tiles, traced strips or averaging still to come), no
        material drawn as it was while its programs compile, and where the view shows the
        reference, a pass of it (not the coarse preview) and its metrics taken on it, or the
        one line saying why there is none."""
        if self.dirty or self.quality != "full" or self.refining or self.compiles.awaiting is not None \
                or self.pending:
            return False
        if not (self.compare.uses_reference or self.monte_carlo.active):
            return True
        rv = self.reference
        if rv is None:
            return False
        if rv.error:
            return True
        if rv.spp == 0:
            return False
        cmp = self.compare
        return cmp.mode == "reference" or not cmp.uses_reference or cmp.metrics_for == rv.key

    def pending_work(self) -> list[str]:
        """What is still to be done before the session rests, by name (empty: nothing; the
        window then draws no frame until something changes): "raster" (a frame to draw or
        refine), "compiling" (a changed material's programs beside the window), "warm-up"
        (idle-time warm-up still to send or compile), "compile ahead" (requests the child has
        not answered), "reference" (a reference render in flight), "prefetch" (the lecture's
        maps being prefiltered)."""
        out = []
        if self.dirty or self.quality != "full" or self.refining:
            out.append("raster")
        if self.compiles.awaiting is not None:
            out.append("compiling")
        if self.warming:
            out.append("warm-up")
        ca = self.compile_ahead
        if ca is not None and ca.alive and getattr(ca, "outstanding", 0):
            out.append("compile ahead")
        rv = self.reference
        if rv is not None and (rv.needs_frames or rv.busy):
            out.append("reference")
        if self.prefetch is not None and not self.prefetch.done:
            out.append("prefetch")
        return out

    def reference_view(self):
        if self.reference is None:
            from viewer.app.reference_view import ReferenceView

            self.reference = ReferenceView(self.ctx, wake=self.wake)
        return self.reference

    def cycle_strategy(self) -> str:
        """The reference's next way of reaching the light (MIS, BSDF sampling alone, light
        sampling alone; the S key): it restarts with it. Returns the strategy now used."""
        from viewer.reference_common.estimator import STRATEGIES, STRATEGY_LABELS

        rv = self.reference_view()
        now = STRATEGIES[(STRATEGIES.index(rv.options["strategy"]) + 1) % len(STRATEGIES)]
        self.monte_carlo.set_options(rv, strategy=now)
        self.changed()
        self.notify(f"reference strategy: {STRATEGY_LABELS[now]} (S: next)")
        return now

    def extents(self) -> dict:
        """material -> [(object, diameter)]: the smallest side of each solid object's bounding box
        (a sphere's diameter, the path through its centre), for the plots' Bouguer tab."""
        if self._extents_for is not None and self._extents_for[0] is self.scene:
            return self._extents_for[1]
        out: dict = {}
        for i, o in enumerate(self.scene.objects):
            if o.mesh == "plane":
                continue
            p = o.world_positions()
            d = float((p.max(axis=0) - p.min(axis=0)).min())
            if d > 0:
                label = Path(o.mesh).stem if o.mesh not in ("sphere", "cube") else f"{o.mesh} {i}"
                out.setdefault(o.material, []).append((label, d))
        self._extents_for = (self.scene, out)
        return out

    @property
    def dirty(self) -> bool:
        """The raster image must be rendered again. Whatever changes the scene in place sets it,
        so ``edits``, counted here, tells one state of the same scene object from another (what
        is worked out once per scene state, e.g. the text sent to the compile-ahead child, keys
        on it)."""
        return self._dirty

    @dirty.setter
    def dirty(self, value) -> None:
        if value:
            self.edits += 1
        self._dirty = bool(value)

    def changed(self) -> None:
        """Something the raster image depends on changed: render it again (and restart the
        brute-force average)."""
        self.dirty = True
