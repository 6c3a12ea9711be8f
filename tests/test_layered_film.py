"""A thin film on the layered model's coating (both twins), a film whose thickness varies with
the object's height (rasterizer and CPU reference), and the plots of the film's R(theta, lambda)."""

import numpy as np
import pytest

from viewer import brdf
from viewer.brdf import layered as layered_mod
from viewer.brdf import thin_film
from viewer.brdf.albedo import directional_albedo

LAYERED = brdf.get("layered")


def _coated(d_nm, alpha=0.1, ior=1.5, film_ior=1.33, base=None, top=-1.0, **coat):
    base = base or {"model": "lambert", "albedo": [0.6, 0.5, 0.4]}
    return LAYERED.params(coating=dict(ior=ior, alpha=alpha, thin_film={"ior": film_ior, "thickness_nm": d_nm,
                                                                        "thickness_top_nm": top}, **coat),
                          base=base)


def _dirs(n, seed):
    rng = np.random.default_rng(seed)
    wi = rng.normal(size=(n, 3))
    wi[:, 2] = np.abs(wi[:, 2])
    wi /= np.linalg.norm(wi, axis=1, keepdims=True)
    wo = rng.normal(size=(n, 3))
    wo[:, 2] = np.abs(wo[:, 2])
    wo /= np.linalg.norm(wo, axis=1, keepdims=True)
    return wi.astype(np.float32).astype(np.float64), wo.astype(np.float32).astype(np.float64)


BASES = [{"model": "lambert", "albedo": [0.6, 0.5, 0.4]},
         {"model": "microfacet", "alpha": 0.3, "fresnel": "conductor"},
         {"model": "oren_nayar", "albedo": [0.3, 0.6, 0.2], "sigma": 0.4}]


@pytest.mark.parametrize("base", BASES)
def test_zero_thickness_film_is_no_film(base):
    wi, wo = _dirs(800, 1)
    plain = LAYERED.params(coating=dict(ior=1.5, alpha=0.2), base=base)
    film0 = _coated(0.0, alpha=0.2, base=base)
    np.testing.assert_array_equal(LAYERED.eval(plain, wi, wo), LAYERED.eval(film0, wi, wo))
    u = np.random.default_rng(2).random((800, 2))
    for a, b in zip(LAYERED.sample(plain, wo, u), LAYERED.sample(film0, wo, u)):
        np.testing.assert_array_equal(a, b)


def test_film_colours_the_coat():
    wi, wo = _dirs(400, 3)
    black = {"model": "lambert", "albedo": [0.0, 0.0, 0.0]}
    f = layered_mod.eval_coat(_coated(300.0, base=black), wi, wo)
    assert np.ptp(f, axis=1).max() > 0.05 * f.max()          # coloured, not grey
    # a smooth coat: the coat's albedo is the film's reflectance at the macro angle
    p = _coated(300.0, alpha=0.001, base=black)
    mu = np.array([0.2, 0.5, 0.9])
    np.testing.assert_allclose(layered_mod.coat_albedo_rgb(p, mu),
                               thin_film.reflectance_rgb(p.coating, mu, 1.5), atol=3e-3)


def test_film_table_interpolation_error():
    # the coat film's RGB R comes from a 32-entry table linear in sqrt(cos), computed once per
    # material (no wavelength loop in the GLSL); against the exact 32-wavelength Airy sum on a
    # fine grid: 1.8e-3 for a 400 nm water film on a 1.5 coat, at most 0.019 over film ior 1.2-3,
    # 50-1000 nm and coat ior 1-3 (the worst at coat ior 1, the steep grazing rise)
    cos = np.linspace(0.0, 1.0, 2001)
    worst = 0.0
    for film_ior, d, coat_ior in ((1.33, 400.0, 1.5), (1.33, 300.0, 1.0), (2.0, 150.0, 1.0),
                                  (1.47, 1000.0, 2.0), (3.0, 700.0, 3.0)):
        p = _coated(d, ior=coat_ior, film_ior=film_ior)
        err = np.abs(layered_mod.coat_fresnel(p, cos) - thin_film.reflectance_rgb(p.coating, cos, coat_ior)).max()
        if (film_ior, d, coat_ior) == (1.33, 400.0, 1.5):
            assert err < 2e-3, err
        worst = max(worst, err)
    assert worst < 0.02, worst


