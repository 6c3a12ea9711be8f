"""Measured (MERL) BRDFs: the file format, the index mapping, evaluation back to the analytic
function a file was written from, sampling (chi-square, weight = f cos / pdf), the GLSL twin
and the rasterizer's texture, the reference, the fit, the plots and the error lines. Every file
is written here from a known function (the MERL data are not redistributable)."""

import struct

import numpy as np
import pytest

from viewer import ViewerError, brdf
from viewer.brdf import chi2, fit, measured, merl

ALBEDO = np.array([0.7, 0.5, 0.3])
GGX = dict(kd=(0.0, 0.0, 0.0), alpha=0.3, f0=(0.9, 0.6, 0.35))  # the closed form without its base


def _dirs(rng, n):
    z = rng.random(n)
    ph = rng.random(n) * 2 * np.pi
    s = np.sqrt(1 - z * z)
    return np.stack([s * np.cos(ph), s * np.sin(ph), z], axis=1)


@pytest.fixture(scope="module")
def lambert_file(tmp_path_factory):
    path = tmp_path_factory.mktemp("merl") / "lambert.binary"
    merl.write(path, np.broadcast_to(ALBEDO / np.pi, (90, 90, 180, 3)))
    return path


@pytest.fixture(scope="module")
def ggx_file(tmp_path_factory):
    path = tmp_path_factory.mktemp("merl") / "ggx.binary"
    merl.write(path, merl.tabulate(lambda wi, wo: measured.example_brdf(wi, wo, **GGX)))
    return path


# ---------------------------------------------------------------- format and mapping
def test_file_layout_and_scales(lambert_file):
    """Header 90 90 180 (int32), then float64 R, G, B blocks stored divided by the MERL scales
    (1/1500, 1.15/1500, 1.66/1500)."""
    raw = lambert_file.read_bytes()
    assert struct.unpack("<3i", raw[:12]) == (90, 90, 180)
    assert len(raw) == 12 + 8 * 3 * 90 * 90 * 180
    vals = np.frombuffer(raw[12:], dtype="<f8").reshape(3, -1)
    np.testing.assert_allclose(vals[:, 0], ALBEDO / np.pi / np.array([1 / 1500, 1.15 / 1500, 1.66 / 1500]))
    np.testing.assert_allclose(merl.read(lambert_file), np.broadcast_to(ALBEDO / np.pi, (90, 90, 180, 3)))


def test_index_mapping():
    """The MERL indices: theta_h = 22.5 deg is bin 45 of the sqrt mapping, theta_d = 45 deg bin 45,
    phi_d = 90 deg bin 90; phi_d and phi_d + 180 deg fold together; the grid angles map to their
    own indices, and (wi, wo) and (wo, wi) to the same entry (reciprocity)."""
    ih, idd, ip = merl.merl_index(np.radians([22.5]), np.radians([45.0]), np.radians([90.0]))
    assert (ih[0], idd[0], ip[0]) == (45, 45, 90)
    th, td, pd = merl.grid_angles()
    assert np.array_equal(merl.merl_index(th + 1e-12, td + 1e-12, pd + 1e-12)[0], np.arange(90))
    rng = np.random.default_rng(3)
    wi, wo = _dirs(rng, 2000), _dirs(rng, 2000)
    a = merl.half_diff(wi, wo)
    b = merl.half_diff(wo, wi)
    np.testing.assert_allclose(a[0], b[0], atol=1e-12)
    np.testing.assert_allclose(a[1], b[1], atol=1e-12)
    np.testing.assert_allclose(np.sin(2 * a[2]), np.sin(2 * b[2]), atol=1e-9)  # equal modulo pi
    w1, w2 = merl.from_half_diff(*a)
    np.testing.assert_allclose(np.array(merl.half_diff(w1, w2)), np.array(a), atol=1e-9)


