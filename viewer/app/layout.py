"""Where the window's parts go, as pure functions of the window size, the UI scale and what is
shown (no imgui, no GL), so the layout can be tested at any size without a display.

``window_layout`` places the side panel (a narrow strip in lecture mode), the docked plots
window (beside the 3D view, never over it) and the 3D view. ``overlay_layout`` places the
view's overlays (compare labels, status toast, RMSE read-out, colour bars, lecture caption) so
that none covers another: labels and toast stack down from the top, the caption, colour bars
and RMSE stack up from the bottom. Every size is in window points and scales with the UI.

Text is measured by a ``measure(text, size_px, wrap_width) -> (w, h)`` callable: imgui's
``calc_text_size`` in the window, a simple fixed-advance model in the tests.
"""

from __future__ import annotations

from dataclasses import dataclass

PANEL_WIDTH = 360      # side panel at UI scale 1 (points)
STRIP_WIDTH = 44       # the panel collapsed to a strip in lecture mode, at UI scale 1
PLOTS_MIN = 300        # docked plots window: at least this wide at UI scale 1 ...
PLOTS_FRACTION = 0.38  # ... and this fraction of what the panel leaves (outside lecture mode)
LECTURE_VIEW_MIN = 0.70  # lecture mode: the 3D view keeps at least this fraction of the window width
FONT_PX = 16.0         # the UI font at scale 1
TITLE_K, CAPTION_K = 1.5, 1.15  # lecture title and caption sizes, times the UI font
CAPTION_MAX = 0.35     # the lecture caption box's share of the view's height it shrinks its text to keep
# the UI scales Ctrl + / Ctrl - step through (projectors: 1.5 and 2 among them)
UI_SCALES = (0.5, 0.75, 1.0, 1.25, 1.5, 1.75, 2.0, 2.5, 3.0)


def step_ui_scale(scale: float, up: bool) -> float:
    """The next of ``UI_SCALES`` above ``scale`` (``up``) or below it; the end one at the ends
    (a scale between two, set by the slider, steps to the next one it passes)."""
    if up:
        return next((s for s in UI_SCALES if s > scale + 1e-6), UI_SCALES[-1])
    return next((s for s in reversed(UI_SCALES) if s < scale - 1e-6), UI_SCALES[0])


@dataclass(frozen=True)
class Rect:
    x: float
    y: float
    w: float
    h: float

    @property
    def right(self) -> float:
        return self.x + self.w

    @property
    def bottom(self) -> float:
        return self.y + self.h

    def intersects(self, o: "Rect") -> bool:
        return (self.w > 0 and self.h > 0 and o.w > 0 and o.h > 0 and self.x < o.right and o.x < self.right
                and self.y < o.bottom and o.y < self.bottom)

    def inside(self, o: "Rect", eps: float = 1e-6) -> bool:
        return (self.x >= o.x - eps and self.y >= o.y - eps and self.right <= o.right + eps
                and self.bottom <= o.bottom + eps)

    def tuple(self) -> tuple[float, float, float, float]:
        return (self.x, self.y, self.w, self.h)


def window_layout(win_w: float, win_h: float, ui_scale: float, *, show_ui: bool = True, lecture: bool = False,
                  plots: bool = False, panel_open: bool = False) -> dict[str, Rect]:
    """{"panel" or "strip", "view", "plots"} in window points (y down). ``panel``: the side panel
    (its width follows the UI scale); in lecture mode a narrow ``strip`` instead, and with
    ``panel_open`` the full panel floating over the view at the lecturer's request (the only part
    allowed over the view). ``plots``: the docked plots window, beside the view; absent when
    hidden or when the view leaves no room for it (the plots window then floats)."""
    s = max(float(ui_scale), 0.1)
    out: dict[str, Rect] = {}
    left = 0.0
    if show_ui:
        if lecture:
            strip = min(STRIP_WIDTH * s, 0.08 * win_w)
            out["strip"] = Rect(0.0, 0.0, strip, win_h)
            left = strip
            if panel_open:
                out["panel"] = Rect(strip, 0.0, min(PANEL_WIDTH * s, 0.6 * win_w), win_h)
        else:
            left = min(PANEL_WIDTH * s, 0.9 * win_w)
            out["panel"] = Rect(0.0, 0.0, left, win_h)
    right = float(win_w)
    if show_ui and plots:
        rest = win_w - left
        if lecture:
            pw = max(0.0, win_w * (1.0 - LECTURE_VIEW_MIN) - left)
        else:
            pw = min(max(PLOTS_MIN * s, PLOTS_FRACTION * rest), 0.5 * rest)
        if pw >= 160:  # narrower than this a plot says nothing: the view keeps the room
            right = win_w - pw
            out["plots"] = Rect(right, 0.0, pw, win_h)
    out["view"] = Rect(left, 0.0, max(right - left, 0.0), float(win_h))
    return out


