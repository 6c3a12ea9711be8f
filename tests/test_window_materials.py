"""The window's material editor, without a display: the preset picker gives exactly the
preset's material (as ``preset = "..."`` in a scene file does), parameters that do nothing in
the chosen variant are hidden, and the roughness slider speaks perceptual roughness."""

import math

import numpy as np
import pytest

from viewer import brdf
from viewer.app import ui
from viewer.brdf.presets import PRESETS


def _scene_material(preset):
    from viewer.scene import parse_scene

    data = {"materials": {"m": {"preset": preset}},
            "objects": [{"mesh": "sphere", "material": "m"}]}
    return parse_scene(data, None, load_meshes=False).materials["m"]


@pytest.mark.parametrize("name", ["gold", "copper", "glass", "brushed_aluminium"])
def test_preset_picker_sets_the_presets_values(name):
    p = ui.preset_params(name)
    assert p.model == PRESETS[name]["model"]
    ref = _scene_material(name)  # the scene file's path to the same preset: an independent expansion
    assert p.to_plain() == ref.to_plain()


def test_every_preset_is_offered_and_loads():
    assert set(ui.preset_names()) == set(PRESETS)
    for n in ui.preset_names():
        ui.preset_params(n)
    nested = ui.preset_names(nested=True)
    assert all(not brdf.get(PRESETS[n]["model"]).spec.nests_material for n in nested)


def test_copper_and_gold_differ_without_typing_n_and_k():
    g, c = ui.preset_params("gold"), ui.preset_params("copper")
    assert g.model == c.model and g.to_plain() != c.to_plain()


def test_parameters_that_do_nothing_are_hidden():
    mf = brdf.get("microfacet").params().replace(spectral="none")
    shown = ui.shown_params(mf.replace(fresnel="conductor"))
    assert {"eta", "k"} <= set(shown) and "ior" not in shown and "f0" not in shown
    shown = ui.shown_params(mf.replace(fresnel="dielectric"))
    assert "ior" in shown and not {"eta", "k", "f0"} & set(shown)
    shown = ui.shown_params(mf.replace(fresnel="schlick"))
    assert "f0" in shown and not {"eta", "k", "ior"} & set(shown)
    # a measured spectral table replaces eta and k
    assert not {"eta", "k"} & set(ui.shown_params(ui.preset_params("gold")))
    # Blinn-Phong's distribution is isotropic: alpha_y does nothing
    assert "alpha_y" not in ui.shown_params(mf.replace(distribution="blinn_phong"))
    mirror = brdf.get("mirror").params()
    assert "ior" not in ui.shown_params(mirror.replace(fresnel="conductor"))
    assert not {"eta", "k", "ior"} & set(ui.shown_params(mirror.replace(fresnel="none")))
    # every hidden parameter really does nothing: the BRDF is unchanged when it changes
    wi, wo = np.array([[0.3, 0.1, 0.95]]), np.array([[-0.4, 0.2, 0.89]])
    for p, name, value in ((mf.replace(fresnel="conductor"), "ior", 2.5),
                           (mf.replace(fresnel="dielectric"), "eta", [2.0, 2.0, 2.0]),
                           (mf.replace(fresnel="dielectric"), "f0", [0.9, 0.1, 0.1])):
        wi_n, wo_n = wi / np.linalg.norm(wi), wo / np.linalg.norm(wo)
        model = brdf.get("microfacet")
        assert np.allclose(model.eval(p, wi_n, wo_n), model.eval(p.replace(**{name: value}), wi_n, wo_n)), name


def test_roughness_slider_is_perceptual():
    assert ui.perceptual(0.04) == pytest.approx(0.2)
    assert ui.perceptual(1.0) == 1.0 and ui.perceptual(0.0) == 0.0
    assert math.isclose(ui.perceptual(0.2) ** 2, 0.2)