def test_bad_files_give_one_line(tmp_path, lambert_file):
    raw = lambert_file.read_bytes()
    cases = {
        "header": (struct.pack("<3i", 90, 90, 360) + raw[12:], "dimensions 90 x 90 x 360"),
        "short": (raw[:1000], "truncated or padded"),
        "tiny": (b"abc", "shorter than the 12-byte header"),
    }
    nan = bytearray(raw)
    nan[12 + 8 * 5: 12 + 8 * 6] = struct.pack("<d", float("nan"))
    cases["nan"] = (bytes(nan), "NaN or infinite")
    for name, (data, words) in cases.items():
        path = tmp_path / f"{name}.binary"
        path.write_bytes(data)
        with pytest.raises(ViewerError) as e:
            merl.read(path)
        msg = str(e.value)
        assert "\n" not in msg and str(path) in msg and words in msg, msg
    for path, words in ((tmp_path / "missing.binary", "file not found"), (tmp_path, "is a folder")):
        with pytest.raises(ViewerError, match=words):
            merl.read(path)
    # in a scene: the field is named too
    from viewer.scene import load_scene_text

    with pytest.raises(ViewerError) as e:
        load_scene_text('[materials.m]\nmodel = "measured"\nfile = "short.binary"\n[[objects]]\nmesh = "sphere"\n'
                        'material = "m"\n', base_dir=tmp_path)
    assert "materials.m.file" in str(e.value) and "truncated" in str(e.value) and "\n" not in str(e.value)


def test_negative_entries_are_missing_measurements(tmp_path, lambert_file, caplog):
    """Negative entries (the MERL reference reader's 'below horizon') read as 0, with one warning."""
    raw = bytearray(lambert_file.read_bytes())
    raw[12: 12 + 16] = struct.pack("<2d", -1.0, -1.0)
    path = tmp_path / "neg.binary"
    path.write_bytes(bytes(raw))
    with caplog.at_level("WARNING"):
        t = merl.read(path)
    assert t[0, 0, 0, 0] == 0.0 and t[0, 0, 1, 0] == 0.0 and t[0, 0, 2, 0] > 0
    assert sum("2 negative values" in r.getMessage() for r in caplog.records) == 1


# ---------------------------------------------------------------- evaluation
def test_lambert_file_evaluates_back_exactly(lambert_file):
    m = brdf.get("measured")
    p = m.params(file=str(lambert_file))
    rng = np.random.default_rng(0)
    wi, wo = _dirs(rng, 5000), _dirs(rng, 5000)
    np.testing.assert_allclose(m.eval(p, wi, wo), np.broadcast_to(ALBEDO / np.pi, (5000, 3)), rtol=1e-12)
    assert np.all(m.eval(p, wi * [1, 1, -1], wo) == 0)  # below the horizon


def test_ggx_file_evaluates_back(ggx_file):
    """Trilinear interpolation of a file written from a GGX lobe (alpha 0.3) against the closed form
    at random directions: at the grid's own angles exact; elsewhere the median relative error is
    stated (about 0.1%; the largest errors are at the peak and at grazing angles, where f changes
    fastest between table entries)."""
    m = brdf.get("measured")
    p = m.params(file=str(ggx_file))
    th, td, pd = merl.grid_angles()
    wi, wo = merl.from_half_diff(th[[3, 20, 50]], td[[10, 30, 60]], pd[[5, 90, 170]])
    np.testing.assert_allclose(m.eval(p, wi, wo), measured.example_brdf(wi, wo, **GGX), rtol=1e-9)
    rng = np.random.default_rng(1)
    wi, wo = _dirs(rng, 20000), _dirs(rng, 20000)
    ref = measured.example_brdf(wi, wo, **GGX)
    got = m.eval(p, wi, wo)
    big = ref > 1e-3
    rel = np.abs(got - ref)[big] / ref[big]
    med, p90 = float(np.median(rel)), float(np.percentile(rel, 90))
    print(f"GGX alpha 0.3 file: median relative interpolation error {med:.2e}, 90th percentile {p90:.2e}")
    assert med < 3e-3 and p90 < 3e-2


