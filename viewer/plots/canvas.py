"""The drawing library (Pillow): a supersampled canvas with text (DejaVu Sans, Greek letters),
dashed polylines and rotated labels; nice axis ticks and their labels; the viridis colour map;
legends beside or below the plot (never over its curves), names ellipsized only when wider than
the canvas; mark labels placed where they cover the fewest curve
points; layers clipped to the plot area; arrows; the figure's header."""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np

CHANNEL_NAMES = ("red", "green", "blue")
CHANNEL_COLOURS = ((214, 39, 40), (44, 160, 44), (31, 119, 180))
NEUTRAL = (25, 25, 25)


@functools.lru_cache(maxsize=32)
def _font(size: int):
    from PIL import ImageFont

    for name in ("DejaVuSans.ttf", "/usr/share/fonts/truetype/dejavu/DejaVuSans.ttf"):
        try:
            return ImageFont.truetype(name, size), True
        except OSError:
            pass
    return ImageFont.load_default(size=size), False  # Aileron: no Greek letters


_GREEK = {"theta": "θ", "sigma": "σ", "rho": "ρ", "phi": "φ", "delta": "δ"}


def _pretty(text: str, unicode_ok: bool) -> str:
    if not unicode_ok:
        return text.replace("°", " deg")
    import re

    for word, g in _GREEK.items():
        text = re.sub(rf"\b{word}(_[a-z]+)?\b", lambda m, g=g: g + (m.group(1) or ""), text)
    return text


class Canvas:
    """A supersampled RGB image with helpers; ``image()`` returns the box-filtered result."""

    def __init__(self, width, height, ss=3):
        from PIL import Image, ImageDraw

        self.ss = ss
        self.w, self.h = width * ss, height * ss
        self.im = Image.new("RGB", (self.w, self.h), (255, 255, 255))
        self.draw = ImageDraw.Draw(self.im)

    def s(self, v):
        return v * self.ss

    def font(self, px):
        return _font(int(round(px * self.ss)))

    def text(self, xy, text, px=13, fill=(30, 30, 30), anchor="la", unicode=True):
        font, ok = self.font(px)
        t = _pretty(text, ok) if unicode else text
        self.draw.text(xy, t, font=font, fill=fill, anchor=anchor)
        return self.draw.textbbox(xy, t, font=font, anchor=anchor)

    def text_size(self, text, px=13):
        font, ok = self.font(px)
        l, t, r, b = self.draw.textbbox((0, 0), _pretty(text, ok), font=font)
        return r - l, b - t

    def vtext(self, xy, text, px=13, fill=(30, 30, 30)):
        """Text rotated 90 degrees (reading upward), centred on xy."""
        from PIL import Image, ImageDraw

        font, ok = self.font(px)
        t = _pretty(text, ok)
        l, tp, r, b = self.draw.textbbox((0, 0), t, font=font)
        tmp = Image.new("L", (r - l + 4, b - tp + 4), 0)
        ImageDraw.Draw(tmp).text((2 - l, 2 - tp), t, font=font, fill=255)
        tmp = tmp.rotate(90, expand=True)
        x, y = int(xy[0] - tmp.width / 2), int(xy[1] - tmp.height / 2)
        self.im.paste(Image.new("RGB", tmp.size, fill), (x, y), tmp)

    def polyline(self, pts, color, width=2.0, style="solid", draw=None):
        draw = draw or self.draw
        pts = [tuple(map(float, q)) for q in pts]
        if len(pts) < 2:
            return
        w = max(1, int(round(width * self.ss)))
        if style == "solid":
            draw.line(pts, fill=color, width=w, joint="curve")
            return
        on, off = {"dashed": (9, 5), "dashdot": (5, 2.5)}.get(style, (2.2, 3.5))
        on, off = on * self.ss * width / 2, off * self.ss * width / 2
        # walk along the polyline, emitting 'on' pieces
        seg, drawing, remaining = [pts[0]], True, on
        for a, b in zip(pts[:-1], pts[1:]):
            ax, ay = a
            bx, by = b
            length = math.hypot(bx - ax, by - ay)
            t = 0.0
            while length - t > remaining:
                t += remaining
                q = (ax + (bx - ax) * t / length, ay + (by - ay) * t / length)
                if drawing:
                    seg.append(q)
                    draw.line(seg, fill=color, width=w, joint="curve")
                seg = [q]
                drawing = not drawing
                remaining = off if not drawing else on
            remaining -= length - t
            if drawing:
                seg.append(b)
            else:
                seg = [b]
        if drawing and len(seg) > 1:
            draw.line(seg, fill=color, width=w, joint="curve")

    def image(self) -> np.ndarray:
        return np.asarray(self.im.reduce(self.ss), dtype=np.uint8).copy()


