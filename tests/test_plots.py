"""BRDF plots (viewer/plots/, ``brdf-viewer plot``): the plotted numbers are the Python
functions' values, the lecture's Fresnel angles come out, and the command fails cleanly."""

import json
import math
import subprocess
import sys

import numpy as np
import pytest

from viewer import ViewerError, brdf, plots
from viewer.brdf.fresnel import (fresnel_conductor, fresnel_dielectric, fresnel_dielectric_polarized)
from viewer.brdf.presets import get_preset


def run(*args, cwd=None):
    return subprocess.run([sys.executable, "-m", "viewer", *map(str, args)], capture_output=True,
                          text=True, timeout=120, cwd=cwd)


def curve(data, label):
    (c,) = [c for c in data["curves"] if c["label"] == label]
    return np.array(c["x"]), np.array(c["y"]), c


# ----------------------------------------------------------------------------- CLI, read back

def test_fresnel_png_data_is_fresnel_dielectric(tmp_path):
    """The lecture's air-glass example: the curves in the PNG are fresnel_dielectric, R_p = 0 at
    Brewster's angle atan(1.5) = 56.31 deg."""
    out, js = tmp_path / "f.png", tmp_path / "f.json"
    r = run("plot", "lecture_air_glass", "--kind", "fresnel", "--out", out, "--data", js)
    assert r.returncode == 0, r.stderr
    from PIL import Image

    img = np.asarray(Image.open(out).convert("RGB"))
    assert img.shape == (600, 900, 3) and img.std() > 10  # a drawing, not a blank image
    data = plots.read_plot_data(out)
    assert data == json.loads(js.read_text())
    assert data["kind"] == "fresnel" and data["params"]["ior"] == 1.5
    x, R, _ = curve(data, "R")
    assert np.allclose(R, fresnel_dielectric(np.cos(np.radians(x)), 1.5), rtol=0, atol=1e-12)
    _, Rs, _ = curve(data, "R_s")
    _, Rp, _ = curve(data, "R_p")
    rs, rp = fresnel_dielectric_polarized(np.cos(np.radians(x)), 1.5)
    assert np.allclose(Rs, rs, atol=1e-12) and np.allclose(Rp, rp, atol=1e-12)
    (mark,) = data["marks"]
    assert "Brewster" in mark["label"] and mark["x"] == pytest.approx(56.31, abs=0.005)
    assert fresnel_dielectric_polarized(math.cos(math.radians(mark["x"])), 1.5)[1] < 1e-12
    assert Rp[np.argmin(np.abs(x - 56.31))] < 1e-4


def test_fresnel_from_inside_glass_critical_angle(tmp_path):
    out = tmp_path / "tir.png"
    r = run("plot", "lecture_air_glass", "--kind", "fresnel", "--inside", "--out", out)
    assert r.returncode == 0, r.stderr
    data = plots.read_plot_data(out)
    marks = {m["label"].split()[0]: m["x"] for m in data["marks"]}
    assert marks["critical"] == pytest.approx(41.81, abs=0.005)
    assert marks["Brewster"] == pytest.approx(math.degrees(math.atan(1 / 1.5)), abs=1e-9)  # 33.69
    x, R, _ = curve(data, "R")
    assert np.allclose(R, fresnel_dielectric(np.cos(np.radians(x)), 1 / 1.5), atol=1e-12)
    assert np.all(R[x > 41.82] == 1.0) and np.all(R[x < 41.8] < 1.0)  # total internal reflection


def test_polar_png_data_is_model_eval(tmp_path):
    out = tmp_path / "p.png"
    r = run("plot", "microfacet", "--kind", "polar", "--set", "alpha=0.3", "--set", "kd=[0.5,0.2,0.1]",
            "--theta-i", "30", "--out", out)
    assert r.returncode == 0, r.stderr
    data = plots.read_plot_data(out)
    p = brdf.get("microfacet").params(alpha=0.3, kd=[0.5, 0.2, 0.1])
    assert data["params"] == json.loads(json.dumps(p.to_plain()))
    assert len(data["curves"]) == 3  # kd differs per channel: one curve per channel
    wi = plots.direction(30.0, 0.0)
    for ch, c in enumerate(data["curves"]):
        t = np.radians(np.array(c["x"]))
        wo = np.stack([-np.sin(t), np.zeros_like(t), np.cos(t)], -1)
        f = brdf.get("microfacet").eval(p, np.broadcast_to(wi, wo.shape), wo)[:, ch]
        assert np.allclose(c["f"], f, rtol=1e-12, atol=0)
        assert np.allclose(c["y"], f * np.cos(t), rtol=1e-12, atol=1e-15)
    # the peak is near the mirror direction (theta_o = +theta_i)
    x, y = np.array(data["curves"][1]["x"]), np.array(data["curves"][1]["y"])
    assert abs(x[np.argmax(y)] - 30.0) < 8.0