# ---------------------------------------------------------------- sampling
@pytest.mark.parametrize("theta", [0.0, 45.0, 80.0])
def test_sampling_chi2_and_weight(ggx_file, theta):
    m = brdf.get("measured")
    p = m.params(file=str(ggx_file))
    wo = np.array([np.sin(np.radians(theta)), 0.0, np.cos(np.radians(theta))])
    res = chi2.chi2_test(m, p, wo, 100_000, np.random.default_rng(7), alpha=1e-4)
    assert res.ok, res.message
    u = np.random.default_rng(8).random((20000, 2))
    wi, weight, pdf = m.sample(p, np.broadcast_to(wo, (20000, 3)), u)
    ok = pdf > 0
    assert ok.mean() > 0.5
    np.testing.assert_allclose(pdf[ok], m.pdf(p, wi[ok], np.broadcast_to(wo, (ok.sum(), 3))), rtol=1e-10)
    f = m.eval(p, wi[ok], np.broadcast_to(wo, (ok.sum(), 3)))
    np.testing.assert_allclose(weight[ok], f * wi[ok, 2:3] / pdf[ok, None], rtol=1e-10)


def test_albedo_of_lambert_file(lambert_file):
    """The sampler's mean weight is the albedo (a constant table: the directional albedo is rho)."""
    m = brdf.get("measured")
    p = m.params(file=str(lambert_file))
    wo = np.array([0.5, 0.0, np.sqrt(0.75)])
    _, w, _ = m.sample(p, np.broadcast_to(wo, (200_000, 3)), np.random.default_rng(2).random((200_000, 2)))
    mean, se = w.mean(axis=0), w.std(axis=0) / np.sqrt(len(w))
    assert np.all(np.abs(mean - ALBEDO) < 5 * se + 1e-9), (mean, se)


# ---------------------------------------------------------------- split-sum environment lighting
def test_split_sum_fit_of_known_tables(lambert_file, ggx_file):
    """The rasterizer's split-sum data for a table: a Lambert table is all diffuse floor; GGX
    alpha 0.3 without a base comes back as alpha 0.3 (to 0.03: F and G are taken constant near
    the specular plane) with no floor to speak of; the built-in example (GGX alpha 0.25 over kd
    (0.12, 0.1, 0.08)) within 0.03 and 25% (the fit's floor absorbs part of the peak's tail)."""
    rho_d, alpha = merl.Measured(merl.read(lambert_file)).split_sum_fit()
    np.testing.assert_allclose(rho_d, ALBEDO, rtol=1e-6)
    rho_d, alpha = merl.Measured(merl.read(ggx_file)).split_sum_fit()
    assert abs(alpha - 0.3) < 0.03 and np.all(rho_d < 0.02), (rho_d, alpha)
    rho_d, alpha = measured.example().split_sum_fit()
    assert abs(alpha - 0.25) < 0.03, alpha
    np.testing.assert_allclose(rho_d, measured.EXAMPLE["kd"], rtol=0.25)


# ---------------------------------------------------------------- fit
def test_fit_recovers_lambert(lambert_file):
    r = fit.fit(merl.read(lambert_file), "lambert")
    np.testing.assert_allclose(r.params.albedo, ALBEDO, rtol=1e-6)


def test_fit_recovers_ggx(ggx_file):
    """A file written from GGX + Schlick + height-correlated Smith (alpha 0.3): the microfacet
    model with those choices recovers alpha and f0 (start: its defaults, alpha 0.2)."""
    start = brdf.get("microfacet").params(distribution="ggx", fresnel="schlick", shadowing="smith")
    r = fit.fit(merl.read(ggx_file), "microfacet", start=start, fixed=("kd",))
    print(f"fit: {r.fitted}, rms {r.rms:.3g}, relative {r.rel:.3g}")
    assert abs(r.params.alpha_x - 0.3) < 1e-4 and abs(r.params.alpha_y - 0.3) < 1e-4
    np.testing.assert_allclose(r.params.f0, GGX["f0"], atol=1e-4)
    assert r.rel < 1e-4