def nice_ticks(lo, hi, target=6):
    span = hi - lo
    if not span > 0:
        return [lo]
    raw = span / target
    e = 10 ** math.floor(math.log10(raw))
    step = min((m * e for m in (1, 2, 2.5, 5, 10) if m * e >= raw), default=10 * e)
    if abs(span - 90) < 1e-9 and lo == 0:
        step = 10.0
    if abs(span - 180) < 1e-9:
        step = 30.0
    first = math.ceil(lo / step - 1e-9) * step
    ticks = []
    v = first
    while v <= hi + 1e-9 * span:
        ticks.append(0.0 if abs(v) < 1e-12 * span else v)
        v += step
    return ticks


def tick_label(v, ticks):
    step = ticks[1] - ticks[0] if len(ticks) > 1 else 1.0
    digits = max(0, -int(math.floor(math.log10(step) + 1e-9))) if step < 1 else 0
    if step < 1 and abs(round(step * 10 ** digits) - step * 10 ** digits) > 1e-6:
        digits += 1
    return f"{v:.{digits}f}"


def nice_ceil(v: float) -> float:
    if not (v > 0 and math.isfinite(v)):
        return 1.0
    e = 10 ** math.floor(math.log10(v))
    for m in (1.0, 1.2, 1.5, 2.0, 2.5, 3.0, 4.0, 5.0, 6.0, 8.0, 10.0):
        if m * e >= v * (1 - 1e-9):
            return m * e
    return 10 * e


_VIRIDIS = np.array([[68, 1, 84], [59, 82, 139], [33, 145, 140], [94, 201, 98], [253, 231, 37]], float)


def colormap(t):
    t = np.clip(np.asarray(t, float), 0, 1) * (len(_VIRIDIS) - 1)
    i = np.minimum(np.floor(t).astype(int), len(_VIRIDIS) - 2)
    f = (t - i)[..., None]
    return _VIRIDIS[i] * (1 - f) + _VIRIDIS[i + 1] * f


def draw_header(cv, fig, width):
    cv.text((cv.s(width / 2), cv.s(10)), fig.title, px=17, anchor="ma")
    if fig.subtitle:
        cv.text((cv.s(width / 2), cv.s(32)), fig.subtitle, px=11, fill=(90, 90, 90), anchor="ma", unicode=False)
    for i, note in enumerate(fig.notes):
        cv.text((cv.s(width / 2), cv.s(50 + 14 * i)), note, px=11, fill=(70, 70, 70), anchor="ma")


@dataclass
class LegendPlan:
    """A legend laid out (canvas pixels, from its top left corner): ``w`` x ``h``, and per entry
    (text as drawn, colour, style, x, y of its row's top, the text's width, the text's room)."""
    w: float
    h: float
    row_h: float
    line_len: float
    cells: list

    def rect(self, x, y) -> tuple:
        return (x, y, x + self.w, y + self.h)


def ellipsize(cv, text, room, px=12) -> str:
    """``text`` whole if it is no wider than ``room`` (canvas pixels) at ``px``, else its longest
    start that fits with "..." after it."""
    if cv.text_size(text, px)[0] <= room:
        return text
    lo, hi = 1, len(text)
    while lo < hi:
        mid = (lo + hi + 1) // 2
        if cv.text_size(text[:mid].rstrip() + "...", px)[0] <= room:
            lo = mid
        else:
            hi = mid - 1
    return text[:lo].rstrip() + "..."