@pytest.mark.parametrize("d_nm", [150.0, 420.0])
def test_white_furnace_with_film(d_nm):
    # a lossless film on a lossless coat over a white Lambert base: the closed form returns all
    # the light (the film's reflectance enters E, T = 1 - E and K alike): 1 within the coat table's
    # error and the sampler's stratification (2e-2) for a smooth coat, 5e-2 for a rough one (the
    # film's E + R_film - F is an approximation there)
    white = {"model": "lambert", "albedo": [1.0, 1.0, 1.0]}
    cos = np.array([0.2, 0.6, 1.0])
    for alpha, tol in ((0.001, 2e-2), (0.3, 5e-2)):
        p = _coated(d_nm, alpha=alpha, base=white)
        a = directional_albedo(LAYERED, p, cos, n_side=48)
        assert np.all(np.abs(a - 1.0) < tol), (alpha, a)


@pytest.mark.parametrize("base", BASES[:2])
def test_glsl_twin_with_coating_film(base, gl_ctx):
    from glsl_eval import GLSLEvaluator

    ev = GLSLEvaluator(gl_ctx)
    wi, wo = _dirs(1200, 5)
    for d, alpha in ((0.0, 0.2), (180.0, 0.05), (640.0, 0.4)):
        p = _coated(d, alpha=alpha, base=base)
        # 1e-4 relative as every twin; 1e-5 absolute: the film's phase in float32 (test_thin_film)
        np.testing.assert_allclose(ev.eval(p, wi, wo), LAYERED.eval(p, wi, wo), rtol=1e-4, atol=1e-5)


def test_glsl_film_height_uses_bottom_thickness(gl_ctx):
    # evaluated without a position (brdf_film_height = 0) a film over height is its bottom's
    from glsl_eval import GLSLEvaluator

    ev = GLSLEvaluator(gl_ctx)
    wi, wo = _dirs(300, 6)
    p = _coated(200.0, top=50.0)
    np.testing.assert_allclose(ev.eval(p, wi, wo), LAYERED.eval(thin_film.local(p, 200.0), wi, wo),
                               rtol=1e-4, atol=1e-5)


def test_thickness_over_height():
    tf = _coated(300.0, top=100.0).coating.thin_film
    np.testing.assert_allclose(thin_film.thickness_at(tf, [0.0, 0.5, 1.0, 2.0]), [300.0, 200.0, 100.0, 100.0])
    assert thin_film.varies(_coated(300.0, top=0.0)) and not thin_film.varies(_coated(300.0))
    q = thin_film.local(_coated(300.0, top=100.0), 123.0)
    assert q.coating.thin_film.thickness_nm == 123.0 and not thin_film.varies(q)


def test_plots_show_the_coating_film():
    from viewer import plots
    from viewer.plots.spectral import spectral_data

    p = _coated(400.0)
    d = plots.fresnel_curves(p)
    np.testing.assert_allclose(d["thin_film"], thin_film.dielectric_reflectance_rgb(
        p.coating, np.cos(np.radians(d["theta"])), 1.5))
    assert "spectral" in plots.applicable_kinds(p)
    s = spectral_data(p)
    assert s["film"] and s["R"].shape == (91, s["wavelength_nm"].size)
    # the renderers' 32-wavelength RGB against the 5 nm integral of the same R(theta, lambda)
    assert s["max_err_schlick"] < 0.02
    assert "spectral" not in plots.applicable_kinds(_coated(0.0))


_HEIGHT_SCENE = """
[camera]
position = [0.0, 0.0, 6.0]
target = [0.0, 0.0, 0.0]
fov_y = 20.0
width = 24
height = 24
[render]
ibl = "off"
shadows = false
msaa = 1
[[lights]]
type = "directional"
direction = [0.0, 0.0, -1.0]
irradiance = [3.0, 3.0, 3.0]
[[objects]]
mesh = "cube"
material = "m"
[materials.m]
model = "MODEL"
FIELDS
"""


def _height_scene(model, fields, extra):
    return _HEIGHT_SCENE.replace("MODEL", model).replace("FIELDS", fields + "\n" + extra)