def test_fit_cli_and_plots(tmp_path, ggx_file, capsys):
    """``brdf-viewer fit`` prints and writes a material file (loadable), the residual slice; ``plot
    FILE.binary --kind slice|polar|albedo --overlay`` draw the measured data with the fit over it."""
    from viewer import plots
    from viewer.commands import cli
    from viewer.scene import load_material_file

    out = tmp_path / "fit.toml"
    res = tmp_path / "res.png"
    rc = cli.main(["fit", str(ggx_file), "--model", "lambert", "--out", str(out), "--residual", str(res)])
    assert rc == 0
    text = capsys.readouterr().out
    assert "RMS of (f_model - f_measured) cos theta_i" in text and "wrote" in text
    name, params = load_material_file(out)
    assert name == "fitted" and params.model == "lambert"
    data = plots.read_plot_data(res)
    assert data["kind"] == "slice" and data["info"]["residual_rms"] > 0
    for kind in ("slice", "polar", "albedo"):
        png = tmp_path / f"{kind}.png"
        assert cli.main(["plot", str(ggx_file), "--kind", kind, "--overlay", str(out), "--out", str(png),
                         "--width", "400", "--height", "300"]) == 0
        d = plots.read_plot_data(png)
        if kind != "slice":
            labels = [c["label"] for c in d["curves"]]
            assert any(lab.startswith("lambert") for lab in labels), labels
    # a bad file: one line, exit status 2
    bad = tmp_path / "bad.binary"
    bad.write_bytes(b"\0" * 100)
    assert cli.main(["fit", str(bad), "--model", "lambert", "--out", str(tmp_path / "x.toml")]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "bad.binary" in err and not (tmp_path / "x.toml").exists()


# ---------------------------------------------------------------- renderers
def _scene(path, material):
    from viewer.scene import SCENE_DIR, load_scene_text

    text = ((SCENE_DIR / "sphere.toml").read_text().split("[materials.ball]")[0] + "[materials.ball]\n" + material)
    return load_scene_text(text, base_dir=path.parent)


def test_raster_measured_lambert_equals_lambert(renderer, lambert_file):
    """The rasterizer binds the table: a measured file of a Lambert BRDF renders as the lambert
    model under a point light (float32 shading; trilinear of a constant table is exact)."""
    a = _scene(lambert_file, f'model = "measured"\nfile = "{lambert_file.name}"\n')
    b = _scene(lambert_file, f"model = \"lambert\"\nalbedo = {ALBEDO.tolist()}\n")
    ia, _ = renderer.render_arrays(a, width=48, height=48)
    ib, _ = renderer.render_arrays(b, width=48, height=48)
    assert ib.max() > 0.05
    np.testing.assert_allclose(ia, ib, atol=2e-5, rtol=2e-4)


def test_reference_and_engines(lambert_file, gl_ctx, tmp_path):
    """The cpu reference renders measured materials (Lambert file vs lambert, within noise); the gpu
    engine binds the scene's one table and agrees with the cpu engine within noise
    (tests/reference_harness.py); a scene whose measured materials read two files it refuses in
    one line."""
    from reference_harness import agreement, check, under_grey_sky
    from viewer.reference_common.select import make_renderer, uses_measured
    from viewer.pathtracer import ReferenceRenderer

    a = _scene(lambert_file, f'model = "measured"\nfile = "{lambert_file.name}"\n')
    b = _scene(lambert_file, f"model = \"lambert\"\nalbedo = {ALBEDO.tolist()}\n")
    assert uses_measured(a) and not uses_measured(b)
    means = []
    for s in (a, b):
        r = ReferenceRenderer(s, width=24, height=24, max_depth=2, seed=1, workers=0)
        try:
            r.step(16)
            means.append(r.mean().astype(np.float64))
        finally:
            r.close()
    assert means[1].mean() > 0.005
    # direct light is next-event estimated identically; only the bounce's sampling differs
    assert abs(means[0].mean() - means[1].mean()) < 0.02 * means[1].mean()
    g = agreement(gl_ctx, under_grey_sky(a), spp=16, max_depth=2, size=16)
    assert g["sigma"] < 0.01, g
    check(g, "lambert.binary")
    other = tmp_path / "other.binary"
    merl.write(other, np.broadcast_to(ALBEDO / np.pi / 2, (90, 90, 180, 3)))
    a.materials["second"] = brdf.get("measured").params(file=str(other))
    with pytest.raises(ViewerError, match="one measured table"):
        make_renderer("gpu", a)


# ---------------------------------------------------------------- bin centres, the sampler's floor
def _centre_file(path, fn):
    """A MERL file of fn written at the bins' centres, computed here from the index mapping
    (theta_h = ((i + 1/2) / 90)^2 pi / 2, theta_d = (i + 1/2) / 90 pi / 2, phi_d = (i + 1/2) / 180 pi)."""
    i = np.arange(90)
    th = ((i + 0.5) / 90) ** 2 * np.pi / 2
    td = (i + 0.5) / 90 * np.pi / 2
    pd = (np.arange(180) + 0.5) / 180 * np.pi
    TH, TD, PD = np.meshgrid(th, td, pd, indexing="ij")
    wi, wo = merl.from_half_diff(TH.ravel(), TD.ravel(), PD.ravel())
    ok = (wi[:, 2] > 0) & (wo[:, 2] > 0)
    t = np.zeros((wi.shape[0], 3))
    t[ok] = fn(wi[ok], wo[ok])
    merl.write(path, t.reshape(90, 90, 180, 3))
    return path


@pytest.fixture(scope="module")
def example_file(tmp_path_factory):
    return _centre_file(tmp_path_factory.mktemp("merl") / "example.binary", measured.example_brdf)


def test_entries_are_read_at_their_bins_centres(example_file):
    # the built-in example (diffuse floor + GGX alpha 0.25) written at the bins' centres reads
    # back with a median relative error of 0.07% (measured; 1.8% when entries stood at their
    # bins' lower edges, half a bin off). Bound 0.3%: linear interpolation's error of a smooth
    # lobe over one bin, (bin / 2)^2 f'' / 2, is ~1e-3 relative away from the peak
    m = brdf.get("measured")
    p = m.params(file=str(example_file))
    rng = np.random.default_rng(1)
    wi, wo = _dirs(rng, 50_000), _dirs(rng, 50_000)
    ref = measured.example_brdf(wi, wo)
    got = m.eval(p, wi, wo)
    big = ref > 1e-3
    rel = np.abs(got - ref)[big] / ref[big]
    assert np.median(rel) < 3e-3, np.median(rel)


@pytest.mark.parametrize("theta, most", [(0.0, 0.06), (45.0, 0.08)])
def test_sampler_half_vectors_leave_the_floor_to_the_cosine(example_file, theta, most):
    # the half-vector density is built from the profile minus its diffuse floor (the cosine part
    # samples that): 4.8% / 6.5% of the samples fall below the horizon at 0 / 45 deg (measured;
    # 14.1% / 15.1% with the floor in the half-vector density; at 80 deg 17% / 20%, where any
    # half-vector sampler reflects part of its lobe below). The pdf stays exact: chi-square.
    m = brdf.get("measured")
    p = m.params(file=str(example_file))
    wo = np.array([np.sin(np.radians(theta)), 0.0, np.cos(np.radians(theta))])
    u = np.random.default_rng(8).random((50_000, 2))
    wi, _, pdf = m.sample(p, np.broadcast_to(wo, (50_000, 3)), u)
    assert (pdf <= 0).mean() < most
    res = chi2.chi2_test(m, p, wo, 100_000, np.random.default_rng(7), alpha=1e-4)
    assert res.ok, res.message
