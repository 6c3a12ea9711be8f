"""The model protocol (viewer.brdf.spec): required functions, optional hooks with defaults,
registration checks that reject a misspelled hook, and the lobes a model computes from its
parameters (``lobes``: viewer/brdf/lobes.py's Lobe; is_delta, has_delta; sample_lobe's lobe per
sample) instead of callers reading its name, checked against what its sampler draws."""

import types

import numpy as np
import pytest

from viewer import ViewerError, brdf
from viewer.brdf import spec as spec_mod
from viewer.brdf.lobes import SIDES, Lobe, drew_delta
from viewer.brdf.spec import HOOKS, ModelSpec, Param, check_module


def _module(**extra):
    """A synthetic Lambert-like model module with ``extra`` public names."""
    m = types.ModuleType("synthetic_model")
    m.SPEC = ModelSpec(name="synthetic", title="synthetic", source="test",
                       params=(Param("albedo", "rgb", [0.5, 0.5, 0.5], lo=0.0, hi=1.0),))
    exec("import numpy as np\n"
         "def eval(p, wi, wo):\n"
         "    ok = (wi[:, 2] > 0) & (wo[:, 2] > 0)\n"
         "    return np.where(ok[:, None], p.albedo / np.pi, 0.0)\n"
         "def pdf(p, wi, wo):\n"
         "    return np.where(wi[:, 2] > 0, wi[:, 2] / np.pi, 0.0)\n"
         "def sample(p, wo, u):\n"
         "    r = np.sqrt(u[:, 0]); phi = 2 * np.pi * u[:, 1]\n"
         "    wi = np.stack([r * np.cos(phi), r * np.sin(phi), np.sqrt(1 - u[:, 0])], 1)\n"
         "    return wi, np.broadcast_to(p.albedo, wi.shape).copy(), wi[:, 2] / np.pi\n",
         m.__dict__)
    for k, v in extra.items():
        if callable(v):
            v.__module__ = m.__name__
        setattr(m, k, v)
    return m


def test_a_correct_synthetic_module_registers_with_every_default():
    model = brdf.Model(_module())
    p = model.params()
    assert not model.is_delta(p) and model.lobes(p) == Lobe.REFLECTION | Lobe.GLOSSY  # the default
    assert model.hook("ibl_split") is None and model.hook("GLSL_RTOL", 1e-4) == 1e-4
    assert model.fresnel_source(p) is None
    wo = np.tile([0.0, 0.0, 1.0], (5, 1))
    wi, w, pdf, lobe = model.sample_lobe(p, wo, np.full((5, 2), 0.3))
    assert lobe.shape == (5,) and np.all(lobe == Lobe.REFLECTION | Lobe.GLOSSY) and np.all(pdf > 0)


@pytest.mark.parametrize("name", ["ibl_splt", "lobe", "sample_lobes", "Glsl_rtol", "ALBEDO_BOUNDS",
                                  "fresnel_sauce", "evl", "has_flm", "is_dispersiv", "uses_spectrl",
                                  "is_measurd", "params_a", "reference_mode"])
def test_a_misspelled_hook_is_an_error_naming_the_hook(name):
    with pytest.raises(ViewerError) as e:
        brdf.Model(_module(**{name: (lambda p: None) if name[0].islower() else 1.0}))
    msg = str(e.value)
    assert "\n" not in msg and repr(name) in msg and "did you mean" in msg


def test_hooks_are_checked_for_their_kind_and_arguments():
    with pytest.raises(ViewerError, match="lobes"):
        brdf.Model(_module(lobes=lambda p, extra: Lobe.DELTA))
    with pytest.raises(ViewerError, match="value"):
        brdf.Model(_module(GLSL_RTOL=lambda: 1e-3))
    m = _module()
    del m.pdf
    with pytest.raises(ViewerError, match="pdf"):
        check_module(m)
    m = _module()
    m.SPEC = None
    with pytest.raises(ViewerError, match="SPEC"):
        check_module(m)


def test_hook_names_outside_the_protocol_are_refused():
    with pytest.raises(KeyError):
        brdf.get("lambert").hook("ibl_splt")


def test_every_registered_module_passes_the_protocol_and_defines_only_known_hooks():
    for name in brdf.names():
        check_module(brdf.get(name).module)
    assert len(HOOKS) >= 11 and all(h.doc and h.default for h in HOOKS.values())


