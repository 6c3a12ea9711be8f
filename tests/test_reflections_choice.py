"""The window's reflections / refraction choice (viewer/app/reflections.py) and the lecture steps
that trace their glass: the choice maps to the scene's [render] keys and back, the steps render
finite with ray tracing on, and the choice changes what the window draws."""

import os
import shutil

import numpy as np
import pytest

from viewer.scene import RenderSettings


def test_choice_maps_to_scene_keys():
    from viewer.app.reflections import MODES, reflection_mode, set_reflection_mode

    r = RenderSettings()
    assert reflection_mode(r) == "off" and (r.ssr, r.raytrace) == (False, False)
    expect = {"off": (False, False), "SSR": (True, False), "ray traced": (False, True)}
    for mode in MODES:
        for start in MODES:  # from every other mode
            set_reflection_mode(r, start)
            set_reflection_mode(r, mode)
            assert (r.ssr, r.raytrace) == expect[mode], (start, mode)
            assert reflection_mode(r) == mode
    # ray traced with SSR kept for the glossy lobes the chain does not trace
    assert set_reflection_mode(r, "ray traced", ssr_on_glossy=True)
    assert (r.ssr, r.raytrace) == (True, True) and reflection_mode(r) == "ray traced"
    assert not set_reflection_mode(r, "ray traced")  # unchanged: keeps its SSR box
    assert (r.ssr, r.raytrace) == (True, True)
    # a scene file with both keys reads as ray traced
    r2 = RenderSettings()
    r2.ssr, r2.raytrace = True, True
    assert reflection_mode(r2) == "ray traced"
    with pytest.raises(ValueError, match="unknown mode"):
        set_reflection_mode(r, "path traced")


TRACED_STEPS = ("fresnel", "tir", "absorbing_glass", "complex_ior", "dispersion")


@pytest.mark.parametrize("key", TRACED_STEPS)
def test_glass_steps_trace_and_render_finite(renderer, key):
    from viewer.image.finite import nonfinite_message
    from viewer.gl.raytrace import chain_traces
    from viewer.scene.lecture import TOUR, tour_scene

    i = [s.key for s in TOUR].index(key)
    scene = tour_scene(i)
    assert scene.render.raytrace, key
    assert any(chain_traces(scene.materials[o.material]) for o in scene.objects)
    assert "compare with the reference" not in TOUR[i].caption  # says what to see in the raster itself
    lin, _ = renderer.render_arrays(scene, width=48, height=32)
    msg = nonfinite_message(lin, f"lecture {key}")
    assert msg is None, msg
    assert lin.min() >= 0.0
    scene.render.raytrace = False
    off, _ = renderer.render_arrays(scene, width=48, height=32)
    assert not np.allclose(lin, off)  # the traced glass is a different picture


@pytest.mark.slow  # a window process with traced glass: minutes on a loaded 2-core software-GL machine
@pytest.mark.skipif(shutil.which("Xvfb") is None and not os.environ.get("DISPLAY"),
                    reason="needs Xvfb or a display")
def test_window_draws_the_choice(tmp_path):
    # The window on the TIR step: switching the choice from ray traced to off changes the keys
    # and the image (the cube goes from mirrors of the sky to one dim panel).
    import subprocess
    import sys
    import textwrap

    code = textwrap.dedent(f"""
        import numpy as np
        from viewer.app.main import App
        from viewer.app.reflections import reflection_mode, set_reflection_mode
        # small (a 200 x 300 view beside the panel) and no MSAA: software GL traces every pixel
        app = App("lecture:3", ["render.msaa=0"], size=(560, 300), restore_state=False)
        try:
            app.plots.visible = False
            app.frame()
            assert reflection_mode(app.session.scene.render) == "ray traced"
            a = app.capture_window()
            set_reflection_mode(app.session.scene.render, "off"); app.session.dirty = True
            b = app.capture_window()
            assert (app.session.scene.render.raytrace, app.session.scene.render.ssr) == (False, False)
            print("DIFF", float(np.abs(a.astype(float) - b.astype(float)).mean()))
        finally:
            app.close()
    """)
    env = dict(os.environ)
    env["BRDF_VIEWER_STATE"] = str(tmp_path / "state.toml")
    env["BRDF_VIEWER_COMPILE_AHEAD"] = "0"  # the switch's programs compile at once, in the frame
    env["BRDF_VIEWER_TILED_FRAMES"] = "0"  # and the frame after it is whole
    env["BRDF_VIEWER_PREPARE_FRAMES"] = "0"  # the scene's first frame too, at once
    cmd = [sys.executable, "-c", code]
    if not env.get("DISPLAY"):
        cmd = ["xvfb-run", "-a"] + cmd
    r = subprocess.run(cmd, env=env, capture_output=True, text=True, timeout=400)
    assert r.returncode == 0, r.stderr[-2000:]
    diff = float(r.stdout.split("DIFF")[1])
    assert diff > 0.5, diff


