"""The modal dialog of the window's twin question (``viewer.app.twin_question``): it names the
``.brdf`` file and its numpy twin, and offers *Run its Python twin* and *Not now*."""

from __future__ import annotations

TITLE = "Run a Python twin?##twin_question"
RUN, NOT_NOW = "Run its Python twin", "Not now"


def draw(imgui, question) -> bool:
    """Draw the question while one waits (the session's ``twins``); True while it is shown."""
    if question.current is None:
        return False
    if not imgui.is_popup_open(TITLE):
        imgui.open_popup(TITLE)
    vp = imgui.get_main_viewport()
    imgui.set_next_window_pos(imgui.ImVec2(vp.pos.x + vp.size.x / 2, vp.pos.y + vp.size.y / 2),
                              imgui.Cond_.appearing, imgui.ImVec2(0.5, 0.5))
    shown, _ = imgui.begin_popup_modal(TITLE, None, imgui.WindowFlags_.always_auto_resize)
    if not shown:
        return False
    imgui.push_text_wrap_pos(imgui.get_font_size() * 34)
    imgui.text_wrapped(question.question())
    imgui.pop_text_wrap_pos()
    answer = None
    if imgui.button(RUN):
        answer = True
    imgui.same_line()
    if imgui.button(NOT_NOW):
        answer = False
    if answer is not None:
        question.answer(answer)
        imgui.close_current_popup()
    imgui.end_popup()
    return True
