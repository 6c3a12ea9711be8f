"""The window's layout, computed without a display (viewer/app/layout.py): at projector sizes and
UI scales no overlay covers another, the plots dock beside the 3D view and lecture mode keeps the
view at least 70% of the window; side by side shows each image whole. Plus the plots panel's
pure helpers (marks, merged identical materials, colours, the glass albedo note, lobe shading)."""

import itertools
import math

import numpy as np
import pytest

from viewer.app.layout import (CAPTION_K, LECTURE_VIEW_MIN, TITLE_K, Rect, boxes, fit_rect, overlay_layout,
                               text_model, window_layout)

SIZES = ((1280, 720), (1920, 1080), (1024, 768))
SCALES = (1.0, 1.25, 2.4)
LONG_STATUS = ("environment: studio (intensity 0.412: mean luminance 0.437 -> mid-grey 0.18; edit it under "
               "Environment) and a second sentence long enough to wrap on every window size")


def _overlays(view, scale, mode, lecture_step, toast=True):
    from viewer.scene.lecture import TOUR

    font = 16.0 * scale
    x, y, w, h = view.tuple()
    labels = {"split": [(x, "raster"), (x + 0.001 * w, "reference (128 spp)")],   # divider at the left edge
              "side by side": [(x, "raster"), (x + w / 2, "reference (128 spp)")],
              "difference": [], "raster": []}[mode]
    bars = [(view, "|raster - reference| / (reference + 0.01)")] if mode == "difference" else []
    if mode == "side by side":  # an error view over the right half too
        bars = [(Rect(x + w / 2, y, w / 2, h), "relative error (standard error / mean)")]
    rmse = "RMSE 0.01234   relMSE 0.0456   (128 spp)" if mode != "raster" else ""
    title = caption = ""
    if lecture_step is not None:
        step = TOUR[lecture_step]
        title, caption = f"{lecture_step + 1}/{len(TOUR)}  {step.title}", step.caption
    return overlay_layout(view, font, text_model(), labels=labels, toast=LONG_STATUS if toast else "",
                          rmse=rmse, bars=bars, title=title, caption=caption)


@pytest.mark.parametrize("size,scale", list(itertools.product(SIZES, SCALES)))
def test_overlays_never_overlap(size, scale):
    from viewer.scene.lecture import TOUR

    longest = max(range(len(TOUR)), key=lambda i: len(TOUR[i].caption))
    for lecture, plots, mode in itertools.product((False, True), (False, True),
                                                  ("raster", "split", "side by side", "difference")):
        lay = window_layout(*size, scale, lecture=lecture, plots=plots)
        view = lay["view"]
        ov = boxes(_overlays(view, scale, mode, longest if lecture else None))
        where = (size, scale, lecture, plots, mode)
        for (a, ra), (b, rb) in itertools.combinations(ov.items(), 2):
            if {a, b} == {f"{a[:4]}_lo", f"{a[:4]}_hi"}:
                continue
            assert not ra.intersects(rb), (where, a, ra, b, rb)
        for k, r in ov.items():
            assert r.inside(view), (where, k, r, view)
        if lecture:
            # the caption keeps to 35% of the view; at x2.4 the longest (187 characters) on a 700 px
            # wide view cannot, its text already at 0.6 x its size: it may take up to 45%
            assert "caption" in ov and ov["caption"].h <= (0.36 if scale < 2 else 0.45) * view.h, (where, ov["caption"])
        # the window's parts: panel / strip, view and docked plots side by side, never over each other
        parts = {k: r for k, r in lay.items() if k in ("panel", "strip", "view", "plots")}
        for (a, ra), (b, rb) in itertools.combinations(parts.items(), 2):
            assert not ra.intersects(rb), (where, a, ra, b, rb)
        if lecture:
            assert view.w >= LECTURE_VIEW_MIN * size[0] - 1e-6, (where, view)
        if plots and lecture:
            assert "plots" in lay, where


def test_caption_wraps_inside_its_box_and_the_title_is_larger():
    assert TITLE_K > CAPTION_K
    for scale in SCALES:
        view = window_layout(1280, 720, scale, lecture=True, plots=True)["view"]
        lay = _overlays(view, scale, "raster", 2, toast=False)
        box, title, text = lay["caption"], lay["caption_title"], lay["caption_text"]
        assert title.inside(box) and text.inside(box), (scale, box, title, text)
        assert not title.intersects(text)
        px = lay["caption_px"]
        assert px.x > px.y >= 16.0 and px.y >= 0.6 * CAPTION_K * 16.0 * scale  # title larger; shrunk at most to 0.6
        assert text.h >= px.y  # at least one line at the caption's size


