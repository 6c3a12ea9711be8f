"""The plots panel's tabs (viewer/app/plot_tabs): the polar plot at equal aspect measured from
implot's own transform, every label whole at UI scales 1, 1.5 and 2 in the docked panel, and
the honest states of the tabs: the refracted ray of smooth glass, a thin film's reflectance on
an index of 1 (no Brewster angle there), sane 3D axes for a delta lobe, no Bouguer plot for a
material that absorbs nothing, an n(lambda) axis about n's own span."""

import math
import shutil
from pathlib import Path

import numpy as np
import pytest

from gui_harness import run_py
from viewer import plots
from viewer.brdf.presets import get_preset


def _p(preset, **extra):
    d = get_preset(preset)
    d.update(extra)
    return plots.as_params(d)


def test_equal_aspect_limits_give_one_unit_per_pixel_on_both_axes():
    from viewer.app.plot_tabs.common import equal_aspect_limits

    for w, h in ((400, 900), (900, 300), (500, 250)):
        x0, x1, y0, y1 = equal_aspect_limits(-1.0, 1.0, -0.02, 1.0, w, h)
        assert (x1 - x0) / w == pytest.approx((y1 - y0) / h)
        assert x0 <= -1.0 and x1 >= 1.0 and y0 <= -0.02 and y1 >= 1.0  # the data stays inside
        assert y0 == -0.02  # widened upwards: the surface stays at the bottom


def test_flow_rows_never_shrink_an_item():
    from viewer.app.plot_tabs.common import flow_rows

    assert flow_rows([50, 50, 50], 200, 10) == [[0, 1, 2]]
    assert flow_rows([50, 50, 50], 120, 10) == [[0, 1], [2]]
    assert flow_rows([300, 50], 120, 10) == [[0], [1]]  # too wide alone: a row of its own


def test_smooth_glass_has_a_refracted_ray_at_snells_angle():
    d = plots.polar_lobe(_p("lecture_air_glass"), 45.0)
    (r,) = d["delta"]
    (t,) = d["refracted"]
    assert math.sin(math.radians(t["theta_t"])) == pytest.approx(math.sin(math.radians(45.0)) / 1.5)
    assert np.allclose(r["reflectance"] + t["transmittance"], 1.0)
    assert plots.polar_lobe(_p("lecture_lambert"), 45.0)["refracted"] == []


def test_an_index_of_one_reflects_by_its_film_alone_and_has_no_brewster_angle():
    from viewer.app.plot_tabs.fresnel import fresnel_marks, fresnel_notes
    from viewer.app.plot_tabs.polar import delta_label

    soap = _p("soap_bubble")
    (dl,) = plots.polar_lobe(soap, 45.0)["delta"]
    assert float(np.mean(dl["reflectance"])) > 0.01  # the film reflects: not "R = 0"
    d = plots.fresnel_curves(soap)
    assert fresnel_marks([("soap", d)], 1) == []  # no "Brewster 45.0 deg" for n = 1
    (note,) = fresnel_notes([("soap", d)], 1)
    assert "no Brewster" in note and "thin film" in note
    bare = _p("soap_bubble", thin_film={"ior": 1.33, "thickness_nm": 0.0})
    assert "reflects nothing" in delta_label("bare", 0.0, bare)
    glass = plots.fresnel_curves(_p("lecture_air_glass"))
    (b,) = [m for m in fresnel_marks([("glass", glass)], 1) if m[1] == "B"]
    assert b[0] == pytest.approx(math.degrees(math.atan(1.5)), abs=0.05)


def test_delta_lobe_axes_follow_the_delta_line():
    from viewer.app.plot_tabs.lobe import extent

    glass = {"g": plots.lobe_3d(_p("lecture_air_glass"), 45.0, n_theta=7, n_phi=9)}
    e = extent(glass, np.asarray)
    assert 0.05 <= e <= 0.1  # R = 0.05 at 45 deg, rounded up: not +-1e-6
    bare = {"b": plots.lobe_3d(_p("soap_bubble", thin_film={"ior": 1.33, "thickness_nm": 0.0}), 45.0,
                               n_theta=7, n_phi=9)}
    assert extent(bare, np.asarray) == 1.0  # nothing reflected: unit axes


