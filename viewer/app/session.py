"""The classroom session without a window: the scene, the camera, the renderer and every action a
student or lecturer can take (open and save scenes, edit materials, load meshes, materials and
environment maps, step the lecture, switch the compare and reflection modes, take screenshots,
keep the window's state), each reporting through one path, ``notify(text, error=False)``.

The window (``App`` in ``viewer/app/main.py``) draws it with imgui and forwards input; tests drive it
in-process on an offscreen EGL context. Nothing here imports imgui or glfw."""

from __future__ import annotations

import dataclasses
import datetime
import os
import sys
import time
from pathlib import Path

import numpy as np

from viewer import ViewerError
from viewer.app.file_actions import FileActions
from viewer.gl.context import release_gl
from viewer.gl.shadow import unshadowed_note

BF_FRAMES = 256  # brute-force IBL: frames averaged before the view stops refining
TRACE_BUDGET_S = 0.12  # traced chains: the time one refining frame's strip of rows aims at
# tiled frames: a still view whose whole frame took longer than this is drawn in tiles of about
# this much time per frame, over the view as it was or its half-resolution preview (the window
# then answers input within a frame's budget on software OpenGL, where one frame at 1280 x 720
# with MSAA takes 0.3 s); less where the rest of the window's frame leaves less of FRAME_GOAL_S
TILE_BUDGET_S = 0.07
#: "0": the window prefilters a new environment map in the frame, as offscreen rendering does
#: (tests that compare the window with offscreen images); else a quick prefilter meanwhile
DEFER_ENV = "BRDF_VIEWER_DEFER_PREFILTER"
FRAME_GOAL_S = 0.12

# the plot tab each lecture step's ``plot`` names
STEP_TABS = {"polar": "Polar", "lobe": "3D lobe", "albedo": "Albedo", "fresnel": "Fresnel",
             "bouguer": "Bouguer", "spectral": "Spectral", "sampling": "Sampling"}


KEEP_IMAGE = object()  # _held_back: keep the view shown as it is (the same scene, seen the same way)
UNTRACED = object()    # _held_back: the scene itself, untraced, while its traced programs compile beside
#: a stand-in material's albedo: a new scene whose programs compile beside is drawn with grey
#: Lambert stand-ins for the materials not ready (its own objects, never the last scene's frame)
STAND_IN_ALBEDO = 0.5


@dataclasses.dataclass(frozen=True)
class FrameSource:
    """What the raster image shown was drawn from: ``scene`` (the session's scene object then),
    its materials (``materials``: name -> params as drawn), and ``form``: "own" (every material
    with its own programs), "held" (the same scene with the edited materials as they were),
    "untraced" (the scene without its traced chains), "stand-in" (its objects, the materials not
    ready drawn as grey Lambert stand-ins). ``under``: where the frame is drawn in tiles, the
    scene of the image the tiles not drawn yet show (the same scene, always)."""
    scene: object
    materials: dict
    form: str
    under: object = None


def scene_digest(scene) -> str:
    """What the saved state remembers of the scene a session ended on: a digest of its text
    without the camera (an orbit, or the camera the last scene file keeps, is the same scene)."""
    import hashlib

    from viewer.scene import scene_to_data, scene_to_toml

    data = scene_to_data(scene, absolute_paths=True)
    data.pop("camera", None)
    return hashlib.sha256(scene_to_toml(data).encode("utf-8")).hexdigest()[:32]


@dataclasses.dataclass(frozen=True)
class Message:
    """One notification: its text, whether it reports a problem, when (perf_counter seconds)."""
    text: str
    error: bool
    time: float


