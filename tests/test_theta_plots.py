"""BRDF Explorer's theta_h, theta_d and theta_v slices, the image slice's phi_d and cosine
options and the microfacet term view (viewer/plots/theta.py, the ``terms`` hook): each curve is f
at the directions its angles describe (rebuilt here from the angles, independently of the plot
code, and checked against the Rusinkiewicz angles they must have), the terms multiply to f, D is
normalized, a ``.brdf`` file's D, F, G run as GLSL and equal the built-in's, the CLI writes the
new kinds (the window's new tabs are drawn in tests/test_plot_tabs.py)."""

import math
from pathlib import Path

import numpy as np
import pytest

from viewer import ViewerError, brdf, plots
from viewer.plots import theta

DATA = Path(__file__).parent / "brdfs"


def _mats():
    """An anisotropic microfacet metal over a diffuse base, Blinn-Phong and Oren-Nayar (the
    slices call a model's eval and nothing else, so these stand for every model: a measured
    table's first eval tabulates it, seconds this file need not spend)."""
    return [brdf.get("microfacet").params(alpha_x=0.15, alpha_y=0.4, kd=[0.1, 0.2, 0.3]),
            brdf.get("blinn_phong").params(),
            brdf.get("oren_nayar").params()]


def _rot_y(v, a):
    c, s = math.cos(a), math.sin(a)
    return np.array([c * v[0] + s * v[2], v[1], -s * v[0] + c * v[2]])


def _explorer_pair(th_deg, td_deg):
    """BRDF Explorer's theta-h / theta-d construction (brdftemplateAnglePlotThetaH.vert): the
    light tilted by theta_d across the x-z plane, then by theta_h about y; the view mirrored about
    h = rot_y(n, theta_h) (the test's own copy: the mirror image in y of Explorer's light, which
    an isotropic or x/y-symmetric model cannot tell apart)."""
    th, td = math.radians(th_deg), math.radians(td_deg)
    L = _rot_y(np.array([0.0, math.sin(td), math.cos(td)]), th)
    H = _rot_y(np.array([0.0, 0.0, 1.0]), th)
    V = 2.0 * np.dot(L, H) * H - L
    return L, V


def _angle(a, b):
    return math.degrees(math.acos(np.clip(np.dot(a, b) / np.linalg.norm(a) / np.linalg.norm(b), -1, 1)))


def test_theta_h_and_theta_d_curves_are_f_at_their_rusinkiewicz_angles():
    for p in _mats():
        d = theta.theta_h_curve(p, theta_d=25.0, n=41)
        e = theta.theta_d_curve(p, theta_h=12.0, n=31, cos=True)
        for curve, pairs in ((d, [(x, 25.0) for x in d["x"]]), (e, [(12.0, x) for x in e["x"]])):
            L, V = map(np.array, zip(*[_explorer_pair(th, td) for th, td in pairs]))
            np.testing.assert_allclose(curve["wi"], L, atol=1e-12)
            np.testing.assert_allclose(curve["wo"], V, atol=1e-12)
            f = brdf.get(p.model).eval(p, L, V)
            want = f * L[:, 2:3] if curve["cos"] else f
            np.testing.assert_allclose(curve["y"], want, rtol=1e-12, atol=1e-15)
        # the angles themselves: h at theta_h from the normal, theta_d between wi and h
        for (th, td), wi, wo in zip([(x, 25.0) for x in d["x"]][::7], d["wi"][::7], d["wo"][::7]):
            h = wi + wo
            assert _angle(h, [0, 0, 1]) == pytest.approx(abs(th), abs=1e-6)
            assert _angle(wi, h) == pytest.approx(td, abs=1e-6)
    assert np.all(np.diff(d["x"]) > 0) and d["x"][0] == -theta.EDGE and d["x"][-1] == theta.EDGE
    # squared spacing: as many points within 22.5 degrees of theta_h = 0 as beyond
    assert np.sum(np.abs(d["x"]) <= 22.5) >= np.sum(np.abs(d["x"]) > 22.5) - 1


def test_theta_v_curve_is_f_along_the_view_for_a_fixed_light():
    p = _mats()[0]
    d = theta.theta_v_curve(p, theta_i=40.0, phi_i=30.0, n=37)
    wi = np.array([math.sin(math.radians(40)) * math.cos(math.radians(30)),
                   math.sin(math.radians(40)) * math.sin(math.radians(30)), math.cos(math.radians(40))])
    np.testing.assert_allclose(d["wi"], np.broadcast_to(wi, d["wi"].shape), atol=1e-12)
    for x, wo in zip(d["x"], d["wo"]):
        assert _angle(wo, [0, 0, 1]) == pytest.approx(abs(x), abs=1e-6)
        if x > 1:  # the mirror side: wo's azimuth is the light's + 180
            assert math.degrees(math.atan2(wo[1], wo[0])) % 360 == pytest.approx(210.0, abs=1e-6)
    np.testing.assert_allclose(d["f"], brdf.get("microfacet").eval(p, d["wi"], d["wo"]), rtol=1e-12)
    c = theta.theta_v_curve(p, theta_i=40.0, phi_i=30.0, n=37, cos=True)
    np.testing.assert_allclose(c["y"], d["f"] * math.cos(math.radians(40)), rtol=1e-12)  # N.L: one constant
    with pytest.raises(ViewerError, match="theta-d"):
        theta.theta_h_curve(p, theta_d=95.0)


