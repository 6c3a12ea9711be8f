"""The side panel's *Environment* section: built-in map or a file (typed, browsed or dropped),
its radiance / intensity / rotation, the IBL mode and multiple-scattering compensation."""

from __future__ import annotations

import numpy as np
from imgui_bundle import imgui

from viewer.app.panels.dialogs import open_dialog, picked


class EnvironmentPanel:
    def __init__(self, session):
        self.session = session
        self.text = ""          # the map path typed (cleared when another scene is shown)
        self.dialog = None
        self._scene = session.scene

    def poll(self) -> None:
        done, path = picked(self.dialog)
        if done:
            self.dialog = None
            if path:
                self.session.set_environment(path)

    def draw(self) -> None:
        from viewer.environment.procedural import builtin_names
        from viewer.gl.renderer import IBL_MODES

        session = self.session
        if session.scene is not self._scene:
            self.text, self._scene = "", session.scene
        env = session.scene.environment
        current = "constant" if env.map is None else (env.map if env.is_builtin else "file")
        choices = ["constant"] + list(builtin_names()) + (["file"] if current == "file" else [])
        ch, i = imgui.combo("map", choices.index(current), choices)
        if ch and choices[i] != current:
            session.set_environment(None if choices[i] == "constant" else choices[i])
        if env.map is not None and not env.is_builtin:
            imgui.text_wrapped(f"file: {env.map}")
        _, self.text = imgui.input_text("##envpath", self.text)
        imgui.same_line()
        if imgui.button("Load .hdr/.exr"):
            session.set_environment(self.text.strip())
        if imgui.button("Browse..."):
            self.dialog = open_dialog(session, "Environment map (.hdr, .exr)",
                                      ["HDR environment maps", "*.hdr *.exr", "All files", "*"])
        imgui.same_line()
        imgui.text_disabled("(or drop a file on the window)")
        self._light(session.scene.environment)
        modes = list(IBL_MODES)
        r = session.scene.render
        ch, i = imgui.combo("IBL", modes.index(r.ibl) if r.ibl in modes else 1, modes)
        if ch:
            r.ibl = modes[i]
            session.changed()
        ch, v = imgui.checkbox("multiple-scattering compensation", bool(r.ms_compensation))
        if ch:
            r.ms_compensation = v
            session.changed()

    def _light(self, env) -> None:
        """Radiance (constant), intensity (mid-grey for a map), rotation."""
        session = self.session
        if env.map is None:
            c = [float(x) for x in (env.constant if env.constant is not None else np.zeros(3))]
            ch, v = imgui.color_edit3("radiance", c, imgui.ColorEditFlags_.float | imgui.ColorEditFlags_.hdr)
            if ch and all(np.isfinite(v)) and min(v) >= 0:
                env.constant = np.array(v, float)
                session.changed()
        ch, v = imgui.slider_float("intensity", float(env.intensity), 0.001, 100.0, "%.3g",
                                   imgui.SliderFlags_.logarithmic)
        if ch and np.isfinite(v) and v >= 0:
            env.intensity = float(v)
            session.changed()
        auto = env.mid_grey_intensity() if env.map is not None else None
        if auto is not None:
            if imgui.button("mid-grey"):
                env.intensity = float(auto)
                session.changed()
            imgui.same_line()
            imgui.text_disabled(f"intensity {auto:.3g}: mean luminance -> 0.18")
        ch, v = imgui.slider_float("rotation (deg)", float(env.rotation_deg), -180.0, 180.0)
        if ch and np.isfinite(v):
            env.rotation_deg = float(v)
            session.changed()
