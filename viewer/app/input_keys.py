"""The window's input (``App.keys``): glfw's callbacks (every event counted, so the loop wakes on
it; single-key taps queued from the key callback, so a tap shorter than a frame, a presentation
clicker's, is never lost: a slow frame only delays it; files dropped on the window), and once per
frame the mouse (orbit, pan, dolly, the compare view's divider), the UI-scale keys and the
queued taps' actions (``key_action``)."""

from __future__ import annotations

import time

# single-key actions, read from glfw's key callback
TAP_KEYS = ("h", "f11", "c", "p", "l", "right", "page_down", "space", "left", "page_up", "escape",
            "1", "2", "3", "4", "5", "6", "7", "8", "9", "0", "r", "f12", "s")


class InputKeys:
    """The input of ``app`` (an ``App``: its ``glfw``, ``imgui``, ``session``, layout and actions)."""

    def __init__(self, app):
        self.app = app
        self.taps: list[str] = []        # keys tapped since the last frame, in order
        glfw = getattr(app, "glfw", None)
        self.tap_codes = {} if glfw is None else {getattr(glfw, "KEY_" + k.upper()): k for k in TAP_KEYS}
        self.input_events = 0            # glfw input and window events so far (``tick`` wakes on them)
        self.last_event = time.perf_counter()   # the last input (tests and benchmarks set it)
        self.last_interaction = -1.0     # the last drag, wheel or slider (a benchmark sets it)

    def install(self, window) -> None:
        """glfw's callbacks on ``window`` (before imgui's backend, which chains to the key and
        pointer callbacks; it installs none for the window's own events and drops)."""
        glfw = self.app.glfw
        glfw.set_key_callback(window, self.on_key)
        for name in ("cursor_pos", "mouse_button", "scroll", "char", "cursor_enter", "window_focus"):
            getattr(glfw, f"set_{name}_callback")(window, self.on_event)
        for name in ("window_size", "framebuffer_size", "window_refresh", "window_iconify"):
            getattr(glfw, f"set_{name}_callback")(window, self.on_event)
        glfw.set_drop_callback(window, self.on_drop)

    @property
    def interacting(self) -> bool:
        """A drag, the wheel or a slider within the last 0.3 s (the frame draws a preview)."""
        return time.perf_counter() - self.last_interaction < 0.3

    # ------------------------------------------------------------------ glfw's callbacks
    def on_event(self, window, *args):
        self.input_events += 1
        self.last_event = time.perf_counter()

    def on_key(self, window, key, scancode, action, mods):
        glfw = self.app.glfw
        self.on_event(window)
        if action == glfw.PRESS and key in self.tap_codes:
            if not mods & (glfw.MOD_CONTROL | glfw.MOD_ALT | glfw.MOD_SUPER):
                name = self.tap_codes[key]
                # Shift + a digit: lecture steps 11-19 (Shift 1 .. Shift 5 on the tour of 15)
                self.taps.append("shift+" + name if mods & glfw.MOD_SHIFT and name.isdigit() else name)

    def on_drop(self, window, paths):
        """glfw's drop callback: the session opens each file by its kind."""
        self.on_event(window)
        self.app.session.open_files(paths)

    # ------------------------------------------------------------------ once per frame
    def handle(self):
        """This frame's mouse and keys (imgui's), then the taps queued since the last frame."""
        app = self.app
        imgui = app.imgui
        io = imgui.get_io()
        s = app.session
        if imgui.is_any_item_active():  # a slider being dragged counts as interaction
            self.last_interaction = time.perf_counter()
        vh = app.viewport()[3]
        divider = not io.want_capture_mouse and s.compare.handle_mouse(imgui, app.view_logical())
        if not io.want_capture_mouse and not divider:
            d = io.mouse_delta
            if imgui.is_mouse_double_clicked(imgui.MouseButton_.left):
                s.reset_camera()
            elif imgui.is_mouse_dragging(imgui.MouseButton_.left):
                s.camera.orbit(d.x, d.y, vh)
                s.changed()
                self.last_interaction = time.perf_counter()
            elif imgui.is_mouse_dragging(imgui.MouseButton_.right) or imgui.is_mouse_dragging(imgui.MouseButton_.middle):
                s.camera.pan(d.x, d.y, vh)
                s.changed()
                self.last_interaction = time.perf_counter()
            if io.mouse_wheel != 0.0:
                s.camera.dolly(io.mouse_wheel)
                s.changed()
                self.last_interaction = time.perf_counter()
        taps, self.taps = self.taps, []
        if io.want_capture_keyboard:  # typing into a field: the keys are the field's
            return
        K = imgui.Key
        pressed = lambda k: imgui.is_key_pressed(k, False)  # noqa: E731
        if io.key_ctrl:
            from viewer.app.layout import step_ui_scale

            if pressed(K.equal) or pressed(K.keypad_add):
                app.set_ui_scale(step_ui_scale(app.ui_scale, up=True))
            if pressed(K.minus) or pressed(K.keypad_subtract):
                app.set_ui_scale(step_ui_scale(app.ui_scale, up=False))
            if pressed(K._0):
                app.set_ui_scale(1.0)
        for key in taps:
            self.key_action(key)

    def key_action(self, key: str) -> None:
        """One key's action (glfw key names in lower case: "l", "right", "page_down", "1"...;
        "shift+1" for Shift and a digit)."""
        app = self.app
        s = app.session
        if key == "r":
            s.reset_camera()
        elif key == "f12":
            app.capture.take_screenshot()
        elif key == "h":
            app.show_ui = not app.show_ui
            s.changed()
        elif key == "f11":
            app.toggle_fullscreen()
        elif key == "c":
            s.cycle_image_mode()
        elif key == "s":
            s.cycle_strategy()
        elif key == "p":
            app.plots.visible = not app.plots.visible
            s.changed()
        elif key == "l":
            s.lecture(0 if s.lecture_step < 0 else None)
        elif s.lecture_step >= 0:
            from viewer.scene.lecture import TOUR

            if key in ("right", "page_down", "space"):
                s.lecture_next()
            elif key in ("left", "page_up"):
                s.lecture_back()
            elif key.isdigit() and (int(key) - 1) % 10 < len(TOUR):
                s.lecture((int(key) - 1) % 10)   # 1-9, 0 = 10
            elif key.startswith("shift+") and key[6:].isdigit() and 10 + (int(key[6:]) - 1) % 10 < len(TOUR):
                s.lecture(10 + (int(key[6:]) - 1) % 10)   # Shift 1-9 = 11-19, Shift 0 = 20
            elif key == "escape":
                s.lecture(None)
