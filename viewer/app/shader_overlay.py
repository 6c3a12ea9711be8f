"""Shader hot reload in the window: watch the shader folder, rebuild the renderer's programs
when a file changes, and show compile errors (file and line of the included file they are
really in) in a red-bordered overlay while the last good programs keep rendering.

Use from the app's frame loop::

    self.hot_reload = HotReload(self.renderer)       # once, after the Renderer exists
    if self.hot_reload.poll():                       # every frame, before rendering
        self.dirty = True
    self.hot_reload.draw_overlay()                   # every frame, between new_frame and render
"""

from __future__ import annotations

import os
import time
from pathlib import Path

from viewer.gl.hot_reload import ShaderWatcher

#: seconds the green "reloaded" note stays up after a successful reload
NOTE_SECONDS = 2.0


class HotReload:
    """Polls the shader folder and rebuilds ``renderer``'s programs when files change.

    ``root``: the folder to watch (default: ``viewer.gl.shaders.shader_root()``, the package's
    shaders/). A different folder becomes the shader root for every later build, so the
    programs are built from the files that are watched. Puts the renderer in hot-reload mode
    (``Renderer.hot_reload``): compile errors are shown, not raised from ``render``."""

    def __init__(self, renderer, root: str | os.PathLike | None = None, interval: float = 0.25):
        from viewer.gl.shaders import set_shader_root, shader_root

        if root is not None and Path(root).resolve() != shader_root():
            set_shader_root(root)
        self.root = shader_root()
        self.renderer = renderer
        renderer.hot_reload = True
        self.watcher = ShaderWatcher(self.root, interval)
        self.last_reload_ms: float | None = None  # from the scan that saw a change to programs rebuilt
        self.last_changed: list[str] = []  # files the last reload was for
        self.last_reloaded: list[str] = []  # programs it replaced
        self.reload_count = 0
        self._note_until = 0.0

    @property
    def errors(self):
        """The current ShaderErrors (``.file``, ``.line``, ``.detail``, ``.summary()``); [] when
        every program compiles. Includes failures of programs compiled lazily since the last poll."""
        return self.renderer.shader_errors

    @property
    def noting(self) -> bool:
        """The "reloaded" note is on screen (it goes ``NOTE_SECONDS`` after a reload)."""
        return time.monotonic() <= self._note_until

    def poll(self, force: bool = False) -> bool:
        """Call once per frame. True when programs were rebuilt (or errors may have gone), i.e.
        when the image must be rendered again."""
        t0 = time.perf_counter()
        changed = self.watcher.poll(force) + self._brdf_files_changed(force)
        if not changed:
            return False
        had_errors = bool(self.renderer.shader_errors)
        errors = self.renderer.reload_shaders(changed)
        self.last_reload_ms = 1000 * (time.perf_counter() - t0)
        self.last_changed = changed
        self.last_reloaded = list(self.renderer.last_reloaded)
        self.reload_count += 1
        if self.last_reloaded and not errors:
            self._note_until = time.monotonic() + NOTE_SECONDS
        return bool(self.last_reloaded) or had_errors

    def _brdf_files_changed(self, force: bool) -> list[str]:
        """Names of the ``.brdf`` files of the renderer's programs changed since the last look
        (polled with the shader folder); a saved file rebuilds its programs, and an error names
        the file's line while the last good program keeps drawing."""
        stats = getattr(self, "_brdf_stats", {})
        now = {}
        for p in sorted(self.renderer.file_brdfs()):
            try:
                st = os.stat(p)
                now[p] = (st.st_mtime_ns, st.st_size, st.st_ino)
            except OSError:
                now[p] = None
        self._brdf_stats = now
        return [Path(p).name for p in now if p in stats and stats[p] != now[p]]

    def draw_overlay(self) -> None:
        """Inside an imgui frame: while errors exist, a red-bordered window at the top right of
        the main viewport listing ``file:line: message`` per error; for a moment after a
        successful reload, a green one saying what was rebuilt and how long it took."""
        from imgui_bundle import imgui

        errors = self.errors
        if not errors and time.monotonic() > self._note_until:
            return
        vp = imgui.get_main_viewport()
        max_w = max(240.0, min(720.0, vp.work_size.x * 0.6))
        imgui.set_next_window_pos(imgui.ImVec2(vp.work_pos.x + vp.work_size.x - 12, vp.work_pos.y + 12),
                                  imgui.Cond_.always, imgui.ImVec2(1.0, 0.0))
        imgui.set_next_window_size_constraints(imgui.ImVec2(240, 0), imgui.ImVec2(max_w, vp.work_size.y * 0.8))
        imgui.set_next_window_bg_alpha(0.9)
        border = imgui.ImVec4(0.95, 0.15, 0.15, 1.0) if errors else imgui.ImVec4(0.2, 0.8, 0.3, 1.0)
        imgui.push_style_color(imgui.Col_.border, border)
        imgui.push_style_var(imgui.StyleVar_.window_border_size, 2.0)
        flags = (imgui.WindowFlags_.no_collapse | imgui.WindowFlags_.always_auto_resize
                 | imgui.WindowFlags_.no_focus_on_appearing | imgui.WindowFlags_.no_nav
                 | imgui.WindowFlags_.no_saved_settings | imgui.WindowFlags_.no_move
                 | imgui.WindowFlags_.no_docking)
        title = (f"Shader errors ({len(errors)})" if errors else "Shaders reloaded") + "###shader_overlay"
        try:
            expanded, _ = imgui.begin(title, None, flags)
            if expanded:
                imgui.push_text_wrap_pos(max_w - 16)
                if errors:
                    imgui.push_style_color(imgui.Col_.text, imgui.ImVec4(1.0, 0.45, 0.4, 1.0))
                    for e in errors:
                        imgui.text_unformatted(e.summary())
                    imgui.pop_style_color()
                    imgui.text_disabled("The last good programs keep rendering; save the file to try again.")
                else:
                    ms = self.last_reload_ms or 0.0
                    imgui.text_unformatted(f"{', '.join(self.last_changed)}: {len(self.last_reloaded)} "
                                           f"program(s) rebuilt in {ms:.0f} ms")
                imgui.pop_text_wrap_pos()
        finally:
            imgui.end()
            imgui.pop_style_var()
            imgui.pop_style_color()
