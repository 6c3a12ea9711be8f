"""The side panel's *Lights* section: each point light's position and intensity, each
directional light's direction and irradiance. A typed value the light cannot take (negative,
beyond the drag's range, not a number) is refused in one line naming the field and its range;
the old value stays."""

from __future__ import annotations

import numpy as np
from imgui_bundle import imgui

from viewer.app.ui import out_of_range

POWER_MAX = 1e6   # intensity (W/sr) and irradiance (W/m^2): the drags' range
POSITION_MAX = 1e4  # metres from the origin along any axis
# field -> (label, lo, hi)
FIELDS = {"position": ("position", -POSITION_MAX, POSITION_MAX),
          "intensity": ("intensity W/sr", 0.0, POWER_MAX),
          "direction": ("direction", -1e6, 1e6),
          "irradiance": ("irradiance W/m2", 0.0, POWER_MAX)}


def set_value(session, index: int, field: str, values) -> bool:
    """Set ``field`` of light ``index`` to ``values`` (3 numbers) if the light can take them;
    else one error notification naming the field and its range, and the old value stays."""
    label, lo, hi = FIELDS[field]
    msg = out_of_range(label, values, lo, hi)
    v = np.asarray(values, float)
    if not msg and field == "direction" and np.linalg.norm(v) <= 1e-6:
        msg = "direction: [0, 0, 0] has no direction; allowed: any non-zero vector"
    if msg:
        session.notify(f"light {index}: {msg}", error=True)
        return False
    light = session.scene.lights[index]
    setattr(light, field, v / np.linalg.norm(v) if field == "direction" else v)
    session.changed()
    return True


def draw(session) -> None:
    if not imgui.collapsing_header("Lights", imgui.TreeNodeFlags_.default_open):
        return
    for i, light in enumerate(session.scene.lights):
        imgui.push_id(f"light{i}")
        imgui.text(f"{i}: {light.type}")
        if light.type == "point":
            rows = (("position", 0.02), ("intensity", 0.1))
        else:
            rows = (("direction", 0.01), ("irradiance", 0.05))
        for field, speed in rows:
            label, lo, hi = FIELDS[field]
            clamp = (lo, hi) if lo >= 0.0 else (0.0, 0.0)  # (0, 0): no limits while dragging
            ch, v = imgui.drag_float3(label, [float(x) for x in getattr(light, field)], speed, *clamp)
            if ch:
                set_value(session, i, field, v)
        imgui.pop_id()
