"""The GPU engine's spectral variant (``#define SPECTRAL``) against the CPU engine's spectral
reference (the oracle), the RGB GPU engine (the upsampling round trip) and a white furnace.

Random numbers differ (pcg4d on the GPU, Philox on the CPU), so only statistics can agree:
block z-scores and image means (tests/spectral_harness.py). Images are tiny (24 x 16: 24
blocks x 3 channels = 72 z-scores) with 64-128 samples, to keep the default run short; the sweep
over the built-in scenes and lecture steps is marked slow.
"""

import numpy as np
import pytest

import spectral_harness as h
from reference_harness import under_grey_sky
from viewer.scene.lecture import TOUR, tour_scene
from viewer.scene import builtin_scene_names, load_scene


@pytest.fixture(scope="module")
def ctx(gl_ctx):
    return gl_ctx


def test_gpu_spectral_agrees_with_cpu_spectral_on_an_rgb_scene(ctx):
    """RGB materials traced as spectra (``spectral=True``) through three bounces, where spectra
    multiply (not the RGB image any more): both engines estimate the same spectral image."""
    sc = h.toml_scene(h.RGB_SCENE, "rgb")
    g = h.gpu(ctx, sc, 64, max_depth=3, spectral=True)
    c = h.cpu(sc, 64, max_depth=3, spectral=True)
    assert g.spectral and c.spectral
    # the mean: within 1% or 4 standard errors (about 1.8% at 64 spp; the block z-scores are the
    # sharper test here)
    h.check(h.agreement(g, c), "rgb scene, spectral", mean_tol=0.01)


# -m slow: about 36 s on two cores (both spectral engines to agreement on a prism); the default
# run keeps the RGB-scene agreement, the white furnaces and the dispersion step's finite check
@pytest.mark.slow
def test_gpu_spectral_agrees_with_cpu_spectral_on_a_dispersive_scene(ctx):
    """Every spectral category at once (tests/spectral_harness.py DISPERSIVE_SCENE): a dispersive
    prism and rough absorbing glass (hero only), rough and varnished gold (tables at four
    wavelengths, a nested spectral base). Both engines switch to wavelengths by themselves."""
    sc = h.toml_scene(h.DISPERSIVE_SCENE, "dispersive")
    g = h.gpu(ctx, sc, 64, max_depth=6)
    c = h.cpu(sc, 64, max_depth=6)
    assert g.spectral and c.spectral
    # the mean: within 1% or 4 standard errors (about 2% at 64 spp: colour noise of the hero-only
    # paths through the glass)
    h.check(h.agreement(g, c), "dispersive scene", mean_tol=0.01)


def test_spectral_gpu_round_trips_the_rgb_gpu_engine_under_white_direct_light(ctx):
    """RGB albedos under white point and directional light, one bounce: the upsampled spectra
    round-trip exactly (the basis maps back to the unit colours under the CIE weights), so the
    spectral image is the RGB one within noise (the spectral one has the colour noise of four
    wavelengths on top)."""
    sc = h.toml_scene(h.RGB_SCENE, "rgb")
    s = h.gpu(ctx, sc, 128, max_depth=1, spectral=True)
    r = h.gpu(ctx, sc, 128, max_depth=1, spectral=False)
    assert s.spectral and not r.spectral
    a = h.agreement(s, r)
    # the mean: within 0.5% or 4 standard errors (~1.2% here)
    h.check(a, "round trip", mean_tol=0.005)
    # and per channel: the image means within 4 of their standard errors
    n = s.mean.shape[0] * s.mean.shape[1]
    se = np.sqrt((s.var + r.var).sum(axis=(0, 1))) / n
    diff = s.mean.mean(axis=(0, 1)) - r.mean.mean(axis=(0, 1))
    assert np.all(np.abs(diff) < 4 * se), (diff, se)