def test_bad_input_exit_2_one_line_no_file(tmp_path):
    out = tmp_path / "x.png"
    cases = [
        (("nosuchmodel", "--kind", "polar"), "nosuchmodel"),
        (("lambert", "--kind", "histogram"), "--kind"),
        (("microfacet", "--kind", "polar", "--set", "alpha=7"), "alpha"),
        (("microfacet", "--kind", "polar", "--set", "alphaa=0.1"), "alphaa"),
        (("microfacet", "--kind", "polar", "--set", "alpha"), "--set"),
        (("lambert", "--kind", "fresnel"), "fresnel"),
        (("phong", "--kind", "bouguer"), "bouguer"),
        (("lambert", "--kind", "polar", "--theta-i", "95"), "--theta-i"),
        (("lambert", "--kind", "polar", "--channel", "alpha"), "--channel"),
        (("gold", "--kind", "fresnel", "--inside"), "--inside"),
    ]
    for args, word in cases:
        r = run("plot", *args, "--out", out)
        assert r.returncode == 2, (args, r.stderr)
        lines = r.stderr.strip().splitlines()
        assert len(lines) == 1 and word in lines[0] and "Traceback" not in r.stderr, (args, r.stderr)
        assert list(tmp_path.iterdir()) == [], args  # no partial or temporary file
    r = run("plot", "lambert", "--kind", "fresnel", "--out", out)
    assert "applies to" in r.stderr and "dielectric" in r.stderr  # says what applies


# ----------------------------------------------------------------------------- data functions

def test_fresnel_conductor_curves_and_pseudo_brewster():
    p = plots.as_params(get_preset("gold"))
    d = plots.fresnel_curves(p)
    c = np.cos(np.radians(d["theta"]))[:, None]
    assert np.allclose(d["R"], fresnel_conductor(c, p.eta[None], p.k[None]), atol=1e-12)
    assert np.all(np.isnan(d["critical"]))
    for ch in range(3):  # the pseudo-Brewster angle is where R_p is smallest
        assert d["Rp"][:, ch].argmin() == np.abs(d["theta"] - d["brewster"][ch]).argmin()
    fig = plots.figure(p, "fresnel")
    assert len(fig.curves) == 9 and len(fig.marks) == 3  # R_s, R_p, R per channel; one angle each


def test_polar_delta_lobe_of_a_mirror():
    p = plots.as_params(get_preset("polished_gold"))
    d = plots.polar_lobe(p, 45.0)
    assert not np.any(d["fcos"])
    (delta,) = d["delta"]
    assert delta["theta_o"] == 45.0
    assert np.allclose(delta["reflectance"], fresnel_conductor(math.cos(math.radians(45)), p.eta, p.k))


def test_anisotropic_planes_differ():
    p = brdf.get("ashikhmin_shirley").params(nu=10.0, nv=1000.0)
    tangent = plots.polar_lobe(p, 30.0, phi=0.0)
    bitangent = plots.polar_lobe(p, 30.0, phi=90.0)
    wi = plots.direction(30.0, 90.0)
    wo = plots.plane_directions(bitangent["theta_o"], 90.0)
    assert np.allclose(wo[:, 0], 0.0, atol=1e-15) and np.allclose(np.linalg.norm(wo, axis=1), 1.0)
    assert np.allclose(bitangent["f"], brdf.get("ashikhmin_shirley").eval(p, np.broadcast_to(wi, wo.shape), wo))
    # nu (along x) is small: the lobe is wide in the tangent plane, narrow in the bitangent plane

    def width(d):  # degrees where f cos is above half its peak
        y = d["fcos"][:, 0]
        return np.ptp(d["theta_o"][y > 0.5 * y.max()])

    assert width(tangent) > 3 * width(bitangent)


