"""The interactive viewer: a glfw window (OpenGL 4.1 core, forward-compatible) with imgui-bundle's
native glfw + opengl3 backends, the same Renderer as the offscreen path, and an orbit camera.

Controls: left drag orbit, right or middle drag pan, wheel dolly, double-click or R reset,
F12 screenshot (PNG whose text chunks hold the scene and all parameters), C cycle the compare
views, P the BRDF plots, L lecture mode (then 1-9, 0 and the arrow / page keys step the tour),
H hide the UI, F11 fullscreen, Ctrl +/- the UI scale. Files dropped on the window load by kind:
.toml / .png scenes, .hdr / .exr environment maps, meshes (.obj .ply .stl .off .glb .gltf)."""

from __future__ import annotations

import ctypes
import datetime
import os
import signal
import sys
import time
from pathlib import Path

import numpy as np

from viewer import ViewerError
from viewer.gl.context import GL_REQUIRED, GLUnavailable

from viewer.app.layout import PANEL_WIDTH  # noqa: F401 - the side panel's width at UI scale 1

# single-key actions, read from glfw's key callback so a tap shorter than a frame (a presentation
# clicker) is never lost: a slow frame only delays it
_TAP_KEYS = ("h", "f11", "c", "p", "l", "right", "page_down", "space", "left", "page_up", "escape",
             "1", "2", "3", "4", "5", "6", "7", "8", "9", "0", "r", "f12")


def _count(n: int, noun: str) -> str:
    """'1 light', '2 lights', '12,345 triangles'."""
    return f"{n:,} {noun}" + ("" if n == 1 else "s")