def view_columns(view: Rect, scale: float, fb_w: int) -> tuple[int, int]:
    """The 3D view's first framebuffer column and its width, for ``view`` in window points and
    ``scale`` framebuffer pixels a point: always an even width (the pixel it leaves goes to the
    panel, or at the window's left edge to the right edge), so that one prepared trace of the
    window's full width holds every layout's view (``viewer.gl.trace_cache``)."""
    x0, x1 = int(round(view.x * scale)), min(int(round(view.right * scale)), int(fb_w))
    if (x1 - x0) % 2 and x1 - x0 > 1:
        if x0 > 0:
            x0 += 1
        else:
            x1 -= 1
    return x0, max(x1 - x0, 0)


def text_model(char_k: float = 0.52, line_k: float = 1.2):
    """A fixed-advance text measure (each character ``char_k`` x the size wide, lines
    ``line_k`` x the size high, wrapped at spaces), for tests and for planning without imgui."""

    def measure(text: str, size: float, wrap: float | None = None):
        adv = char_k * size
        lines = []
        for para in text.split("\n"):
            cur = ""
            for word in para.split(" "):
                cand = word if not cur else cur + " " + word
                if wrap and cur and len(cand) * adv > wrap:
                    lines.append(cur)
                    cur = word
                else:
                    cur = cand
            lines.append(cur)
        return max(len(t) for t in lines) * adv, len(lines) * line_k * size

    return measure


