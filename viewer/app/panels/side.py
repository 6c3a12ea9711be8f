"""The side panel: the sections (scene, materials, files, lecture, display, reference,
environment, lights) one under another, the screenshot button and the latest message. The
material editor comes second, so it opens above the fold at 1280 x 720 (``materials_y``: where
it started on the last frame, window points)."""

from __future__ import annotations

from imgui_bundle import imgui

from viewer.app.panels import display, lecture, lights, materials, scene
from viewer.app.panels.environment import EnvironmentPanel
from viewer.app.panels.files import FilesPanel


class SidePanel:
    def __init__(self, win):
        self.win = win
        self.files = FilesPanel(win.session)
        self.environment = EnvironmentPanel(win.session)
        self.materials_y = 0.0

    def poll(self) -> None:
        """The file dialogs that closed since the last frame."""
        self.files.poll()
        self.environment.poll()

    def draw(self, rect=None) -> None:
        win, session = self.win, self.win.session
        if rect is None:
            rect = win.layout()["panel"]
        imgui.set_next_window_pos(imgui.ImVec2(rect.x, rect.y))
        imgui.set_next_window_size(imgui.ImVec2(rect.w, rect.h))
        flags = imgui.WindowFlags_.no_move | imgui.WindowFlags_.no_resize | imgui.WindowFlags_.no_collapse
        imgui.begin("brdf-viewer", None, flags)
        scene.draw(session, win.frame_ms)
        self.materials_y = imgui.get_cursor_screen_pos().y
        materials.draw(session)
        self.files.draw()
        lecture.draw_section(session)
        display.draw(win)
        session.monte_carlo.draw_settings(session.reference_view(), session.compare.uses_reference)
        if imgui.collapsing_header("Environment", imgui.TreeNodeFlags_.default_open):
            self.environment.draw()
            if session.scene.render.ibl == "brute_force":
                imgui.text(f"brute force: {session.bf_count} frames x 16 samples per pixel")
        lights.draw(session)
        imgui.separator()
        if imgui.button("Screenshot (F12)"):
            win.capture.take_screenshot()
        if session.status:
            imgui.text_wrapped(session.status)
        imgui.end()
