"""Measured anisotropic BRDFs in the MIT format (``.dat``, as BRDF Explorer opens them): the
file layout, the index mapping, evaluation back to the known function a file was written from
(exact at the grid, the product of 1D linear interpolants between), the error lines, sampling,
the GLSL twin, the rasterizer against the cpu reference. Every file is written here from a
known function (the published data are not redistributed)."""

import struct

import numpy as np
import pytest

from viewer import ViewerError, brdf
from viewer.brdf import chi2, measured, mit_aniso

DIMS = (8, 8, 16, 16)  # theta_in, theta_out, phi_diff, phi_in
KD = np.array([0.5, 0.35, 0.2])
KS = np.array([0.15, 0.2, 0.25])
AX, AY = 0.3, 0.6


def ward(wi, wo):
    """Lambert plus an anisotropic Ward lobe (Ward 1992; alpha_x 0.3 along the tangent, alpha_y 0.6)."""
    h = wi + wo
    h = h / np.linalg.norm(h, axis=1, keepdims=True)
    ci, co = np.clip(wi[:, 2], 1e-6, 1), np.clip(wo[:, 2], 1e-6, 1)
    e = -((h[:, 0] / AX) ** 2 + (h[:, 1] / AY) ** 2) / h[:, 2] ** 2
    s = np.exp(e) / (4 * np.pi * AX * AY * np.sqrt(ci * co))
    return KD[None] / np.pi + KS[None] * s[:, None]


# a separable function of the four angles: its quadrilinear interpolant is the product of the
# four 1D linear interpolants of its factors, computed here independently of the reader
FACTORS = (lambda t: 1.0 + 0.5 * np.cos(t), lambda t: 1.0 + 0.3 * np.cos(2 * t),
           lambda p: 1.0 + 0.4 * np.cos(p), lambda p: 1.0 + 0.5 * np.cos(2 * p))


def separable(wi, wo):
    a = mit_aniso.angles(wi, wo)
    v = np.prod([g(x) for g, x in zip(FACTORS, a)], axis=0)
    return (KD[None] / np.pi) * v[:, None]


def _dirs(rng, n, zmin=0.05):
    z = zmin + (1 - zmin) * rng.random(n)
    ph = rng.random(n) * 2 * np.pi
    s = np.sqrt(1 - z * z)
    return np.stack([s * np.cos(ph), s * np.sin(ph), z], axis=1)


@pytest.fixture(scope="module")
def ward_file(tmp_path_factory):
    path = tmp_path_factory.mktemp("mit") / "ward.dat"
    mit_aniso.write(path, mit_aniso.tabulate(ward, DIMS))
    return path


@pytest.fixture(scope="module")
def lambert_file(tmp_path_factory):
    path = tmp_path_factory.mktemp("mit") / "lambert.dat"
    mit_aniso.write(path, np.broadcast_to(KD / np.pi, (*DIMS, 3)))
    return path


# ---------------------------------------------------------------- format and mapping
def test_layout_written_by_hand_reads_as_published(tmp_path):
    """A file built here from the format's description (16 int32, then float32 R, G, B blocks,
    phi_in fastest, BRDF = 10 x stored) reads back entry for entry."""
    dims = (2, 3, 4, 5)
    n = int(np.prod(dims))
    stored = np.arange(3 * n, dtype="<f4").reshape(3, n) / (3 * n)
    head = [0] * 16
    head[:4] = dims
    head[6], head[7], head[9], head[10] = 1, 0, 0, 3
    path = tmp_path / "hand.dat"
    path.write_bytes(struct.pack("<16i", *head) + stored.tobytes())
    t = mit_aniso.read(path)
    assert t.shape == (2, 3, 4, 5, 3)
    for (ti, to, pd, pi_) in [(0, 0, 0, 0), (1, 2, 3, 4), (1, 0, 2, 1)]:
        k = pi_ + 5 * (pd + 4 * (to + 3 * ti))
        np.testing.assert_allclose(t[ti, to, pd, pi_], 10.0 * stored[:, k], rtol=1e-6)
    # the writer writes that layout
    mit_aniso.write(tmp_path / "again.dat", t)
    again = (tmp_path / "again.dat").read_bytes()
    assert again[:64] == path.read_bytes()[:64]
    np.testing.assert_allclose(np.frombuffer(again[64:], dtype="<f4"), stored.ravel(), rtol=1e-6)