def test_gold_mirror_is_the_spectral_integral(ctx):
    """A polished gold sphere in a white environment, seen at normal incidence: the pixel
    estimates to_rgb(R(0, lambda)) of the Johnson & Christy table, unclipped (1.037, 0.728,
    0.365) -- an exact value for the table category (n, k at four wavelengths per path). 1024
    spp x 9 pixels: the standard error per channel is 0.0025-0.005; 4 of them plus 2e-3 (the 3
    degree view's departure from normal incidence, and the sphere's facets)."""
    from viewer import spectral
    from viewer.brdf import spectral_fresnel as sf

    g = h.gpu(ctx, h.toml_scene(h.GOLD_MIRROR_SCENE, "gold"), 1024, size=(3, 3), spectral=True)
    assert g.bad == 0
    want = spectral.to_rgb(sf.spectral_reflectance("Au", 1.0), sf.GRID_NM)
    got = g.mean.reshape(-1, 3).mean(axis=0)
    se = np.sqrt(g.var.reshape(-1, 3).sum(axis=0)) / 9
    np.testing.assert_array_less(np.abs(got - want), 4 * se + 2e-3)
    assert got[0] > 1.0   # beyond the Rec.709 gamut, as the spectrum says (RGB would clip the table)


def test_white_furnace_is_one_at_every_pixel(ctx):
    """Lossless white Lambert and dispersive smooth glass (SF11, diamond) in a constant white
    environment: radiance 1 at every wavelength, so RGB 1 in every pixel, within noise (the
    colour noise of four sampled wavelengths, the 4x hero weight past the glass). max_depth 32:
    paths trapped longer inside a sphere (internal reflection near grazing) are rarer than the
    noise at this spp."""
    sc = h.toml_scene(h.FURNACE_SCENE, "furnace")
    g = h.gpu(ctx, sc, 128, max_depth=32)
    assert g.spectral
    one = h.Estimate(np.ones_like(g.mean), np.zeros_like(g.var), 0, True, 0)
    a = h.agreement(g, one)
    # the mean: within 0.5% or 4 standard errors (~1% here); z-scores per block as against the CPU
    h.check(a, "white furnace", mean_tol=0.005)
    assert a["n_z"] == g.mean.size // h.BLOCK**2   # every block is noisy: wavelengths vary everywhere


def test_white_furnace_is_one_under_every_estimator_option(ctx):
    """The estimator's options are compile-time variants of the spectral pass too: light sampling
    alone with no roulette, BSDF sampling alone, the balance heuristic; every option converges to
    the same image (1 here), with its own noise."""
    sc = h.toml_scene(h.FURNACE_SCENE, "furnace")
    one = None
    for opts in (dict(strategy="light", russian_roulette=False), dict(strategy="bsdf"),
                 dict(mis_heuristic="balance")):
        g = h.gpu(ctx, sc, 64, max_depth=32, **opts)
        one = one or h.Estimate(np.ones_like(g.mean), np.zeros_like(g.var), 0, True, 0)
        # the mean: within 0.5% or 4 standard errors (~1.4% here)
        h.check(h.agreement(g, one), f"white furnace {opts}", mean_tol=0.005)


def test_dispersion_lecture_step_renders_without_bad_values(ctx):
    """The lecture's dispersion step (an SF11 prism and a diamond under the sky map) as it is:
    the GPU engine takes wavelengths by itself, and no radiance is NaN, infinite or negative."""
    g = h.gpu(ctx, tour_scene(11), 8, max_depth=8)
    assert g.spectral
    assert g.bad == 0
    assert np.all(np.isfinite(g.mean)) and g.mean.max() > 0