def test_dispersive_glass_n_axis_spans_n_not_zero():
    from viewer.app.plot_tabs.spectral import nk_limits
    from viewer.plots.spectral import spectral_data

    d = spectral_data(plots.as_params({"model": "dielectric", "spectral": "SF11"}))
    lo, hi = nk_limits(d["n"], d["k"])
    assert 1.7 < lo < float(np.min(d["n"])) and float(np.max(d["n"])) < hi < 1.9
    assert (float(np.max(d["n"])) - float(np.min(d["n"]))) / (hi - lo) > 0.8  # the curve fills the plot
    g = spectral_data(_p("polished_gold"))
    assert nk_limits(g["n"], g["k"])[0] == 0.0  # a metal's k is drawn: from 0


def test_sampling_headline_leads_with_the_p_value():
    from viewer.app.plot_tabs.sampling import headline

    h = headline({"p_value": 0.297, "chi2": 1175.1, "dof": 1150, "theta_i": 45.0, "phi": 0.0, "samples": 50000})
    assert h.startswith("chi-square p = 0.297")


GUI = r'''
import numpy as np
from viewer import plots
from viewer.app.layout import window_layout
from viewer.app.main import App
from viewer.app.plots_panel import TABS
from viewer.brdf.presets import get_preset
from viewer.scene import material_from_name

NEW = ("Theta H", "Theta D", "Theta V", "Terms", "Image slice")  # checked below, at 1.5, on their own materials

app = App("sphere", size=(1600, 900), restore_state=False)
app.session.warm = []
app.plots.visible = False
panel = app.plots.__class__()
P = lambda n, **e: plots.as_params({**get_preset(n), **e})
materials = {"lambert": P("lecture_lambert"), "glass": P("lecture_air_glass"), "soap": P("soap_bubble"),
             "green": P("green_glass"), "gold": P("polished_gold"),
             "sf11": plots.as_params({"model": "dielectric", "spectral": "SF11"})}
state = {}
draw = app.side_panel.draw
app.side_panel.draw = lambda *a: (draw(*a), panel.draw(materials, state["rect"]))
for scale in (1.0, 1.5, 2.0):
    app.set_ui_scale(scale)
    state["rect"] = window_layout(1600, 900, scale, lecture=True, plots=True)["plots"]
    # every material alone at the projector's 1.5; all of them and the soap film's long labels at
    # 1 and 2 (a label's room scales with the UI: the extremes clip first, whatever the material)
    for solo in ((None, "lambert", "glass", "soap", "sf11") if scale == 1.5 else (None, "soap")):
        panel.solo = solo
        for tab in [t for t in TABS if t not in NEW]:
            panel.select_tab(tab)
            app.frame(); app.frame()
            assert panel.tab == tab
            assert panel.clipped == [], (scale, solo, tab, panel.clipped)
            if tab == "Polar":
                assert abs(panel.aspects["polar"] - 1.0) < 0.01, (scale, solo, panel.aspects)
            if tab == "Fresnel" and solo == "soap":
                assert any("no Brewster" in m for m in panel.messages), panel.messages
            if tab == "Bouguer" and solo == "glass":
                assert any("no absorption" in m for m in panel.messages), panel.messages
            if tab == "3D lobe" and solo == "glass":
                assert 0.05 <= panel.lobe_extent <= 0.1, panel.lobe_extent
            if tab == "Spectral" and solo == "sf11":
                assert panel.nk_range[0] > 1.7, panel.nk_range
    print("SCALE", scale, "aspect", round(panel.aspects["polar"], 4))
# BRDF Explorer's slices and the term view at the projector's 1.5, for built-in and file materials,
# linear and log, with and without the cosine: every label whole, the legend under the plot, the
# materials a tab cannot show named in a message
app.set_ui_scale(1.5)
state["rect"] = window_layout(1600, 900, 1.5, lecture=True, plots=True)["plots"]
panel.solo = None
materials.clear()
materials.update({"lambert": P("lecture_lambert"), "glass": P("lecture_air_glass"),
                  "rough_gold": plots.as_params({"model": "microfacet", "alpha": 0.3}),
                  "ggx_terms": material_from_name(FILE)})
for log in (False, True):
    panel.log = panel.slices.cos = log
    for tab in NEW:
        panel.select_tab(tab)
        app.frame(); app.frame()
        assert panel.tab == tab and not panel.computing, tab
        assert panel.clipped == [], (tab, panel.clipped)
        box, frame = panel.legend_boxes.get(tab), panel.plot_rects[tab]
        if box is not None:
            assert box[1] >= frame[3], (tab, box, frame)  # under the plot, off its curves
        msgs = " ".join(panel.messages)
        assert ("lambert" in msgs) if tab == "Terms" else ("glass" in msgs), (tab, panel.messages)
    words = {c.full for c in panel.legend_cells["Theta H"]}
    assert {"lambert", "rough_gold", "ggx_terms"} <= words, words
panel.close()
app.close()
print("TABS OK")
'''.replace("FILE", repr(str(Path(__file__).parent / "brdfs" / "ggx_terms.brdf")))


