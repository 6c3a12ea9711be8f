"""What the plots panel's tabs share: the material palette, the light's and the Fresnel
components' colours, colour vectors, text labels in a plot, the comparison of plot data, the
flowed tab row (tabs that never shrink into "Sa...") and the legend's layout under a plot."""

from __future__ import annotations

import json
import zlib
from dataclasses import dataclass

import numpy as np
from imgui_bundle import imgui, implot

CHANNELS = ("lum", "r", "g", "b")
CHANNEL_LABELS = ("luminance", "red", "green", "blue")
# the materials' colours (Tableau 10, then lighter tints), chosen by ``colour_slots``
PALETTE = ((0.12, 0.47, 0.71), (1.00, 0.50, 0.05), (0.17, 0.63, 0.17), (0.84, 0.15, 0.16),
           (0.58, 0.40, 0.74), (0.55, 0.34, 0.29), (0.89, 0.47, 0.76), (0.50, 0.50, 0.50),
           (0.74, 0.74, 0.13), (0.09, 0.75, 0.81),
           (0.68, 0.78, 0.91), (1.00, 0.73, 0.47), (0.60, 0.87, 0.54), (1.00, 0.60, 0.59),
           (0.77, 0.69, 0.84), (0.77, 0.61, 0.58), (0.97, 0.71, 0.82), (0.78, 0.78, 0.78),
           (0.86, 0.86, 0.55), (0.62, 0.85, 0.90))


STRONG = 10  # PALETTE[:STRONG]: the saturated colours, used before the tints


def colour_slot(name: str) -> int:
    """The palette entry a material called ``name`` asks for, among the saturated ones: CRC-32
    of its name (the same in every process, unlike ``hash``, which Python salts per process)."""
    return zlib.crc32(name.encode("utf-8")) % STRONG


def colour_slots(names) -> dict[str, int]:
    """Palette entries for the materials ``names``, all different while there are no more of
    them than colours: each takes the entry its name asks for (``colour_slot``) or, where an
    earlier name took it, the next free saturated one, and only when those are all taken a tint
    (the names taken in sorted order). A function of the set of names alone, so a material keeps
    its colour from run to run, whatever order the scene lists them in or the window met them."""
    out: dict[str, int] = {}
    for name in sorted(set(names)):
        want = colour_slot(name)
        order = [(want + i) % STRONG for i in range(STRONG)]
        order += [STRONG + (want + i) % (len(PALETTE) - STRONG) for i in range(len(PALETTE) - STRONG)]
        free = [i for i in order if i not in out.values()]
        out[name] = free[0] if free else want
    return out


# the incident direction: a colour of its own, far from every material's (a test checks it): white,
# as no material's is (a yellow read as the olive material's on a projector)
LIGHT = (1.00, 1.00, 1.00)
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


# two curves that differ by at most this fraction of their largest value are drawn once: at a
# thousandth they lie under half a pixel apart on a plot 500 pixels tall, one hidden under the other
CURVE_TOL = 1e-3


def curve_gap(a, b) -> float | None:
    """How far apart two plot data (as ``same_data`` takes them) are: the largest difference of
    their float arrays, each relative to the largest magnitude in that pair of arrays; None
    when they differ in anything else (keys, lengths, shapes, other values)."""
    if isinstance(a, dict) and isinstance(b, dict):
        if a.keys() != b.keys():
            return None
        gaps = [curve_gap(a[k], b[k]) for k in a]
    elif isinstance(a, (list, tuple)) and isinstance(b, (list, tuple)):
        if len(a) != len(b):
            return None
        gaps = [curve_gap(x, y) for x, y in zip(a, b)]
    elif isinstance(a, np.ndarray) or isinstance(b, np.ndarray) or isinstance(a, float) or isinstance(b, float):
        a, b = np.asarray(a), np.asarray(b)
        if a.shape != b.shape:
            return None
        if a.dtype.kind not in "fiu" or b.dtype.kind not in "fiu":
            return 0.0 if np.array_equal(a, b) else None
        a, b = a.astype(np.float64), b.astype(np.float64)
        if not np.array_equal(np.isnan(a), np.isnan(b)):
            return None
        ok = ~np.isnan(a)
        if not ok.any():
            return 0.0
        scale = max(float(np.abs(a[ok]).max()), float(np.abs(b[ok]).max()))
        return float(np.abs(a[ok] - b[ok]).max()) / scale if scale > 0 else 0.0
    else:
        return 0.0 if a == b else None
    return None if any(g is None for g in gaps) else max(gaps, default=0.0)


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


def legend_text(label: str) -> str:
    """What a plot item's label shows: the part before ``##`` (implot's hidden id), empty for a
    label that starts with it."""
    return label.split("##", 1)[0]


