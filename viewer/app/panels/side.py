"""The side panel: the sections (scene, files, lecture, display, reference, environment,
lights, materials) one under another, the screenshot button and the latest message."""

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
        self.files.draw()
        lecture.draw_section(session)
        display.draw(win)
        session.monte_carlo.draw_settings(session.reference_view(), session.compare.uses_reference)
        if imgui.collapsing_header("Environment", imgui.TreeNodeFlags_.default_open):
            self.environment.draw()
            if session.scene.render.ibl == "brute_force":
                imgui.text(f"brute force: {session.bf_count} frames x 16 samples per pixel")
        lights.draw(session)
        materials.draw(session)
        imgui.separator()
        if imgui.button("Screenshot (F12)"):
            win.take_screenshot()
        if session.status:
            imgui.text_wrapped(session.status)
        imgui.end()