def test_lobes_follow_the_parameters():
    R, T, D, G, X = Lobe.REFLECTION, Lobe.TRANSMISSION, Lobe.DIFFUSE, Lobe.GLOSSY, Lobe.DELTA
    d = brdf.get("dielectric")
    assert d.lobes(d.params(alpha=0.0)) == R | T | X and d.lobes(d.params(alpha=0.2)) == R | T | G
    assert d.is_delta(d.params(alpha=0.0)) and not d.is_delta(d.params(alpha=0.2))
    assert brdf.get("mirror").lobes() == R | X and brdf.get("lambert").lobes() == R | D
    mf = brdf.get("microfacet")
    assert mf.lobes(mf.params(kd=0.0)) == R | G and mf.lobes(mf.params(kd=0.3)) == R | G | D
    lay = brdf.get("layered")
    over_mirror = lay.params(base={"model": "mirror"})
    over_glass = lay.params(base={"model": "dielectric", "alpha": 0.3})
    assert lay.lobes(over_mirror) == R | G | X and lay.lobes(over_mirror).is_mixed
    assert lay.has_delta(over_mirror) and not lay.is_delta(over_mirror)
    assert lay.lobes(over_glass).is_smooth and not lay.lobes(over_glass).transmits  # the coat keeps it in
    assert (R | X).is_delta and not (R | X | G).is_delta and (R | G).is_smooth and not Lobe.NONE.has_delta


# every model at its defaults, and the sets whose lobes differ from them
_LOBE_CASES = [(n, {}) for n in brdf.names() if n != "custom"] + [
    ("dielectric", {"alpha": 0.3}), ("dielectric", {"alpha": 0.05, "ior": 2.4}),
    ("microfacet", {"kd": 0.4}), ("layered", {"base": {"model": "mirror"}}),
    ("layered", {"base": {"model": "dielectric"}}), ("layered", {"base": {"model": "dielectric", "alpha": 0.3}})]