def ellipsize(text: str, room: float, width_of) -> str:
    """``text`` whole when ``width_of(text)`` fits ``room``, else its longest start that fits
    with "..." after it (at least the first letter)."""
    if width_of(text) <= room:
        return text
    lo, hi = 1, len(text)
    while lo < hi:  # the longest start that fits, found by bisection
        mid = (lo + hi + 1) // 2
        if width_of(text[:mid].rstrip() + "...") <= room:
            lo = mid
        else:
            hi = mid - 1
    return text[:lo].rstrip() + "..."


@dataclass(frozen=True)
class LegendCell:
    """One legend entry laid out: its text (ellipsized to its room), the text's width, the
    colour, the whole text, and its cell (x, y from the legend's top left corner, w, h); the swatch is the
    cell's first ``swatch`` points (``style``: "line", a thick line; "dots", a thin line with
    dots on it, as a curve drawn with markers), the text starts ``text_x`` from the cell's left."""
    text: str
    text_w: float
    colour: tuple
    full: str
    x: float
    y: float
    w: float
    h: float
    text_x: float
    style: str = "line"

    @property
    def text_room(self) -> float:
        return self.w - self.text_x


def legend_layout(entries, width_of, avail: float, swatch: float, gap: float, spacing: float,
                  row_h: float) -> tuple[list[LegendCell], tuple[float, float]]:
    """A legend of ``entries`` [(text, colour) or (text, colour, style)] in rows under the plot,
    ``avail`` wide: each
    entry a swatch, a gap and its text, placed left to right with ``spacing`` between them and
    a new row where the next would pass ``avail`` (``flow_rows``); an entry wider than ``avail``
    alone is ellipsized to it. Returns the cells and the legend's (width, height)."""
    text_x = swatch + gap
    room = max(avail - text_x, 1.0)
    shown = [ellipsize(e[0], room, width_of) for e in entries]
    text_w = [width_of(t) for t in shown]
    rows = flow_rows([text_x + w for w in text_w], avail, spacing)
    cells = []
    for r, row in enumerate(rows):
        x = 0.0
        for i in row:
            w = text_x + text_w[i]
            style = entries[i][2] if len(entries[i]) > 2 else "line"
            cells.append(LegendCell(shown[i], text_w[i], tuple(entries[i][1]), entries[i][0], x, r * row_h, w,
                                    row_h, text_x, style))
            x += w + spacing
    width = max((c.x + c.w for c in cells), default=0.0)
    return cells, (width, len(rows) * row_h)


def legend_below(panel, entries) -> None:
    """``entries`` [(text, colour) or (text, colour, style)] as a legend under the plot of ``panel`` (a ``PlotsPanel``),
    outside the axes: a grid of equal cells (``legend_layout``), as many columns as the widest
    entry allows, an entry wider than the window ellipsized (its whole text in a tooltip); its
    box and cells are recorded in ``panel.legend_boxes`` / ``legend_cells`` by tab, and an
    entry whose text does not fit its cell in ``panel.clipped``."""
    if not entries:
        panel.legend_boxes.pop(panel.tab, None)
        panel.legend_cells.pop(panel.tab, None)
        return
    k = panel.font_k()
    style = imgui.get_style()
    row_h = imgui.get_text_line_height_with_spacing()
    swatch, gap = 22 * k, style.item_inner_spacing.x + 2 * k
    cells, (w, h) = legend_layout(entries, lambda t: imgui.calc_text_size(t).x, panel.avail_x(), swatch, gap,
                                  2 * style.item_spacing.x, row_h)
    o = imgui.get_cursor_screen_pos()
    dl = imgui.get_window_draw_list()
    text_col = imgui.get_color_u32(imgui.Col_.text)
    text_h = imgui.get_text_line_height()
    for c in cells:
        x, y = o.x + c.x, o.y + c.y
        cy = y + row_h / 2
        col = imgui.get_color_u32(vec4(c.colour))
        dl.add_line(imgui.ImVec2(x, cy), imgui.ImVec2(x + swatch, cy), col, (1.0 if c.style == "dots" else 3.0) * k)
        if c.style == "dots":
            for f in (0.2, 0.5, 0.8):
                dl.add_circle_filled(imgui.ImVec2(x + f * swatch, cy), 2.5 * k, col)
        dl.add_text(imgui.ImVec2(x + c.text_x, y + (row_h - text_h) / 2), text_col, c.text)
        if c.text != c.full and imgui.is_mouse_hovering_rect(imgui.ImVec2(x, y), imgui.ImVec2(x + c.w, y + c.h)):
            imgui.set_tooltip(c.full)
        if c.text_w > c.text_room + 0.5:
            panel.clipped.append(c.text)
    imgui.dummy(imgui.ImVec2(max(w, 1.0), h))
    panel.legend_boxes[panel.tab] = (o.x, o.y, o.x + w, o.y + h)
    panel.legend_cells[panel.tab] = cells
