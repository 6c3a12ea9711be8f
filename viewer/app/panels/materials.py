"""The side panel's *Materials* section: one tree node per material with its editor
(``viewer.app.ui.material_editor``); refused values are the session's error notifications."""

from __future__ import annotations

from imgui_bundle import imgui

from viewer.app import ui


def draw(session) -> None:
    if not imgui.collapsing_header("Materials", imgui.TreeNodeFlags_.default_open):
        return
    s = session.scene

    def on_error(text):
        session.notify(text, error=True)

    from viewer.app.reflections import traced_hint

    hint = traced_hint(s)
    if hint:  # glass with reflections off is a flat silhouette: say what shows it
        imgui.push_style_color(imgui.Col_.text, imgui.ImVec4(1.0, 0.8, 0.35, 1.0))
        imgui.text_wrapped(hint)
        imgui.pop_style_color()
    for i, name in enumerate(list(s.materials)):
        imgui.push_id(f"mat_{name}")
        if i == 0:  # the first material starts open
            imgui.set_next_item_open(True, imgui.Cond_.once)
        if imgui.tree_node(f"{name} ({s.materials[name].model})"):
            ch, new = ui.material_editor(s.materials[name], f"{name}.", on_error=on_error)
            if ch:
                session.set_material(name, new)
            imgui.tree_pop()
        imgui.pop_id()