# slow: every tab at every UI scale in a real window (22 s on two loaded cores); the gallery legend
# test and test_plots.py draw every tab in the default run
@pytest.mark.slow
@pytest.mark.skipif(shutil.which("Xvfb") is None, reason="needs Xvfb")
def test_docked_tabs_fit_at_every_ui_scale(display):
    """Docked beside the lecture's view at UI 1, 1.5 and 2, for all materials and each alone (at
    1.5; at 1 and 2 all of them and the soap film alone): no label wider than its room, the polar plot at equal aspect (pixels per unit along x
    over y from implot's transform, within 1 %: a Lambert lobe is a circle), and the states of
    the tabs named above; the Theta H, Theta D, Theta V, Terms and Image slice tabs at 1.5 for a
    microfacet metal, a .brdf file defining D, F, G, Lambert and smooth glass."""
    r = run_py(GUI, display, timeout=600)
    assert r.returncode == 0 and "TABS OK" in r.stdout, r.stdout + r.stderr[-3000:]


# ---------------------------------------------------------------------- many materials

def _gallery_names():
    from viewer.scene import load_scene

    return list(load_scene("gallery", load_meshes=False).materials)


def test_legend_layout_of_the_gallery_fits_every_name_in_its_cell():
    """The gallery's materials (and the light) in a legend 300 points wide, text about 9 points
    a letter: rows of entries, every text no wider than its cell's room, every cell inside the
    legend's box and none over another; a name wider than the whole legend is ellipsized, never
    cut."""
    from viewer.app.plot_tabs.common import ellipsize, legend_layout

    def width_of(t):
        return 9.0 * len(t)

    entries = [("light (wi)", (1, 1, 0))] + [(n, (0.5, 0.5, 0.5)) for n in _gallery_names()]
    entries.append(("glass (refracted at 28.1 deg, T = 0.96)", (0.2, 0.3, 0.9)))  # 351 points of text
    cells, (w, h) = legend_layout(entries, width_of, 300.0, 20.0, 6.0, 12.0, 18.0)
    assert [c.full for c in cells] == [t for t, _ in entries]
    for a in cells:
        assert a.text_w <= a.text_room + 1e-9, a
        assert 0.0 <= a.x and a.x + a.w <= w + 1e-9 and 0.0 <= a.y and a.y + a.h <= h + 1e-9, a
        for b in cells:
            assert a is b or a.y != b.y or a.x + a.w <= b.x or b.x + b.w <= a.x, (a, b)
    assert w <= 300.0 and h == 18.0 * len({c.y for c in cells})
    assert [c.text == c.full for c in cells].count(False) == 1 and cells[-1].text.endswith("...")
    assert cells[-1].text_w <= 300.0 - 26.0
    assert ellipsize("torrance_sparrow", 60.0, width_of) == "tor..."
    wide, _ = legend_layout(entries, width_of, 2000.0, 20.0, 6.0, 12.0, 18.0)
    assert all(c.text == c.full for c in wide) and len({c.y for c in wide}) == 1