def test_the_slice_holds_phi_d_and_multiplies_by_cos_theta_i():
    from viewer.brdf import merl
    from viewer.plots.measured import slice_data

    p = _mats()[0]
    d = slice_data(p, n_d=9, phi_d=45.0, cos=True)
    th, _, _ = merl.grid_angles()
    td = (np.arange(9) + 0.5) / 9 * merl.HALF_PI
    TD, TH = np.meshgrid(td, th, indexing="ij")
    wi, wo = merl.from_half_diff(TH.ravel(), TD.ravel(), math.radians(45.0))
    # the held phi_d, measured here: wi seen from h's frame (h in the x-z plane: rotate back by theta_h)
    for w, t in zip(wi[::17], TH.ravel()[::17]):
        dv = _rot_y(w, -t)
        assert math.degrees(math.atan2(dv[1], dv[0])) == pytest.approx(45.0, abs=1e-6)
    f = brdf.get("microfacet").eval(p, wi, wo) * np.maximum(wi[:, 2], 0)[:, None]
    ok = (wi[:, 2] > 0) & (wo[:, 2] > 0)
    np.testing.assert_allclose(d["f"].reshape(-1, 3)[ok], f[ok], rtol=1e-12)
    with pytest.raises(ViewerError, match="phi-d"):
        slice_data(p, phi_d=200.0)


# ----------------------------------------------------------------------------- the term view

TERM_CASES = [dict(distribution=dn, shadowing=sh, fresnel=fr, alpha_x=ax, alpha_y=ay)
              for dn, sh, fr, ax, ay in (("ggx", "smith", "conductor", 0.2, 0.2), ("ggx", "v_cavity", "schlick", 0.1, 0.5),
                                         ("beckmann", "smith", "dielectric", 0.3, 0.15),
                                         ("blinn_phong", "smith", "conductor", 0.25, 0.25))]


@pytest.mark.parametrize("case", TERM_CASES, ids=lambda c: f"{c['distribution']}-{c['shadowing']}-{c['fresnel']}")
def test_the_terms_multiply_to_f(case):
    """D F G / (4 cos cos) of the plotted terms is f: the same float64 factors multiplied in
    another order, so they agree to a few roundings (rtol 1e-12 is ~5000 ulps: the products
    involve 4 multiplications and one division, each within 2^-53 relative)."""
    m = brdf.get("microfacet")
    p = m.params(**case)
    d = theta.term_curves(p, 35.0, 20.0, n=181)
    np.testing.assert_allclose(d["product"], d["f"], rtol=1e-12, atol=1e-300)
    assert np.all(d["f"][np.abs(d["x"]) < 80] > 0)  # a test that cannot fail on zeros alone
    # a diffuse base: the term view says what f adds to the product
    q = m.params(**case, kd=[0.3, 0.2, 0.1])
    e = theta.term_curves(q, 35.0, 20.0, n=181)
    np.testing.assert_allclose(e["product"] + e["other"], e["f"], rtol=1e-12)
    assert np.all(e["other"][np.abs(e["x"]) < 80] > 0)


@pytest.mark.parametrize("dist,ax,ay", [("ggx", 0.3, 0.3), ("ggx", 0.15, 0.45), ("beckmann", 0.25, 0.25),
                                        ("blinn_phong", 0.3, 0.3)])
def test_plotted_d_integrates_to_one_over_projected_half_vector_area(dist, ax, ay):
    """The D of the term view (the hook at wi = wo = h, where h = normalize(wi + wo) is h
    itself): the integral of D(h) cos theta_h over the hemisphere is 1 (the microfacets' projected
    area is the macro surface's). Midpoint rule on 400 x 48 cells in (t, phi), cos theta_h = 1 - t^2
    (cells packed toward the normal, where D peaks): the rule's error is 1.2e-5 to 1.7e-5 for
    these four (it falls as 1 / cells^2: 1.7e-7 on 4000 cells), the tolerance 2e-4; a D off by
    any usual factor (1 / pi, a missing cos, alpha for alpha^2) misses it by far more."""
    p = brdf.get("microfacet").params(distribution=dist, alpha_x=ax, alpha_y=ay)
    nu, nphi = 400, 48
    t = (np.arange(nu) + 0.5) / nu
    ph = (np.arange(nphi) + 0.5) / nphi * 2 * np.pi
    MU, PH = np.meshgrid(1.0 - t * t, ph, indexing="ij")
    weight = np.broadcast_to((2.0 * t / nu)[:, None], MU.shape).ravel() * (2 * np.pi / nphi)  # d(cos) dphi
    s = np.sqrt(1 - MU ** 2)
    h = np.stack([s * np.cos(PH), s * np.sin(PH), MU], axis=-1).reshape(-1, 3)
    D = brdf.get("microfacet").terms(p, h, h)["D"]
    assert float(np.sum(D * h[:, 2] * weight)) == pytest.approx(1.0, abs=2e-4)