def test_index_mapping():
    """BRDF Explorer's floor indices: phi measured from the reversed tangent, phi_diff = phi_out -
    phi_in in [0, 2 pi); the grid angles map to their own indices through the directions."""
    g = np.meshgrid(*mit_aniso.grid_angles(DIMS), indexing="ij")
    wi, wo = mit_aniso.directions(*(a.ravel() for a in g))
    got = mit_aniso.index(*mit_aniso.angles(wi, wo), DIMS)
    for k, a in enumerate(g):
        want = np.rint(a.ravel() / mit_aniso.ranges()[k] * DIMS[k] - 0.5).astype(int)
        assert np.array_equal(got[k], want)
    # a light along -tangent has phi_in 0; along +bitangent phi_in = 3 pi / 2
    s = np.sin(0.5)
    ti, to, pd, pi_ = mit_aniso.angles(np.array([[-s, 0, np.cos(0.5)], [0, s, np.cos(0.5)]]),
                                       np.array([[s, 0, np.cos(0.5)], [s, 0, np.cos(0.5)]]))
    np.testing.assert_allclose(pi_, [0.0, 1.5 * np.pi], atol=1e-12)
    np.testing.assert_allclose(pd, [np.pi, 1.5 * np.pi], atol=1e-12)


def test_lookup_exact_at_grid_and_linear_between(tmp_path):
    """At the bins' centres the lookup is the function; between them it is the product of the four
    1D linear interpolants (entries at centres, thetas clamped, azimuths periodic), and within the
    interpolation bound sum_k h_k^2 max|g_k''| / 8 x the other factors' maxima of the function."""
    path = tmp_path / "sep.dat"
    mit_aniso.write(path, mit_aniso.tabulate(separable, DIMS))
    m = brdf.get("measured")
    p = m.params(file=str(path))
    g = np.meshgrid(*mit_aniso.grid_angles(DIMS), indexing="ij")
    wi, wo = mit_aniso.directions(*(a.ravel() for a in g))
    np.testing.assert_allclose(m.eval(p, wi, wo), separable(wi, wo), rtol=1e-6)
    rng = np.random.default_rng(2)
    wi, wo = _dirs(rng, 20000, zmin=0.0), _dirs(rng, 20000, zmin=0.0)
    a = mit_aniso.angles(wi, wo)
    want = np.ones(len(wi))
    for k, (g_, x) in enumerate(zip(FACTORS, a)):
        n, r = DIMS[k], mit_aniso.ranges()[k]
        centres = (np.arange(n) + 0.5) / n * r
        if k < 2:
            li = np.interp(x, centres, g_(centres))  # clamped beyond the end centres
        else:
            li = np.interp(x, np.concatenate([centres - r, centres, centres + r]), np.tile(g_(centres), 3))
        want = want * li
    got = m.eval(p, wi, wo)
    np.testing.assert_allclose(got, (KD[None] / np.pi) * want[:, None], rtol=2e-6)
    # the error against the function itself where no theta is beyond its end centres
    inner = np.all([(a[k] > 0.5 * np.pi / 2 / DIMS[k]) & (a[k] < (DIMS[k] - 0.5) * np.pi / 2 / DIMS[k])
                    for k in (0, 1)], axis=0)
    h = [r / n for r, n in zip(mit_aniso.ranges(), DIMS)]
    curv = [0.5, 0.3 * 4, 0.4, 0.5 * 4]  # max |g_k''|
    top = [1.5, 1.3, 1.4, 1.5]  # max g_k
    bound = sum(h[k] ** 2 * curv[k] / 8 * np.prod(top) / top[k] for k in range(4)) * KD.max() / np.pi
    err = np.abs(got - separable(wi, wo))[inner].max()
    print(f"separable table {DIMS}: max interpolation error {err:.2e}, bound {bound:.2e}")
    assert err <= bound


def test_ward_file_evaluates_back(ward_file):
    """An anisotropic Ward lobe over Lambert: exact at grid points; at random directions the median
    relative error is stated (the largest errors are at grazing angles, where 1 / sqrt(cos_i cos_o)
    grows beyond the last theta centre, and at the peak)."""
    m = brdf.get("measured")
    p = m.params(file=str(ward_file))
    rng = np.random.default_rng(1)
    wi, wo = _dirs(rng, 20000), _dirs(rng, 20000)
    rel = np.abs(m.eval(p, wi, wo) - ward(wi, wo)) / ward(wi, wo)
    med, p90 = float(np.median(rel)), float(np.percentile(rel, 90))
    print(f"Ward file {DIMS}: median relative error {med:.2e}, 90th percentile {p90:.2e}")
    assert med < 0.02 and p90 < 0.1
    # anisotropic: backscatter with the half vector tilted along the tangent (alpha_x 0.3) is
    # darker than the same pair turned 90 degrees about the normal (tilted along alpha_y 0.6)
    rot = np.array([[0, -1, 0], [1, 0, 0], [0, 0, 1.0]])
    a = np.array([[np.sin(0.4), 0, np.cos(0.4)]])
    f, g = m.eval(p, a, a)[0, 2], m.eval(p, a @ rot.T, a @ rot.T)[0, 2]
    assert ward(a @ rot.T, a @ rot.T)[0, 2] > 1.3 * ward(a, a)[0, 2] and g > 1.3 * f
    assert np.all(m.eval(p, wi * [1, 1, -1], wo) == 0)


