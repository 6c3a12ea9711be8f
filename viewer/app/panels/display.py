"""The side panel's *Display* section: the compare image, the plots, the UI scale, exposure, tone
map, view mode, shadows, reflections / refraction."""

from __future__ import annotations

import numpy as np
from imgui_bundle import imgui

from viewer.app import ui


def draw(win) -> None:
    from viewer.app.compare_view import MODES
    from viewer.gl.renderer import TONEMAPS, VIEW_MODES

    session = win.session
    cmp = session.compare
    if not imgui.collapsing_header("Display", imgui.TreeNodeFlags_.default_open):
        return
    ch, i = imgui.combo("image (C)", MODES.index(cmp.mode), list(MODES))
    if ch:
        session.set_image_mode(MODES[i])
    _compare_settings(session)
    ch, v = imgui.checkbox("BRDF plots (P)", win.plots.visible)
    if ch:
        win.plots.visible = v
    ch, v = imgui.slider_float("UI scale", float(win.ui_scale), 0.5, 3.0, "%.2f")
    if imgui.is_item_hovered():
        from viewer.app.layout import UI_SCALES

        imgui.set_tooltip("Ctrl + / Ctrl - step through " + ", ".join(f"{v:g}" for v in UI_SCALES) + "; Ctrl 0: 1")
    if ch and np.isfinite(v):
        win.set_ui_scale(v)
    r = session.scene.render
    ch, v = imgui.slider_float("exposure (EV)", float(r.exposure), -10.0, 10.0)
    if ch:
        r.exposure = ui.finite_or(v, r.exposure)
    names = list(TONEMAPS)
    ch, i = imgui.combo("tone map", names.index(r.tonemap) if r.tonemap in names else 0, names)
    if ch:
        r.tonemap = names[i]
    ch, i = imgui.combo("view", session.view_mode, list(VIEW_MODES))
    if ch:
        session.set_view_mode(i)
    ch, v = imgui.checkbox("shadows", bool(r.shadows))
    if ch:
        r.shadows = v
        session.changed()
    _reflections(session)


def _compare_settings(session) -> None:
    cmp = session.compare
    if cmp.mode == "split":
        ch, v = imgui.slider_float("divider", float(cmp.split), 0.0, 1.0)
        if ch:
            cmp.split = float(np.clip(ui.finite_or(v, 0.5), 0.0, 1.0))
    if cmp.mode in ("difference", "relative difference"):
        ch, v = imgui.checkbox("auto scale (99th percentile)", cmp.auto_scale)
        if ch:
            cmp.auto_scale = v
        if not cmp.auto_scale:
            ch, v = imgui.slider_float("scale", float(cmp.scale), 1e-4, 10.0, "%.4g",
                                       imgui.SliderFlags_.logarithmic)
            if ch and np.isfinite(v) and v > 0:
                cmp.scale = float(v)
    rv = session.reference
    if cmp.uses_reference and rv is not None:
        imgui.text(f"reference ({rv.active_engine or rv.engine or '...'}): {rv.spp} spp, "
                   f"{rv.samples_per_second / 1e3:.1f} k samples/s")
        if session.metrics_text():  # the same words as over the image
            imgui.text_wrapped(session.metrics_text())
        if rv.engine_note:
            imgui.text_wrapped(rv.engine_note)
        if rv.error:
            imgui.text_wrapped(rv.error)


def _reflections(session) -> None:
    """Reflections / refraction: off, SSR, ray traced (viewer/app/reflections.py)."""
    from viewer.app.reflections import MODES, TOOLTIPS

    mode = session.reflection_mode
    imgui.text("reflections / refraction")
    ch, i = imgui.combo("##reflections", MODES.index(mode), list(MODES))
    if imgui.is_item_hovered():
        imgui.set_tooltip(TOOLTIPS[MODES[i]])
    if ch:
        session.set_reflection_mode(MODES[i])
    if session.reflection_mode == "ray traced":
        ch, v = imgui.checkbox("+ SSR on glossy lobes", bool(session.scene.render.ssr))
        if ch:
            session.set_reflection_mode("ray traced", ssr_on_glossy=v)
