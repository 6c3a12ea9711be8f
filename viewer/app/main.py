"""The interactive viewer: a glfw window (OpenGL 4.1 core, forward-compatible) with imgui-bundle's
native glfw + opengl3 backends, showing a ``viewer.app.session.Session`` (the scene, the renderer
and every action) through the panels of ``viewer.app.panels``.

Controls: left drag orbit, right or middle drag pan, wheel dolly, double-click or R reset,
F12 screenshot (PNG whose text chunks hold the scene and all parameters), C cycle the compare
views, S the reference's sampling strategy (MIS, BSDF, light), P the BRDF plots, L lecture mode
(then 1-9 and 0 for steps 1-10, Shift 1-5 for 11-15, the arrow / page keys step the tour), H hide
the UI, F11 fullscreen, Ctrl + / Ctrl - the UI scale (through ``layout.UI_SCALES``: 1, 1.25, 1.5,
2...), Ctrl 0 scale 1. Files dropped on the window load by kind: .toml / .png scenes, .hdr / .exr
environment maps, meshes (.obj .ply .stl .off .glb .gltf)."""

from __future__ import annotations

import ctypes
import os
import signal
import sys
import time
from pathlib import Path

import numpy as np

from viewer import ViewerError
from viewer.app.capture import Capture
from viewer.app.input_keys import InputKeys
from viewer.app.pacing import Pacing
from viewer.app.parts import Part
from viewer.app.window_geometry import WindowGeometry
from viewer.gl.context import GL_REQUIRED, GLUnavailable

# "0" turns the compile-ahead child off (viewer/app/compile_ahead.py): programs then compile on
# the window's thread, as with --no-compile-ahead
COMPILE_AHEAD_ENV = "BRDF_VIEWER_COMPILE_AHEAD"
# "0" draws every still frame whole, however long it takes (Session's tiled_frames off)
TILED_FRAMES_ENV = "BRDF_VIEWER_TILED_FRAMES"
# "0" draws a scene's first frame at once, however long its programs take (Session's
# prepare_frames off: viewer/app/view_prep.py)
PREPARE_FRAMES_ENV = "BRDF_VIEWER_PREPARE_FRAMES"
# "0" computes the plots' data on the window's thread, in the frame that shows them (PlotsPanel's
# background off)
PLOT_WORKER_ENV = "BRDF_VIEWER_PLOT_WORKER"



def window_state(ui_scale: float, show_ui: bool, plots_visible: bool, pos_size, size_failed: bool,
                 window_px) -> dict:
    """What the window writes to the state file at exit: its UI, its windowed place and size
    ``pos_size`` = (x, y, w, h) unless a frame failed at that size (``size_failed``) or it is under
    64 px, and the framebuffer it drew into (``window_px``: full screen, HiDPI), which
    ``bake --lecture`` prepares when given no size."""
    x, y, w, h = pos_size
    st = dict(ui_scale=ui_scale, show_ui=show_ui, plots_visible=plots_visible)
    if not size_failed and w >= 64 and h >= 64:
        st.update(window_width=w, window_height=h, window_x=x, window_y=y)
    if window_px:
        st.update(framebuffer_width=window_px[0], framebuffer_height=window_px[1])
    return st