def test_glass_with_reflections_off_says_ray_tracing_shows_it(gl_ctx, renderer):
    """A glass, mirror or soap preset on the default scene with reflections off: one notice
    (and the Materials panel's line) naming the material and the choice that shows it; none
    for a rough lobe, none once traced."""
    from viewer.app.reflections import delta_materials, set_reflection_mode, traced_hint
    from viewer.app.session import Session
    from viewer.app.ui import preset_params

    s = Session(gl_ctx, "default", renderer=renderer, prefetch=False)
    try:
        assert traced_hint(s.scene) == ""  # terracotta and a floor: nothing to trace
        for preset in ("glass", "polished_silver", "soap_bubble"):
            s.set_material("ball", preset_params("gold"))
            n0 = len(s.messages)
            s.set_material("ball", preset_params(preset))
            new = [m.text for m in s.messages[n0:]]
            assert delta_materials(s.scene) == ["ball"], preset
            assert len(new) == 1 and "ball" in new[0] and "ray traced" in new[0], (preset, new)
        s.set_material("ball", preset_params("gold"))
        assert traced_hint(s.scene) == ""  # a rough conductor: the environment is its reflection
        s.set_material("ball", preset_params("glass"))
        set_reflection_mode(s.scene.render, "ray traced")
        assert traced_hint(s.scene) == ""
    finally:
        s.release()


def _materials():
    from viewer import brdf

    return {"mirror": brdf.get("mirror").params(),
            "glass": brdf.get("dielectric").params(),
            "frosted": brdf.get("dielectric").params(alpha=0.2),
            "coated_mirror": brdf.get("layered").params(coating={"alpha": 0.2},
                                                        base={"model": "mirror", "fresnel": "conductor"}),
            "soap": brdf.get("dielectric").params(ior=1.0, thin_film={"ior": 1.33, "thickness_nm": 300.0}),
            "clay": brdf.get("lambert").params()}


def test_delta_materials_are_the_ones_the_chains_trace():
    """The reflections hint names the materials whose every lobe is delta (the model's is_delta):
    exactly those the traced chains follow. A coat over a mirror has a delta lobe under a smooth
    coat, which the chains shade like any rough surface, so ray tracing does not show it more:
    it is not named, though it has a delta lobe (has_delta)."""
    from types import SimpleNamespace

    from viewer import brdf
    from viewer.app.reflections import delta_materials
    from viewer.gl.raytrace import chain_traces

    mats = _materials()
    scene = SimpleNamespace(materials=mats)
    assert delta_materials(scene) == ["mirror", "glass", "soap"]
    assert delta_materials(scene) == [n for n, p in mats.items() if chain_traces(p)]
    coated = mats["coated_mirror"]
    assert brdf.get("layered").has_delta(coated) and not brdf.is_delta(coated)
    assert brdf.get("layered").lobes(coated).is_mixed


def test_plots_draw_a_delta_lobe_where_the_model_says_so():
    # the polar and 3D lobe plots draw the mirror arrow of pure delta materials (is_delta); a coat
    # over a mirror is drawn as its smooth coat lobe (f > 0), with no arrow
    from viewer.plots import data

    mats = _materials()
    for name, p in mats.items():
        pol = data.polar_lobe(p, theta_i=30.0, n=91)
        lobe = data.lobe_3d(p, theta_i=30.0, n_theta=10, n_phi=13)
        pure = name in ("mirror", "glass", "soap")
        assert bool(pol["delta"]) == pure and bool(lobe["delta"]) == pure, name
        if pure:
            assert not np.any(pol["f"] > 0), name
    assert np.any(data.polar_lobe(mats["coated_mirror"], theta_i=30.0, n=91)["f"] > 0)