def test_toast_is_clipped_above_the_bottom_stack():
    view = Rect(0, 0, 400, 300)  # a small window: a long status cannot fit, it is cut, not overlaid
    lay = overlay_layout(view, 20.0, text_model(), toast=LONG_STATUS * 3, rmse="RMSE 0.1", title="1/14 Lambert",
                         caption="a caption that wraps over two lines in a small window")
    assert lay["toast"].h > 0 and lay["toast"].bottom <= lay["rmse"].y + 1e-9
    # smaller still: the RMSE read-out is left out rather than drawn over the caption
    lay = overlay_layout(Rect(0, 0, 300, 150), 32.0, text_model(), rmse="RMSE 0.1", title="1/14 Lambert",
                         caption="a caption that wraps over a few lines in a very small window")
    assert "rmse" not in lay and "caption" in lay


def test_labels_do_not_collide_when_the_divider_is_at_the_left_edge():
    view = Rect(0, 0, 800, 600)
    lay = overlay_layout(view, 16.0, text_model(), labels=[(0.0, "raster"), (0.0, "reference (8 spp)")])
    assert not lay["label0"].intersects(lay["label1"])
    lay = overlay_layout(view, 40.0, text_model(), labels=[(0.0, "raster"), (780.0, "reference (8 spp)")])
    assert not lay["label0"].intersects(lay["label1"]) and lay["label1"].inside(view)


def test_lecture_mode_keeps_the_view_and_collapses_the_panel():
    for (w, h), s in itertools.product(SIZES, SCALES):
        lay = window_layout(w, h, s, lecture=True, plots=False)
        assert "panel" not in lay and lay["strip"].w <= 0.08 * w + 1e-9
        assert lay["view"].w >= 0.9 * w, lay
        opened = window_layout(w, h, s, lecture=True, panel_open=True)
        assert "panel" in opened  # the full panel on request, floating over the view
    lay = window_layout(1280, 720, 2.4, lecture=False)  # outside lecture mode the panel follows the scale
    assert lay["panel"].w == pytest.approx(360 * 2.4)


def test_side_by_side_fits_each_image_whole():
    # each half shows the whole view's framing, letterboxed (nothing cropped)
    x, y, w, h = fit_rect(1000, 600, (0, 0, 500, 600))
    assert (w, h) == (500, 300) and y == 150 and x == 0
    assert fit_rect(1000, 600, (500, 0, 500, 600)) == (500, 150, 500, 300)


def test_side_by_side_rects_keep_the_view_aspect():
    from viewer.app.compare_view import CompareView

    cv = CompareView.__new__(CompareView)
    cv.mode = "side by side"
    view = (100, 0, 900, 700)
    for r in (cv.raster_rect(view), cv.reference_rect(view)):
        assert abs(r[2] / r[3] - 900 / 700) < 0.01, r
        assert r[2] <= 450 + 1
    assert cv.raster_rect(view)[0] + cv.raster_rect(view)[2] <= cv.reference_rect(view)[0]


def test_metrics_text_is_one_string_for_panel_and_image():
    from viewer.app.compare_view import CompareView

    cv = CompareView.__new__(CompareView)
    cv.mode, cv.metrics, cv.metrics_spp = "split", {"rmse": 0.0123, "relative_mse": 0.5}, 64
    assert cv.metrics_text() == "RMSE 0.0123   relMSE 0.5   (64 spp)"
    cv.mode = "reference"
    assert cv.metrics_text() == ""


# ---------------------------------------------------------------------- plots panel helpers

def _hue(rgb):
    import colorsys

    return colorsys.rgb_to_hsv(*rgb)[0] * 360.0


def _apart(a, b) -> bool:
    """Two line colours a class tells apart: hues 40 degrees apart where both are colours, else
    (a grey: no hue) 0.4 apart in saturation or in brightness (HSV)."""
    import colorsys

    (ha, sa, va), (hb, sb, vb) = colorsys.rgb_to_hsv(*a), colorsys.rgb_to_hsv(*b)
    if sa > 0.3 and sb > 0.3:
        dh = abs(ha - hb) * 360.0
        return min(dh, 360.0 - dh) > 40.0
    return abs(sa - sb) > 0.4 or abs(va - vb) > 0.4