@pytest.mark.parametrize("name,values", _LOBE_CASES, ids=[f"{n}-{v}" for n, v in _LOBE_CASES])
def test_each_models_sampler_draws_only_the_lobes_it_declares(name, values):
    """What ``sample_lobe`` reports against what it drew: each sample's lobe is one side and
    lies in ``lobes(p)``; it went below the surface (wi, wo on opposite sides) exactly when its
    lobe says TRANSMISSION, which only a model with TRANSMISSION draws; a DELTA lobe is discrete
    (the pdf of the pair is not the sample's: 0 for a delta model), any other has the density
    ``pdf`` gives."""
    model = brdf.get(name)
    p = model.params(**values)
    own = model.lobes(p)
    rng = np.random.default_rng(11)
    n = 1500
    th = np.radians(rng.uniform(0.0, 85.0, n))
    ph = rng.uniform(0.0, 2 * np.pi, n)
    wo = np.stack([np.sin(th) * np.cos(ph), np.sin(th) * np.sin(ph), np.cos(th)], axis=1)
    if own.transmits:
        wo[: n // 3, 2] *= -1  # from inside
    wi, w, pdf, lobe = model.sample_lobe(p, wo, rng.random((n, 2)))
    ok = pdf > 0
    assert ok.mean() > 0.1, f"{name}: almost every sample fails"  # (a coat over glass: 12% succeed)
    lo = lobe[ok]
    assert np.all((lo & ~np.uint8(own)) == 0), f"{name}: a sample's lobe outside lobes(p) = {own!r}"
    side = lo & np.uint8(SIDES)
    assert np.all((side == Lobe.REFLECTION) | (side == Lobe.TRANSMISSION)), f"{name}: not one side"
    below = wi[ok, 2] * wo[ok, 2] < 0
    assert np.array_equal(below, side == Lobe.TRANSMISSION), f"{name}: the side is not where wi went"
    if not own.transmits:
        assert not below.any()
    else:
        assert below.any()  # the test reaches the transmission lobe
    disc = drew_delta(lo)
    cont = model.pdf(p, wi[ok], wo[ok])
    if own.is_delta:
        assert disc.all() and np.all(cont == 0), f"{name}: a delta model's sample with a density"
    elif own.is_smooth:
        assert not disc.any()
        np.testing.assert_allclose(pdf[ok], cont, rtol=1e-6, atol=1e-12, err_msg=name)
    else:  # mixed: both kinds drawn, the discrete ones off the density
        assert disc.any() and (~disc).any(), f"{name}: a mixed model drew one kind only"
        np.testing.assert_allclose(pdf[ok][~disc], cont[~disc], rtol=1e-6, atol=1e-12, err_msg=name)
        assert np.all(np.abs(pdf[ok][disc] - cont[disc]) > 0)


def test_sample_lobe_says_which_samples_drew_the_delta_base():
    lay = brdf.get("layered")
    p = lay.params(base={"model": "mirror"})
    rng = np.random.default_rng(3)
    n = 4000
    wo = np.tile([0.3, 0.0, np.sqrt(1 - 0.09)], (n, 1))
    wi, w, pdf, lobe = lay.sample_lobe(p, wo, rng.random((n, 2)))
    disc = drew_delta(lobe) & (pdf > 0)
    ok = pdf > 0
    # the base's mirror direction is the discrete one (refraction in and out keeps it mirror)
    mirror = np.isclose(wi[:, 0], -wo[:, 0], atol=1e-9) & np.isclose(wi[:, 1], -wo[:, 1], atol=1e-9)
    assert disc.any() and (~disc & ok).any()
    assert np.all(mirror[disc])
    # a discrete sample's pdf is the lobe's probability, not the continuous pdf at that pair
    cont = lay.pdf(p, wi[disc], wo[disc])
    assert np.all(np.abs(pdf[disc] - cont) > 0)
    assert np.all(lobe[disc] == Lobe.REFLECTION | Lobe.DELTA)
    assert np.all(lobe[ok & ~disc] == Lobe.REFLECTION | Lobe.GLOSSY)  # the coat, and the base's ...
    # the plain sample is sample_lobe without the lobes
    wi2, w2, pdf2 = lay.sample(p, wo, np.random.default_rng(3).random((n, 2)))
    assert np.array_equal(wi2, wi) and np.array_equal(pdf2, pdf)


def test_fresnel_source_is_each_models_hook():
    from viewer.plots import fresnel_source

    mf = brdf.get("microfacet")
    assert fresnel_source(mf.params(fresnel="schlick"))["type"] == "schlick"
    assert fresnel_source(brdf.get("layered").params())["field"] == "coating.ior"
    assert fresnel_source(brdf.get("mirror").params(fresnel="none")) is None
    assert fresnel_source(brdf.get("lambert").params()) is None
    assert fresnel_source(brdf.get("dielectric").params(ior=1.7))["ior"] == 1.7
    assert spec_mod.HOOKS["fresnel_source"].kind == "function"


def test_the_material_predicates_default_and_ask_the_nested_model():
    # the synthetic model: every predicate at its default
    model = brdf.Model(_module())
    p = model.params()
    assert not (model.has_film(p) or model.is_dispersive(p) or model.uses_spectral(p) or model.walks(p)
                or model.is_measured(p))
    assert model.reference_model(p) is model
    q = model.params_at(p, [450.0, 550.0, 650.0])
    assert q.model == "synthetic" and q.albedo.shape == (3,)
    # a hook answers for the model's own values: a synthetic dispersive model
    disp = brdf.Model(_module(is_dispersive=lambda p: True, walks=lambda p: True))
    assert disp.is_dispersive(disp.params()) and disp.walks(disp.params())
    # a layered base is asked through its own model
    L = brdf.get("layered")
    assert brdf.is_measured(L.params(base={"model": "measured"})) and not brdf.is_measured(L.params())
    assert brdf.walks(L.params(base={"model": "microfacet", "multiple_scattering": True}))
    assert brdf.walks(L.params(reference="random_walk"))
    assert brdf.is_dispersive(L.params(base={"model": "dielectric", "spectral": "BK7"}))
    assert brdf.is_dispersive(L.params(coating={"spectral": "BK7"}))
    assert not brdf.is_dispersive(brdf.get("microfacet").params(spectral="Au"))   # a metal: no refraction
    assert brdf.uses_spectral(brdf.get("microfacet").params(spectral="Au"))
    assert brdf.uses_spectral(L.params(base={"model": "microfacet", "spectral": "Au"}))
    assert type(L.reference_model(L.params(reference="random_walk"))).__name__ == "WalkModel"
    assert L.reference_model(L.params(reference="random_walk", base={"model": "mirror"})) is L   # delta base