class App:
    def __init__(self, scene_ref=None, overrides=(), size=None, title="brdf-viewer", restore_state: bool = True):
        import glfw
        import moderngl
        from imgui_bundle import imgui, implot

        from viewer.camera import OrbitCamera
        from viewer.gl.renderer import Renderer
        from viewer.scene import load_scene

        from viewer.app import state as state_mod

        self.t_start = time.perf_counter()
        self.scene = load_scene(scene_ref, overrides)  # bad input: ViewerError before any window
        self._state = state_mod.load_state() if restore_state else {}
        self._save_state_on_close = restore_state
        if size is None:
            size = (self._state.get("window_width", 1280), self._state.get("window_height", 720))
        if not glfw.init():
            from viewer.cli import HEADLESS_HINT

            raise GLUnavailable(f"cannot initialise glfw (no display?); {HEADLESS_HINT}")
        glfw.window_hint(glfw.CONTEXT_VERSION_MAJOR, GL_REQUIRED // 100)
        glfw.window_hint(glfw.CONTEXT_VERSION_MINOR, (GL_REQUIRED % 100) // 10)
        glfw.window_hint(glfw.OPENGL_PROFILE, glfw.OPENGL_CORE_PROFILE)
        glfw.window_hint(glfw.OPENGL_FORWARD_COMPAT, True)
        self.window = glfw.create_window(int(size[0]), int(size[1]), title, None, None)
        if not self.window:
            glfw.terminate()
            from viewer.cli import HEADLESS_HINT

            raise GLUnavailable("cannot create an OpenGL 4.1 core window: this viewer needs OpenGL 4.1 "
                                f"(update the graphics driver); {HEADLESS_HINT}")
        if "window_x" in self._state and "window_y" in self._state:
            glfw.set_window_pos(self.window, self._state["window_x"], self._state["window_y"])
        glfw.make_context_current(self.window)
        glfw.swap_interval(1)
        self.glfw = glfw
        self.ctx = moderngl.create_context(require=GL_REQUIRED)
        self.imgui = imgui
        imgui.create_context()
        implot.create_context()
        io = imgui.get_io()
        io.set_ini_filename("")  # no imgui.ini in the user's working folder
        self._taps: list[str] = []
        self._tap_codes = {getattr(glfw, "KEY_" + k.upper()): k for k in _TAP_KEYS}
        glfw.set_key_callback(self.window, self._on_key)  # before imgui's backend, which chains to it
        addr = ctypes.cast(self.window, ctypes.c_void_p).value
        imgui.backends.glfw_init_for_opengl(addr, True)
        imgui.backends.opengl3_init("#version 410")
        glfw.set_drop_callback(self.window, self._on_drop)  # imgui installs no drop callback
        self._load_font()
        self.renderer = Renderer(self.ctx)
        self.camera = OrbitCamera.from_scene(self.scene)
        from viewer.app.compare_view import MODES, CompareView
        from viewer.app.plots_panel import PlotsPanel
        from viewer.app.shader_overlay import HotReload

        self.compare = CompareView(self.ctx)
        from viewer.app.monte_carlo import MonteCarloPanel

        self.mc = MonteCarloPanel(self.ctx)  # reference settings, error views, convergence
        self.hot_reload = HotReload(self.renderer)
        self.plots = PlotsPanel()
        self.plots.visible = bool(self._state.get("plots_visible", False))
        self.raster_version = 0
        self.lecture_step = -1  # -1: lecture mode off; else the tour's step shown
        self.set_ui_scale(self._state.get("ui_scale", 1.0))
        self.show_ui = bool(self._state.get("show_ui", True))
        if self._state.get("compare_mode") in MODES:
            self.compare.mode = self._state["compare_mode"]
        self.compare.split = float(self._state.get("split", 0.5))
        self._fullscreen_restore = None
        self.view_mode = 0
        from viewer.gl.renderer import VIEW_MODES

        if 0 <= self._state.get("view_mode", 0) < len(VIEW_MODES):
            self.view_mode = self._state.get("view_mode", 0)
        self.status = ""
        self.dirty = True
        self.hdr = None
        self.frame_count = 0
        self.frame_ms = 0.0
        self.render_ms = 0.0
        self.first_frame_s = None
        self._closing = False
        self._last_interaction = -1.0
        self._quality = "full"
        self._hdr_for = None
        from viewer import brdf

        self._warm = list(brdf.names())
        self.screenshot_dir = Path.cwd()
        from viewer.scene import LECTURE_NAME

        m = LECTURE_NAME.fullmatch(str(scene_ref)) if scene_ref is not None else None
        if m is not None:  # opened as lecture:N: lecture mode at that step
            self._enter_step(int(m.group(1)) - 1)

    # ------------------------------------------------------------------ lifecycle
    def request_close(self, *_):
        self._closing = True
        try:
            self.glfw.set_window_should_close(self.window, True)
        except Exception:  # noqa: BLE001 - during teardown the window may be gone
            pass

    def should_close(self) -> bool:
        return self._closing or bool(self.glfw.window_should_close(self.window))

    def run(self, frames: int = 0, screenshot: str | None = None) -> int:
        old = signal.signal(signal.SIGTERM, self.request_close)
        try:
            while not self.should_close():
                self.frame()
                if frames and self.frame_count >= frames:
                    if screenshot and self.take_screenshot(screenshot) is None:
                        print(f"brdf-viewer: error: {self.status}", file=sys.stderr)
                        return 2
                    break
        finally:
            signal.signal(signal.SIGTERM, old)
            self.close()
        return 0

    def close(self):
        if self.window is None:
            return
        imgui = self.imgui
        if self._save_state_on_close:
            self.save_state()
        if self._reference is not None:
            self._reference.close()
        if self._prefetch is not None:
            self._prefetch.stop()
        self.compare.release()
        self.mc.release()
        self.plots.close()
        if self._bf_tex is not None:
            self._bf_tex.release()
        self.renderer.release()
        imgui.backends.opengl3_shutdown()
        imgui.backends.glfw_shutdown()
        from imgui_bundle import implot

        implot.destroy_context()
        imgui.destroy_context()
        self.ctx.release()
        self.glfw.destroy_window(self.window)
        self.glfw.terminate()
        self.window = None

    # ------------------------------------------------------------------ frame
    panel_open = False  # lecture mode: the full panel floats over the view (the strip's "menu")

    def layout(self):
        """The window's parts (``viewer.app.layout.window_layout``) in window points."""
        from viewer.app.layout import window_layout

        ww, wh = self.glfw.get_window_size(self.window)
        return window_layout(ww, wh, self.ui_scale, show_ui=self.show_ui, lecture=self.lecture_step >= 0,
                             plots=self.plots.visible, panel_open=self.panel_open)

    def viewport(self):
        """The 3D view in framebuffer pixels (x, y from the bottom-left, w, h)."""
        fw, fh = self.glfw.get_framebuffer_size(self.window)
        ww, _ = self.glfw.get_window_size(self.window)
        scale = fw / ww if ww else 1.0
        v = self.layout()["view"]
        x0, x1 = int(round(v.x * scale)), int(round(v.right * scale))
        return x0, 0, max(min(x1, fw) - x0, 0), fh

    def view_logical(self):
        """The 3D view in imgui's coordinates (window points, y down)."""
        return self.layout()["view"].tuple()

    @property
    def panel_width(self) -> int:
        lay = self.layout()
        r = lay.get("strip") or lay.get("panel")
        return int(r.w) if r is not None else 0

    _extents_for = None
    _said_no_room = False

    def _extents(self) -> dict:
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

    def _on_key(self, window, key, scancode, action, mods):
        if action == self.glfw.PRESS and key in self._tap_codes:
            if not mods & (self.glfw.MOD_CONTROL | self.glfw.MOD_ALT | self.glfw.MOD_SUPER):
                self._taps.append(self._tap_codes[key])

    ui_scale = 1.0

    show_ui = True

    def frame(self):
        glfw, imgui = self.glfw, self.imgui
        t0 = time.perf_counter()
        if self.dirty or self._quality != "full" or (self.scene.render.ibl == "brute_force" and self._bf_count < 256):
            glfw.poll_events()
        else:
            glfw.wait_events_timeout(0.05)
        fw, fh = glfw.get_framebuffer_size(self.window)
        if fw == 0 or fh == 0:  # minimized: nothing to draw into
            time.sleep(0.02)
            return
        imgui.backends.opengl3_new_frame()
        imgui.backends.glfw_new_frame()
        imgui.new_frame()
        if self.hot_reload.poll():
            self.dirty = True
        self._poll_dialogs()
        self._handle_input()
        if self.show_ui and not self._view_only:
            lay = self.layout()
            if self.lecture_step >= 0:
                self._strip(lay["strip"])
            if "panel" in lay:
                self._panel(lay["panel"])
            self.plots.extents = self._extents()
            if "plots" in lay or self.lecture_step < 0:
                self.plots.draw(self.scene.materials, lay.get("plots"))
            elif self.plots.visible and not self._said_no_room:  # never over the lecture's view
                self.status = "the plots need a wider window beside the view (or a smaller UI scale, Ctrl -)"
                self._said_no_room = True
            self.mc.draw_windows(self._reference)
        if not self._view_only:
            self.hot_reload.draw_overlay()
        vx, vy, vw, vh = self.viewport()
        view = (vx, vy, vw, vh)
        cmp = self.compare
        _, _, rw_full, rh_full = cmp.raster_rect(view)
        if cmp.mode == "reference":
            self.dirty = False  # no raster image is shown; the reference restarts on its own key
        elif rw_full > 0 and rh_full > 0:
            now = time.perf_counter()
            interacting = now - self._last_interaction < 0.3
            # While the user drags, render at half resolution without MSAA (software GL is slow);
            # a full-quality frame follows as soon as the interaction pauses.
            scale = 0.5 if interacting else 1.0
            rw, rh = max(1, int(rw_full * scale)), max(1, int(rh_full * scale))
            want_full = not interacting and self._quality != "full"
            progressive = self.scene.render.ibl == "brute_force" and not interacting and self._bf_count < 256
            stale = self.hdr is None or self._hdr_for != (rw_full, rh_full)
            if self.dirty or want_full or stale or progressive:
                t1 = time.perf_counter()
                restart = self.dirty or want_full or stale
                if restart:
                    self._bf_count, self._bf_sum = 0, None
                try:
                    self.hdr = self.renderer.render(self.scene, self.camera, rw, rh, self.view_mode,
                                                    msaa=0 if interacting else None, frame_index=self._bf_count)
                    if self.scene.render.ibl == "brute_force" and not interacting:
                        self.hdr = self._accumulate(self.hdr)
                except ViewerError as e:  # e.g. a shader that never compiled: keep the last image
                    self.status = str(e)
                self.ctx.finish()
                if not interacting and self.hdr is not None:
                    self._check_finite(self.hdr)
                self.raster_version += 1
                self.render_ms = 1000 * (time.perf_counter() - t1)
                self._hdr_for = (rw_full, rh_full)
                self._quality = "preview" if interacting else "full"
                self.dirty = False
                if self._step_timer is not None and not interacting:
                    self._step_shown()
        ref_tex = None
        if (cmp.uses_reference or self.mc.active) and vw > 0 and vh > 0:
            _, _, ref_w, ref_h = cmp.reference_rect(view)
            rv = self.reference_view()
            rv.update(self.scene, self.camera, (ref_w, ref_h))
            ref_tex = rv.texture_for_display()
            if cmp.mode != "reference" and self._quality == "full" and self.hdr is not None:
                cmp.update_metrics(self.renderer, self.hdr, self.raster_version, rv)
        screen = self.ctx.screen
        screen.use()
        screen.viewport = (0, 0, fw, fh)
        self.ctx.clear(0.08, 0.08, 0.09)
        if vw > 0 and vh > 0:
            r = self.scene.render
            cmp.draw(self.renderer, screen, view, self.hdr, ref_tex, r.exposure, r.tonemap)
            self.mc.draw_view(self.renderer, screen, cmp.reference_rect(view), self._reference)
            self._overlays()
        screen.viewport = (0, 0, fw, fh)
        imgui.render()
        imgui.backends.opengl3_render_draw_data(imgui.get_draw_data())
        if self._capture_next is not None:
            self._capture_next(self._read_screen(fw, fh))
            self._capture_next = None
        glfw.swap_buffers(self.window)
        if not self.dirty and self._warm:
            self._warm_one()
        self.frame_count += 1
        if self.first_frame_s is None:
            self.first_frame_s = time.perf_counter() - self.t_start
            print(f"brdf-viewer: first frame after {self.first_frame_s:.2f} s", file=sys.stderr, flush=True)
        self.frame_ms = 1000 * (time.perf_counter() - t0)

    _nonfinite_said = None

    def _check_finite(self, hdr):
        """Say in one line (status toast and stderr, once per distinct message) when the view
        holds NaN or Inf pixels: a renderer bug the class would see as holes."""
        from viewer.finite import nonfinite_message, render_switches

        try:
            img = self.renderer.read_linear(hdr)
        except Exception:  # noqa: BLE001 - a lost target is no reason to stop drawing
            return
        msg = nonfinite_message(img, f"view of {self.scene.label}", (), render_switches(self.scene))
        self.nonfinite = msg
        if msg and msg != self._nonfinite_said:
            self.status = msg
            print("brdf-viewer: " + msg, file=sys.stderr, flush=True)
        self._nonfinite_said = msg

    nonfinite = None

    def _handle_input(self):
        imgui = self.imgui
        io = imgui.get_io()
        if imgui.is_any_item_active():  # a slider being dragged counts as interaction
            self._last_interaction = time.perf_counter()
        vx, vy, vw, vh = self.viewport()
        divider = not io.want_capture_mouse and self.compare.handle_mouse(imgui, self.view_logical())
        if not io.want_capture_mouse and not divider:
            d = io.mouse_delta
            if imgui.is_mouse_double_clicked(imgui.MouseButton_.left):
                self.camera.reset()
                self.dirty = True
            elif imgui.is_mouse_dragging(imgui.MouseButton_.left):
                self.camera.orbit(d.x, d.y, vh)
                self.dirty = True
                self._last_interaction = time.perf_counter()
            elif imgui.is_mouse_dragging(imgui.MouseButton_.right) or imgui.is_mouse_dragging(imgui.MouseButton_.middle):
                self.camera.pan(d.x, d.y, vh)
                self.dirty = True
                self._last_interaction = time.perf_counter()
            if io.mouse_wheel != 0.0:
                self.camera.dolly(io.mouse_wheel)
                self.dirty = True
                self._last_interaction = time.perf_counter()
        taps, self._taps = self._taps, []
        if io.want_capture_keyboard:  # typing into a field: the keys are the field's
            return
        K = imgui.Key
        pressed = lambda k: imgui.is_key_pressed(k, False)  # noqa: E731
        if io.key_ctrl:
            if pressed(K.equal) or pressed(K.keypad_add):
                self.set_ui_scale(self.ui_scale * 1.25)
            if pressed(K.minus) or pressed(K.keypad_subtract):
                self.set_ui_scale(self.ui_scale / 1.25)
            if pressed(K._0):
                self.set_ui_scale(1.0)
        for key in taps:
            self.key_action(key)

    def key_action(self, key: str) -> None:
        """One key's action (glfw key names in lower case: "l", "right", "page_down", "1"...)."""
        from viewer.app.compare_view import MODES

        if key == "r":
            self.camera.reset()
            self.dirty = True
        elif key == "f12":
            self.take_screenshot()
        elif key == "h":
            self.show_ui = not self.show_ui
            self.dirty = True
        elif key == "f11":
            self.toggle_fullscreen()
        elif key == "c":
            self.set_image_mode(MODES[(MODES.index(self.compare.mode) + 1) % len(MODES)])
        elif key == "p":
            self.plots.visible = not self.plots.visible
            self.dirty = True
        elif key == "l":
            self.lecture(0 if self.lecture_step < 0 else None)
        elif self.lecture_step >= 0:
            from viewer.lecture import TOUR

            if key in ("right", "page_down", "space"):
                self.lecture((self.lecture_step + 1) % len(TOUR))
            elif key in ("left", "page_up"):
                self.lecture((self.lecture_step - 1) % len(TOUR))
            elif key.isdigit() and (int(key) - 1) % 10 < len(TOUR):
                self.lecture((int(key) - 1) % 10)
            elif key == "escape":
                self.lecture(None)

    # ------------------------------------------------------------------ panel
    def _strip(self, rect):
        """Lecture mode's narrow strip instead of the side panel: menu (the full panel over the
        view), previous / next step, the step number, plots on / off."""
        from viewer.lecture import TOUR

        imgui = self.imgui
        imgui.set_next_window_pos(imgui.ImVec2(rect.x, rect.y))
        imgui.set_next_window_size(imgui.ImVec2(rect.w, rect.h))
        flags = (imgui.WindowFlags_.no_move | imgui.WindowFlags_.no_resize | imgui.WindowFlags_.no_collapse
                 | imgui.WindowFlags_.no_title_bar | imgui.WindowFlags_.no_scrollbar)
        imgui.push_style_var(imgui.StyleVar_.window_padding, imgui.ImVec2(2, 6))
        imgui.begin("##lecture_strip", None, flags)
        bw = imgui.ImVec2(rect.w - 4, 0)
        if imgui.button("=##menu", bw):
            self.panel_open = not self.panel_open
        if imgui.is_item_hovered():
            imgui.set_tooltip("the full panel (settings, materials) over the view")
        if imgui.button("<##prev", bw):
            self.lecture((self.lecture_step - 1) % len(TOUR))
        imgui.text(f"{self.lecture_step + 1}")
        if imgui.button(">##next", bw):
            self.lecture((self.lecture_step + 1) % len(TOUR))
        if imgui.button("P##plots", bw):
            self.plots.visible = not self.plots.visible
        if imgui.is_item_hovered():
            imgui.set_tooltip("BRDF plots (P)")
        if self._prefetch is not None and not self._prefetch.done and self._prefetch.total:
            imgui.text_disabled(f"{self._prefetch.finished}/{self._prefetch.total}")
            if imgui.is_item_hovered():
                imgui.set_tooltip(self._prefetch.progress_text())
        imgui.end()
        imgui.pop_style_var()

    def _panel(self, rect=None):
        from viewer.app import ui
        from viewer.gl.renderer import TONEMAPS, VIEW_MODES

        imgui = self.imgui
        if rect is None:
            rect = self.layout()["panel"]
        imgui.set_next_window_pos(imgui.ImVec2(rect.x, rect.y))
        imgui.set_next_window_size(imgui.ImVec2(rect.w, rect.h))
        flags = imgui.WindowFlags_.no_move | imgui.WindowFlags_.no_resize | imgui.WindowFlags_.no_collapse
        imgui.begin("brdf-viewer", None, flags)
        s = self.scene
        if imgui.collapsing_header("Scene", imgui.TreeNodeFlags_.default_open):
            imgui.text(f"file: {s.label}")
            tris = sum(len(o.mesh_data.indices) for o in s.objects)
            imgui.text(f"{_count(len(s.objects), 'object')}, {_count(tris, 'triangle')}, "
                       f"{_count(len(s.lights), 'light')}")
            imgui.text(f"render {self.render_ms:.1f} ms, frame {self.frame_ms:.1f} ms")
            imgui.text_wrapped(f"GL: {self.ctx.info['GL_RENDERER']}")
            if imgui.button("Reset camera (R)"):
                self.camera.reset()
                self.dirty = True
            imgui.same_line()
            if imgui.button("Fit scene"):
                self.camera.fit(*s.bounds())
                self.dirty = True
        self._file_panel()
        self._lecture_panel()
        if imgui.collapsing_header("Display", imgui.TreeNodeFlags_.default_open):
            from viewer.app.compare_view import MODES

            ch, i = imgui.combo("image (C)", MODES.index(self.compare.mode), list(MODES))
            if ch:
                self.set_image_mode(MODES[i])
            if self.compare.mode == "split":
                ch, v = imgui.slider_float("divider", float(self.compare.split), 0.0, 1.0)
                if ch:
                    self.compare.split = float(np.clip(ui.finite_or(v, 0.5), 0.0, 1.0))
            if self.compare.mode in ("difference", "relative difference"):
                ch, v = imgui.checkbox("auto scale (99th percentile)", self.compare.auto_scale)
                if ch:
                    self.compare.auto_scale = v
                if not self.compare.auto_scale:
                    ch, v = imgui.slider_float("scale", float(self.compare.scale), 1e-4, 10.0, "%.4g",
                                               imgui.SliderFlags_.logarithmic)
                    if ch and np.isfinite(v) and v > 0:
                        self.compare.scale = float(v)
            if self.compare.uses_reference and self._reference is not None:
                rv = self._reference
                imgui.text(f"reference ({rv.engine or '...'}): {rv.spp} spp, "
                           f"{rv.samples_per_second / 1e3:.1f} k samples/s")
                if self.compare.metrics_text():  # the same words as over the image
                    imgui.text_wrapped(self.compare.metrics_text())
                if rv.error:
                    imgui.text_wrapped(rv.error)
            ch, v = imgui.checkbox("BRDF plots (P)", self.plots.visible)
            if ch:
                self.plots.visible = v
            ch, v = imgui.slider_float("UI scale", float(self.ui_scale), 0.5, 3.0, "%.2f")
            if imgui.is_item_hovered():
                imgui.set_tooltip("Ctrl + / Ctrl - / Ctrl 0")
            if ch and np.isfinite(v):
                self.set_ui_scale(v)
            r = s.render
            ch, v = imgui.slider_float("exposure (EV)", float(r.exposure), -10.0, 10.0)
            if ch:
                r.exposure = ui.finite_or(v, r.exposure)
            names = list(TONEMAPS)
            ch, i = imgui.combo("tone map", names.index(r.tonemap) if r.tonemap in names else 0, names)
            if ch:
                r.tonemap = names[i]
            modes = list(VIEW_MODES)
            ch, i = imgui.combo("view", self.view_mode, modes)
            if ch:
                self.view_mode = i
                self.dirty = True
            ch, v = imgui.checkbox("shadows", bool(r.shadows))
            if ch:
                r.shadows = v
                self.dirty = True
            self._reflections_widget(r)
        self.mc.draw_settings(self.reference_view(), self.compare.uses_reference)
        if imgui.collapsing_header("Environment", imgui.TreeNodeFlags_.default_open):
            self._environment_panel()
            if s.render.ibl == "brute_force":
                imgui.text(f"brute force: {self._bf_count} frames x 16 samples per pixel")
        if imgui.collapsing_header("Lights", imgui.TreeNodeFlags_.default_open):
            for i, light in enumerate(s.lights):
                imgui.push_id(f"light{i}")
                imgui.text(f"{i}: {light.type}")
                if light.type == "point":
                    ch, v = imgui.drag_float3("position", [float(x) for x in light.position], 0.02)
                    if ch and all(np.isfinite(v)):
                        light.position = np.array(v, float)
                        self.dirty = True
                    ch, v = imgui.drag_float3("intensity W/sr", [float(x) for x in light.intensity], 0.1, 0.0, 1e6)
                    if ch and all(np.isfinite(v)) and min(v) >= 0:
                        light.intensity = np.array(v, float)
                        self.dirty = True
                else:
                    ch, v = imgui.drag_float3("direction", [float(x) for x in light.direction], 0.01)
                    if ch and all(np.isfinite(v)) and np.linalg.norm(v) > 1e-6:
                        light.direction = np.array(v, float) / np.linalg.norm(v)
                        self.dirty = True
                    ch, v = imgui.drag_float3("irradiance W/m2", [float(x) for x in light.irradiance], 0.05, 0.0, 1e6)
                    if ch and all(np.isfinite(v)) and min(v) >= 0:
                        light.irradiance = np.array(v, float)
                        self.dirty = True
                imgui.pop_id()
        if imgui.collapsing_header("Materials", imgui.TreeNodeFlags_.default_open):
            for i, name in enumerate(list(s.materials)):
                imgui.push_id(f"mat_{name}")
                if i == 0:  # the first material starts open
                    imgui.set_next_item_open(True, imgui.Cond_.once)
                if imgui.tree_node(f"{name} ({s.materials[name].model})"):
                    ch, new = ui.material_editor(s.materials[name], f"{name}.")
                    if ch:
                        s.materials[name] = new
                        self.dirty = True
                    imgui.tree_pop()
                imgui.pop_id()
        imgui.separator()
        if imgui.button("Screenshot (F12)"):
            self.take_screenshot()
        if ui.last_error:
            self.status, ui.last_error = ui.last_error, ""
        if self.status:
            imgui.text_wrapped(self.status)
        imgui.end()

    _capture_next = None
    _warm = None
    _reference = None

    @property
    def image_mode(self) -> str:
        return self.compare.mode

    def reference_view(self):
        if self._reference is None:
            from viewer.app.reference_view import ReferenceView

            self._reference = ReferenceView(self.ctx)
        return self._reference

    def set_image_mode(self, mode: str):
        """One of ``compare_view.MODES``: raster, reference, split, side by side, difference,
        relative difference. Modes without the reference stop its render (no CPU spent)."""
        from viewer.app.compare_view import MODES

        if mode not in MODES:
            raise ViewerError(f"image mode {mode!r}: unknown; allowed: {', '.join(MODES)}")
        self.compare.mode = mode
        if not self.compare.uses_reference and not self.mc.active and self._reference is not None:
            self._reference.stop()
        self.dirty = True

    _toast = ("", 0.0)
    TOAST_S = 6.0
    _ERROR_WORDS = ("not loaded", "not opened", "not changed", "not saved", "failed", "error", "unknown",
                    "no file dialog", "skipped")

    def _measure(self):
        """Text extents for ``layout.overlay_layout``: imgui's, at the size drawn."""
        imgui = self.imgui
        unscaled = imgui.get_style().font_scale_main

        def measure(text, size, wrap=None):  # at the size itself: glyph advances are not linear in it
            imgui.push_font(None, size / max(unscaled, 1e-6))
            try:
                v = imgui.calc_text_size(text, False, wrap if wrap else -1.0)
            finally:
                imgui.pop_font()
            return v.x, v.y

        return measure

    def overlay_plan(self):
        """The view's overlays as drawn this frame: (layout, texts); see ``layout.overlay_layout``."""
        from viewer.app.layout import overlay_layout

        view = self.view_logical()
        cmp = self.compare
        now = time.perf_counter()
        if self.status and self.status != self._toast[0]:
            self._toast = (self.status, now)
        toast = self._toast[0] if now - self._toast[1] <= self.TOAST_S else ""
        labels = cmp.overlay_labels(view, self._reference.spp if self._reference is not None else 0)
        bars = cmp.overlay_bars(view) + self.mc.overlay_bars(cmp.reference_rect(view))
        if self._view_only:
            toast = ""
        title = caption = ""
        if self.lecture_step >= 0 and not self._view_only:
            from viewer.lecture import TOUR

            title = f"{self.lecture_step + 1}/{len(TOUR)}  {TOUR[self.lecture_step].title}"
            caption = TOUR[self.lecture_step].caption
        from viewer.app.layout import Rect

        texts = dict(labels=labels, toast=toast, rmse=cmp.metrics_text(), bars=bars, title=title, caption=caption)
        return overlay_layout(Rect(*view), self.imgui.get_font_size(), self._measure(), **texts), texts

    def _overlays(self):
        """Every overlay of the view, laid out by ``overlay_plan`` so none covers another."""
        imgui = self.imgui
        x, y, w, h = self.view_logical()
        if w < 60 or h < 60:
            return
        lay, t = self.overlay_plan()
        dl = imgui.get_background_draw_list()  # over the 3D view, under imgui windows
        white = imgui.get_color_u32(imgui.ImVec4(1, 1, 1, 1))
        shade = imgui.get_color_u32(imgui.ImVec4(0, 0, 0, 0.55))
        pad = lay["pad"].x
        font, base = imgui.get_font(), imgui.get_font_size()

        def label(r, text, align_right=False):
            tw = min(imgui.calc_text_size(text).x, r.w - 2 * pad) if not align_right else imgui.calc_text_size(text).x
            bx = r.right - tw - 2 * pad if align_right else r.x
            dl.push_clip_rect(imgui.ImVec2(x, y), imgui.ImVec2(x + w, y + h), True)  # never past the view
            dl.add_rect_filled(imgui.ImVec2(bx, r.y), imgui.ImVec2(bx + tw + 2 * pad, r.bottom), shade)
            dl.add_text(imgui.ImVec2(bx + pad, r.y + pad), white, text)
            dl.pop_clip_rect()

        self.compare.draw_overlay(imgui, (x, y, w, h), lay, label)
        for i, (_, text) in enumerate(t["labels"]):
            label(lay[f"label{i}"], text)
        j = 0
        if self.compare.overlay_bars((x, y, w, h)) and "bar0" in lay:
            from viewer.app.compare_view import draw_colour_bar

            draw_colour_bar(imgui, dl, lay, 0, label, self.compare.scale, t["bars"][0][1])
            j = 1
        if len(t["bars"]) > j and f"bar{j}" in lay:
            self.mc.draw_overlay(imgui, lay, j, label)
        if t["rmse"] and "rmse" in lay:
            r = lay["rmse"]
            dl.add_rect_filled(imgui.ImVec2(r.x, r.y), imgui.ImVec2(r.right, r.bottom), shade)
            dl.add_text(font, base, imgui.ImVec2(r.x + pad, r.y + pad), white, t["rmse"], lay["wrap"].x)
        if "caption" in lay:
            r = lay["caption"]
            dl.add_rect_filled(imgui.ImVec2(r.x, r.y), imgui.ImVec2(r.right, r.bottom),
                               imgui.get_color_u32(imgui.ImVec4(0, 0, 0, 0.6)), 6.0 * base / 16)
            px = lay["caption_px"]
            for key, text, size in (("caption_title", t["title"], px.x), ("caption_text", t["caption"], px.y)):
                rr = lay[key]
                tw, _ = self._measure()(text, size, rr.w)
                dl.add_text(font, size, imgui.ImVec2(rr.x + max((rr.w - tw) / 2, 0.0), rr.y), white, text, rr.w)
        if t["toast"] and "toast" in lay:
            r = lay["toast"]
            bad = any(k in t["toast"] for k in self._ERROR_WORDS)
            bg = imgui.ImVec4(0.45, 0.05, 0.05, 0.85) if bad else imgui.ImVec4(0, 0, 0, 0.6)
            dl.push_clip_rect(imgui.ImVec2(r.x, r.y), imgui.ImVec2(r.right, r.bottom), True)
            dl.add_rect_filled(imgui.ImVec2(r.x, r.y), imgui.ImVec2(r.right, r.bottom), imgui.get_color_u32(bg), 4.0)
            dl.add_text(font, base, imgui.ImVec2(r.x + pad, r.y + pad), white, t["toast"], lay["wrap"].x)
            dl.pop_clip_rect()

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
        self.dirty = True

    def toggle_fullscreen(self):
        glfw = self.glfw
        if self._fullscreen_restore is None:
            monitor = glfw.get_primary_monitor()
            mode = glfw.get_video_mode(monitor) if monitor else None
            if not monitor or mode is None:
                self.status = "fullscreen: no monitor reported by the window system"
                return
            x, y = glfw.get_window_pos(self.window)
            w, h = glfw.get_window_size(self.window)
            self._fullscreen_restore = (x, y, w, h)
            glfw.set_window_monitor(self.window, monitor, 0, 0, mode.size.width, mode.size.height,
                                    mode.refresh_rate)
        else:
            x, y, w, h = self._fullscreen_restore
            self._fullscreen_restore = None
            glfw.set_window_monitor(self.window, None, x, y, w, h, 0)
        self.dirty = True

    def _reflections_widget(self, r):
        """Display panel: reflections / refraction (off, SSR, ray traced; viewer/app/reflections.py)."""
        from viewer.app.reflections import MODES, TOOLTIPS, reflection_mode, set_reflection_mode

        imgui = self.imgui
        mode = reflection_mode(r)
        imgui.text("reflections / refraction")
        ch, i = imgui.combo("##reflections", MODES.index(mode), list(MODES))
        if imgui.is_item_hovered():
            imgui.set_tooltip(TOOLTIPS[MODES[i]])
        if ch and set_reflection_mode(r, MODES[i]):
            self.dirty = True
        if reflection_mode(r) == "ray traced":
            ch, v = imgui.checkbox("+ SSR on glossy lobes", bool(r.ssr))
            if ch and set_reflection_mode(r, "ray traced", ssr_on_glossy=v):
                self.dirty = True

    # ------------------------------------------------------------------ lecture mode
    def lecture(self, step: int | None):
        """Show the lecture tour's ``step`` (0-based; None ends lecture mode). The step's scene
        replaces the current one; a step that fails to load leaves the scene as it was."""
        from viewer.lecture import TOUR, tour_scene

        if step is None:
            self.lecture_step = -1
            self.panel_open = False
            self.status = "lecture mode off"
            return True
        step %= len(TOUR)
        t0 = time.perf_counter()
        try:
            scene = tour_scene(step)
        except ViewerError as e:
            self.status = f"lecture step {step + 1} not loaded: {e}"
            return False
        self._set_scene(scene)
        self._enter_step(step)
        self.status = f"lecture {step + 1}/{len(TOUR)}: {TOUR[step].title} (loading...)"
        self._step_timer = (step, t0)  # the true time: until the step's first full frame is drawn
        return True

    _step_timer = None
    _prefetch = None

    def _step_shown(self):
        """The step's first full frame is drawn: say how long the key press took to show it."""
        from viewer.lecture import TOUR

        step, t0 = self._step_timer
        self._step_timer = None
        if step != self.lecture_step:
            return
        dt = time.perf_counter() - t0
        why = ""
        st = getattr(self.renderer.ibl(), "stats", {})
        if st.get("prefilter_passes"):
            why = f"; the environment map was prefiltered in {st.get('prefilter_s', 0.0):.1f} s, cached from now on"
        self.status = f"lecture {step + 1}/{len(TOUR)}: {TOUR[step].title} ({dt:.2f} s{why})"

    def _enter_step(self, step: int):
        """Lecture mode on at ``step`` for the scene already shown: the matching plot."""
        from viewer.lecture import TOUR

        self.lecture_step = step
        if self._prefetch is None:  # the tour's other maps, prefiltered in the background
            from viewer.app.prefetch import Prefetch

            self._prefetch = Prefetch(step)
        if TOUR[step].image:  # a step about the reference shows it
            self.set_image_mode(TOUR[step].image)
        tab = {"polar": "Polar", "lobe": "3D lobe", "albedo": "Albedo", "fresnel": "Fresnel",
               "bouguer": "Bouguer", "spectral": "Spectral", "sampling": "Sampling"}.get(TOUR[step].plot)
        if tab:
            self.plots.select_tab(tab)
            self.plots.visible = True  # the step's plot beside its scene
        self.plots.inside = TOUR[step].key == "tir"  # the critical angle needs light from inside
        for name in self.scene.materials:  # plot the step's subjects, not the floor under them
            self.plots.shown[name] = name != "floor"

    def _lecture_panel(self):
        from viewer.lecture import TOUR

        imgui = self.imgui
        if imgui.collapsing_header("Lecture (L)"):
            labels = ["(off)"] + [f"{i + 1}. {s.title}" for i, s in enumerate(TOUR)]
            ch, i = imgui.combo("step", self.lecture_step + 1, labels)
            if ch:
                self.lecture(i - 1 if i > 0 else None)
            if imgui.button("< prev"):
                self.lecture((max(self.lecture_step, 0) - 1) % len(TOUR))
            imgui.same_line()
            if imgui.button("next >"):
                self.lecture((self.lecture_step + 1) % len(TOUR))
            imgui.text_disabled("keys: L on/off, 1-9 0, arrows, PgUp/PgDn, Esc")
            if self._prefetch is not None:
                imgui.text_wrapped(self._prefetch.progress_text())

    # ------------------------------------------------------------------ scenes, materials, meshes
    def _set_scene(self, scene):
        from viewer.camera import OrbitCamera

        self.renderer.forget_meshes(keep=[o.mesh_data for o in scene.objects])  # the old scene's buffers
        self.scene = scene
        self.camera = OrbitCamera.from_scene(scene)
        self._env_path_text = ""
        self.hdr = None
        self.dirty = True

    def open_scene(self, ref) -> bool:
        """Load a scene file, a screenshot (.png) or a built-in name; on failure keep the old."""
        from viewer.scene import load_scene

        try:
            scene = load_scene(str(ref))
        except ViewerError as e:
            self.status = f"scene not opened: {e}"
            return False
        except Exception as e:  # noqa: BLE001 - anything unexpected keeps the running scene
            self.status = f"scene not opened: {ref}: {type(e).__name__}: {e}"
            return False
        self._set_scene(scene)
        self.lecture_step = -1
        self.status = f"opened {ref}"
        return True

    def save_scene(self, path) -> bool:
        """The current scene (camera as seen) as TOML in the scene-file format, written atomically."""
        from viewer.io import atomic_write_bytes
        from viewer.screenshot import scene_with_camera
        from viewer.scene import scene_to_toml

        try:
            text = scene_to_toml(scene_with_camera(self.scene, self.camera))
            atomic_write_bytes(Path(path).expanduser(), text.encode("utf-8"))
        except (OSError, ViewerError) as e:
            self.status = f"scene not saved: {e}"
            return False
        self.status = f"saved scene {path}"
        return True

    def save_material(self, name: str, path) -> bool:
        """One material as a ``[materials.NAME]`` table (the scene file's format)."""
        from viewer.io import atomic_write_bytes
        from viewer.scene import material_to_toml

        try:
            text = material_to_toml(name, self.scene.materials[name])
            atomic_write_bytes(Path(path).expanduser(), text.encode("utf-8"))
        except (OSError, KeyError, ViewerError) as e:
            self.status = f"material not saved: {e}"
            return False
        self.status = f"saved material {name} to {path}"
        return True

    def load_material(self, name: str, path) -> bool:
        """Replace material ``name`` with the first material of a TOML file (a material file or
        a whole scene), validated like a scene's; on any problem the old material stays."""
        from viewer.scene import load_material_file

        try:
            first, params = load_material_file(path)
        except ViewerError as e:
            self.status = f"material not loaded: {e}"
            return False
        self.scene.materials[name] = params
        self.dirty = True
        self.status = f"material {name} <- {path} [{first}]"
        return True

    def load_mesh(self, path, object_index: int | None = None) -> bool:
        """Replace one object's mesh (default: the largest object that is not a plane) with a
        mesh file, scaled to the same bounding-sphere radius and centre; errors keep the old."""
        from viewer.mesh import load_mesh

        objs = self.scene.objects
        if not objs:
            self.status = "mesh not loaded: the scene has no objects"
            return False
        if object_index is None:
            object_index = self.mesh_target
        object_index = int(np.clip(object_index, 0, len(objs) - 1))
        obj = objs[object_index]
        try:
            md = load_mesh(str(Path(path).expanduser().absolute()), None, where="Files > Load mesh")
        except ViewerError as e:
            self.status = f"mesh not loaded: {e}"
            return False
        except Exception as e:  # noqa: BLE001 - trimesh raises many kinds for a broken file
            self.status = f"mesh not loaded: {path}: {type(e).__name__}: {e}"
            return False

        def sphere(points):
            lo, hi = points.min(axis=0), points.max(axis=0)
            return (lo + hi) / 2, max(float(np.linalg.norm(hi - lo)) / 2, 1e-12)

        old_c, old_r = sphere(obj.world_positions())
        new_p = np.asarray(md.positions, np.float64).reshape(-1, 3)
        new_c, new_r = sphere(new_p)
        s = old_r / new_r
        obj.mesh = str(Path(path).expanduser().absolute())
        obj.mesh_data = md
        self.renderer.forget_meshes(keep=[o.mesh_data for o in objs])
        obj.scale = s
        obj.rotate_y_deg = 0.0
        obj.translate = old_c - s * new_c
        self.dirty = True
        self.status = f"object {object_index} <- {path} ({len(md.indices):,} triangles)"
        return True

    @property
    def mesh_target(self) -> int:
        """The object a loaded mesh replaces: the one picked in the panel, else the largest
        object that is not a plane."""
        if self._mesh_target is not None and self._mesh_target < len(self.scene.objects):
            return self._mesh_target
        best, best_r = 0, -1.0
        for i, o in enumerate(self.scene.objects):
            if o.mesh == "plane":
                continue
            p = o.world_positions()
            r = float(np.linalg.norm(p.max(axis=0) - p.min(axis=0)))
            if r > best_r:
                best, best_r = i, r
        return best

    _mesh_target = None
    _dialog = None  # (kind, portable_file_dialogs object)
    _file_text = ""

    def _file_panel(self):
        imgui = self.imgui
        if not imgui.collapsing_header("Files"):
            return
        ch, self._file_text = imgui.input_text("path##files", self._file_text)
        names = [f"{i}: {o.mesh if len(o.mesh) < 24 else '...' + o.mesh[-21:]} ({o.material})"
                 for i, o in enumerate(self.scene.objects)]
        ch, i = imgui.combo("object", self.mesh_target, names)
        if ch:
            self._mesh_target = i
        mats = list(self.scene.materials)
        mat = self.scene.objects[self.mesh_target].material if self.scene.objects else (mats[0] if mats else "")
        path = self._file_text.strip()
        if imgui.button("Open scene"):
            self._open_or_browse("scene", path)
        imgui.same_line()
        if imgui.button("Save scene"):
            self._open_or_browse("save_scene", path)
        imgui.same_line()
        if imgui.button("Load mesh"):
            self._open_or_browse("mesh", path)
        if mat:
            if imgui.button(f"Save material '{mat}'"):
                self._open_or_browse("save_material", path)
            imgui.same_line()
            if imgui.button("Load material"):
                self._open_or_browse("material", path)
        from viewer.app import state as state_mod

        if state_mod.last_scene_path().exists() and imgui.button("Reopen last session"):
            self.open_scene(state_mod.last_scene_path())
        imgui.text_disabled("empty path: a file dialog; or drop files on the window")

    _FILTERS = {
        "scene": ["Scenes and screenshots", "*.toml *.png", "All files", "*"],
        "save_scene": ["Scene (.toml)", "*.toml"],
        "mesh": ["Meshes", "*.obj *.ply *.stl *.off *.glb *.gltf", "All files", "*"],
        "material": ["Materials and scenes (.toml)", "*.toml", "All files", "*"],
        "save_material": ["Material (.toml)", "*.toml"],
    }

    def _open_or_browse(self, kind: str, path: str):
        if path:
            self._file_action(kind, path)
            return
        try:  # the desktop's own dialog (zenity / kdialog on Linux), polled, never blocking
            from imgui_bundle import portable_file_dialogs as pfd

            title = kind.replace("_", " ")
            if kind.startswith("save"):
                self._dialog = (kind, pfd.save_file(title, str(Path.cwd()), self._FILTERS[kind]))
            else:
                self._dialog = (kind, pfd.open_file(title, str(Path.cwd()), self._FILTERS[kind]))
        except Exception as e:  # noqa: BLE001 - no dialog backend: say so, keep going
            self.status = f"no file dialog available ({e}); type a path or drop a file"

    def _poll_dialogs(self):
        if self._dialog is not None and self._dialog[1].ready(0):
            kind, dlg = self._dialog
            self._dialog = None
            picked = dlg.result()
            if isinstance(picked, list):
                picked = picked[0] if picked else ""
            if picked:
                self._file_action(kind, picked)
        if self._env_dialog is not None and self._env_dialog.ready(0):
            picked = self._env_dialog.result()
            self._env_dialog = None
            if picked:
                self.set_environment(picked[0])

    def _file_action(self, kind: str, path: str) -> bool:
        target = self.scene.objects[self.mesh_target].material if self.scene.objects else None
        if kind == "scene":
            return self.open_scene(path)
        if kind == "save_scene":
            return self.save_scene(path if path.lower().endswith(".toml") else path + ".toml")
        if kind == "mesh":
            return self.load_mesh(path)
        if kind == "material" and target:
            return self.load_material(target, path)
        if kind == "save_material" and target:
            return self.save_material(target, path if path.lower().endswith(".toml") else path + ".toml")
        return False

    def save_state(self):
        """The window's state for the next start, and the scene as last_scene.toml (atomic)."""
        from viewer.app import state as state_mod
        from viewer.io import atomic_write_bytes
        from viewer.scene import scene_to_toml
        from viewer.screenshot import scene_with_camera

        st = dict(self._state)
        try:
            if self._fullscreen_restore is not None:
                x, y, w, h = self._fullscreen_restore
            else:
                (x, y), (w, h) = self.glfw.get_window_pos(self.window), self.glfw.get_window_size(self.window)
            if w >= 64 and h >= 64:
                st.update(window_width=w, window_height=h, window_x=x, window_y=y)
            st.update(ui_scale=self.ui_scale, show_ui=self.show_ui, compare_mode=self.compare.mode,
                      split=self.compare.split, view_mode=self.view_mode, plots_visible=self.plots.visible)
            state_mod.save_state(st)
            text = scene_to_toml(scene_with_camera(self.scene, self.camera))
            atomic_write_bytes(state_mod.last_scene_path(), text.encode("utf-8"))
        except Exception as e:  # noqa: BLE001 - never lose the session to a state-file problem
            print(f"brdf-viewer: window state not saved: {type(e).__name__}: {e}", file=sys.stderr)

    def _warm_one(self):
        """Compile one model's forward program while idle, so switching models later does not
        wait for the shader compiler (software GL compiles take 0.1-0.5 s each)."""
        from viewer import brdf

        name = self._warm.pop(0)
        try:
            self.renderer.forward_program(brdf.get(name).params())
        except ViewerError as e:
            self.status = str(e)

    def _read_screen(self, fw, fh) -> np.ndarray:
        data = self.ctx.screen.read(viewport=(0, 0, fw, fh), components=3, alignment=1)
        return np.frombuffer(data, np.uint8).reshape(fh, fw, 3)[::-1].copy()

    _view_only = False  # one frame of the view alone: no windows, no caption, no toast

    def capture_view(self) -> np.ndarray:
        """The 3D view as shown (compare view, heat maps, their labels and colour bars), without
        the panels, the lecture caption and the status toast: (H, W, 3) uint8, row 0 = top."""
        self._view_only = True
        try:
            img = self.capture_window()
        finally:
            self._view_only = False
        vx, _, vw, vh = self.viewport()
        return img[img.shape[0] - vh:, vx:vx + vw].copy()

    def capture_window(self) -> np.ndarray:
        """The whole window as shown (3D view and UI), (H, W, 3) uint8, row 0 = top."""
        out = []
        self._capture_next = out.append
        self.dirty = True
        self.frame()
        return out[0] if out else None

    _env_path_text = ""
    _bf_count = 0
    _bf_sum = None
    _bf_tex = None

    def _accumulate(self, hdr):
        """Brute-force IBL: the running mean of frames with new sample sets (as the offscreen
        ``render_arrays(frames=K)``), shown while it converges."""
        img = self.renderer.read_linear(hdr).astype(np.float64)
        self._bf_sum = img if self._bf_sum is None else self._bf_sum + img
        self._bf_count += 1
        from viewer.app.compare_view import upload_rgb

        self._bf_tex = upload_rgb(self.ctx, self._bf_tex, self._bf_sum / self._bf_count)
        return self._bf_tex
    _env_dialog = None

    def _environment_panel(self):
        from viewer.environment.procedural import builtin_names
        from viewer.gl.renderer import IBL_MODES

        imgui = self.imgui
        env = self.scene.environment
        current = "constant" if env.map is None else (env.map if env.is_builtin else "file")
        choices = ["constant"] + list(builtin_names()) + (["file"] if current == "file" else [])
        ch, i = imgui.combo("map", choices.index(current), choices)
        if ch and choices[i] != current:
            self.set_environment(None if choices[i] == "constant" else choices[i])
        if env.map is not None and not env.is_builtin:
            imgui.text_wrapped(f"file: {env.map}")
        ch, self._env_path_text = imgui.input_text("##envpath", self._env_path_text)
        imgui.same_line()
        if imgui.button("Load .hdr/.exr"):
            self.set_environment(self._env_path_text.strip())
        if imgui.button("Browse..."):
            try:  # the desktop's own dialog (zenity / kdialog on Linux), polled, never blocking
                from imgui_bundle import portable_file_dialogs as pfd

                self._env_dialog = pfd.open_file("Environment map (.hdr, .exr)", str(Path.cwd()),
                                                 ["HDR environment maps", "*.hdr *.exr", "All files", "*"])
            except Exception as e:  # noqa: BLE001 - no dialog backend: say so, keep going
                self.status = f"no file dialog available ({e}); type a path or drop a file"
        imgui.same_line()
        imgui.text_disabled("(or drop a file on the window)")
        if env.map is None:
            c = [float(x) for x in (env.constant if env.constant is not None else np.zeros(3))]
            ch, v = imgui.color_edit3("radiance", c, imgui.ColorEditFlags_.float | imgui.ColorEditFlags_.hdr)
            if ch and all(np.isfinite(v)) and min(v) >= 0:
                env.constant = np.array(v, float)
                self.dirty = True
        ch, v = imgui.slider_float("intensity", float(env.intensity), 0.001, 100.0, "%.3g",
                                   imgui.SliderFlags_.logarithmic)
        if ch and np.isfinite(v) and v >= 0:
            env.intensity = float(v)
            self.dirty = True
        auto = env.mid_grey_intensity() if env.map is not None else None
        if auto is not None:
            if imgui.button("mid-grey"):
                env.intensity = float(auto)
                self.dirty = True
            imgui.same_line()
            imgui.text_disabled(f"intensity {auto:.3g}: mean luminance -> 0.18")
        ch, v = imgui.slider_float("rotation (deg)", float(env.rotation_deg), -180.0, 180.0)
        if ch and np.isfinite(v):
            env.rotation_deg = float(v)
            self.dirty = True
        modes = list(IBL_MODES)
        r = self.scene.render
        ch, i = imgui.combo("IBL", modes.index(r.ibl) if r.ibl in modes else 1, modes)
        if ch:
            r.ibl = modes[i]
            self.dirty = True
        ch, v = imgui.checkbox("multiple-scattering compensation", bool(r.ms_compensation))
        if ch:
            r.ms_compensation = v
            self.dirty = True

    def set_environment(self, ref) -> bool:
        """Switch the environment to a built-in map name, a .hdr/.exr path or None (constant).
        A file that does not load leaves the previous environment and shows why."""
        import dataclasses
        from pathlib import Path as _P

        env = self.scene.environment
        new = dataclasses.replace(env)
        new.__dict__.pop("_map_cache", None)
        if ref is None:
            new.map = None
            if new.constant is None:
                new.constant = np.array([0.1, 0.1, 0.1])
        else:
            from viewer.environment.procedural import builtin_names

            new.map = ref if ref in builtin_names() else _P(ref).expanduser()
            new.constant = None
            try:
                new.radiance_map()
            except ViewerError as e:
                self.status = f"environment not changed: {e}"
                return False
            except Exception as e:  # noqa: BLE001 - any decoder failure keeps the old map
                self.status = f"environment not changed: {ref}: {type(e).__name__}: {e}"
                return False
        self.scene.environment = new
        self.status = f"environment: {ref or 'constant'}"
        if new.map is not None:  # a map's own units (the sky is in kcd/m^2): start at mid-grey
            auto = new.mid_grey_intensity()
            if auto is not None:
                new.intensity = float(auto)
                self.status += (f" (intensity {auto:.3g}: mean luminance {new.mean_luminance():.3g} -> mid-grey "
                                "0.18; edit it under Environment)")
        self.dirty = True
        return True

    MESH_SUFFIXES = (".obj", ".ply", ".stl", ".off", ".glb", ".gltf")

    def _on_drop(self, window, paths):
        for p in paths:
            low = p.lower()
            if low.endswith((".hdr", ".exr")):
                self.set_environment(p)
            elif low.endswith((".toml", ".png")):
                self.open_scene(p)
            elif low.endswith(self.MESH_SUFFIXES):
                self.load_mesh(p)
            else:
                self.status = (f"dropped {p}: unknown kind; allowed: .toml/.png scenes, .hdr/.exr maps, "
                               "meshes " + " ".join(self.MESH_SUFFIXES))

    # ------------------------------------------------------------------ actions
    def take_screenshot(self, path: str | os.PathLike | None = None) -> Path | None:
        """Save the 3D view (no UI) as a PNG with the scene and parameters in its text chunks."""
        from viewer.gl.renderer import VIEW_MODES
        from viewer.io import write_png
        from viewer.screenshot import png_text

        if path is None:
            stamp = datetime.datetime.now().strftime("%Y%m%d-%H%M%S")
            path = self.screenshot_dir / f"brdf-viewer-{stamp}.png"
        _, _, vw, vh = self.viewport()
        if vw == 0 or vh == 0:
            self.status = "screenshot skipped: the window is minimized"
            return None
        try:
            view = list(VIEW_MODES)[self.view_mode]
            extra = {"view": view, "image": self.compare.mode}
            if self.compare.mode == "raster" and not self.mc.active:
                # the raster alone: rendered afresh at the view's size (no overlay to keep)
                hdr = self.renderer.render(self.scene, self.camera, vw, vh, self.view_mode)
                srgb = self.renderer.read_srgb(hdr, self.scene.render.exposure, self.scene.render.tonemap)
            else:  # what the view shows: split, side by side, heat map with its colour bar, labels
                srgb = self.capture_view()
                if self.compare.metrics_text():
                    extra["metrics"] = self.compare.metrics_text()
            write_png(path, srgb, png_text(self.scene, self.camera, extra))
        except (OSError, ViewerError) as e:
            self.status = f"screenshot failed: {e}"
            return None
        self.dirty = True
        self.status = f"saved {path}"
        print(self.status, file=sys.stderr)
        return Path(path)


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


def run_app(scene_ref=None, overrides=(), size=None, frames=0, screenshot=None) -> int:
    if screenshot:
        check_writable(screenshot)
    app = App(scene_ref, overrides, size)
    return app.run(frames=frames, screenshot=screenshot)