_FILM_MF = "{ ior = 2.0, thickness_nm = 0.0, thickness_top_nm = 50.0 }"
_MF_SCENE = _height_scene("microfacet", 'fresnel = "dielectric"\nior = 1.5\nalpha = 0.5\nkd = [0.0, 0.0, 0.0]',
                          f"thin_film = {_FILM_MF}")
_LAYERED_FIELDS = 'base = { model = "lambert", albedo = [0.0, 0.0, 0.0] }'
_COAT = "coating = {{ ior = 1.5, alpha = 0.5, thin_film = {{ ior = 2.0, thickness_nm = 50.0{} }} }}"
_LAYERED_OVER = _height_scene("layered", _LAYERED_FIELDS, _COAT.format(", thickness_top_nm = 0.0"))
_LAYERED_BOTTOM = _height_scene("layered", _LAYERED_FIELDS, _COAT.format(""))


@pytest.fixture(scope="module")
def height_rasters():
    """The rasters of the height scenes, all drawn before any reference renders in this process
    (a raster drawn after an in-process reference render comes out wrong on main as well: a
    separate defect, not this module's)."""
    import viewer

    return {k: viewer.render(s, width=24, height=24)[:, 12]
            for k, s in (("mf", _MF_SCENE), ("over", _LAYERED_OVER), ("bottom", _LAYERED_BOTTOM))}


def test_film_over_height_raster_and_reference(height_rasters):
    # a cube's front face lit head-on: a high-index film (n 2.0 on glass 1.5) from 0 nm at the
    # bottom to 50 nm at the top, below a quarter wave for every visible wavelength, so the
    # reflectance of every channel rises monotonically with height, blue most; the rasterizer
    # (per fragment) and the CPU reference (per hit, 0.25 nm steps) agree within 3e-3: the
    # reference's 4 jittered samples per pixel across the gradient (~5e-3 per row; measured < 2e-3)
    import viewer

    ras = height_rasters["mf"]
    ref = viewer.reference(_MF_SCENE, spp=4, width=24, height=24, seed=0, max_depth=1, workers=1)[:, 12]
    face = ras[:, 0] > 0.01
    assert face.sum() >= 16
    for img in (ras, ref):
        col = img[face]
        assert np.all(np.diff(col, axis=0) < 0), col          # row 0 is the top: brighter there
        gain = col[0] / col[-1]
        assert gain[2] > gain[1] > gain[0] > 1.5, gain         # blue rises most (its quarter wave is nearest)
    np.testing.assert_allclose(ras[face], ref[face], atol=3e-3)


def test_layered_coat_film_over_height(height_rasters):
    # a layered coat's film comes from tables computed once per material (no wavelength loop in
    # the GLSL), so the rasterizer draws the bottom's thickness all over the object; the CPU
    # reference follows the height per hit: 50 nm of n 2.0 at the bottom thinning to none at
    # the top, so there the reference's rows darken upward and the raster's do not
    import viewer

    ras = height_rasters["over"]
    np.testing.assert_allclose(ras, height_rasters["bottom"], rtol=1e-6, atol=1e-7)
    ref = viewer.reference(_LAYERED_OVER, spp=4, width=24, height=24, seed=0, max_depth=1, workers=1)[:, 12]
    face = ras[:, 0] > 0.01
    assert face.sum() >= 16
    col = ref[face]
    assert np.all(np.diff(col, axis=0) > 0), col              # row 0 is the top: darker there
    gain = col[-1] / col[0]
    assert gain[2] > gain[1] > gain[0] > 1.5, gain
    # the raster is the reference of the uniform bottom film (3e-3: as above, the reference's jitter)
    ref_b = viewer.reference(_LAYERED_BOTTOM, spp=4, width=24, height=24, seed=0, max_depth=1, workers=1)[:, 12]
    np.testing.assert_allclose(ras[face], ref_b[face], atol=3e-3)