def plan_legend(cv, items, max_w, px=12, max_cols=None):
    """items: [(label, color, style)] as a legend at most ``max_w`` canvas pixels wide: columns
    of the widest entry's width (as many as fit, at most ``max_cols``), filled top to bottom; an
    entry wider than the legend is ellipsized. None without items."""
    if not items:
        return None
    pad, line_len, gap, col_gap = cv.s(6), cv.s(28), cv.s(8), cv.s(16)
    sizes = [cv.text_size(lbl, px) for lbl, _, _ in items]
    row_h = max(cv.s(px + 4), max(h for _, h in sizes) + cv.s(4))
    inner = max(max_w - 2 * pad, line_len + gap + cv.s(12))
    col_w = min(line_len + gap + max(tw for tw, _ in sizes), inner)
    cols = max(1, int((inner + col_gap) // (col_w + col_gap)))
    cols = min(cols, len(items), max_cols or len(items))
    rows = -(-len(items) // cols)
    room = col_w - line_len - gap
    cells = []
    for i, (lbl, col, style) in enumerate(items):
        c, r = divmod(i, rows)
        text = ellipsize(cv, lbl, room, px)
        cells.append((text, col, style, pad + c * (col_w + col_gap), pad + r * row_h, cv.text_size(text, px)[0], room))
    return LegendPlan(cols * col_w + (cols - 1) * col_gap + 2 * pad, rows * row_h + 2 * pad, row_h, line_len, cells)


def draw_legend(cv, plan, x, y, px=12):
    """The legend ``plan`` (``plan_legend``) with its top left corner at (x, y); its rect."""
    if plan is None:
        return None
    cv.draw.rectangle(list(plan.rect(x, y)), fill=(255, 255, 255), outline=(170, 170, 170), width=cv.s(1))
    for text, col, style, cx, cy, _, _ in plan.cells:
        mid = y + cy + plan.row_h / 2
        cv.polyline([(x + cx, mid), (x + cx + plan.line_len, mid)], col, 2.0, style)
        cv.text((x + cx + plan.line_len + cv.s(8), mid), text, px=px, anchor="lm")
    return plan.rect(x, y)


def legend_beside_or_below(cv, items, width, height, beside_frac=0.3, px=12):
    """Where a plot's legend goes, outside its axes: ("beside", plan) when one column of it,
    nothing ellipsized, takes at most ``beside_frac`` of the canvas width and fits its height;
    else ("below", plan) in as many columns as the canvas width allows; (None, None) without
    items. Canvas sizes in unscaled pixels; the plan in canvas pixels."""
    if not items:
        return None, None
    one = plan_legend(cv, items, cv.s(width * beside_frac), px, max_cols=1)
    whole = all(c[0] == lbl for c, (lbl, _, _) in zip(one.cells, items))
    if whole and one.h <= cv.s(height * 0.7):
        return "beside", one
    return "below", plan_legend(cv, items, cv.s(width - 40), px)


def curve_pixels(fig, to_px, step):
    """Points along every curve in canvas pixels, at most ``step`` apart."""
    xs, ys = [], []
    for c in fig.curves:
        px, py = to_px(np.asarray(c.x, float), np.asarray(c.y, float))
        seg = np.hypot(np.diff(px), np.diff(py))
        k = np.maximum(1, np.ceil(seg / step)).astype(int)
        for a in range(int(k.max()) if k.size else 0):
            f = a / k
            use = a < k
            xs.append((px[:-1] + np.diff(px) * f)[use])
            ys.append((py[:-1] + np.diff(py) * f)[use])
        xs.append(px[-1:])
        ys.append(py[-1:])
    if not xs:
        return np.zeros(0), np.zeros(0)
    return np.concatenate(xs), np.concatenate(ys)


def place_labels(cv, labels, box, px_pts, py_pts, obstacles):
    """Positions (x, y, w, h) for mark labels next to their vertical lines, where they cover the
    fewest curve points and no other label or the legend."""
    x0, y0, x1, y1 = box
    placed = []
    for lx, text in labels:
        tw, th = cv.text_size(text, 12)
        th += cv.s(4)
        best = None
        ys = np.arange(y0 + cv.s(6), y1 - th - cv.s(4), max(1.0, th / 3))
        for side in (1, -1):
            tx = lx + cv.s(5) if side > 0 else lx - cv.s(5) - tw
            if tx < x0 + cv.s(2) or tx + tw > x1 - cv.s(2):
                continue
            for ty in ys:
                r = (tx - cv.s(3), ty - cv.s(3), tx + tw + cv.s(3), ty + th + cv.s(3))
                hits = np.count_nonzero((px_pts >= r[0]) & (px_pts <= r[2]) & (py_pts >= r[1]) & (py_pts <= r[3]))
                over = sum(1 for o in obstacles + [p[4] for p in placed]
                           if o and not (r[2] < o[0] or r[0] > o[2] or r[3] < o[1] or r[1] > o[3]))
                score = hits + 1000 * over + (ty - y0) / (y1 - y0) * 0.5 + (0.25 if side < 0 else 0)
                if best is None or score < best[0]:
                    best = (score, tx, ty, tw, th, r)
        if best is None:
            best = (0, lx + cv.s(5), y0 + cv.s(6), tw, th, None)
        placed.append((best[1], best[2], best[3], best[4], best[5]))
    return placed


def clipped_layer(cv):
    """A transparent layer over the canvas; ``paste_clipped`` puts it back inside a rect."""
    from PIL import Image, ImageDraw

    layer = Image.new("RGBA", cv.im.size, (0, 0, 0, 0))
    return layer, ImageDraw.Draw(layer)


def paste_clipped(cv, layer, box):
    from PIL import Image, ImageChops

    mask = Image.new("L", cv.im.size, 0)
    mask.paste(255, tuple(int(round(v)) for v in box))
    alpha = ImageChops.multiply(layer.getchannel("A"), mask)
    cv.im.paste(layer.convert("RGB"), (0, 0), alpha)


def arrow(cv, a, b, color, width=2.0, head=10):
    cv.draw.line([a, b], fill=color, width=max(1, int(cv.s(width))))
    ang = math.atan2(b[1] - a[1], b[0] - a[0])
    h = cv.s(head)
    pts = [b, (b[0] - h * math.cos(ang - 0.4), b[1] - h * math.sin(ang - 0.4)),
           (b[0] - h * math.cos(ang + 0.4), b[1] - h * math.sin(ang + 0.4))]
    cv.draw.polygon(pts, fill=color)


def draw_grid(cv, a, box, signed=False, vmax=None):
    """An (rows, cols) array as cells in ``box`` (canvas pixels): grey ramp from 0 to vmax, or
    red (positive) / blue (negative) up to +-vmax."""
    x0, y0, x1, y1 = box
    rows, cols = a.shape
    if vmax is None:
        vmax = float(np.abs(a).max()) or 1.0
    t = np.clip(a / vmax, -1.0, 1.0)
    if signed:
        rgb = np.stack([1 - np.clip(-t, 0, 1), 1 - np.abs(t), 1 - np.clip(t, 0, 1)], axis=-1)
    else:
        rgb = np.repeat((1.0 - t)[..., None], 3, axis=-1)
    from PIL import Image

    img = Image.fromarray((rgb * 255 + 0.5).astype(np.uint8)).resize((int(x1 - x0), int(y1 - y0)), Image.NEAREST)
    cv.im.paste(img, (int(x0), int(y0)))
    cv.draw.rectangle([x0, y0, x1, y1], outline=(90, 90, 90), width=cv.s(1))
    return vmax
