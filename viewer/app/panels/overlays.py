"""Everything drawn over the 3D view: the compare labels and divider, colour bars, the RMSE
read-out, the lecture caption and the toast of the session's latest message (red for an error),
laid out by ``viewer.app.layout.overlay_layout`` so that none covers another."""

from __future__ import annotations

import time

from imgui_bundle import imgui

from viewer.app.layout import Rect, overlay_layout

ERROR_BG = (0.45, 0.05, 0.05, 0.85)
INFO_BG = (0, 0, 0, 0.6)


def measure():
    """Text extents for ``layout.overlay_layout``: imgui's, at the size drawn."""
    unscaled = imgui.get_style().font_scale_main

    def measure(text, size, wrap=None):  # at the size itself: glyph advances are not linear in it
        imgui.push_font(None, size / max(unscaled, 1e-6))
        try:
            v = imgui.calc_text_size(text, False, wrap if wrap else -1.0)
        finally:
            imgui.pop_font()
        return v.x, v.y

    return measure


def toast(session, toast_s: float):
    """The message to show as a toast now (None: none), shown for ``toast_s`` seconds; none but
    an error while the view shows its placeholder (no image: its label, what is being prepared
    and what it waits for, is then all the view says; a note about the environment light stood
    there for 6 s of a 10 s wait)."""
    m = session.last_message
    if m is None or not m.text or time.perf_counter() - m.time > toast_s:
        return None
    prep = session.frames.prep
    if prep.active and prep.kept is None and not m.error:
        return None
    return m


def plan(win):
    """The view's overlays as drawn this frame: (layout, texts); see ``layout.overlay_layout``."""
    session = win.session
    view = win.view_logical()
    cmp = session.compare
    m = None if win.view_only else toast(session, win.TOAST_S)
    rv = session.reference
    labels = cmp.overlay_labels(view, rv.spp if rv is not None else 0, preview=rv is not None and rv.preview,
                                error=rv.error if rv is not None else "",
                                estimator=rv.estimator_label if rv is not None else "")
    bars = cmp.overlay_bars(view) + session.monte_carlo.overlay_bars(cmp.reference_rect(view))
    title, caption = ("", "") if win.view_only else session.lecture_title
    # the progressive trace's progress stands where a toast would (a toast comes first)
    status = "" if win.view_only else session.trace_status  # the window's status line, not the view's
    texts = dict(labels=labels, toast=m.text if m else status, rmse=session.metrics_text(), bars=bars, title=title,
                 caption=caption)
    lay = overlay_layout(Rect(*view), imgui.get_font_size(), measure(), **texts)
    texts["toast_error"] = bool(m and m.error)
    return lay, texts


def draw(win) -> None:
    """Every overlay of the view, laid out by ``plan``."""
    from viewer.app.compare_view import draw_colour_bar

    session = win.session
    x, y, w, h = win.view_logical()
    if w < 60 or h < 60:
        return
    lay, t = plan(win)
    dl = imgui.get_background_draw_list()  # over the 3D view, under imgui windows
    white = imgui.get_color_u32(imgui.ImVec4(1, 1, 1, 1))
    shade = imgui.get_color_u32(imgui.ImVec4(0, 0, 0, 0.55))
    pad = lay["pad"].x
    font, base = imgui.get_font(), imgui.get_font_size()

    def label(r, text, align_right=False):
        tw = min(imgui.calc_text_size(text).x, r.w - 2 * pad) if not align_right else imgui.calc_text_size(text).x
        bx = r.right - tw - 2 * pad if align_right else r.x
        dl.push_clip_rect(imgui.ImVec2(x, y), imgui.ImVec2(x + w, y + h), True)  # never past the view
        dl.add_rect_filled(imgui.ImVec2(bx, r.y), imgui.ImVec2(bx + tw + 2 * pad, r.bottom), shade)
        dl.add_text(imgui.ImVec2(bx + pad, r.y + pad), white, text)
        dl.pop_clip_rect()

    session.compare.draw_overlay(imgui, (x, y, w, h), lay, label)
    for i, (_, text) in enumerate(t["labels"]):
        label(lay[f"label{i}"], text)
    j = 0
    if session.compare.overlay_bars((x, y, w, h)) and "bar0" in lay:
        draw_colour_bar(imgui, dl, lay, 0, label, session.compare.scale, t["bars"][0][1])
        j = 1
    if len(t["bars"]) > j and f"bar{j}" in lay:
        session.monte_carlo.draw_overlay(imgui, lay, j, label)
    if t["rmse"] and "rmse" in lay:
        r = lay["rmse"]
        dl.add_rect_filled(imgui.ImVec2(r.x, r.y), imgui.ImVec2(r.right, r.bottom), shade)
        dl.add_text(font, base, imgui.ImVec2(r.x + pad, r.y + pad), white, t["rmse"], lay["wrap"].x)
    if "caption" in lay:
        _caption(dl, lay, t, white, font, base)
    if t["toast"] and "toast" in lay:
        r = lay["toast"]
        bg = imgui.ImVec4(*(ERROR_BG if t["toast_error"] else INFO_BG))
        dl.push_clip_rect(imgui.ImVec2(r.x, r.y), imgui.ImVec2(r.right, r.bottom), True)
        dl.add_rect_filled(imgui.ImVec2(r.x, r.y), imgui.ImVec2(r.right, r.bottom), imgui.get_color_u32(bg), 4.0)
        dl.add_text(font, base, imgui.ImVec2(r.x + pad, r.y + pad), white, t["toast"], lay["wrap"].x)
        dl.pop_clip_rect()


def _caption(dl, lay, t, white, font, base) -> None:
    """The lecture step's title and caption, centred in their box."""
    r = lay["caption"]
    dl.add_rect_filled(imgui.ImVec2(r.x, r.y), imgui.ImVec2(r.right, r.bottom),
                       imgui.get_color_u32(imgui.ImVec4(0, 0, 0, 0.6)), 6.0 * base / 16)
    px = lay["caption_px"]
    m = measure()
    for key, text, size in (("caption_title", t["title"], px.x), ("caption_text", t["caption"], px.y)):
        rr = lay[key]
        y = rr.y
        # each line measured and centred on its own (imgui's wrapped drawing can run a word past
        # the box that its measuring kept inside)
        for line in wrap_lines(text, rr.w, lambda s, size=size: m(s, size)[0]):
            tw, th = m(line, size)
            dl.add_text(font, size, imgui.ImVec2(rr.x + max((rr.w - tw) / 2, 0.0), y), white, line)
            y += th


def wrap_lines(text: str, width: float, text_width) -> list[str]:
    """``text`` broken at spaces into lines no wider than ``width`` by ``text_width(line)``
    (a word wider than ``width`` gets a line of its own)."""
    lines: list[str] = []
    for word in text.split():
        if lines and text_width(lines[-1] + " " + word) <= width:
            lines[-1] += " " + word
        else:
            lines.append(word)
    return lines