def test_models_without_terms_say_so_and_the_hook_is_the_only_question():
    lam = brdf.get("lambert").params()
    assert brdf.get("lambert").terms(lam, [[0, 0, 1.0]], [[0, 0, 1.0]]) is None
    assert "terms" not in plots.applicable_kinds(lam)
    assert "terms" in plots.applicable_kinds(brdf.get("microfacet").params())
    with pytest.raises(ViewerError, match="no D, F, G"):
        plots.figure(lam, "terms")
    glass = plots.as_params({"model": "dielectric"})
    assert not {"theta_h", "theta_d", "theta_v"} & set(plots.applicable_kinds(glass))  # a delta lobe


def test_a_files_d_f_g_run_as_glsl_and_equal_the_built_in_terms():
    """tests/brdfs/ggx_terms.brdf writes GGX D, Schlick F and Smith G2 as functions D, F, G:
    detected in its GLSL, run on the GPU path (float32) and equal to the built-in microfacet's
    terms with the same formulas within 2e-5 relative (float32 rounding of the directions,
    about 6e-8, grows in D's denominator (cos^2 (a^2 - 1) + 1)^2 near the peak)."""
    from viewer.brdf.brdffile import parse, term_functions
    from viewer.scene import material_from_name

    bf = parse(DATA / "ggx_terms.brdf")
    assert term_functions(bf) == {"D": "float", "F": "vec3", "G": "float"}
    assert term_functions(parse("x.brdf", "analytic\n::begin shader\nfloat D(float c) { return c; }\n"
                                "vec3 BRDF(vec3 L, vec3 V, vec3 N, vec3 X, vec3 Y) { return vec3(D(1.0)); }\n"
                                "::end shader\n")) == {}
    p = material_from_name(str(DATA / "ggx_terms.brdf"), ["alpha=0.35"])
    assert "terms" in plots.applicable_kinds(p)
    q = brdf.get("microfacet").params(distribution="ggx", shadowing="smith", fresnel="schlick", alpha=0.35,
                                      f0=[0.9, 0.6, 0.3])
    a, b = theta.term_curves(p, 40.0, 0.0, n=91), theta.term_curves(q, 40.0, 0.0, n=91)
    for k in ("D", "F", "G", "1/(4 cos cos)", "product", "f"):
        np.testing.assert_allclose(a[k], b[k], rtol=2e-5, atol=1e-7, err_msg=k)
    np.testing.assert_allclose(a["product"], a["f"], rtol=2e-5)  # the file's BRDF is its terms' product
    every = material_from_name(str(DATA / "every_declaration.brdf"))
    assert "terms" not in plots.applicable_kinds(every)  # no D, F, G functions


# ----------------------------------------------------------------------------- the CLI


def test_plot_cli_writes_the_new_kinds(tmp_path, capsys):
    from viewer.commands.cli import main

    runs = [("theta_h", ["--theta-d", "20", "--cos"]), ("theta_d", ["--theta-h", "5", "--log"]),
            ("theta_v", ["--theta-i", "30", "--phi-v", "10"]), ("terms", ["--log"]), ("slice", ["--phi-d", "60"])]
    for kind, extra in runs:
        out = tmp_path / f"{kind}.png"
        assert main(["plot", "microfacet", "--kind", kind, "--out", str(out), "--set", "alpha=0.25",
                     "--width", "480", "--height", "320"] + extra) == 0
        data = plots.read_plot_data(out)
        assert data["kind"] == kind
    th = plots.read_plot_data(tmp_path / "theta_h.png")
    assert th["info"]["theta_d"] == 20.0 and th["info"]["cos"] is True
    terms = plots.read_plot_data(tmp_path / "terms.png")
    labels = [c["label"] for c in terms["curves"]]
    assert labels[0] == "D" and "G" in labels and "1/(4 cos cos)" in labels
    assert main(["plot", "lambert", "--kind", "terms", "--out", str(tmp_path / "x.png")]) == 2
    assert "no D, F, G" in capsys.readouterr().err
    assert main(["plot", "microfacet", "--kind", "theta_h", "--theta-d", "91", "--out", str(tmp_path / "y.png")]) == 2