class Session(FileActions):
    """The state and the actions of one viewing session on the OpenGL context ``ctx``.

    ``scene``: a loaded Scene, else ``scene_ref`` / ``overrides`` are loaded (``lecture:N``
    starts lecture mode at step N). ``state``: the saved window state (``viewer.app.state``)
    whose compare mode, divider and view mode are restored. ``prefetch``: prefilter the lecture's
    environment maps in a background process when lecture mode starts. ``compile_ahead``:
    compile a changed material's programs in a background process (viewer/app/compile_ahead.py)
    and keep drawing it as it was meanwhile; the scene's presets compile ahead while idle.
    ``tiled_frames``: a still view whose whole frame takes longer than ``TILE_BUDGET_S`` is
    drawn in tiles over the next frames, over the view as it was or its half-resolution preview
    (``quality`` "refining" meanwhile)."""

    def __init__(self, ctx, scene_ref=None, overrides=(), *, scene=None, renderer=None,
                 state: dict | None = None, prefetch: bool = True, compile_ahead: bool = False,
                 tiled_frames: bool = False):
        from viewer import brdf
        from viewer.app.compare_view import MODES, CompareView
        from viewer.app.monte_carlo import MonteCarloPanel
        from viewer.camera import OrbitCamera
        from viewer.gl.renderer import VIEW_MODES, Renderer
        from viewer.scene import LECTURE_NAME, load_scene

        self.ctx = ctx
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
        self.status = ""           # the latest message's text
        self.dirty = True          # the raster image must be rendered again
        self.hdr = None            # the raster image shown (a texture), None before the first
        self.raster_version = 0
        self.render_ms = 0.0
        self.frame_rest_s = 0.0    # what the window's frame costs beside render_view (the window sets it)
        self.quality = "full"      # "preview" after an interactive (half-resolution) frame
        self.bf_count = 0          # brute-force IBL: frames in the running mean
        self.lecture_step = -1     # -1: lecture mode off; else the tour's step shown
        self.reference = None      # the ReferenceView, made on first use
        self.prefetch = None       # the lecture maps' background prefilter
        self.nonfinite = None      # the last check's message about NaN / Inf pixels, else None
        # models whose programs compile while idle on this thread (with the compile-ahead child
        # the picker's presets compile there instead, and this list stays empty)
        self.warm = [] if compile_ahead else list(brdf.names())
        self.screenshot_dir = Path.cwd()
        self.step_listeners: list = []  # called with the step lecture mode shows (None: mode off)
        self.wake = None           # called from any thread when the reference has a new image
        self._prefetch_on = prefetch
        # a map the disk cache lacks: drawn at once with a quick prefilter, its full prefilter in
        # a child process (viewer.app.prefetch.MapPrefilter), never on this thread
        self._env_job = None
        self._env_failed: set[str] = set()
        if prefetch and os.environ.get(DEFER_ENV, "1") != "0":
            self.renderer.ibl().defer = True
        self._compile_ahead_on = compile_ahead
        self.compile_ahead = None  # the CompileAhead child, started on first need
        self.pending: list[str] = []  # materials drawn as they were while their programs compile
        self._drawn_materials = None  # (scene, {material name: params}) last drawn with their own programs
        self.frame_source = None   # what the raster image shown was drawn from (FrameSource)
        self._tiles_under = None   # the scene of the image under a tiled frame's tiles
        self._awaiting = None      # the compile-ahead request the view waits for
        self._compile_note = None  # the message saying so (a toast only while it is true)
        self._ahead_sent = False  # the presets still to send to the child (False: not begun)
        self.presets_ahead = True  # with compile_ahead: the picker's presets compile ahead while idle
        self._mesh_target = None
        self._bf_sum = None
        self._bf_tex = None
        self._hdr_for = None
        self._step_timer = None
        self._nonfinite_said = None
        self._extents_for = None
        self._trace = None         # the progressive trace of a still view (viewer.gl.raytrace)
        self._tiles_on = tiled_frames
        self._tiles = None         # the still raster frame drawn in tiles (a ProgressiveTrace, traced=False)
        self._whole_s = None       # ((w, h), seconds, scene's objects): what the last whole full-quality frame cost
        self._untraced_tiles = False  # a traced view's untraced frame is being drawn in tiles first
        self._drawn_view = None    # the camera and view mode of the frame shown (_view_key)
        self.prep = None           # Prepare lecture's job (viewer.app.lecture_prep), None when none ran
        self.window_px = None      # the window's framebuffer size (w, h), set by the window each frame
        self._shown = None         # (texture, framebuffer): the view kept while the preparation renders
        m = LECTURE_NAME.fullmatch(str(scene_ref)) if scene_ref is not None else None
        if m is not None:  # opened as lecture:N: lecture mode at that step
            self._enter_step(int(m.group(1)) - 1)
        note = self.scene.size_note()   # a large scene: its first frame takes a while; say why
        if note:
            self.notify(f"{self.scene.label}: {note}")
        note = unshadowed_note(self.scene)   # lights beyond the shadow atlas
        if note:
            self.notify(f"{self.scene.label}: {note}")
        from viewer.app.twin_question import TwinQuestion

        self.twins = TwinQuestion(self)  # a .brdf file's numpy twin runs only when the user says so

    # ------------------------------------------------------------------ notifications
    def notify(self, text: str, error: bool = False) -> None:
        """The one way anything reports to the user: the window shows the latest as a toast
        (red for an error) and in the panel."""
        self.status = str(text)
        self.messages.append(Message(self.status, bool(error), time.perf_counter()))
        del self.messages[:-50]

    @property
    def last_message(self) -> Message | None:
        """The latest message, as the window shows it (its toast); the note that a material
        compiles beside the window goes once the compile is over (it is not true any more)."""
        m = self.messages[-1] if self.messages else None
        if m is not None and m is self._compile_note and not self.compiling:
            return None
        return m

    def release(self) -> None:
        """Stop the reference and the prefetch, free the GL objects this session made."""
        self.twins.release()
        if self.reference is not None:
            self.reference.close()
        if self.prefetch is not None:
            self.prefetch.stop()
        if self._env_job is not None:
            self._env_job.stop()
            self._env_job = None
        if self.compile_ahead is not None:
            self.compile_ahead.stop()
        self.compare.release()
        self.monte_carlo.release()
        if self._bf_tex is not None:
            self._bf_tex.release()
            self._bf_tex = None
        for t in (self._trace, self._tiles):
            if t is not None:
                t.release()
        self._trace = self._tiles = None
        if self.prep is not None:
            self.prep.cancel()
        if self._shown is not None:
            release_gl(self._shown[1], self._shown[0])
            self._shown = None
        if self._own_renderer:
            self.renderer.release()

    # ------------------------------------------------------------------ rendering
    @property
    def refining(self) -> bool:
        """Frames should follow without waiting for input (brute-force IBL still averaging, or
        the traced chains still refining)."""
        return ((self.scene.render.ibl == "brute_force" and self.bf_count < BF_FRAMES) or self.tracing
                or self.tiling)

    @property
    def tiling(self) -> bool:
        """The still view's raster frame is being drawn in tiles (``tiled_frames``)."""
        return self._tiles is not None and self._tiles.active and not self._tiles.done

    @property
    def trace(self):
        """The progressive trace of the still view (``viewer.gl.raytrace.ProgressiveTrace``), or
        None before the first traced view."""
        return self._trace

    @property
    def preparing(self) -> bool:
        """Prepare lecture is tracing the lecture's steps into the traced-frame cache (in a child
        process: the window's frames go on as usual)."""
        return self.prep is not None and not self.prep.done

    @property
    def tracing(self) -> bool:
        """The traced image of the still view is being built, strip by strip."""
        return self._trace is not None and self._trace.active and not self._trace.done

    @property
    def trace_status(self) -> str:
        """What the view says while the traced image refines ("" otherwise)."""
        if self.tiling:
            return f"drawing the view in tiles: {100 * self._tiles.progress:.0f}% (the rest as it was)"
        if not self.tracing:
            return self.prep.progress_text() if self.preparing else ""
        t = self._trace
        stage = "half resolution first" if t.coarse else "full resolution"
        return (f"ray tracing: {100 * t.progress:.0f}%, {stage}, {time.perf_counter() - t.started:.0f} s "
                "(what is not traced yet is drawn untraced)")

    def _progressive(self) -> bool:
        """Traced chains drawn untraced while the view moves and traced in strips once it is
        still: a scene that traces, without SSR (its pass reads the whole frame) and brute-force
        IBL (which averages whole frames); those trace every full frame at once."""
        r = self.scene.render
        return self.renderer.traces(self.scene) and not r.ssr and r.ibl != "brute_force"

    def render_view(self, size, interacting: bool = False) -> None:
        """Render the raster image for a view of ``size`` = (w, h) pixels if anything changed:
        at half resolution without MSAA while the user drags (software GL is slow), at full
        quality once the interaction pauses; brute-force IBL keeps averaging frames."""
        rw_full, rh_full = size
        if self.compare.mode == "reference":
            self.dirty = False  # no raster image is shown; the reference restarts on its own key
            return
        if rw_full <= 0 or rh_full <= 0:
            return
        scale = 0.5 if interacting else 1.0
        rw, rh = max(1, int(rw_full * scale)), max(1, int(rh_full * scale))
        want_full = not interacting and self.quality == "preview"
        progressive = (self.tracing or self.tiling
                       or (self.scene.render.ibl == "brute_force" and self.bf_count < BF_FRAMES)) and not interacting
        stale = self.hdr is None or self._hdr_for != (rw_full, rh_full)
        if self._awaiting is not None and self.compile_ahead.answered(self._awaiting):
            self._awaiting = None
            self.dirty = True  # the programs are ready: draw the material as it now is
        if self.preparing:
            self._prepare_step()
        self._watch_environment()
        if not (self.dirty or want_full or stale or progressive):
            return
        t1 = time.perf_counter()
        restart = self.dirty or want_full or stale
        whole_from = None
        if restart:
            self.bf_count, self._bf_sum = 0, None
        traced = self._progressive()
        quality = "preview" if interacting else "full"
        held = self._held_back(False if traced and interacting else None, False if traced else None, stale) \
            if self._compile_ahead_on else None
        source = None
        try:
            if held is KEEP_IMAGE:
                quality = self.quality
            elif traced and not interacting and held is None:  # still: untraced, then traced in strips
                quality = self._trace_step(rw, rh, restart)
                source = FrameSource(self.scene, dict(self.scene.materials), "own")
            else:
                if self._trace is not None:
                    self._trace.cancel()
                # held: a changed material's programs compile beside, so it is drawn as it was
                # (not "preview" when still: that would draw it again each frame until the
                # answer comes, which marks the view dirty by itself)
                drawn = self.scene if held is None or held is UNTRACED else held
                form = ("own" if held is None else "untraced" if held is UNTRACED
                        else "stand-in" if getattr(held, "stand_in", False) else "held")
                source = FrameSource(self.scene, dict(drawn.materials), form)
                if not interacting and self._tiled(drawn, rw, rh):
                    quality = self._tile_step(drawn, rw, rh, restart)
                    source = dataclasses.replace(source, under=self._tiles_under)
                else:
                    if self._tiles is not None:
                        self._tiles.cancel()
                    t2 = time.perf_counter()
                    self.hdr = self.renderer.render(drawn, self.camera, rw, rh, self.view_mode,
                                                    msaa=0 if interacting else None, frame_index=self.bf_count,
                                                    raytrace=False if traced else None)
                    if drawn.render.ibl == "brute_force" and not interacting:
                        self.hdr = self._accumulate(self.hdr)
                    elif not interacting:
                        whole_from = t2  # a whole still frame: its cost, once finished below
            if held is None:  # what a held frame may show of these materials while others compile
                self._drawn_materials = (self.scene, dict(self.scene.materials))
            if held is not KEEP_IMAGE:
                self._drawn_view = self._view_key()
                self.frame_source = source
        except ViewerError as e:  # e.g. a shader that never compiled: keep the last image
            self.notify(str(e), error=True)
        self.ctx.finish()
        if whole_from is not None:
            self._whole_s = ((rw, rh), time.perf_counter() - whole_from, drawn.objects)
        if quality == "full" and self.hdr is not None:
            self._check_finite(self.hdr)
        self.raster_version += 1
        self.render_ms = 1000 * (time.perf_counter() - t1)
        self._hdr_for = (rw_full, rh_full)
        self.quality = quality
        self.dirty = False
        self._watch_environment()
        if self._step_timer is not None and not interacting and held is not KEEP_IMAGE:
            self._step_shown()

    @property
    def environment_provisional(self) -> bool:
        """The environment light is drawn with a quick prefilter while the full one runs in the
        background (or failed there)."""
        ibl = self.renderer.ibl()
        return ibl.defer and ibl.provisional is not None

    def _watch_environment(self):
        """A map drawn with a quick prefilter (``viewer.gl.ibl.IBL.defer``): its full prefilter
        in a child process; once the disk cache holds it, the view is drawn again with it."""
        ibl = self.renderer.ibl()
        job = self._env_job
        if job is not None:
            if job.key != ibl.provisional:  # another map now (or the full one is read): not needed
                job.stop()
                self._env_job = job = None
            elif job.ready:
                self._env_job = None
                self.dirty = True  # the next frame reads it from the disk cache
                self.notify(f"environment light: fully prefiltered in the background "
                            f"({time.perf_counter() - job.started:.1f} s)")
                return
            elif job.finished:
                self._env_job = None
                self._env_failed.add(job.key)
                self.notify(f"environment light stays a quick prefilter: {job.error}", error=True)
                return
        if ibl.defer and ibl.provisional is not None and job is None and ibl.provisional not in self._env_failed:
            from viewer.app.prefetch import MapPrefilter

            self._env_job = MapPrefilter(ibl.provisional, ibl.pending_map)
            if self._env_job.error:
                self._env_failed.add(ibl.provisional)
                self.notify(self._env_job.error, error=True)
                self._env_job = None
            else:
                self.notify("environment light: a quick low-resolution prefilter until the full one, "
                            "prefiltered in the background, is ready")

    def _tiled(self, scene, w, h) -> bool:
        """Whether the still view of ``scene`` is drawn in tiles: ``tiled_frames`` on, its last
        whole frame (or tiled one) over ``TILE_BUDGET_S`` (at another size, scaled by the pixels),
        or another scene (its cost not known yet: a lecture step's soap bubbles cost 30 times the
        step before), a frame that tiles (not SSR, whose pass reads the whole frame, nor brute-force
        IBL, which averages whole frames)."""
        if not self._tiles_on or scene.render.ssr or scene.render.ibl == "brute_force":
            return False
        if self.tiling:
            return True
        if self._whole_s is None:
            return False
        (w0, h0), cost, objects = self._whole_s
        # another size (side by side, a resize, lecture mode's strip): the cost scaled by the pixels
        return objects is not scene.objects or cost * (w * h) / max(w0 * h0, 1) > self.tile_budget_s

    def _new_scene(self, scene) -> bool:
        """No frame of ``scene`` was drawn whole yet (another scene was)."""
        return self._whole_s is not None and self._whole_s[2] is not scene.objects

    @property
    def tile_budget_s(self) -> float:
        """A tiled frame's time per frame: ``TILE_BUDGET_S``, or less where the rest of the
        window's frame (``frame_rest_s``: the interface, the view's tone mapping) leaves less of
        ``FRAME_GOAL_S``, though not under 30 ms."""
        return min(TILE_BUDGET_S, max(0.03, FRAME_GOAL_S - self.frame_rest_s))

    def _view_key(self):
        return (self.view_mode, self.camera.fov_y, tuple(self.camera.position), tuple(self.camera.target))

    def _tile_step(self, scene, w, h, restart: bool) -> str:
        """The tiled raster frame: (re)start it, or draw its next tiles; "refining" until it is
        whole. Meanwhile the view shows what it showed (materials edited in the same scene at
        the same size: the new look replaces the old from the top) or its preview (the
        half-resolution frame just drawn while the view moved, else one drawn now)."""
        from viewer.gl.raytrace import ProgressiveTrace

        if self._tiles is None:
            self._tiles = ProgressiveTrace(self.ctx)
        t = self._tiles
        if restart or not t.active:
            under = None
            same = (self._drawn_materials is not None and self._drawn_materials[0] is self.scene
                    and self._drawn_view == self._view_key())  # the same scene seen the same way
            # the preview of this scene just drawn while the view moved, never another scene's
            ours = self.frame_source is not None and self.frame_source.scene is self.scene
            if self.hdr is not None and ours and (self.quality == "preview" or (same and tuple(self.hdr.size) == (w, h))):
                under = self.hdr  # read before any tile draws over the renderer's target
            self._tiles_under = self.frame_source.scene if under is not None else self.scene
            # the first tile: a 32nd of the view (the cost per pixel of a changed material is
            # not known yet); the next follow the time of the last
            self.hdr = t.start(self.renderer, scene, self.camera, w, h, self.view_mode, traced=False,
                               under=under, like_last=same, rows=max(4, h // 32), max_pixels=w * h,
                               preview_scale=4 if self._new_scene(scene) else 2)
            if under is None:  # this frame drew the preview
                return "refining"
        self.hdr = t.step(self.tile_budget_s)
        if not t.done:
            return "refining"
        self._tiles_under = self.scene
        self._whole_s = ((w, h), t.trace_s, scene.objects)
        return "full"

    def _trace_step(self, w, h, restart: bool) -> str:
        """The progressive trace: (re)start it with the untraced view, or trace its next strip;
        "tracing" until the traced image is complete, then "full". Where the untraced frame
        itself is over the tile budget (or its cost is not known: another scene, ray tracing
        just turned on) and the traced-frame cache does not hold the view, the untraced frame is
        drawn in tiles first (``_tile_step``), then traced from it."""
        from viewer.gl.raytrace import ProgressiveTrace

        if self._trace is None:
            self._trace = ProgressiveTrace(self.ctx)
        t = self._trace
        if restart:
            self._untraced_tiles = False
        if (restart or not t.active) and not self._untraced_tiles:
            if self._tiled(self.scene, w, h) and not self._trace_cached(w, h):
                self._untraced_tiles = True
                t.cancel()
        if self._untraced_tiles:
            if self._tile_step(self.scene, w, h, restart) != "full":
                return "tracing"
            self._untraced_tiles = False
            self.hdr = t.start(self.renderer, self.scene, self.camera, w, h, self.view_mode,
                               store=self.lecture_step >= 0, untraced=self.hdr)
            return "tracing" if not t.done else "full"
        if restart or not t.active:
            self.hdr = t.start(self.renderer, self.scene, self.camera, w, h, self.view_mode, cache=True,
                               store=self.lecture_step >= 0)
            if self.environment_provisional:  # a quick prefilter lights it: not for the cache
                t.keep_out_of_cache()
            if t.cache_message:
                self.notify(t.cache_message)
            if not t.from_cache:
                return "tracing"
            self.notify(f"ray traced view from the prepared cache ({t.elapsed_s:.2f} s)")
            return "full"
        self.hdr = t.step(TRACE_BUDGET_S)
        if not t.done:
            return "tracing"
        # the true time: from the still view's first frame to the last tile, frames between included
        self.notify(f"ray traced in {t.elapsed_s:.1f} s ({t.steps} tiles, {t.trace_s:.1f} s of them tracing)")
        return "full"

    def _trace_cached(self, w, h) -> bool:
        """The traced-frame cache holds the still view at (w, h)."""
        from viewer.gl import trace_cache

        key = trace_cache.frame_key(self.scene, self.camera, w, h, self.view_mode, None,
                                    self.ctx.info.get("GL_RENDERER", ""))
        return trace_cache.path_for(key).exists()

    # ------------------------------------------------------------------ Prepare lecture
    def prepare_lecture(self, size=None, steps=None) -> bool:
        """Trace every lecture step with traced chains (``steps``: only those) for the window's
        size (``size`` = (w, h) framebuffer pixels; by default ``window_px``, which the window
        sets each frame, else the view's last size) into the traced-frame cache, in a child
        process (``viewer.app.lecture_prep.BackgroundPrep``: ``bake --lecture``), so that every
        layout of a window of that size finds its steps prepared. Again while it runs: cancelled."""
        from viewer.app.lecture_prep import BackgroundPrep

        if self.preparing:
            self.prep.cancel()
            self.notify("Prepare lecture cancelled")
            return False
        size = size or self.window_px or self._hdr_for
        if not size or size[0] <= 0 or size[1] <= 0:
            self.notify("Prepare lecture: no view to size it by yet (draw a frame first)", error=True)
            return False
        self.prep = BackgroundPrep(size, steps)
        self.notify(self.prep.progress_text(), error=bool(self.prep.error))
        return not self.prep.error

    def _prepare_step(self):
        """What the preparation's child said since the last frame, as the view's messages."""
        results = self.prep.poll()
        for msg in self.prep.messages:
            self.notify(msg)
        self.prep.messages.clear()
        if self.prep.error:
            self.notify(self.prep.error, error=True)
        elif results and self.prep.done:
            traced = [r for r in self.prep.results if not r.cached]
            self.notify(f"{self.prep.progress_text()} ({len(self.prep.results)} steps, {len(traced)} traced now)")
        elif results or self.prep.done:
            self.notify(self.prep.progress_text())

    def _keep_view(self):
        """Copy the view's image into a texture of the session's own unless it has one already
        (the trace's, the brute-force mean's, this copy)."""
        own = [x for x in (self._trace and self._trace.texture, self._bf_tex, self._shown and self._shown[0]) if x]
        if self.hdr is None or any(self.hdr is x for x in own):
            return
        size = self.hdr.size
        if self._shown is None or self._shown[0].size != size:
            if self._shown is not None:
                release_gl(self._shown[1], self._shown[0])
            tex = self.ctx.texture(size, 4, dtype="f4")
            tex.filter = (self.ctx.NEAREST, self.ctx.NEAREST)
            self._shown = (tex, self.ctx.framebuffer(color_attachments=[tex]))
        src = self.ctx.framebuffer(color_attachments=[self.hdr])
        try:
            self.ctx.copy_framebuffer(self._shown[1], src)
        finally:
            release_gl(src)
        self.hdr = self._shown[0]

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
        if self.compare.metrics_for != rv.key:  # taken on another scene or view: gone with it
            self.compare.forget_metrics()
        # the raster as the scene now is: whole, at full quality, no material drawn as it was
        if self.compare.mode != "reference" and self.quality == "full" and self.hdr is not None \
                and self._awaiting is None and not self.pending:
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

    def _accumulate(self, hdr):
        """Brute-force IBL: the running mean of frames with new sample sets (as the offscreen
        ``render_arrays(frames=K)``), shown while it converges."""
        from viewer.app.compare_view import upload_rgb

        img = self.renderer.read_linear(hdr).astype(np.float64)
        self._bf_sum = img if self._bf_sum is None else self._bf_sum + img
        self.bf_count += 1
        self._bf_tex = upload_rgb(self.ctx, self._bf_tex, self._bf_sum / self.bf_count)
        return self._bf_tex

    def _check_finite(self, hdr):
        """Say in one line (a notification and stderr, once per distinct message) when the view
        holds NaN or Inf pixels: a renderer bug the class would see as holes. The texels are
        tested as read (no flipped copy, no mask: a frame at 1456x1080 costs a quarter of that);
        only a frame with such pixels is read again to name them."""
        from viewer.finite import nonfinite_message, render_switches

        try:
            msg = None
            if not np.isfinite(np.frombuffer(hdr.read(), dtype="f4")).all():  # alpha too: then looked at closely
                msg = nonfinite_message(self.renderer.read_linear(hdr), f"view of {self.scene.label}", (),
                                        render_switches(self.scene))
        except Exception:  # noqa: BLE001 - a lost target is no reason to stop drawing
            return
        self.nonfinite = msg
        if msg and msg != self._nonfinite_said:
            self.notify(msg, error=True)
            print("brdf-viewer: " + msg, file=sys.stderr, flush=True)
        self._nonfinite_said = msg

    @property
    def compiling(self) -> bool:
        """A changed material's programs are compiling beside the window (``pending`` names
        the materials drawn as they were meanwhile)."""
        return self._awaiting is not None and not self.compile_ahead.answered(self._awaiting)

    @property
    def compile_ready(self) -> bool:
        """The programs the view waits for are ready: the next frame draws the material as it is."""
        return self._awaiting is not None and self.compile_ahead.answered(self._awaiting)

    def _compile_worker(self):
        """The compile-ahead child (started on first use), None when it cannot run."""
        if self.compile_ahead is None:
            from viewer.app.compile_ahead import CompileAhead

            self.compile_ahead = CompileAhead(on_done=lambda: self.wake and self.wake(), on_notice=self.notify)
        return self.compile_ahead if self.compile_ahead.alive else None

    def _held_back(self, rt_now, rt_held, stale: bool):
        """What to draw while programs compile beside the window: None (the scene, now: nothing
        to compile, or no child to compile it), a copy of the scene with the changed materials
        as they were last drawn (their programs are ready), KEEP_IMAGE (the same scene seen the
        same way: the view shown stays), UNTRACED (the scene without its traced chains, whose
        programs are ready) or, for another scene than the one drawn, the scene with the
        materials not ready as grey stand-ins: never another scene's frame or materials.
        ``rt_now`` / ``rt_held``: the traced-chain switch of the frame and of a held one."""
        from viewer.app.compile_ahead import params_key

        from viewer.gl.renderer import frame_switches

        keys = self.renderer.forward_keys(self.scene, raytrace=rt_now)
        progs = self.renderer.programs
        tables = self.renderer.tables
        ssr_on, env_on = frame_switches(self.scene, rt_now)[:2]
        ms_scene = bool(self.scene.render.ms_compensation)

        def needs_tables(p):  # as Renderer._environment builds them: for IBL, SSR and compensation
            return ssr_on or env_on or ms_scene or bool(p.get("multiple_scattering", False))

        missing = [n for n, k in keys.items() if k not in progs
                   or (needs_tables(self.scene.materials[n]) and not tables.ready(self.scene.materials[n]))]
        if not missing:  # drawn with its own programs: nothing is awaited for this scene
            self.pending, self._awaiting = [], None
            return None
        ca = self._compile_worker()
        rid = None if ca is None else ca.request(self.scene, urgent=True)
        done_beside = ca is not None and all(
            (keys[n] in progs or keys[n] in ca.compiled) and params_key(self.scene.materials[n]) in ca.tables
            for n in missing)
        if rid is None or ca.answered(rid) or done_beside:
            # compiled beside (the driver's cache has the programs; the tables come along), or
            # it failed there: compile here, which reports the error as always
            for n in missing:
                data = ca.tables.get(params_key(self.scene.materials[n])) if ca is not None else None
                if data is not None:
                    tables.adopt(self.scene.materials[n], data)
            self.pending = []
            return None
        drawn_scene, drawn = self._drawn_materials or (None, {})
        # the same scene with materials edited (another scene, e.g. a lecture step, is never
        # mixed with what was drawn before: it is drawn itself, untraced or with stand-ins)
        before = {n: drawn.get(n) for n in missing} if drawn_scene is self.scene else {}
        out, how = None, "drawn as before until ready"
        if before and all(p is not None for p in before.values()):
            held = dataclasses.replace(self.scene, materials={**self.scene.materials, **before})
            if all(k in progs for k in self.renderer.forward_keys(held, raytrace=rt_held).values()):
                out = held
        if out is None and not stale and drawn_scene is self.scene:
            out = KEEP_IMAGE  # the same scene seen the same way: the view shown stays
        if out is None and rt_held is False and self.renderer.traces(self.scene):
            untraced = self.renderer.forward_keys(self.scene, raytrace=False)
            if all(untraced[n] in progs and (not needs_tables(self.scene.materials[n])
                                             or tables.ready(self.scene.materials[n])) for n in untraced):
                out, how = UNTRACED, "drawn untraced until ready"
        if out is None:  # another scene: its own objects, the materials not ready as stand-ins
            out, how = self._stand_in(missing), "drawn with grey stand-ins until ready"
        if self._awaiting != rid:
            self.notify(f"compiling {', '.join(missing)} in the background: {how}")
            self._compile_note = self.messages[-1]
        self._awaiting = rid
        self.pending = missing
        return out

    def _stand_in(self, missing):
        """The scene with ``missing`` materials as grey Lambert stand-ins (``STAND_IN_ALBEDO``):
        its own objects, drawn with the cheapest program there is (compiled here if it must be,
        a fraction of what the missing ones cost) while theirs compile beside."""
        from viewer import brdf

        grey = brdf.get("lambert").params(albedo=[STAND_IN_ALBEDO] * 3)
        out = dataclasses.replace(self.scene, materials={**self.scene.materials, **{n: grey for n in missing}})
        out.stand_in = True  # FrameSource.form "stand-in"
        return out

    @property
    def warming(self) -> bool:
        """Idle-time warm-up still to do on this thread: models to compile (no compile-ahead
        child), or presets still to send to the child (one per ``warm_one``)."""
        if self._compile_ahead_on:
            if not self.presets_ahead or self._ahead_sent == []:
                return False
            return self.compile_ahead is None or self.compile_ahead.alive
        return bool(self.warm)

    @property
    def view_finished(self) -> bool:
        """The view is as it will stay until something changes (what ``--screenshot`` waits for):
        the raster whole at full quality (no tiles, traced strips or averaging still to come), no
        material drawn as it was while its programs compile, and where the view shows the
        reference, a pass of it (not the coarse preview) and its metrics taken on it, or the
        one line saying why there is none."""
        if self.dirty or self.quality != "full" or self.refining or self._awaiting is not None or self.pending:
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

    @property
    def warms_beside(self) -> bool:
        """The idle-time warm-up goes to the compile-ahead child (a preset's scene sent per step,
        no frame needed), not compiled on this thread."""
        return self._compile_ahead_on

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
        if self._awaiting is not None:
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

    def warm_one(self) -> None:
        """Compile one model's forward program while idle, so switching models later does not
        wait for the shader compiler (software GL compiles take 0.1-0.5 s each). With the
        compile-ahead child: ask it once for the scene's presets on its first material instead,
        and nothing compiles here."""
        from viewer import brdf

        if self._compile_ahead_on:
            if self.presets_ahead:
                self._warm_presets_ahead()
            return
        if not self.warm:
            return
        name = self.warm.pop(0)
        try:
            self.renderer.forward_program(brdf.get(name).params())
        except ViewerError as e:
            self.notify(str(e), error=True)

    def _ask_ahead(self, step: int) -> None:
        from viewer.lecture import tour_scene

        ca = self._compile_worker()
        if ca is not None:
            try:
                ca.request(tour_scene(step), urgent=False)
            except ViewerError:
                pass  # the step reports its own problem when it opens

    def _warm_presets_ahead(self) -> None:
        """The presets the material picker offers, each on the scene's first non-plane object,
        sent to the compile-ahead child behind any urgent request, one per idle frame (writing
        a scene's text takes milliseconds)."""
        import dataclasses

        from viewer.brdf.presets import PRESETS
        from viewer.scene import material_from_name

        if self._ahead_sent is False:
            self._ahead_sent = sorted(PRESETS)
        if not self._ahead_sent:
            return
        preset = self._ahead_sent.pop(0)
        ca = self._compile_worker()
        objs = [o for o in self.scene.objects if o.mesh != "plane"] or self.scene.objects
        if ca is None or not objs:
            self._ahead_sent = []
            return
        try:
            params = material_from_name(preset)
        except ViewerError:
            return
        name = objs[0].material
        ca.request(dataclasses.replace(self.scene, materials={**self.scene.materials, name: params}), urgent=False)

    def reference_view(self):
        if self.reference is None:
            from viewer.app.reference_view import ReferenceView

            self.reference = ReferenceView(self.ctx, wake=self.wake)
        return self.reference

    def cycle_strategy(self) -> str:
        """The reference's next way of reaching the light (MIS, BSDF sampling alone, light
        sampling alone; the S key): it restarts with it. Returns the strategy now used."""
        from viewer.pathtracer.integrator import STRATEGIES, STRATEGY_LABELS

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

    # ------------------------------------------------------------------ camera and display
    def changed(self) -> None:
        """Something the raster image depends on changed: render it again (and restart the
        brute-force average)."""
        self.dirty = True

    def reset_camera(self) -> None:
        self.camera.reset()
        self.dirty = True

    def fit_camera(self) -> None:
        self.camera.fit(*self.scene.bounds())
        self.dirty = True

    @property
    def image_mode(self) -> str:
        return self.compare.mode

    def set_image_mode(self, mode: str):
        """One of ``compare_view.MODES``: raster, reference, split, side by side, difference,
        relative difference. Modes without the reference stop its render (no CPU spent). The
        raster image shown stays (a mode whose raster has another size, side by side, draws it
        anew; one after the reference alone, which draws no raster, too)."""
        from viewer.app.compare_view import MODES

        if mode not in MODES:
            raise ViewerError(f"image mode {mode!r}: unknown; allowed: {', '.join(MODES)}")
        was, self.compare.mode = self.compare.mode, mode
        if not self.compare.uses_reference and not self.monte_carlo.active and self.reference is not None:
            self.reference.stop()
        if was == "reference" or self.hdr is None:
            self.dirty = True

    def cycle_image_mode(self) -> None:
        from viewer.app.compare_view import MODES

        self.set_image_mode(MODES[(MODES.index(self.compare.mode) + 1) % len(MODES)])

    def set_view_mode(self, index: int) -> None:
        """One of ``viewer.gl.renderer.VIEW_MODES`` by index (shaded, normals, ...)."""
        from viewer.gl.renderer import VIEW_MODES

        if not 0 <= int(index) < len(VIEW_MODES):
            self.notify(f"view {index}: unknown; allowed 0..{len(VIEW_MODES) - 1}", error=True)
            return
        self.view_mode = int(index)
        self.dirty = True

    @property
    def reflection_mode(self) -> str:
        from viewer.app.reflections import reflection_mode

        return reflection_mode(self.scene.render)

    def set_reflection_mode(self, mode: str, ssr_on_glossy: bool | None = None) -> bool:
        """Reflections / refraction: off, SSR or ray traced (``viewer.app.reflections``)."""
        from viewer.app.reflections import MODES, set_reflection_mode

        if mode not in MODES:
            self.notify(f"reflections {mode!r}: unknown; allowed: {', '.join(MODES)}", error=True)
            return False
        if set_reflection_mode(self.scene.render, mode, ssr_on_glossy=ssr_on_glossy):
            self.dirty = True
            return True
        return False

    # ------------------------------------------------------------------ lecture mode
    def lecture(self, step: int | None):
        """Show the lecture tour's ``step`` (0-based; None ends lecture mode). The step's scene
        replaces the current one; a step that fails to load leaves the scene as it was."""
        from viewer.lecture import TOUR, tour_scene

        if step is None:
            self.lecture_step = -1
            self.notify("lecture mode off")
            for listener in self.step_listeners:
                listener(None)
            return True
        step %= len(TOUR)
        t0 = time.perf_counter()
        try:
            scene = tour_scene(step)
        except ViewerError as e:
            self.notify(f"lecture step {step + 1} not loaded: {e}", error=True)
            return False
        self._set_scene(scene)
        self._enter_step(step)
        self.notify(f"lecture {step + 1}/{len(TOUR)}: {TOUR[step].title} (loading...)")
        self._step_timer = (step, t0)  # the true time: until the step's first full frame is drawn
        return True

    def lecture_next(self):
        from viewer.lecture import TOUR

        return self.lecture((self.lecture_step + 1) % len(TOUR))

    def lecture_previous(self):
        """The step before (from lecture mode off: the last one)."""
        from viewer.lecture import TOUR

        return self.lecture((max(self.lecture_step, 0) - 1) % len(TOUR))

    def lecture_back(self):
        """The key / strip's previous step (from the first: the last)."""
        from viewer.lecture import TOUR

        return self.lecture((self.lecture_step - 1) % len(TOUR))

    @property
    def lecture_title(self) -> tuple[str, str]:
        """("3/15  Total internal reflection", caption) of the step shown, ("", "") when off."""
        from viewer.lecture import TOUR

        if self.lecture_step < 0:
            return "", ""
        s = TOUR[self.lecture_step]
        return f"{self.lecture_step + 1}/{len(TOUR)}  {s.title}", s.caption

    def step_plot(self, step: int) -> dict:
        """What the plots show beside ``step``: its tab (or None), light from inside (the
        critical angle), the materials plotted (the step's subjects, not the floor)."""
        from viewer.lecture import TOUR

        return dict(tab=STEP_TABS.get(TOUR[step].plot), inside=TOUR[step].key == "tir",
                    shown={name: name != "floor" for name in self.scene.materials})

    def _step_shown(self):
        """The step's first frame is drawn (its preview where the view is drawn in tiles, its
        untraced view where it traces): say how long the key press took to show it."""
        from viewer.lecture import TOUR

        step, t0 = self._step_timer
        self._step_timer = None
        if step != self.lecture_step:
            return
        dt = time.perf_counter() - t0
        why = ""
        st = getattr(self.renderer.ibl(), "stats", {})
        if st.get("provisional"):
            why = "; the environment light is a quick prefilter until the full one is ready (in the background)"
        elif st.get("prefilter_passes"):
            why = f"; the environment map was prefiltered in {st.get('prefilter_s', 0.0):.1f} s, cached from now on"
        self.notify(f"lecture {step + 1}/{len(TOUR)}: {TOUR[step].title} ({dt:.2f} s{why})")

    def _enter_step(self, step: int):
        """Lecture mode on at ``step`` for the scene already shown."""
        from viewer.lecture import TOUR

        self.lecture_step = step
        if self.prefetch is None and self._prefetch_on:  # the tour's other maps, prefiltered in the background
            from viewer.app.prefetch import Prefetch

            self.prefetch = Prefetch(step)
        if TOUR[step].image:  # a step about the reference shows it
            self.set_image_mode(TOUR[step].image)
        if self._compile_ahead_on and step + 1 < len(TOUR):  # the next step's programs, compiled ahead
            self._ask_ahead(step + 1)
        for listener in self.step_listeners:
            listener(step)

    # ------------------------------------------------------------------ screenshots and state
    def take_screenshot(self, path=None, size=None, capture=None) -> Path | None:
        """Save the view as a PNG (atomic) with the scene and parameters in its text chunks.
        ``size``: the view's (w, h); the raster alone is rendered afresh at it. ``capture``: a
        function returning the view as shown ((H, W, 3) uint8), used for the compare views and
        error maps (the window's); without one they fall back to the raster."""
        from viewer.gl.renderer import VIEW_MODES
        from viewer.io import write_png
        from viewer.screenshot import png_text

        if path is None:
            stamp = datetime.datetime.now().strftime("%Y%m%d-%H%M%S")
            path = self.screenshot_dir / f"brdf-viewer-{stamp}.png"
        vw, vh = size if size is not None else (self.scene.camera.width, self.scene.camera.height)
        if vw == 0 or vh == 0:
            self.notify("screenshot skipped: the window is minimized", error=True)
            return None
        try:
            extra = {"view": list(VIEW_MODES)[self.view_mode], "image": self.compare.mode}
            if capture is None or (self.compare.mode == "raster" and not self.monte_carlo.active):
                # the raster alone, as shown when the view holds it at full quality (a traced
                # view, finished or not, is saved as it stands: nothing waits, nothing restarts);
                # otherwise rendered afresh at the view's size
                shown = self.hdr is not None and not self.dirty and self.quality in ("full", "tracing")
                if shown and tuple(self.hdr.size) == (vw, vh):
                    srgb = self.renderer.read_srgb(self.hdr, self.scene.render.exposure, self.scene.render.tonemap)
                else:
                    srgb = self.render_image(vw, vh)
                    self.dirty = True  # the renderer's target was drawn over
            else:  # what the view shows: split, side by side, heat map with its colour bar, labels
                srgb = capture()
                if self.metrics_text():
                    extra["metrics"] = self.metrics_text()
            write_png(path, srgb, png_text(self.scene, self.camera, extra))
        except (OSError, ViewerError) as e:
            self.notify(f"screenshot failed: {e}", error=True)
            return None
        self.notify(f"saved {path}")
        print(self.status, file=sys.stderr)
        return Path(path)

    def state_entries(self) -> dict:
        """The session's part of the saved state."""
        return dict(compare_mode=self.compare.mode, split=self.compare.split, view_mode=self.view_mode,
                    scene_digest=scene_digest(self.scene))

    def save_state(self, window: dict | None = None, path: os.PathLike | None = None) -> bool:
        """The state for the next start (the session's entries and the window's, ``window``) and
        the scene as last_scene.toml next to it, both written atomically. A problem is reported
        on stderr and returns False: the session is never lost to a state file."""
        from viewer.app import state as state_mod
        from viewer.io import atomic_write_bytes
        from viewer.scene import scene_to_toml
        from viewer.screenshot import scene_with_camera

        st = dict(self.state)
        st.update(window or {})
        st.update(self.state_entries())
        try:
            state_mod.save_state(st, path)
            text = scene_to_toml(scene_with_camera(self.scene, self.camera))
            last = state_mod.last_scene_path() if path is None else Path(path).with_name("last_scene.toml")
            atomic_write_bytes(last, text.encode("utf-8"))
        except Exception as e:  # noqa: BLE001 - never lose the session to a state-file problem
            print(f"brdf-viewer: window state not saved: {type(e).__name__}: {e}", file=sys.stderr)
            return False
        self.state = st
        return True