# ---------------------------------------------------------------- bad files
def _header(dims=DIMS, param=1, binning=0, half=0, channels=3):
    h = [0] * 16
    h[:4] = dims
    h[6], h[7], h[9], h[10] = param, binning, half, channels
    return struct.pack("<16i", *h)


def test_bad_files_give_one_line(tmp_path, ward_file, caplog):
    good = ward_file.read_bytes()
    body = good[64:]
    cases = {
        "short.dat": (b"\0" * 10, "shorter than the 64-byte header"),
        "param.dat": (_header(param=0) + body, "paramType 0"),
        "bins.dat": (_header(binning=1) + body, "binType 1"),
        "half.dat": (_header(half=1) + body, "half_data 1"),
        "chan.dat": (_header(channels=4) + body, "4 channels"),
        "zero.dat": (_header(dims=(0, 8, 16, 16)) + body, "0 theta_in bins"),
        "many.dat": (_header(dims=(8, 8, 16, 100000)) + body, "100000 phi_in bins"),
        "trunc.dat": (good[:-4], "truncated or padded"),
        "padded.dat": (good + b"\0" * 4, "truncated or padded"),
    }
    nan = np.frombuffer(body, dtype="<f4").copy()
    nan[5] = np.nan
    cases["nan.dat"] = (good[:64] + nan.tobytes(), "NaN or infinite")
    for name, (data, words) in cases.items():
        (tmp_path / name).write_bytes(data)
        with pytest.raises(ViewerError) as e:
            mit_aniso.read(tmp_path / name)
        msg = str(e.value)
        assert "\n" not in msg and name in msg and words in msg, (name, msg)
    huge = tmp_path / "huge.dat"
    with open(huge, "wb") as f:  # sparse: the size is checked before anything is read
        f.truncate(mit_aniso.MAX_BYTES + 1)
    with pytest.raises(ViewerError, match="at most"):
        mit_aniso.read(huge)
    with pytest.raises(ViewerError, match="file not found"):
        mit_aniso.read(tmp_path / "none.dat")
    # in a scene material: the file is named with the material's key
    with pytest.raises(ViewerError, match="trunc.dat"):
        brdf.get("measured").params(file=str(tmp_path / "trunc.dat"))
    # a negative channel: the entry reads as 0 (BRDF Explorer draws black there), one warning
    neg = np.frombuffer(body, dtype="<f4").copy()
    neg[0] = -1.0
    (tmp_path / "neg.dat").write_bytes(good[:64] + neg.tobytes())
    t = mit_aniso.read(tmp_path / "neg.dat")
    assert np.all(t[0, 0, 0, 0] == 0) and np.all(t[0, 0, 0, 1] > 0)
    assert "missing measurements" in caplog.text


# ---------------------------------------------------------------- sampling
@pytest.mark.parametrize("theta", [60.0])
def test_sampling_chi2_and_weight(ward_file, theta):
    m = brdf.get("measured")
    p = m.params(file=str(ward_file))
    wo = np.array([np.sin(np.radians(theta)), 0.0, np.cos(np.radians(theta))])
    res = chi2.chi2_test(m, p, wo, 40_000, np.random.default_rng(7), alpha=1e-4)
    assert res.ok, res.message
    u = np.random.default_rng(8).random((5000, 2))
    wi, weight, pdf = m.sample(p, np.broadcast_to(wo, (5000, 3)), u)
    ok = pdf > 0
    f = m.eval(p, wi[ok], np.broadcast_to(wo, (ok.sum(), 3)))
    np.testing.assert_allclose(weight[ok], f * wi[ok, 2:3] / pdf[ok, None], rtol=1e-10)


# ---------------------------------------------------------------- GLSL twin, raster, reference
def test_glsl_twin(gl_ctx, ward_file):
    """The GLSL lookup (MEASURED_ANISO, 16 texel fetches) is the numpy one to float32 rounding
    (the bound of the MERL twin, measured.GLSL_RTOL: angles rounded to float32 move the
    interpolation weights by about 1e-6 of a cell, times neighbour differences)."""
    from glsl_eval import GLSLEvaluator
    from viewer.gl.brdf_glsl import program_defines

    m = brdf.get("measured")
    p = m.params(file=str(ward_file))
    assert "MEASURED_ANISO" in program_defines([p])
    rng = np.random.default_rng(4)
    wi, wo = _dirs(rng, 3000).astype(np.float32), _dirs(rng, 3000).astype(np.float32)
    got = GLSLEvaluator(gl_ctx).eval(p, wi, wo)
    want = m.eval(p, wi.astype(np.float64), wo.astype(np.float64))
    np.testing.assert_allclose(got, want, rtol=measured.GLSL_RTOL, atol=1e-6)