def overlay_layout(view: Rect, font_px: float, measure, *, labels=(), toast: str = "", rmse: str = "",
                   bars=(), title: str = "", caption: str = "") -> dict[str, Rect]:
    """The overlays' boxes inside ``view``; each name maps to the box drawn (its text inside with
    ``pad`` around it). ``labels``: [(anchor_x, text)] in one row at the top, each moved right of
    the one before it when they would touch (a split divider at the left edge), wrapping to a new
    row at the view's right edge. ``bars``: [(owner Rect, what)] colour bars, each centred in its
    owner. Where the view is too small for all, the RMSE and then the colour bars are left out
    (the caption never: it shrinks its text), and the toast is cut. ``title`` / ``caption``: the lecture box at the bottom (title at TITLE_K x the font,
    caption at CAPTION_K x, both wrapped to the box). Keys: "label0".., "toast", "rmse",
    "bar0".. (the ramp), "bar0_what", "bar0_lo", "bar0_hi", "caption" (with "caption_title" and
    "caption_text" inside it, "caption_px": their font sizes as x, y), plus "pad" and "wrap" (the padding and the width the RMSE and
    toast texts wrap at, as 0-size rects' x, to keep one return type)."""
    k = font_px / FONT_PX
    m, pad = 8.0 * k, 4.0 * k
    line = measure("Ag", font_px, None)[1]
    out: dict[str, Rect] = {}
    x0, x1 = view.x + m, view.right - m
    top = view.y + m
    # ---- top: label row(s)
    row_y, row_h, prev_right = top, 0.0, None
    for i, (ax, text) in enumerate(labels):
        w, h = measure(text, font_px, None)
        bx = max(float(ax), x0)
        if prev_right is not None and bx < prev_right + m:
            bx = prev_right + m
        if prev_right is not None and bx + w + 2 * pad > x1:  # no room on this row
            row_y += row_h + m
            row_h, bx = 0.0, x0
        r = Rect(bx, row_y, max(min(w + 2 * pad, x1 - bx), 0.0), h + 2 * pad)  # clipped to the view
        out[f"label{i}"] = r
        prev_right, row_h = r.right, max(row_h, r.h)
    top = row_y + row_h + (m if row_h else 0.0)
    # ---- bottom: caption, colour bars, RMSE, stacked upwards
    bottom = view.bottom - m
    inner = max(view.w - 2 * m - 2 * 3 * pad, 40.0)
    if title or caption:
        for shrink in (1.0, 0.9, 0.8, 0.7, 0.6):  # a long caption on a small view: smaller text, up
            tpx, cpx = TITLE_K * font_px * shrink, CAPTION_K * font_px * shrink  # to CAPTION_MAX of it
            _, th = measure(title, tpx, inner) if title else (0.0, 0.0)
            _, ch = measure(caption, cpx, inner) if caption else (0.0, 0.0)
            box_h = 3 * pad + th + pad + ch + 3 * pad
            if box_h <= CAPTION_MAX * view.h or cpx * 0.9 < FONT_PX:
                break
        r = Rect(x0, bottom - box_h, x1 - x0, box_h)
        out["caption"] = r
        out["caption_px"] = Rect(tpx, cpx, 0.0, 0.0)  # (title size, caption size) as drawn
        out["caption_title"] = Rect(r.x + 3 * pad, r.y + 3 * pad, inner, th)
        out["caption_text"] = Rect(r.x + 3 * pad, r.y + 4 * pad + th, inner, ch)
        bottom = r.y - m
    for j, (owner, what) in enumerate(bars):
        bw = min(360.0 * k, owner.w * 0.5)
        bh = 14.0 * k
        bx = owner.x + (owner.w - bw) / 2
        lo_y = bottom - (line + 2 * pad)
        bar_y = lo_y - pad - bh
        ww, wh = measure(what, font_px, None)
        what_y = bar_y - pad - (wh + 2 * pad)
        if what_y < top:  # no room left between the top row and the bottom stack: left out
            break
        out[f"bar{j}"] = Rect(bx, bar_y, bw, bh)
        out[f"bar{j}_lo"] = Rect(bx, lo_y, bw * 0.3, line + 2 * pad)  # end labels share one row under the ramp
        out[f"bar{j}_hi"] = Rect(bx + bw * 0.7, lo_y, bw * 0.3, line + 2 * pad)
        wbox = min(ww + 2 * pad, x1 - x0)  # wider than the view: clipped when drawn
        wx = max(min(bx + bw / 2 - wbox / 2, x1 - wbox), x0)
        out[f"bar{j}_what"] = Rect(wx, what_y, wbox, wh + 2 * pad)
        bottom = what_y - m
    wrap = max(x1 - x0 - 2 * pad, 60.0)  # the width long texts (RMSE, toast) wrap at
    if rmse:
        w, h = measure(rmse, font_px, wrap)
        r = Rect(x0, bottom - h - 2 * pad, min(w + 2 * pad, x1 - x0), h + 2 * pad)
        if r.y >= top:  # else no room: left out (the panel shows it too)
            out["rmse"] = r
            bottom = r.y - m
    # ---- the toast: under the labels, clipped above the bottom stack
    if toast:
        w, h = measure(toast, font_px, wrap)
        h = max(0.0, min(h + 2 * pad, bottom - top))
        out["toast"] = Rect(x0, top, min(w + 2 * pad, x1 - x0), h)
    out["pad"] = Rect(pad, 0.0, 0.0, 0.0)
    out["wrap"] = Rect(wrap, 0.0, 0.0, 0.0)
    return out


def boxes(layout: dict[str, Rect]) -> dict[str, Rect]:
    """The drawn boxes of an ``overlay_layout`` (the parts that must not overlap): everything but
    the bookkeeping entries and the caption's inner text rects (inside the caption box)."""
    return {k: r for k, r in layout.items() if k not in ("pad", "wrap", "caption_title", "caption_text", "caption_px")}


def fit_rect(img_w: int, img_h: int, box: tuple) -> tuple[int, int, int, int]:
    """The largest rect with the image's aspect ratio centred in ``box`` = (x, y, w, h): the whole
    image shown (letterboxed), never cropped."""
    x, y, w, h = box
    if img_w <= 0 or img_h <= 0 or w <= 0 or h <= 0:
        return (int(x), int(y), 0, 0)
    s = min(w / img_w, h / img_h)
    fw, fh = max(1, int(round(img_w * s))), max(1, int(round(img_h * s)))
    return (int(x + (w - fw) // 2), int(y + (h - fh) // 2), fw, fh)