GALLERY_GUI = r'''
import numpy as np
from viewer import plots
from viewer.app.layout import window_layout
from viewer.app.main import App

# what is measured is the plots: the view untraced, unshadowed (a traced gallery costs its programs' compile)
app = App("gallery", ["render.raytrace=false", "render.shadows=false"], size=(1920, 1080), restore_state=False)
app.session.warm = []
app.set_ui_scale(1.5)
app.plots.visible = False
panel = app.plots.__class__()
materials = app.session.scene.materials
rect = window_layout(1920, 1080, 1.5, lecture=True, plots=True)["plots"]
draw = app.side_panel.draw
app.side_panel.draw = lambda *a: (draw(*a), panel.draw(materials, rect))
for tab in ("Polar", "3D lobe", "Fresnel", "Albedo", "Bouguer", "Spectral"):
    panel.select_tab(tab)
    app.frame(); app.frame()
    box, frame, cells = panel.legend_boxes[tab], panel.plot_rects[tab], panel.legend_cells[tab]
    print("TAB", tab, "frame", [round(v) for v in frame], "legend", [round(v) for v in box], "entries", len(cells),
          "ellipsized", [c.full for c in cells if c.text != c.full])
    overlap = not (box[2] <= frame[0] or box[0] >= frame[2] or box[3] <= frame[1] or box[1] >= frame[3])
    assert not overlap, (tab, box, frame)
    assert box[1] >= frame[3] and box[3] <= rect.y + rect.h + 0.5, (tab, box, frame)  # under the plot, in the window
    for c in cells:
        assert c.text_w <= c.text_room + 0.5, (tab, c)
        assert box[0] + c.x + c.w <= box[2] + 0.5 and box[1] + c.y + c.h <= box[3] + 0.5, (tab, c)
    words = {w for c in cells for w in c.full.replace("=", " ").split()}
    if tab == "Spectral":  # gold's errors against the spectral integral, Schlick's and three wavelengths'
        assert [(c.full, c.style) for c in cells] == [("Schlick", "line"), ("3 wavelengths", "dots")], cells
        continue
    want = {n for n, p in materials.items() if tab != "Fresnel" or "fresnel" in plots.applicable_kinds(p)}
    if tab == "Bouguer":  # the materials that absorb: the glass alone (the layered coat's sigma_a is 0)
        want = {n for n, p in materials.items() if "bouguer" in plots.applicable_kinds(p)
                and np.any(np.asarray(plots.bouguer_curve(p)["sigma_a"]) > 0)}
        assert want == {"glass"}, want
    assert want <= words, (tab, want - words)  # every material named (those with one curve together)
    assert panel.clipped == [], (tab, panel.clipped)
    assert panel.listed is None  # the list of 11 folded: its rows would have pushed the plot down
panel.close()
app.close()
print("GALLERY OK")
'''


@pytest.mark.skipif(shutil.which("Xvfb") is None, reason="needs Xvfb")
def test_gallery_legends_lie_under_the_plots_and_fit(display):
    """The gallery's 11 materials in the plots docked beside the lecture's view at 1920 x 1080,
    UI 1.5: in the Polar, 3D lobe, Fresnel, Albedo, Bouguer and Spectral tabs (the last two
    had their legend inside the plot, over the curves' start) the legend's box lies under the
    plot's frame (no overlap with the axes, so no curve is covered) and inside the window, and
    every entry's text fits its cell (ellipsized where it would not)."""
    r = run_py(GALLERY_GUI, display, timeout=600)
    print(r.stdout)
    assert r.returncode == 0 and "GALLERY OK" in r.stdout, r.stdout + r.stderr[-3000:]