def test_light_and_fresnel_component_colours_stand_apart():
    from viewer.app.plots_panel import LIGHT, PALETTE, R_P_COLOUR, R_S_COLOUR

    for c in PALETTE[:10]:  # the light's line cannot be taken for a material's curve
        assert _apart(LIGHT, c), c
    assert not _apart((1.00, 0.92, 0.20), (0.74, 0.74, 0.13))  # two yellows: a class saw one colour
    dh = abs(_hue(R_S_COLOUR) - _hue(R_P_COLOUR))
    assert min(dh, 360 - dh) > 60  # R_s and R_p: distinct hues


def test_identical_materials_are_drawn_once_and_brewster_marked_once():
    from viewer import plots
    from viewer.app.plots_panel import PlotsPanel, fresnel_marks, same_data
    from viewer.scene import load_scene

    mats = load_scene("lecture:2", load_meshes=False).materials  # a glass ball and a black glass mirror
    data = {n: plots.fresnel_curves(mats[n]) for n in ("glass", "black_glass")}
    panel = PlotsPanel()
    keys = ("type", "R", "Rs", "Rp")
    groups = panel.groups(list(data), data, lambda a, b: same_data({k: a[k] for k in keys}, {k: b[k] for k in keys}))
    assert groups == [("glass = black_glass", ["glass", "black_glass"])]
    assert any("the same curve" in m for m in panel.messages)
    marks = fresnel_marks([(n, data[n]) for n in data], 1)  # both listed: still one Brewster mark
    assert [m[1] for m in marks] == ["B"]
    assert marks[0][0] == pytest.approx(math.degrees(math.atan(1.5)), abs=0.01)


def test_bouguer_marks_the_spheres_diameters():
    from viewer import plots
    from viewer.app.plots_panel import bouguer_marks
    from viewer.scene import load_scene

    mats = load_scene("lecture:10", load_meshes=False).materials
    data = {n: plots.bouguer_curve(mats[n]) for n in ("glass_big", "glass_small")}
    marks = bouguer_marks(data, {"glass_big": [("big", 1.4)], "glass_small": [("small", 0.6)]}, "g")
    assert [m[0] for m in marks] == [1.4, 0.6]
    sig = float(np.asarray(mats["glass_big"]["sigma_a"])[1])
    assert f"T = {math.exp(-sig * 1.4):.3g}" in marks[0][2]  # Bouguer's law at the diameter


def test_glass_albedo_note_explains_the_radiance_scaling():
    from viewer import plots
    from viewer.app.plots_panel import albedo_note
    from viewer.scene import load_scene

    glass = load_scene("lecture:2", load_meshes=False).materials["glass"]
    note = albedo_note(glass, plots.albedo_curve(glass, n=4))
    assert "1/eta^2 = 0.44" in note
    assert "R + eta^2 T = 1.00" in note  # a smooth interface loses no energy: the independent check
    lam = load_scene("lecture:1", load_meshes=False).materials["ball"]
    assert albedo_note(lam, plots.albedo_curve(lam, n=4)) == ""


def test_lobe_is_shaded():
    from viewer.app.plots_panel import shaded_quads

    t, p = np.meshgrid(np.radians(np.linspace(0, 90, 16)), np.radians(np.linspace(0, 360, 31)), indexing="ij")
    pts = np.stack([np.sin(t) * np.cos(p), np.sin(t) * np.sin(p), np.cos(t)], -1)  # a hemisphere
    q = shaded_quads(pts)
    levels = [lv for lv, _ in q]
    assert len(levels) >= 4 and max(levels) - min(levels) > 0.4  # not one flat colour
    assert sum(len(xs) for _, (xs, _, _) in q) == 4 * 15 * 30  # every quad drawn once


def test_caption_lines_are_broken_to_fit_their_box():
    from viewer.app.panels.overlays import wrap_lines

    width = lambda s: 10.0 * len(s)  # noqa: E731 - a monospaced measure
    lines = wrap_lines("Same alpha = 0.2, black base so only the lobe shows", 120.0, width)
    assert all(width(line) <= 120.0 for line in lines) and " ".join(lines) == \
        "Same alpha = 0.2, black base so only the lobe shows"
    assert wrap_lines("a verylongwordindeed b", 50.0, width) == ["a", "verylongwordindeed", "b"]