def test_spectral_bands_are_bit_identical_to_whole_passes(ctx):
    """Wavelengths are drawn from the camera sample's hash: time-sliced bands (``step_for``) and
    whole passes give bit-identical spectral sums, and another seed another image."""
    from viewer.gpupt import GpuReferenceRenderer

    sc = h.toml_scene(h.FURNACE_SCENE, "furnace")
    with GpuReferenceRenderer(sc, width=24, height=16, max_depth=3, seed=4, ctx=ctx) as a:
        a.step(3)
        ref = a.mean()
    with GpuReferenceRenderer(sc, width=24, height=16, max_depth=3, seed=4, ctx=ctx) as b:
        b.rows_per_pass = 5
        while b.spp < 3:
            b.step_for(1e-4)
        assert np.array_equal(b.mean(), ref)
    with GpuReferenceRenderer(sc, width=24, height=16, max_depth=3, seed=5, ctx=ctx) as c:
        c.step(3)
        assert not np.array_equal(c.mean(), ref)


def test_make_renderer_builds_the_spectral_gpu_engine(ctx):
    """``make_renderer("gpu", ...)`` traces wavelengths where the scene needs them (dispersive,
    or ``spectral=True``) instead of refusing; the setup says so, so the reference cache keys a
    GPU spectral image as the CPU engine's spectral image of the same scene, apart from RGB."""
    from viewer.reference_common.select import make_renderer
    from viewer.reference_common import cache

    disp = h.toml_scene(h.FURNACE_SCENE, "furnace")
    with make_renderer("gpu", disp, width=24, height=16, max_depth=3, ctx=ctx) as g:
        assert g.engine == "gpu" and g.is_spectral
        key_gpu = cache.setup_key(g.setup)
    with make_renderer("cpu", disp, width=24, height=16, max_depth=3, workers=0) as c:
        assert c.is_spectral
        assert cache.setup_key(c.setup) == key_gpu
    rgb = h.toml_scene(h.RGB_SCENE, "rgb")
    with make_renderer("gpu", rgb, width=24, height=16, max_depth=3, ctx=ctx) as g:
        assert not g.is_spectral
        key_rgb = cache.setup_key(g.setup)
    with make_renderer("gpu", rgb, width=24, height=16, max_depth=3, ctx=ctx, spectral=True) as g:
        assert g.is_spectral
        assert cache.setup_key(g.setup) != key_rgb
        g.reset(rgb)                       # a reset keeps the mode
        assert g.is_spectral


def test_auto_follows_the_gl_for_dispersive_scenes(ctx):
    """``auto`` no longer sends a dispersive scene to the CPU engine for being dispersive: it is
    the ordinary choice (software GL: the CPU engine; a hardware GPU: the GPU engine)."""
    from viewer.reference_common.select import choose_for_scenes, gl_renderer_name, is_software

    engine, why = choose_for_scenes("auto", [tour_scene(11)], ctx=ctx)
    assert engine == ("cpu" if is_software(gl_renderer_name(ctx)) else "gpu"), why
    assert "wavelength" not in why and "dispersive" not in why, why


def test_gpu_still_refuses_what_it_cannot_trace():
    """The microfacet random walk: the same one-line refusal, spectral or not."""
    from viewer import ViewerError
    from viewer.reference_common.select import make_renderer

    walk = h.toml_scene(h.FURNACE_SCENE.replace('material = "flint"', 'material = "walker"')
                        + '\n[materials.walker]\nmodel = "microfacet"\nmultiple_scattering = true\n', "walk")
    with pytest.raises(ViewerError, match="random walk"):
        make_renderer("gpu", walk, width=8, height=8, spectral=True)


@pytest.mark.slow
@pytest.mark.parametrize("step", [10, 11])
def test_gpu_spectral_agrees_with_cpu_spectral_lecture_steps(ctx, step):
    """The lecture's spectral steps (complex IOR: gold, silver, copper mirrors; dispersion),
    under a grey sky (the sky map's sun seen in a mirror or through glass from the floor is a
    caustic neither engine samples well at this spp), both engines spectral."""
    sc = under_grey_sky(tour_scene(step))
    g = h.gpu(ctx, sc, 256, size=(32, 32), spectral=True)
    c = h.cpu(sc, 256, size=(32, 32), spectral=True)
    # the mean: within 0.5% or 4 standard errors
    h.check(h.agreement(g, c), f"lecture step {step}", mean_tol=0.005)


