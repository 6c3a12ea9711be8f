"""The side panel's *Lights* section: each point light's position and intensity, each
directional light's direction and irradiance (non-finite or negative values are ignored)."""

from __future__ import annotations

import numpy as np
from imgui_bundle import imgui


def draw(session) -> None:
    if not imgui.collapsing_header("Lights", imgui.TreeNodeFlags_.default_open):
        return
    for i, light in enumerate(session.scene.lights):
        imgui.push_id(f"light{i}")
        imgui.text(f"{i}: {light.type}")
        if light.type == "point":
            ch, v = imgui.drag_float3("position", [float(x) for x in light.position], 0.02)
            if ch and all(np.isfinite(v)):
                light.position = np.array(v, float)
                session.changed()
            ch, v = imgui.drag_float3("intensity W/sr", [float(x) for x in light.intensity], 0.1, 0.0, 1e6)
            if ch and all(np.isfinite(v)) and min(v) >= 0:
                light.intensity = np.array(v, float)
                session.changed()
        else:
            ch, v = imgui.drag_float3("direction", [float(x) for x in light.direction], 0.01)
            if ch and all(np.isfinite(v)) and np.linalg.norm(v) > 1e-6:
                light.direction = np.array(v, float) / np.linalg.norm(v)
                session.changed()
            ch, v = imgui.drag_float3("irradiance W/m2", [float(x) for x in light.irradiance], 0.05, 0.0, 1e6)
            if ch and all(np.isfinite(v)) and min(v) >= 0:
                light.irradiance = np.array(v, float)
                session.changed()
        imgui.pop_id()