def test_lobe_3d_surface_is_fcos_times_direction():
    p = plots.as_params(get_preset("lecture_ggx"))
    d = plots.lobe_3d(p, 40.0, n_theta=19, n_phi=37)
    assert d["x"].shape == (19, 37)
    wo = plots.direction(*np.meshgrid(d["theta"], d["phi"], indexing="ij"))
    f = brdf.get("microfacet").eval(p, np.broadcast_to(plots.direction(40.0), (19 * 37, 3)), wo.reshape(-1, 3))
    value = (f * wo.reshape(-1, 3)[:, 2:]) @ plots.LUMINANCE
    assert np.allclose(d["value"].ravel(), value, rtol=1e-12)
    assert np.allclose(np.stack([d["x"], d["y"], d["z"]], -1), d["value"][..., None] * wo)
    assert np.allclose(d["x"][:, 0], d["x"][:, -1])  # the surface closes around phi


def test_albedo_of_lambert_is_its_albedo():
    p = brdf.get("lambert").params(albedo=[0.7, 0.4, 0.1])
    d = plots.albedo_curve(p)
    assert np.allclose(d["albedo"], [0.7, 0.4, 0.1], atol=1e-12)
    fig = plots.figure(p, "albedo")
    assert [c.label for c in fig.curves] == ["albedo (red)", "albedo (green)", "albedo (blue)"]
    p = plots.as_params(get_preset("varnished_gold"))  # the slowest model: a layered coat over a microfacet
    d = plots.albedo_curve(p)   # its time: benchmarks/run.py
    assert np.all(np.isfinite(d["albedo"])) and np.all((d["albedo"] >= 0) & (d["albedo"] <= 1 + 1e-6))


def test_bouguer_is_exp_minus_sigma_d():
    p = plots.as_params(get_preset("green_glass"))
    d = plots.bouguer_curve(p)
    assert np.allclose(d["T"], np.exp(-np.outer(d["d"], [8.0, 0.5, 6.0])), rtol=1e-14)
    assert d["d"][-1] == pytest.approx(3.0 / 0.5)
    p = brdf.get("layered").params(coating={"thickness": 20.0, "sigma_a": [0.01, 0.02, 0.05]})
    fig = plots.figure(p, "bouguer")
    assert fig.marks and fig.marks[0].x == 20.0 and "um" in fig.x_label


def test_kinds_that_apply():
    assert plots.applicable_kinds(brdf.get("lambert").params()) == ("polar", "lobe", "albedo", "sampling", "slice",
                                                                     "theta_h", "theta_d", "theta_v")
    assert plots.applicable_kinds(brdf.get("microfacet").params())[-1] == "terms"
    assert "fresnel" in plots.applicable_kinds(brdf.get("layered").params())
    assert "bouguer" in plots.applicable_kinds(brdf.get("dielectric").params())
    with pytest.raises(ViewerError, match="fresnel = 'none'"):
        plots.fresnel_curves(brdf.get("mirror").params(fresnel="none"))
    with pytest.raises(ViewerError, match="bouguer applies to: layered, dielectric"):
        plots.bouguer_curve(brdf.get("microfacet").params())


@pytest.mark.parametrize("kind", ["polar", "lobe", "albedo"])
def test_every_model_draws(kind):
    """Every registered model gives a finite figure that draws, for the kinds that apply to all."""
    for name in brdf.names():
        p = brdf.get(name).params()
        fig = plots.figure(p, kind, theta_i=50.0)
        for c in fig.curves:
            assert np.all(np.isfinite(c.y)), (name, c.label)
        json.dumps(plots.figure_json(fig))
        if name in ("lambert", "dielectric", "ashikhmin_shirley"):
            img = plots.render_figure(fig, 400, 300, ss=2)
            assert img.shape == (300, 400, 3) and img.std() > 5


# ----------------------------------------------------------------------------- the GUI panel

GUI_SCRIPT = r'''
import sys
import numpy as np
from viewer import brdf, plots
from viewer.app.main import App
from viewer.app.plots_panel import PlotsPanel, TABS
from viewer.brdf.presets import get_preset

app = App("sphere", size=(1200, 800))
app.session.warm = []
panel = PlotsPanel()
materials = {"ball": app.session.scene.materials["ball"], "glass": plots.as_params(get_preset("green_glass")),
             "gold": plots.as_params(get_preset("gold"))}
draw = app.side_panel.draw
app.side_panel.draw = lambda *a: (draw(*a), panel.draw(materials))
app.frame()
shots = {}
for tab in TABS:
    panel.select_tab(tab)
    app.frame()
    shots[tab] = app.capture_window()[40:760, 380:1180].astype(float)
    assert panel.tab == tab, (panel.tab, tab)
panel.solo, panel.inside = "glass", True
panel.select_tab("Fresnel")
app.frame()
assert panel.active(materials) == ["glass"] and panel.messages == [], panel.messages
panel.select_tab("Bouguer")
app.frame()
assert panel.messages == [], panel.messages  # green glass absorbs
panel.solo = None
app.frame()
assert any("ball" in m and "absorption" in m for m in panel.messages), panel.messages  # lambert does not
panel.select_tab("Spectral")  # n, k, R(theta, lambda) of the spectral material (gold's table)
app.frame()
app.frame()  # the tab bar switches on the frame after the request; its content draws on this one
assert panel.tab == "Spectral", panel.tab
assert panel.spectral_material == "gold", panel.spectral_material
assert any("ball" in m and "glass" in m and "spectral table" in m for m in panel.messages), panel.messages
for tab, img in shots.items():
    assert img.std() > 10, tab
for a, b in zip(TABS, TABS[1:]):
    assert np.abs(shots[a] - shots[b]).mean() > 1, (a, b)
panel.close()
app.close()
print("PANEL OK")
'''