@pytest.mark.parametrize("p", [
    _coated(300.0, base={"model": "lambert", "albedo": [0.2, 0.2, 0.2]}),
    brdf.get("microfacet").params(fresnel="conductor", alpha=0.3, eta=[0.2, 0.5, 1.4], k=[3.4, 2.4, 1.8],
                                  thin_film={"ior": 1.45, "thickness_nm": 250.0}),
])
def test_spectral_reference_evaluates_the_film_per_wavelength(p):
    from viewer.brdf.fresnel import fresnel_thin_film
    from viewer.brdf import params_at, uses_spectral

    assert uses_spectral(p)
    lam3 = np.array([430.0, 515.0, 702.0])
    q = params_at(p, lam3)
    owner = q if "thin_film" in q else q.coating
    cos = np.array([0.15, 0.6, 1.0])
    if p.model == "layered":
        n2 = np.full(3, 1.5 + 0j)
        got = layered_mod.coat_fresnel(q, cos)
    else:
        n2 = thin_film.rgb_to_spectral_at(p.eta, lam3) + 1j * thin_film.rgb_to_spectral_at(p.k, lam3)
        got = thin_film.reflectance_rgb(owner, cos, q.eta, q.k)
    want = fresnel_thin_film(cos[:, None], lam3[None, :], owner.thin_film.ior, owner.thin_film.thickness_nm,
                             n2[None, :])
    np.testing.assert_allclose(got, want, rtol=1e-12)


def test_program_defines_see_the_coat_film():
    # a coat film inside the coating table: its own define (tables only), not the wavelength loop
    from viewer.gl.brdf_glsl import program_defines

    assert program_defines([_coated(300.0)]) == {"COAT_FILM": "1"}
    assert program_defines([_coated(0.0, top=80.0)]) == {"COAT_FILM": "1"}   # a film at the top only
    assert program_defines([_coated(0.0)]) == {} and not brdf.has_film(_coated(0.0))
    own = brdf.get("microfacet").params(fresnel="conductor", thin_film={"ior": 1.4, "thickness_nm": 200.0})
    assert program_defines([_coated(300.0), own]) == {"COAT_FILM": "1", "THIN_FILM": "1"}
    # (a nested base takes no film: the validator says so, the top thickness included)
    from viewer import ViewerError

    with pytest.raises(ViewerError, match="nested base"):
        _coated(300.0, base={"model": "microfacet", "thin_film": {"thickness_nm": 0.0, "thickness_top_nm": 9.0}})


def test_gpu_spectral_pass_refuses_films():
    # the spectral reference traces a film per wavelength; the GPU engine's spectral pass would
    # evaluate it in RGB, so it refuses in one line and auto takes the cpu engine
    from viewer import ViewerError
    from viewer.reference_common.select import choose_for_scenes, make_renderer
    from viewer.scene import load_scene_text

    for text in (_LAYERED_BOTTOM, _MF_SCENE):   # the latter's film: 0 nm at the bottom, 50 nm at the top
        scene = load_scene_text(text)
        assert choose_for_scenes("auto", [scene], spectral=True)[0] == "cpu"
        with pytest.raises(ViewerError, match="thin films per wavelength"):
            make_renderer("gpu", scene, spectral=True)


def test_gpu_engine_refuses_a_film_over_height():
    # the gpu engine shades a hit without its height, so a film over height came out at its bottom
    # thickness: the microfacet scene's film (0 nm at the bottom, 50 nm at the top) was missing
    # from the gpu image, while the rasterizer and the cpu engine agree on its gradient (measured
    # at 24 x 24, 4 spp: the face's top / bottom blue 4.66 in both, 1.00 on the gpu engine). It
    # refuses such a scene in one line and auto takes the cpu engine; a uniform film stays its own.
    from viewer import ViewerError
    from viewer.reference_common.refusals import FILM_HEIGHT_REFUSAL, cpu_only
    from viewer.reference_common.select import choose_for_scenes, make_renderer
    from viewer.scene import load_scene_text

    for text in (_MF_SCENE, _LAYERED_OVER):
        scene = load_scene_text(text)
        assert cpu_only(scene, False).refusal == FILM_HEIGHT_REFUSAL
        assert choose_for_scenes("auto", [scene], spectral=False)[0] == "cpu"
        with pytest.raises(ViewerError, match="film over height"):
            make_renderer("gpu", scene, spectral=False)
    assert cpu_only(load_scene_text(_LAYERED_BOTTOM), False) is None