COLOURS = r'''
import json
from viewer.app.plots_panel import PlotsPanel
from viewer.scene import load_scene

gallery = list(load_scene("gallery", load_meshes=False).materials)
a = PlotsPanel()
a.set_materials(load_scene("lecture:11", load_meshes=False).materials)  # gold seen first elsewhere
a.set_materials(gallery)
b = PlotsPanel()
b.set_materials(gallery[::-1])
print(json.dumps({"a": {n: a.colour(n) for n in gallery}, "b": {n: b.colour(n) for n in gallery}}))
'''


def test_a_material_keeps_its_colour_from_run_to_run():
    """Two processes with different string-hash salts (PYTHONHASHSEED), each giving the gallery's
    materials their colours after another scene and in the reverse order: the same colour for
    every material, and no two materials of the scene alike."""
    import json
    import os
    import subprocess
    import sys

    runs = []
    for seed in ("1", "4242"):
        env = dict(os.environ, PYTHONHASHSEED=seed)
        r = subprocess.run([sys.executable, "-c", COLOURS], env=env, capture_output=True, text=True, timeout=120)
        assert r.returncode == 0, r.stderr[-2000:]
        runs.append(json.loads(r.stdout.strip().splitlines()[-1]))
    first = runs[0]["a"]
    for run in runs:
        assert run["a"] == first and run["b"] == first
    assert len({tuple(c) for c in first.values()}) == len(first)


def test_a_brdf_file_and_its_built_in_twin_are_one_curve_said_so():
    """Lecture step 15: the .brdf file's lobe (its GLSL, evaluated) and the built-in microfacet
    with the same choices agree to about 2e-6 of the peak, so the file's curve lay hidden under
    the built-in one with nothing said. They are drawn once, labelled "file = builtin", and a
    message says by how little they differ; a material a few percent rougher stays a curve of
    its own."""
    from viewer.app.plots_panel import CURVE_TOL, PlotsPanel, curve_gap, same_data
    from viewer.scene import load_scene

    mats = load_scene("lecture:15", load_meshes=False).materials
    rough = plots.as_params(dict(mats["builtin"].to_plain(), alpha_x=0.33, alpha_y=0.33))
    data = {n: plots.polar_lobe(p, 45.0, 0.0) for n, p in (("file", mats["file"]), ("builtin", mats["builtin"]),
                                                             ("rough", rough))}
    gap = curve_gap(data["file"], data["builtin"])
    assert 0.0 < gap <= CURVE_TOL  # not the same numbers (GLSL against numpy), the same curve
    assert curve_gap(data["builtin"], data["rough"]) > 30 * CURVE_TOL
    panel = PlotsPanel()
    assert panel.groups(list(data), data, same_data) == [("file = builtin", ["file", "builtin"]),
                                                         ("rough", ["rough"])]
    assert len(panel.messages) == 1 and panel.messages[0].startswith("builtin: the same curve as file, at most ")
    assert curve_gap({"a": np.ones(3)}, {"b": np.ones(3)}) is None  # different curves: never merged
    # the next frame, the same data objects: the same groups and message, nothing compared again
    compared = []

    def counting(a, b):
        compared.append(1)
        return same_data(a, b)

    panel.messages = []
    assert panel.groups(list(data), data, counting) == [("file = builtin", ["file", "builtin"]), ("rough", ["rough"])]
    assert not compared and len(panel.messages) == 1
    data = dict(data, rough=dict(data["builtin"]))  # new data (a slider moved): compared afresh
    panel.messages = []
    assert panel.groups(list(data), data, counting) == [("file = builtin = rough", ["file", "builtin", "rough"])]
    assert compared and len(panel.messages) == 2
    assert curve_gap({"a": "x"}, {"a": "y"}) is None and curve_gap([1.0, 2.0], [1.0, 2.0]) == 0.0
