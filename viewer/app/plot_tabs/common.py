"""What the plots panel's tabs share: the material palette, the light's and the Fresnel
components' colours, colour vectors, text labels in a plot, the comparison of plot data, and
the flowed tab row (tabs that never shrink into "Sa...")."""

from __future__ import annotations

import json

import numpy as np
from imgui_bundle import imgui, implot

CHANNELS = ("lum", "r", "g", "b")
CHANNEL_LABELS = ("luminance", "red", "green", "blue")
# one colour per material, in the order materials are first seen (Tableau 10, then lighter tints)
PALETTE = ((0.12, 0.47, 0.71), (1.00, 0.50, 0.05), (0.17, 0.63, 0.17), (0.84, 0.15, 0.16),
           (0.58, 0.40, 0.74), (0.55, 0.34, 0.29), (0.89, 0.47, 0.76), (0.50, 0.50, 0.50),
           (0.74, 0.74, 0.13), (0.09, 0.75, 0.81),
           (0.68, 0.78, 0.91), (1.00, 0.73, 0.47), (0.60, 0.87, 0.54), (1.00, 0.60, 0.59),
           (0.77, 0.69, 0.84), (0.77, 0.61, 0.58), (0.97, 0.71, 0.82), (0.78, 0.78, 0.78),
           (0.86, 0.86, 0.55), (0.62, 0.85, 0.90))
# the incident direction: a colour of its own, far from every material's (a test checks it)
LIGHT = (1.00, 0.92, 0.20)
# Fresnel components: hues of their own (R keeps the material's colour), as the CLI plot's
R_S_COLOUR, R_P_COLOUR = (0.30, 0.80, 1.00), (1.00, 0.30, 0.65)
# wavelength ticks of the spectral tab's half-width plots (implot's defaults collide there)
WAVELENGTH_TICKS = (400.0, 550.0, 700.0)


def vec4(rgb, a=1.0):
    return imgui.ImVec4(float(rgb[0]), float(rgb[1]), float(rgb[2]), float(a))


def label(text, x, y, left: bool = False):
    """Text in a plot starting just right of (x, y), or ending just left of it (plot_text
    centres it)."""
    half = imgui.calc_text_size(text).x / 2 + 4
    implot.plot_text(text, x, y, imgui.ImVec2(-half if left else half, 0))


def same_data(a, b) -> bool:
    """Two plot data (dicts of arrays, lists, numbers, strings) hold the same curves."""
    if isinstance(a, dict) and isinstance(b, dict):
        return a.keys() == b.keys() and all(same_data(a[k], b[k]) for k in a)
    if isinstance(a, (list, tuple)) and isinstance(b, (list, tuple)):
        return len(a) == len(b) and all(same_data(x, y) for x, y in zip(a, b))
    if isinstance(a, np.ndarray) or isinstance(b, np.ndarray):
        a, b = np.asarray(a), np.asarray(b)
        if a.shape != b.shape:
            return False
        if a.dtype.kind in "fc" or b.dtype.kind in "fc":
            return bool(np.allclose(a, b, rtol=1e-9, atol=1e-12, equal_nan=True))
        return bool(np.array_equal(a, b))
    return a == b


def params_key(p) -> str:
    return json.dumps(p.to_plain(), sort_keys=True, default=str)


def flow_rows(widths, avail: float, spacing: float) -> list[list[int]]:
    """Items of ``widths`` laid out left to right, a new row whenever the next would pass
    ``avail``: [[indices of row 0], [row 1], ...]. An item wider than ``avail`` gets a row of
    its own (it is never shrunk)."""
    rows: list[list[int]] = []
    x = None
    for i, w in enumerate(widths):
        if x is None or x + spacing + w > avail:
            rows.append([i])
            x = w
        else:
            rows[-1].append(i)
            x += spacing + w
    return rows


def equal_aspect_limits(x0, x1, y0, y1, width_px: float, height_px: float):
    """Axis limits containing [x0, x1] x [y0, y1] with the same data units per pixel on both
    axes of a plot area ``width_px`` x ``height_px`` (a circle drawn as a circle, 45 degrees
    drawn at 45 degrees): the axis with room to spare is widened about its centre."""
    w, h = max(float(width_px), 1.0), max(float(height_px), 1.0)
    ux, uy = (x1 - x0) / w, (y1 - y0) / h
    u = max(ux, uy)
    cx, cy = (x0 + x1) / 2, (y0 + y1) / 2
    if ux < u:
        x0, x1 = cx - u * w / 2, cx + u * w / 2
    if uy < u:
        # keep the bottom (the surface, or the refracted side) where it is: widen upwards
        y1 = y0 + u * h
    return x0, x1, y0, y1


def pixel_aspect(x_unit: float = 1.0, y_unit: float = 1.0) -> float:
    """Inside a plot: pixels per data unit along x over pixels per data unit along y, measured
    from implot's own transform (1 = equal aspect)."""
    o = implot.plot_to_pixels(0.0, 0.0)
    px = implot.plot_to_pixels(x_unit, 0.0)
    py = implot.plot_to_pixels(0.0, y_unit)
    return abs(px.x - o.x) / x_unit / max(abs(py.y - o.y) / y_unit, 1e-12)
