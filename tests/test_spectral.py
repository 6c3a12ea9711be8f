"""viewer.spectral: the observer, the tables and dispersion formulas against published values, and
the RGB upsampling round trip."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from viewer import spectral
from viewer.brdf.fresnel import f0_conductor


def test_materials_names():
    names = spectral.materials()
    for required in ("Au", "Ag", "Cu", "Al", "Cr", "Fe", "Ti", "BK7", "SiO2", "H2O", "diamond",
                     "sapphire", "SF11"):
        assert required in names
    for name in names:
        assert spectral.source(name)


def test_ior_array_in_array_out():
    lam = np.array([[400.0, 500.0], [600.0, 700.0]])
    for name in spectral.materials():
        n = spectral.ior(name, lam)
        assert n.shape == lam.shape and n.dtype == np.complex128
        assert np.all(n.imag >= 0) and np.all(n.real > 0)
        assert isinstance(spectral.ior(name, 550.0), complex)
    assert np.all(spectral.ior("BK7", lam).imag == 0)
    assert np.all(spectral.ior("Au", lam).imag > 1.0)


def test_ior_bad_input():
    with pytest.raises(KeyError, match="unknown spectral material 'gold'"):
        spectral.ior("gold", 500.0)
    with pytest.raises(ValueError, match="finite and positive"):
        spectral.ior("Au", np.nan)


@pytest.mark.parametrize("grid", [np.array([550.0]), np.linspace(360, 780, 5), np.linspace(300, 900, 61),
                                  np.arange(360.0, 781.0)])
def test_flat_spectrum_is_white(grid):
    np.testing.assert_allclose(spectral.to_rgb(np.ones(grid.size), grid), [1.0, 1.0, 1.0], atol=1e-12)


def test_to_rgb_is_linear():
    rng = np.random.default_rng(1)
    lam = np.sort(rng.uniform(350, 800, 40))
    a, b = rng.uniform(0, 1, (2, 40))
    got = spectral.to_rgb(2.5 * a - 0.7 * b, lam)
    np.testing.assert_allclose(got, 2.5 * spectral.to_rgb(a, lam) - 0.7 * spectral.to_rgb(b, lam),
                               atol=1e-12)
    # broadcasting over leading axes
    np.testing.assert_allclose(spectral.to_rgb(np.stack([a, b]), lam)[1], spectral.to_rgb(b, lam))


def test_to_rgb_monochromatic_chromaticity():
    """A narrow band at 700 nm is the reddest the observer sees: Rec.709 red beats green and blue
    (an independent sanity check of the matrix orientation)."""
    lam = np.arange(360.0, 781.0)
    rgb = spectral.to_rgb((np.abs(lam - 700) < 3).astype(float), lam)
    assert rgb[0] > 0 and rgb[0] > 5 * abs(rgb[1]) and rgb[0] > 5 * abs(rgb[2])


@pytest.mark.parametrize("metal", ["Au", "Ag", "Cu"])
def test_metal_normal_incidence_colour_against_colour_science(metal):
    """R(0, lambda) at the table's own wavelengths, integrated by colour-science's sd_to_XYZ
    (its own resampling, its own D65, its Rec.709 matrix with the standard D65 white point) and by
    ``to_rgb``. Both interpolate R linearly between the measured samples. Tolerance 1e-3: the
    standard white point (0.3127, 0.3290) differs from the D65 table's own by about 1e-4 in xy, and
    colour-science's 1 nm D65 and its 780-830 nm tail differ slightly (measured: <= 4e-4)."""
    colour = pytest.importorskip("colour")
    t = spectral.metal_table(metal)
    R = f0_conductor(t[:, 1], t[:, 2])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        sd = colour.SpectralDistribution(dict(zip(t[:, 0], R)), interpolator=colour.LinearInterpolator,
                                         extrapolator_kwargs={"method": "Constant", "left": None,
                                                              "right": None})
        xyz = colour.sd_to_XYZ(sd, colour.MSDS_CMFS["CIE 1931 2 Degree Standard Observer"],
                               colour.SDS_ILLUMINANTS["D65"], method="Integration") / 100.0
        ref = colour.RGB_COLOURSPACES["ITU-R BT.709"].matrix_XYZ_to_RGB @ xyz
    np.testing.assert_allclose(spectral.to_rgb(R, t[:, 0]), ref, atol=1e-3)


