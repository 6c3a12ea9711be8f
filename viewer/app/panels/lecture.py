"""Lecture mode's controls: the side panel's *Lecture* section and the narrow strip that replaces
the side panel while the lecture runs (menu, previous / next step, the step number, plots)."""

from __future__ import annotations

from imgui_bundle import imgui


def draw_section(session) -> None:
    from viewer.scene.lecture import TOUR

    if not imgui.collapsing_header("Lecture (L)"):
        return
    labels = ["(off)"] + [f"{i + 1}. {s.title}" for i, s in enumerate(TOUR)]
    ch, i = imgui.combo("step", session.lecture_step + 1, labels)
    if ch:
        session.lecture(i - 1 if i > 0 else None)
    if imgui.button("< prev"):
        session.lecture_previous()
    imgui.same_line()
    if imgui.button("next >"):
        session.lecture_next()
    imgui.text_disabled(step_keys_text(len(TOUR)))
    if imgui.button("Cancel preparing" if session.preparing else "Prepare lecture"):
        session.prepare_lecture()
    if imgui.is_item_hovered():
        imgui.set_tooltip("trace every step with glass or mirrors for this window's size into the cache,\n"
                          "in the background, so each opens fully traced in every layout of this window")
    if session.prep is not None:
        imgui.text_wrapped(session.prep.progress_text())
    if session.prefetch is not None:
        imgui.text_wrapped(session.prefetch.progress_text())


def step_keys_text(steps: int) -> str:
    """The lecture keys, for a tour of ``steps`` steps (Shift and a digit reach 11-19)."""
    shifted = f", Shift 1-{steps - 10} = {11}-{steps}" if steps > 11 else (", Shift 1 = 11" if steps == 11 else "")
    return f"keys: L on/off, 1-9 0 = steps 1-10{shifted}, arrows, PgUp/PgDn, Esc"


def draw_strip(win, rect) -> None:
    """The strip at ``rect``; its menu button floats the full panel over the view
    (``win.panel_open``)."""
    session = win.session
    imgui.set_next_window_pos(imgui.ImVec2(rect.x, rect.y))
    imgui.set_next_window_size(imgui.ImVec2(rect.w, rect.h))
    flags = (imgui.WindowFlags_.no_move | imgui.WindowFlags_.no_resize | imgui.WindowFlags_.no_collapse
             | imgui.WindowFlags_.no_title_bar | imgui.WindowFlags_.no_scrollbar)
    imgui.push_style_var(imgui.StyleVar_.window_padding, imgui.ImVec2(2, 6))
    imgui.begin("##lecture_strip", None, flags)
    bw = imgui.ImVec2(rect.w - 4, 0)
    if imgui.button("=##menu", bw):
        win.panel_open = not win.panel_open
    if imgui.is_item_hovered():
        imgui.set_tooltip("the full panel (settings, materials) over the view")
    if imgui.button("<##prev", bw):
        session.lecture_back()
    imgui.text(f"{session.lecture_step + 1}")
    if imgui.button(">##next", bw):
        session.lecture_next()
    if imgui.button("P##plots", bw):
        win.plots.visible = not win.plots.visible
    if imgui.is_item_hovered():
        imgui.set_tooltip("BRDF plots (P)")
    pf = session.prefetch
    if pf is not None and not pf.done and pf.total:
        imgui.text_disabled(f"{pf.finished}/{pf.total}")
        if imgui.is_item_hovered():
            imgui.set_tooltip(pf.progress_text())
    imgui.end()
    imgui.pop_style_var()
