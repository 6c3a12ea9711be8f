"""The drawing library (Pillow): a supersampled canvas with text (DejaVu Sans, Greek letters),
dashed polylines and rotated labels; nice axis ticks and their labels; the viridis colour map;
legends placed in the emptiest corner; mark labels placed where they cover the fewest curve
points; layers clipped to the plot area; arrows; the figure's header."""

from __future__ import annotations

import functools
import math

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


def draw_legend(cv, items, box, corner, px=12, draw=True):
    """items: [(label, color, style)]; box: the plot rect (x0, y0, x1, y1) in canvas pixels.
    Returns the legend's rect."""
    if not items:
        return None
    pad, line_len, gap = cv.s(6), cv.s(28), cv.s(4)
    sizes = [cv.text_size(lbl, px) for lbl, _, _ in items]
    row_h = max(cv.s(px + 4), max(h for _, h in sizes) + gap)
    w = line_len + cv.s(8) + max(tw for tw, _ in sizes) + 2 * pad
    h = row_h * len(items) + 2 * pad
    x0, y0, x1, y1 = box
    m = cv.s(8)
    lx = x0 + m if corner[1] == "l" else x1 - m - w
    ly = y0 + m if corner[0] == "t" else y1 - m - h
    if draw:
        cv.draw.rectangle([lx, ly, lx + w, ly + h], fill=(255, 255, 255), outline=(170, 170, 170), width=cv.s(1))
        for i, (lbl, col, style) in enumerate(items):
            cy = ly + pad + row_h * i + row_h / 2
            cv.polyline([(lx + pad, cy), (lx + pad + line_len, cy)], col, 2.0, style)
            cv.text((lx + pad + line_len + cv.s(8), cy), lbl, px=px, anchor="lm")
    return (lx, ly, lx + w, ly + h)


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


def best_corner(fig, to_px, box):
    """The plot corner where the fewest curve points lie (for the legend)."""
    x0, y0, x1, y1 = box
    cw, ch = (x1 - x0) * 0.45, (y1 - y0) * 0.4
    counts = {}
    for corner in ("tr", "tl", "br", "bl"):
        cx0 = x0 if corner[1] == "l" else x1 - cw
        cy0 = y0 if corner[0] == "t" else y1 - ch
        n = 0
        for c in fig.curves:
            px, py = to_px(np.asarray(c.x), np.asarray(c.y))
            n += int(np.sum((px >= cx0) & (px <= cx0 + cw) & (py >= cy0) & (py <= cy0 + ch)))
        counts[corner] = n
    return min(counts, key=lambda k: (counts[k], ("tr", "tl", "br", "bl").index(k)))


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