@pytest.mark.skipif(__import__("shutil").which("xvfb-run") is None, reason="needs xvfb-run")
def test_plots_panel_draws_every_tab(tmp_path):
    """The GUI panel under a virtual X server: every tab draws, solo and the Fresnel 'inside'
    switch work, and models without a Fresnel term / absorption are named."""
    script = tmp_path / "panel.py"
    script.write_text(GUI_SCRIPT)
    r = subprocess.run(["xvfb-run", "-a", "-s", "-screen 0 1600x1000x24", sys.executable, str(script)],
                       capture_output=True, text=True, timeout=120, cwd=tmp_path)
    assert r.returncode == 0 and "PANEL OK" in r.stdout, r.stdout + r.stderr


# ---------------------------------------------------------------------- legends outside the axes

GALLERY = ("floor", "lambert", "oren_nayar", "lafortune", "ashikhmin_shirley", "layered", "torrance_sparrow",
           "ggx", "gold", "mirror", "glass", "copper")  # the gallery's materials and one more: 12


def _many_curves(kind, names):
    x = np.linspace(-90.0, 90.0, 91) if kind == "polar" else np.linspace(0.0, 90.0, 91)
    curves = [plots.Curve(n, x, np.full_like(x, 0.5 + 0.02 * i), (20 * i, 100, 200 - 10 * i))
              for i, n in enumerate(names)]
    return plots.Figure(kind, "lambert", {}, "many", "x", "y", curves, x_range=(x[0], x[-1]), y_range=(0.0, 1.0),
                        info={"theta_i": 45.0, "delta": []})


def _disjoint(a, b):
    return a[2] <= b[0] or b[2] <= a[0] or a[3] <= b[1] or b[3] <= a[1]


def _check_cells(plan, rect, canvas):
    for text, _, _, x, y, text_w, room in plan.cells:
        assert text_w <= room + 1e-9, (text, text_w, room)  # every name fits its room
        assert rect[0] + x + room <= rect[2] + 1e-9 and rect[1] + y <= rect[3], (text, rect)
    assert 0 <= rect[0] and 0 <= rect[1] and rect[2] <= canvas.w and rect[3] <= canvas.h, (rect, canvas.w, canvas.h)


@pytest.mark.parametrize("size", [(900, 600), (1920, 1080), (480, 320)])
def test_a_legend_of_twelve_materials_lies_outside_the_axes(size):
    """Twelve curves named after the gallery's materials: the legend's box lies outside the data
    rect (the cartesian axes, the polar semicircle with its angle labels) and inside the canvas,
    each name no wider than its room; at 900 x 600 and up nothing is ellipsized."""
    from viewer.plots.canvas import Canvas
    from viewer.plots.draw import cartesian_frame, polar_frame

    w, h = size
    cv = Canvas(w, h)
    fig = _many_curves("fresnel", GALLERY)
    box, plan, corner = cartesian_frame(cv, fig, w, h)
    rect = plan.rect(*corner)
    assert _disjoint(rect, box), (rect, box)
    _check_cells(plan, rect, cv)
    fig = _many_curves("polar", GALLERY)
    cx, cy, R, plan, corner = polar_frame(cv, fig, w, h)
    rect = plan.rect(*corner)
    semicircle = (cx - R - cv.s(24), cy - R - cv.s(20), cx + R + cv.s(24), cy + cv.s(36))  # labels included
    assert _disjoint(rect, semicircle), (rect, semicircle)
    _check_cells(plan, rect, cv)
    if w >= 900:
        assert all(c[0] == n for c, n in zip(plan.cells, GALLERY))
    img = plots.render_figure(fig, w, h)  # and it draws
    assert img.shape == (h, w, 3)