def test_gold_is_yellow_silver_neutral():
    lam = np.arange(360.0, 781.0, 5.0)
    def f0(name):
        n = spectral.ior(name, lam)
        return spectral.to_rgb(f0_conductor(n.real, n.imag), lam)
    au, ag, cu = f0("Au"), f0("Ag"), f0("Cu")
    assert au[0] > au[1] > au[2] and au[2] < 0.4
    assert np.ptp(ag) < 0.02 and ag.min() > 0.95
    assert cu[0] > cu[1] and cu[0] > cu[2]


def test_bk7_against_schott_catalogue():
    """Schott's N-BK7 data sheet: n_F = 1.52238 (486.13 nm), n_d = 1.51680 (587.56 nm),
    n_C = 1.51432 (656.27 nm), Abbe number 64.17; the catalogue's tolerance is 5e-4."""
    n_f, n_d, n_c = spectral.ior("BK7", np.array([486.13, 587.56, 656.27])).real
    np.testing.assert_allclose([n_f, n_d, n_c], [1.52238, 1.51680, 1.51432], atol=5e-4)
    assert abs((n_d - 1.0) / (n_f - n_c) - 64.17) < 0.2
    # the other Schott glasses at the d line (catalogue n_d)
    assert abs(spectral.ior("SF11", 587.56).real - 1.78472) < 5e-4
    assert abs(spectral.ior("F2", 587.56).real - 1.62004) < 5e-4


def test_fused_silica_against_published_table():
    """Malitson's formula against the tabulated fused silica of the Crystran handbook (5th ed.,
    2023, from Palik's handbook): 1.47012, 1.46233, 1.45804 at 400, 500, 600 nm (5 decimals)."""
    n = spectral.ior("SiO2", np.array([400.0, 500.0, 600.0])).real
    np.testing.assert_allclose(n, [1.47012, 1.46233, 1.45804], atol=5e-5)


def test_water_against_an_independent_measurement():
    """Daimon & Masumura 2007 (20 C) against Kedenburg et al. 2012, Opt. Mater. Express 2, 1588
    (distilled water, 20 C; their Sellmeier fit n^2 - 1 = 0.75831 l^2/(l^2 - 0.01007) +
    0.08495 l^2/(l^2 - 8.91377), valid 500-1600 nm) at three wavelengths. The two measurements
    differ by up to 3.7e-4 here, hence 5e-4."""
    lam = np.array([500.0, 589.3, 700.0])
    l2 = (lam * 1e-3) ** 2
    kedenburg = np.sqrt(1 + 0.75831 * l2 / (l2 - 0.01007) + 0.08495 * l2 / (l2 - 8.91377))
    np.testing.assert_allclose(spectral.ior("H2O", lam).real, kedenburg, atol=5e-4)


def test_diamond_and_sapphire_d_line():
    """Handbook d-line indices: diamond 2.4175, sapphire (ordinary ray) 1.7681."""
    assert abs(spectral.ior("diamond", 589.3).real - 2.4175) < 1e-3
    assert abs(spectral.ior("sapphire", 589.3).real - 1.7681) < 1e-3


def test_dispersion_is_normal():
    lam = np.linspace(400, 700, 31)
    for name in ("BK7", "F2", "SF11", "SiO2", "H2O", "diamond", "sapphire"):
        assert np.all(np.diff(spectral.ior(name, lam).real) < 0), name