def _scene(path, material):
    from viewer.scene import SCENE_DIR, load_scene_text

    text = ((SCENE_DIR / "sphere.toml").read_text().split("[materials.ball]")[0] + "[materials.ball]\n" + material)
    return load_scene_text(text, base_dir=path.parent)


def test_raster_lambert_file_equals_lambert(renderer, lambert_file):
    a = _scene(lambert_file, f'model = "measured"\nfile = "{lambert_file.name}"\n')
    b = _scene(lambert_file, f"model = \"lambert\"\nalbedo = {KD.tolist()}\n")
    ia, _ = renderer.render_arrays(a, width=32, height=32)
    ib, _ = renderer.render_arrays(b, width=32, height=32)
    assert ib.max() > 0.05
    np.testing.assert_allclose(ia, ib, atol=2e-5, rtol=2e-4)


def test_raster_and_reference_agree(renderer, ward_file):
    """The sphere of the Ward file under the scene's point light with no environment: the raster's
    direct light against the cpu reference at max_depth 1 (next-event estimation of the same
    light, the same table), on the pixels wholly inside the lit sphere (at the silhouette and the
    terminator the raster's tessellated, multisampled coverage and the reference's box-filtered
    sphere differ: 2.2% on the image mean for the lambert model itself at 24 x 24): per pixel
    within 5 standard errors plus 5% (the raster shades a pixel's centre, the reference averages
    the pixel: for the lambert model itself they differ by up to 4.7% per inner pixel at 256
    samples), and the means within 1%."""
    from viewer.pathtracer import ReferenceRenderer

    s = _scene(ward_file, f'model = "measured"\nfile = "{ward_file.name}"\n')
    s.environment.map = None
    s.environment.constant = np.zeros(3)
    s.environment.intensity = 0.0
    img, _ = renderer.render_arrays(s, width=24, height=24)
    with ReferenceRenderer(s, width=24, height=24, max_depth=1, seed=3, workers=0) as r:
        r.step(64)
        ref, var = r.mean().astype(np.float64), r.variance().astype(np.float64)
    img = np.asarray(img, dtype=np.float64)[..., :3]
    lit = ref.sum(axis=-1) > 1e-3 * ref.sum(axis=-1).max()
    inner = lit.copy()
    for dy in (-1, 0, 1):
        for dx in (-1, 0, 1):
            inner &= np.roll(np.roll(lit, dy, 0), dx, 1)
    assert inner.sum() > 100
    z = np.abs(img - ref)[inner] / (5.0 * np.sqrt(var[inner]) + 0.05 * ref[inner] + 1e-6)
    rel = img[inner].mean() / ref[inner].mean() - 1
    print(f"Ward file sphere, {inner.sum()} inner pixels: raster / reference mean {rel:+.2e}, largest |difference| / allowed {z.max():.2f}")
    assert abs(rel) < 0.01 and z.max() < 1.0


def test_engines_agree(gl_ctx, ward_file, tmp_path):
    """The gpu engine binds the scene's one measured table (MEASURED_ANISO in its program) and
    agrees with the cpu engine within noise (tests/reference_harness.py: block z-scores, means
    within 0.5% or 4 standard errors) on the Ward file's sphere under a grey sky; two tables in
    one scene: the gpu engine refuses in one line and auto takes the cpu engine."""
    from reference_harness import agreement, check, under_grey_sky
    from viewer.reference_common.select import make_renderer

    s = under_grey_sky(_scene(ward_file, f'model = "measured"\nfile = "{ward_file.name}"\n'))
    a = agreement(gl_ctx, s, spp=32, max_depth=2, size=16)
    print(f"Ward file sphere, gpu vs cpu engine: mean {a['rel']:+.2e} (sigma {a['sigma']:.1e}), "
          f"z^2 {a['z2']:.2f}, max |z| {a['zmax']:.2f}")
    assert a["sigma"] < 0.01, a  # the harness's mean check is only as tight as the noise
    check(a, "ward.dat")
    other = tmp_path / "other.dat"
    mit_aniso.write(other, np.full((2, 2, 4, 4, 3), 0.1))
    s.materials["second"] = brdf.get("measured").params(file=str(other))
    with pytest.raises(ViewerError, match="one measured table"):
        make_renderer("gpu", s)


def test_plot_of_a_dat_file(ward_file, tmp_path):
    """``brdf-viewer plot FILE.dat`` plots the measured model on the file (the lobe's numbers in
    the PNG are the table's values)."""
    from viewer.commands import cli
    from viewer.plots import read_plot_data

    out = tmp_path / "polar.png"
    assert cli.main(["plot", str(ward_file), "--kind", "polar", "--out", str(out)]) == 0
    data = read_plot_data(out)
    assert data["params"]["file"].endswith("ward.dat") and data["curves"]