class App:
    """The window: glfw, the imgui backends, the frame and the toasts. ``session`` holds the
    scene and the actions; the panels draw it. Its other jobs are parts of its own that it holds
    and passes itself to, as ``Session`` does: ``keys`` (``viewer.app.input_keys.InputKeys``:
    glfw's callbacks, the mouse, the keys' actions), ``pacing`` (``viewer.app.pacing.Pacing``:
    the loop's next step and one turn of it), ``capture`` (``viewer.app.capture.Capture``:
    the window or the view as drawn, screenshots) and ``geometry``
    (``viewer.app.window_geometry.WindowGeometry``: the sizes, read once a frame, the layout, the
    view's rectangle, fullscreen); the parts' actions scripts and tests call are
    the window's too (``Part``: ``app.tick`` is ``app.pacing.tick``).

    The loop (``run``, one ``tick`` per turn) draws while anything changes and otherwise waits on
    the window system's events (``Pacing.loop_wait`` chooses, from the state alone): while
    something on screen changes with time (a toast, the CPU reference's passes, the lecture
    maps' prefilter) it draws when the reference publishes a pass (its thread wakes the loop), at
    once on any input, and every ``Pacing.IDLE_FRAME_S`` otherwise; once nothing does, it rests: no
    frame at all until input or a wake-up, the hot reloader and the file dialogs polled every
    ``Pacing.POLL_S``. Idle-time warm-up (the presets sent to the compile-ahead child) runs between
    those waits without a frame."""

    TOAST_S = 6.0
    # pacing: the loop
    tick = Part("pacing")
    idle = Part("pacing")
    settled = Part("pacing")
    # capture: the window or the view as drawn, screenshots
    capture_window = Part("capture")
    capture_view = Part("capture")
    take_screenshot = Part("capture")
    # geometry: the window's sizes, its layout, the view's rectangle, fullscreen
    sizes = Part("geometry")
    layout = Part("geometry")
    viewport = Part("geometry")
    view_logical = Part("geometry")
    panel_width = Part("geometry")
    toggle_fullscreen = Part("geometry")
    panel_open = False  # lecture mode: the full panel floats over the view (the strip's "menu")
    ui_scale = 1.0
    show_ui = True
    view_only = False   # one frame of the view alone: no windows, no caption, no toast

    def __init__(self, scene_ref=None, overrides=(), size=None, title="brdf-viewer", restore_state: bool = True,
                 compile_ahead: bool | None = None):
        import glfw
        import moderngl
        from imgui_bundle import imgui, implot

        from viewer.app import state as state_mod
        from viewer.app.plots_panel import PlotsPanel
        from viewer.app.panels.side import SidePanel
        from viewer.app.session import Session
        from viewer.app.shader_overlay import HotReload
        from viewer.app.twin_question import trust_remembered
        from viewer.base.heap import keep_freed_memory
        from viewer.scene import load_scene

        self.t_start = time.perf_counter()
        # the frames' readbacks, tiles and metrics take arrays of megabytes again and again: kept
        # in the heap, and without numpy's huge-page advice, whose first fault may compact memory
        # (a 315 ms first RMSE of a 672x540 reference, 38 ms after; viewer.base.heap)
        keep_freed_memory()
        state = state_mod.load_state() if restore_state else {}
        trust_remembered(state)  # the folders whose numpy twins the user let run before
        scene = load_scene(scene_ref, overrides)  # bad input: ViewerError before any window
        self._save_state_on_close = restore_state
        from_state = size is None  # the state file's size is fitted to the display, an asked one is not
        if size is None:
            size = (state.get("window_width", state_mod.DEFAULT_WINDOW[0]),
                    state.get("window_height", state_mod.DEFAULT_WINDOW[1]))
        self.glfw, self.imgui = glfw, imgui
        self._size_failed = False  # a frame raised: the window's size is not saved for the next start
        self.window = self._open_window(size, title, fit_display=from_state)
        if "window_x" in state and "window_y" in state:
            glfw.set_window_pos(self.window, state["window_x"], state["window_y"])
        glfw.make_context_current(self.window)
        glfw.swap_interval(1)
        self.ctx = moderngl.create_context(require=GL_REQUIRED)
        self._fit_gl_limits()
        imgui.create_context()
        implot.create_context()
        imgui.get_io().set_ini_filename("")  # no imgui.ini in the user's working folder
        self.keys = InputKeys(self)
        self.pacing = Pacing(self)
        self.capture = Capture(self)
        self.geometry = WindowGeometry(self)
        self.keys.install(self.window)  # before imgui's backend, which chains to its callbacks
        imgui.backends.glfw_init_for_opengl(ctypes.cast(self.window, ctypes.c_void_p).value, True)
        imgui.backends.opengl3_init("#version 410")
        self._load_font()
        if compile_ahead is None:  # on unless the environment turns it off (the window tests do)
            compile_ahead = os.environ.get(COMPILE_AHEAD_ENV, "1") != "0"
        tiled = os.environ.get(TILED_FRAMES_ENV, "1") != "0"
        prepared = os.environ.get(PREPARE_FRAMES_ENV, "1") != "0"
        self.session = Session(self.ctx, scene_ref, scene=scene, state=state, compile_ahead=compile_ahead,
                               tiled_frames=tiled, prepare_frames=prepared)
        self.session.step_listeners.append(self._on_step)
        self.session.wake = glfw.post_empty_event  # the reference's thread ends the loop's sleep
        self.hot_reload = HotReload(self.session.renderer)
        self.plots = PlotsPanel()
        self.plots.background = os.environ.get(PLOT_WORKER_ENV, "1") != "0"
        self.plots.wake = glfw.post_empty_event  # a result ready ends the loop's sleep
        self.plots.visible = bool(state.get("plots_visible", False)) and self.session.same_scene
        self.side_panel = SidePanel(self)
        self.set_ui_scale(state.get("ui_scale", 1.0))
        self.show_ui = bool(state.get("show_ui", True))
        self.frame_count = 0
        self.frame_ms = 0.0
        self.first_frame_s = None
        self.first_view_s = None  # the first frame that shows the scene (viewer/app/view_prep.py)
        self._closing = False
        self._said_no_room = False
        if self.session.lecture_step >= 0:  # opened as lecture:N
            self._on_step(self.session.lecture_step)

    def _open_window(self, size, title, fit_display: bool = False):
        glfw = self.glfw
        from viewer.app import window_size
        from viewer.commands.names import HEADLESS_HINT

        if not glfw.init():
            raise GLUnavailable(f"cannot initialise glfw (no display?); {HEADLESS_HINT}")
        size = window_size.fit(size, *window_size.monitor_bound(glfw)) if fit_display else \
            window_size.fit(size, None, "")
        glfw.window_hint(glfw.CONTEXT_VERSION_MAJOR, GL_REQUIRED // 100)
        glfw.window_hint(glfw.CONTEXT_VERSION_MINOR, (GL_REQUIRED % 100) // 10)
        glfw.window_hint(glfw.OPENGL_PROFILE, glfw.OPENGL_CORE_PROFILE)
        glfw.window_hint(glfw.OPENGL_FORWARD_COMPAT, True)
        window = glfw.create_window(int(size[0]), int(size[1]), title, None, None)
        if not window:
            glfw.terminate()
            raise GLUnavailable("cannot create an OpenGL 4.1 core window: this viewer needs OpenGL 4.1 "
                                f"(update the graphics driver); {HEADLESS_HINT}")
        return window

    def _fit_gl_limits(self) -> None:
        """Shrink the window whose framebuffer is larger than the context draws (its textures,
        renderbuffers and viewport), with one line on stderr."""
        from viewer.app import window_size

        side = window_size.gl_bound(self.ctx.info)
        fw, fh = self.glfw.get_framebuffer_size(self.window)
        if fw <= side and fh <= side:
            return
        ww, wh = self.glfw.get_window_size(self.window)
        sx, sy = fw / max(ww, 1), fh / max(wh, 1)  # framebuffer pixels per window point
        w, h = window_size.fit((ww, wh), (int(side / sx), int(side / sy)), "this OpenGL's largest framebuffer")
        self.glfw.set_window_size(self.window, w, h)

    def _on_step(self, step):
        """Lecture mode shows ``step`` (None: it ended): the step's plot beside its scene."""
        if step is None:
            self.panel_open = False
            return
        p = self.session.step_plot(step)
        if p["tab"]:
            self.plots.select_tab(p["tab"])
            self.plots.visible = True
        self.plots.inside = p["inside"]  # the critical angle needs light from inside
        for name, shown in p["shown"].items():
            self.plots.shown[name] = shown

    # ------------------------------------------------------------------ lifecycle
    def request_close(self, *_):
        from viewer.gl.file_probe import cancel_all

        self._closing = True
        cancel_all()  # a file's test render the frame waits on ends now: the window closes at once
        try:
            self.glfw.set_window_should_close(self.window, True)
        except Exception:  # noqa: BLE001 - during teardown the window may be gone
            pass

    def should_close(self) -> bool:
        return self._closing or bool(self.glfw.window_should_close(self.window))

    def run(self, frames: int = 0, screenshot: str | None = None) -> int:
        old = signal.signal(signal.SIGTERM, self.request_close)
        try:
            waited_from = None
            while not self.should_close():
                try:
                    self.tick()
                except Exception:
                    self._size_failed = True  # never saved: the next start must not fail again
                    raise
                if frames and self.frame_count >= frames:
                    if screenshot and not self._finished_for(waited_from):
                        waited_from = waited_from or time.perf_counter()
                        continue
                    if screenshot and self.capture.take_screenshot(screenshot) is None:
                        print(f"brdf-viewer: error: {self.session.status}", file=sys.stderr)
                        return 2
                    break
        finally:
            signal.signal(signal.SIGTERM, old)
            self.close()
        return 0

    SCREENSHOT_WAIT_S = 600.0  # --screenshot: the longest wait for the finished frame

    def _finished_for(self, waited_from) -> bool:
        """``--screenshot``: the view is finished (``Session.view_finished``), or it has been waited
        for ``SCREENSHOT_WAIT_S`` (then saved as it stands, with one line saying so)."""
        if self.session.view_finished:
            return True
        if waited_from is not None and time.perf_counter() - waited_from > self.SCREENSHOT_WAIT_S:
            print(f"brdf-viewer: --screenshot: the view was not finished after {self.SCREENSHOT_WAIT_S:.0f} s "
                  f"({', '.join(self.session.pending_work()) or 'the reference'}); saved as it stands",
                  file=sys.stderr)
            return True
        return False

    def close(self):
        if self.window is None:
            return
        imgui = self.imgui
        if self._save_state_on_close:
            self.save_state()
        self.session.release()
        self.plots.close()
        imgui.backends.opengl3_shutdown()
        imgui.backends.glfw_shutdown()
        from imgui_bundle import implot

        implot.destroy_context()
        imgui.destroy_context()
        self.ctx.release()
        self.glfw.destroy_window(self.window)
        self.glfw.terminate()
        self.window = None

    def save_state(self) -> bool:
        """The window's state for the next start, and the scene as last_scene.toml (atomic)."""
        try:
            x, y, w, h = self.geometry.window_rect()
        except Exception as e:  # noqa: BLE001 - never lose the session to a state-file problem
            print(f"brdf-viewer: window state not saved: {type(e).__name__}: {e}", file=sys.stderr)
            return False
        st = window_state(self.ui_scale, self.show_ui, self.plots.visible, (x, y, w, h), self._size_failed,
                          self.session.window_px)
        if self._size_failed:  # neither this size nor the one restored: the next start opens at the default
            for k in ("window_width", "window_height", "window_x", "window_y"):
                self.session.state.pop(k, None)
        return self.session.save_state(st)

    def overlay_plan(self):
        """The view's overlays as drawn this frame: (layout, texts); see ``layout.overlay_layout``."""
        from viewer.app.panels import overlays

        return overlays.plan(self)

    # ------------------------------------------------------------------ frame
    def frame(self, wait: bool = True):
        """Draw one frame (``wait``: while nothing is dirty, wait up to 50 ms for input first)."""
        glfw, s = self.glfw, self.session
        t0 = time.perf_counter()
        if s.dirty or s.quality != "full" or s.refining or not wait:
            glfw.poll_events()
        else:
            glfw.wait_events_timeout(0.05)
        self.pacing.frame_begins()
        try:
            (fw, fh), _ = self.geometry.begin_frame()  # read once: see viewer.app.window_geometry
            if fw == 0 or fh == 0:  # minimized: nothing to draw into
                time.sleep(0.02)
                return
            self._frame(fw, fh, t0)
        finally:
            self.geometry.end_frame()

    def _frame(self, fw, fh, t0):
        from viewer.app.panels import twin_dialog

        glfw, imgui, s = self.glfw, self.imgui, self.session
        s.window_px = (fw, fh)  # what Prepare lecture prepares for
        imgui.backends.opengl3_new_frame()
        imgui.backends.glfw_new_frame()
        imgui.new_frame()
        reloaded = self.hot_reload.poll()
        # a .brdf file saved with other parameters (or ranges): its materials fitted to it
        if s.refit_file_materials() or reloaded:
            s.changed()
        self.side_panel.poll()
        self.keys.handle()
        if self.show_ui and not self.view_only:
            self._draw_panels()
        if not self.view_only:
            self.hot_reload.draw_overlay()
            twin_dialog.draw(imgui, s.twins)  # a .brdf file's numpy twin waits for the user's answer
        view = self.viewport()
        _, _, rw, rh = s.compare.raster_rect(view)
        interacting = self.keys.interacting
        drawn = s.raster_version
        s.render_view((rw, rh), interacting=interacting)
        _, _, ref_w, ref_h = s.compare.reference_rect(view)
        ref_tex = s.update_reference((ref_w, ref_h), interacting) if view[2] > 0 and view[3] > 0 else None
        self._draw_view(fw, fh, view, ref_tex)
        imgui.render()
        imgui.backends.opengl3_render_draw_data(imgui.get_draw_data())
        self.capture.frame_drawn(fw, fh)
        glfw.swap_buffers(self.window)
        if not s.dirty:
            s.warm_one()
        self.frame_count += 1
        if self.first_frame_s is None:
            self.first_frame_s = time.perf_counter() - self.t_start
            print(f"brdf-viewer: first frame after {self.first_frame_s:.2f} s", file=sys.stderr, flush=True)
        if self.first_view_s is None and s.hdr is not None and s.frames.prep.on:  # the placeholder's frames before
            self.first_view_s = time.perf_counter() - self.t_start
            print(f"brdf-viewer: first view after {self.first_view_s:.2f} s", file=sys.stderr, flush=True)
        self.frame_ms = 1000 * (time.perf_counter() - t0)
        if s.raster_version != drawn:  # the rest of a frame that drew the view: the tiles' budget
            rest = max(0.0, self.frame_ms - s.render_ms) / 1000
            s.frame_rest_s = rest if s.frame_rest_s == 0.0 else 0.7 * s.frame_rest_s + 0.3 * rest

    def _draw_panels(self):
        from viewer.app.panels import lecture

        s = self.session
        lay = self.layout()
        if s.lecture_step >= 0:
            lecture.draw_strip(self, lay["strip"])
        if "panel" in lay:
            self.side_panel.draw(lay["panel"])
        self.plots.extents = s.extents()
        if "plots" in lay or s.lecture_step < 0:
            self.plots.draw(s.scene.materials, lay.get("plots"))
        elif self.plots.visible and not self._said_no_room:  # never over the lecture's view
            s.notify("the plots need a wider window beside the view (or a smaller UI scale, Ctrl -)")
            self._said_no_room = True
        s.monte_carlo.draw_windows(s.reference)

    def _draw_view(self, fw, fh, view, ref_tex):
        from viewer.app.panels import overlays

        s = self.session
        screen = self.ctx.screen
        screen.use()
        screen.viewport = (0, 0, fw, fh)
        self.ctx.clear(0.08, 0.08, 0.09)
        if view[2] > 0 and view[3] > 0:
            r = s.scene.render
            s.compare.draw(s.renderer, screen, view, s.hdr, ref_tex, r.exposure, r.tonemap)
            s.monte_carlo.draw_view(s.renderer, screen, s.compare.reference_rect(view), s.reference)
            overlays.draw(self)
        screen.viewport = (0, 0, fw, fh)

    # ------------------------------------------------------------------ UI scale, fullscreen
    def _load_font(self):
        """DroidSans from imgui-bundle's assets (imgui >= 1.92 rasterizes fonts at any size, so
        the UI scale stays sharp on a projector); imgui's built-in font when it is missing."""
        import imgui_bundle

        path = Path(imgui_bundle.__file__).parent / "assets" / "fonts" / "DroidSans.ttf"
        if path.exists():
            try:
                self.imgui.get_io().fonts.add_font_from_file_ttf(str(path), 16.0)
            except Exception as e:  # noqa: BLE001 - a font is cosmetic: keep the default
                print(f"brdf-viewer: font {path} not loaded ({e})", file=sys.stderr)

    def set_ui_scale(self, scale: float):
        scale = float(np.clip(scale if np.isfinite(scale) else 1.0, 0.5, 3.0))
        self.ui_scale = scale
        self.imgui.get_style().font_scale_main = scale
        self.session.changed()


def check_writable(path) -> Path:
    """``path``'s folder exists and is writable, or a ViewerError in one line (checked before the
    window opens, so a typo in ``--screenshot`` does not cost the start-up)."""
    p = Path(path).expanduser()
    folder = p.parent if str(p.parent) else Path(".")
    if not folder.is_dir():
        raise ViewerError(f"--screenshot {path}: the folder {folder} does not exist")
    if p.is_dir():
        raise ViewerError(f"--screenshot {path}: is a folder; give a file name ending in .png")
    import tempfile

    try:  # a real probe: permissions, read-only or pseudo file systems, a full disk's quota
        with tempfile.NamedTemporaryFile(dir=folder, prefix=".brdf-viewer-probe-"):
            pass
    except OSError as e:
        raise ViewerError(f"--screenshot {path}: the folder {folder} is not writable ({e.strerror or e})") from None
    return p


def run_app(scene_ref=None, overrides=(), size=None, frames=0, screenshot=None, compile_ahead=None) -> int:
    if screenshot:
        check_writable(screenshot)
    app = App(scene_ref, overrides, size, compile_ahead=compile_ahead)
    return app.run(frames=frames, screenshot=screenshot)
