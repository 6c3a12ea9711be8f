"""The window's geometry, a part of the ``App`` (``app.geometry``): its size and its
framebuffer's, the parts laid out in it (``viewer.app.layout``), the 3D view in framebuffer
pixels and in imgui's points, and fullscreen.

The sizes are read from the window system once a frame, as the frame begins (``begin_frame``),
and held until it ends: each read is a round trip to the X server, which on a loaded machine
waits behind the last frame's image (a frame of the split view asked 11 times, 72 ms). Between
frames they are read live, so a script that resizes the window finds the new size at once."""

from __future__ import annotations


class WindowGeometry:
    def __init__(self, app):
        self.app = app
        self._frame_sizes = None     # (framebuffer (w, h), window (w, h)) during a frame
        self._fullscreen_restore = None  # (x, y, w, h) of the window before fullscreen

    def begin_frame(self):
        """The frame's sizes, read now and held until ``end_frame``: ((fw, fh), (ww, wh))."""
        self._frame_sizes = None
        self._frame_sizes = self.sizes()
        return self._frame_sizes

    def end_frame(self):
        self._frame_sizes = None

    def sizes(self):
        """((framebuffer width, height), (window width, height)): this frame's, or the window's
        now between frames."""
        if self._frame_sizes is not None:
            return self._frame_sizes
        glfw, window = self.app.glfw, self.app.window
        return tuple(glfw.get_framebuffer_size(window)), tuple(glfw.get_window_size(window))

    def layout(self):
        """The window's parts (``viewer.app.layout.window_layout``) in window points."""
        from viewer.app.layout import window_layout

        app = self.app
        _, (ww, wh) = self.sizes()
        return window_layout(ww, wh, app.ui_scale, show_ui=app.show_ui, lecture=app.session.lecture_step >= 0,
                             plots=app.plots.visible, panel_open=app.panel_open)

    def viewport(self):
        """The 3D view in framebuffer pixels (x, y from the bottom-left, w, h)."""
        from viewer.app.layout import view_columns

        (fw, fh), (ww, _) = self.sizes()
        scale = fw / ww if ww else 1.0
        v = self.layout()["view"]
        x0, w = view_columns(v, scale, fw)  # an even width: see viewer.gl.trace_cache
        return x0, 0, w, fh

    def view_logical(self):
        """The 3D view in imgui's coordinates (window points, y down)."""
        return self.layout()["view"].tuple()

    @property
    def panel_width(self) -> int:
        lay = self.layout()
        r = lay.get("strip") or lay.get("panel")
        return int(r.w) if r is not None else 0

    def window_rect(self):
        """(x, y, w, h) of the window as the next start opens it: where it was before
        fullscreen, else where it is."""
        if self._fullscreen_restore is not None:
            return self._fullscreen_restore
        glfw, window = self.app.glfw, self.app.window
        (x, y), (w, h) = glfw.get_window_pos(window), glfw.get_window_size(window)
        return x, y, w, h

    def toggle_fullscreen(self):
        """Fullscreen on the primary monitor, or back to the window as it was."""
        app = self.app
        glfw = app.glfw
        if self._fullscreen_restore is None:
            monitor = glfw.get_primary_monitor()
            mode = glfw.get_video_mode(monitor) if monitor else None
            if not monitor or mode is None:
                app.session.notify("fullscreen: no monitor reported by the window system", error=True)
                return
            x, y = glfw.get_window_pos(app.window)
            w, h = glfw.get_window_size(app.window)
            self._fullscreen_restore = (x, y, w, h)
            glfw.set_window_monitor(app.window, monitor, 0, 0, mode.size.width, mode.size.height,
                                    mode.refresh_rate)
        else:
            x, y, w, h = self._fullscreen_restore
            self._fullscreen_restore = None
            glfw.set_window_monitor(app.window, None, x, y, w, h, 0)
        app.session.changed()