def test_upsampling_round_trip_in_gamut():
    rng = np.random.default_rng(7)
    rgb = np.vstack([rng.uniform(0, 1, (200, 3)), np.eye(3), [[1, 1, 1], [0, 0, 0], [1, 1, 0]]])
    lam = np.arange(360.0, 781.0)
    spec = spectral.rgb_to_spectrum(rgb[:, None, :], lam)
    assert spec.shape == (rgb.shape[0], lam.size)
    # reflectances stay reflectances (the basis file holds 9 decimals: 1e-8)
    assert spec.min() >= -1e-8 and spec.max() <= 1 + 1e-8
    np.testing.assert_allclose(spectral.to_rgb(spec, lam), rgb, atol=1e-3)
    np.testing.assert_allclose(spectral.rgb_to_spectrum([1.0, 1.0, 1.0], lam), 1.0, atol=1e-9)


def test_rgb_weight_integrates_like_to_rgb():
    """The per-wavelength weight of the Monte Carlo estimator integrates to to_rgb (trapezoid on
    a fine grid vs the 1 nm sum: same function, quadrature error only)."""
    lam = np.linspace(spectral.LAMBDA_MIN, spectral.LAMBDA_MAX, 4201)
    v = 0.5 + 0.4 * np.sin(lam / 37.0)
    est = np.trapezoid(spectral.rgb_weight(lam) * v[:, None], lam, axis=0)
    np.testing.assert_allclose(est, spectral.to_rgb(v, lam), atol=2e-3)


# ----------------------------------------------------------------------------- RGB Fresnel tables

def test_fresnel_table_is_the_spectral_integral():
    """Every table entry is to_rgb of the exact R(theta, lambda) (kept above 1, clipped at 0, float32);
    lookups between entries interpolate."""
    from viewer.brdf import spectral_fresnel as sf

    for name in ("Au", "Ag", "Cu", "Al", "BK7"):
        c = sf.table_cos()
        direct = np.maximum(spectral.to_rgb(sf.spectral_reflectance(name, c), sf.GRID_NM), 0)
        np.testing.assert_allclose(sf.table(name), direct, atol=1e-6)
        np.testing.assert_allclose(sf.lookup(name, c), direct, atol=1e-6)
        # halfway between two samples (in sqrt(cos)) the exact integral is close to the lerp
        x = (np.arange(sf.TABLE_N - 1) + 0.5) / (sf.TABLE_N - 1)
        exact = np.maximum(spectral.to_rgb(sf.spectral_reflectance(name, x * x), sf.GRID_NM), 0)
        # linear interpolation error of a smooth curve over 1/23 in sqrt(cos): below 1e-2
        assert np.abs(sf.lookup(name, x * x) - exact).max() < 1e-2
    np.testing.assert_allclose(sf.table("Au")[0], 1.0)          # grazing: R = 1


def test_spectral_material_uses_the_table():
    from viewer import brdf
    from viewer.brdf import spectral_fresnel as sf

    p = brdf.get("microfacet").params(spectral="Cu", alpha=0.3)
    assert p.fresnel == "conductor"
    np.testing.assert_allclose(p.eta, spectral.ior("Cu", [650.0, 550.0, 450.0]).real)
    wi = np.array([[0.3, 0.1, 0.9]]) / np.linalg.norm([0.3, 0.1, 0.9])
    wo = np.array([[-0.2, 0.0, 1.0]]) / np.linalg.norm([-0.2, 0.0, 1.0])
    from viewer.brdf.microfacet import fdg

    F, _, _, h = fdg(p, wi, wo)
    np.testing.assert_allclose(F, sf.lookup("Cu", np.sum(wi * h, axis=1)))
    # a file's explicit ior / eta wins over the table's defaults
    assert brdf.get("dielectric").params(spectral="diamond").ior == pytest.approx(2.4175, abs=1e-3)
    assert brdf.get("dielectric").params(spectral="diamond", ior=2.0).ior == 2.0
    assert brdf.get("layered").params(coating={"spectral": "SF11"}).coating.ior == pytest.approx(1.7847, abs=1e-3)


def test_spectral_choice_refuses_metals_in_glass():
    from viewer import ViewerError, brdf

    with pytest.raises(ViewerError, match="spectral"):
        brdf.get("dielectric").params(spectral="Au")