@pytest.mark.slow
@pytest.mark.parametrize("opts", [dict(strategy="bsdf"), dict(strategy="light", russian_roulette=False),
                                  dict(mis_heuristic="balance")], ids=["bsdf", "light_no_rr", "balance"])
def test_gpu_spectral_options_agree_with_cpu_spectral(ctx, opts):
    """The estimator's options on the dispersive scene, both engines spectral: the same image and
    the same noise per option."""
    sc = h.toml_scene(h.DISPERSIVE_SCENE, "dispersive")
    g = h.gpu(ctx, sc, 64, max_depth=6, **opts)
    c = h.cpu(sc, 64, max_depth=6, **opts)
    h.check(h.agreement(g, c), f"dispersive scene {opts}", mean_tol=0.01)   # as the default-option test


@pytest.mark.slow
@pytest.mark.parametrize("name", builtin_scene_names())
def test_gpu_spectral_builtin_scenes_agree_with_cpu(ctx, name):
    """Every built-in scene traced as spectra by both engines (RGB materials upsampled, the
    metals of the gallery as tables, the soap film evaluated in RGB and upsampled), at the RGB
    engines' sweep's 512 spp: at 64 spp the Cornell box's ceiling next to its point light (1/r^2)
    has heavy-tailed samples whose variance estimate is too low (its means then differ by 3.7
    standard errors in RGB too, both engines; at 512 they agree)."""
    sc = load_scene(name)
    g = h.gpu(ctx, sc, 512, size=(32, 32), spectral=True)
    c = h.cpu(sc, 512, size=(32, 32), spectral=True)
    h.check(h.agreement(g, c), name, mean_tol=0.005)   # the mean: within 0.5% or 4 standard errors


@pytest.mark.slow
@pytest.mark.parametrize("step", range(len(TOUR)))
def test_gpu_spectral_lecture_steps_have_no_bad_values(ctx, step):
    g = h.gpu(ctx, tour_scene(step), 4, size=(24, 16), spectral=True)
    assert g.bad == 0 and np.all(np.isfinite(g.mean)), step


@pytest.mark.slow
@pytest.mark.parametrize("name", ["microfacet", "mirror", "dielectric", "layered"])
def test_gpu_spectral_parameter_corners_have_no_bad_values(ctx, name):
    """The NaN sweep's parameter corners of the models that take spectral tables, traced as
    spectra (their spectral choice at the corners' values: dispersive glass and coatings, metal
    tables, over the corners' extreme parameters): no NaN, infinite or negative radiance at any
    wavelength, and the image's XYZ non-negative (Rec.709 RGB of a spectral estimate is negative
    outside the gamut; 1e-6 relative: float32 rounding)."""
    import nan_sweep_cases as nc
    from viewer.spectral.colorimetry import rgb_to_xyz

    scene = nc.sweep_scene(10, 8, ibl="off")   # the NaN sweep's scene (its raster keys do not reach a reference)
    from viewer import ViewerError
    from viewer.brdf import has_film

    traced = 0
    for k, p in enumerate(nc.corner_sets(name, 4, 20240614)):   # the NaN sweep's reference corners
        scene.materials["ball"] = p
        if has_film(p):   # refused in one line: the spectral pass has no per-wavelength films
            with pytest.raises(ViewerError, match="does not trace thin films"):
                h.gpu(ctx, scene, 2, size=(10, 8), max_depth=4, seed=k, spectral=True)
            continue
        traced += 1
        g = h.gpu(ctx, scene, 2, size=(10, 8), max_depth=4, seed=k, spectral=True)
        assert g.bad == 0, (name, p.to_plain())
        assert np.all(np.isfinite(g.mean)), (name, p.to_plain())
        assert rgb_to_xyz(g.mean).min() >= -1e-6 * max(1.0, float(np.abs(g.mean).max())), (name, p.to_plain())
    assert traced >= 1, f"{name}: every corner had a thin film"