def test_metal_presets_are_spectral():
    from viewer.brdf.presets import PRESETS, SPECTRAL_METALS

    for name, sym in SPECTRAL_METALS.items():
        assert PRESETS[name]["spectral"] == sym
        assert PRESETS[f"polished_{name}"]["spectral"] == sym


def test_glsl_spectral_fresnel_matches_numpy(gl_ctx):
    """The GLSL twin reads the table through u_mat: microfacet and mirror-coated (layered) metals
    agree with numpy at random directions to the twins' float32 bound."""
    from glsl_eval import GLSLEvaluator
    from viewer import brdf

    ev = GLSLEvaluator(gl_ctx)
    rng = np.random.default_rng(3)
    v = rng.normal(size=(400, 3))
    v[:, 2] = np.abs(v[:, 2])
    v /= np.linalg.norm(v, axis=1, keepdims=True)
    wi, wo = v[:200].astype(np.float32).astype(np.float64), v[200:].astype(np.float32).astype(np.float64)
    m = brdf.get("microfacet")
    mats = [m.params(spectral=s, alpha=0.4, kd=[0.2, 0.3, 0.1]) for s in ("Au", "Ag", "Cu", "Ti", "BK7")]
    mats.append(brdf.get("layered").params(base={"model": "microfacet", "spectral": "Cu", "alpha": 0.3}))
    for p in mats:
        ref = brdf.get(p.model).eval(p, wi, wo)
        got = ev.eval(p, wi, wo)
        np.testing.assert_allclose(got, ref, rtol=1e-4, atol=1e-6)
    # and the table values themselves: the F term view (RGB mean of F at the half vector)
    p = m.params(spectral="Au", alpha=0.5)
    from viewer.brdf.microfacet import fdg

    got_terms = ev.eval(p, wi, wo, what=1)
    F = fdg(p, wi, wo)[0].mean(axis=1)
    np.testing.assert_allclose(got_terms[:, 0], F, rtol=1e-4, atol=1e-6)


# ----------------------------------------------------------------------------- the spectral plot

def test_spectral_plot_data_and_png(tmp_path):
    """The plot's swatch is the spectral integral (to_rgb of R(theta, lambda)); Schlick with the
    spectral f0 is exact at normal incidence and at grazing; the three-wavelength approximation
    misses gold's colour by several per cent (the reason for the tables)."""
    from viewer import plots
    from viewer.brdf.presets import get_preset
    from viewer.plots.spectral import spectral_data

    d = spectral_data("Au")
    np.testing.assert_allclose(d["rgb"][0], spectral.to_rgb(f0_conductor(d["n"], d["k"]), d["wavelength_nm"]),
                               atol=1e-12)
    np.testing.assert_allclose(d["err_schlick"][[0, -1]], 0.0, atol=1e-9)
    assert d["max_err_three"] > 0.03
    p = plots.as_params(get_preset("gold"))
    assert "spectral" in plots.applicable_kinds(p)
    out = tmp_path / "s.png"
    plots.write_plot(plots.figure(p, "spectral", name="gold"), out)
    data = plots.read_plot_data(out)
    assert data["kind"] == "spectral" and data["info"]["name"] == "Au"
    from viewer import ViewerError

    with pytest.raises(ViewerError, match="no spectral table"):
        plots.figure(plots.as_params({"model": "lambert"}), "spectral")


def test_a_reflectance_colour_over_one_is_said_to_lie_outside_the_srgb_cube():
    """Gold's normal-incidence linear sRGB has red above 1 although no wavelength reflects more
    than all its light: the note says why; a colour inside the cube (silver) gets none."""
    from viewer.plots.spectral import rgb_over_one, spectral_data

    gold = spectral_data("Au")
    R0 = f0_conductor(gold["n"], gold["k"])
    assert R0.max() <= 1.0 and gold["rgb"][0][0] > 1.0
    assert "R over 1" in rgb_over_one(gold["rgb"][0]) and "G" not in rgb_over_one(gold["rgb"][0]).split(":")[0]
    silver = spectral_data("Ag")
    assert silver["rgb"][0].max() <= 1.0 and rgb_over_one(silver["rgb"][0]) == ""
