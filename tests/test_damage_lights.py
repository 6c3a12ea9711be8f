"""Every light of a scene counts: the rasterizer draws up to MAX_LIGHTS lights (the first
SHADOW_LIGHTS with shadow maps, the others without), both reference engines take them all, and
the scene validator refuses more in one line. Truths: the analytic Lambert value of a point light
on a plane (docs/conventions.md) and the linearity of light transport."""

from __future__ import annotations

import tomllib

import numpy as np
import pytest

from viewer import ViewerError

from viewer.commands import cli
from viewer.scene.camera import OrbitCamera
from viewer.gl.constants import MAX_LIGHTS, SHADOW_LIGHTS
from viewer.gl.shadow import unshadowed_note
from viewer.scene import parse_scene

from render_util import camera_rays, hit_plane_y, lambert_point
from scene_text import camera, material, obj, point_light, render, scene, sphere_on_floor, table

L5 = (0.5, 2.0, -0.3)          # the one bright light, fifth in the list
I5 = [30.0, 20.0, 10.0]
ALBEDO = [0.8, 0.5, 0.3]
DARK = ((1.0, 1.0, 1.0), (-1.0, 2.0, 0.0), (0.0, 3.0, -1.0), (2.0, 1.0, -2.0))
W, H = 96, 72
PIXELS = ((36, 48), (20, 30), (50, 70), (60, 10))   # (row, column), all on the floor


def _parse(text: str):
    return parse_scene(tomllib.loads(text), None, label="lights")


def five_lights(shadows=True) -> str:
    """A Lambert floor under five point lights, only the fifth of them bright."""
    lights = [point_light(p, [0.0, 0.0, 0.0]) for p in DARK] + [point_light(L5, I5)]
    return scene(camera([0.0, 4.0, 4.0], [0.0, 0.0, 0.0], 45.0, W, H, up=[0.0, 1.0, 0.0]),
                 render(msaa=0, shadows=shadows), *lights,
                 obj("plane", "floor", scale=3.0), material("floor", model="lambert", albedo=ALBEDO))


def _floor_truth(sc):
    """Where each pixel centre's ray meets the floor, and the fifth light's Lambert value there."""
    cam = sc.camera
    d = camera_rays(cam.position, cam.target, cam.up, cam.fov_y, cam.width, cam.height)
    t = hit_plane_y(cam.position, d, 0.0)
    p = cam.position + d * np.where(np.isfinite(t), t, 0.0)[..., None]
    on = np.isfinite(t) & (np.abs(p[..., 0]) < 2.9) & (np.abs(p[..., 2]) < 2.9)
    return on, lambert_point(ALBEDO, I5, L5, p, np.array([0.0, 1.0, 0.0]))


def _raster(renderer, sc):
    return renderer.render_arrays(sc, OrbitCamera.from_scene(sc))[0].astype(np.float64)


def test_the_fifth_light_lights_the_raster_as_lambert_says(renderer):
    sc = _parse(five_lights())
    img = _raster(renderer, sc)
    on, expected = _floor_truth(sc)
    assert on.sum() > 0.6 * W * H                         # the floor fills most of the view
    for i, j in PIXELS:
        assert on[i, j]
        np.testing.assert_allclose(img[i, j], expected[i, j], rtol=1e-4)
    rel = np.abs(img[on] - expected[on]) / expected[on]
    assert rel.max() < 1e-3, rel.max()
    assert expected[on][:, 0].min() > 0.05                # lit everywhere: no pixel passes by being black


def test_the_cpu_reference_takes_the_fifth_light_and_agrees_with_the_raster(renderer):
    from viewer.pathtracer import ReferenceRenderer

    sc = _parse(five_lights())
    with ReferenceRenderer(sc, width=W, height=H, max_depth=2, seed=1, workers=0) as c:
        c.step(16)
        ref = c.mean().astype(np.float64)
    _, expected = _floor_truth(sc)
    # the reference averages each pixel's square (the raster shades its centre): a few tenths of
    # a percent here, where the irradiance changes by less than 2% across a pixel
    for i, j in PIXELS:
        np.testing.assert_allclose(ref[i, j], expected[i, j], rtol=0.02)
    raster = _raster(renderer, sc)
    assert abs(ref.mean() / raster.mean() - 1.0) < 0.01


@pytest.mark.slow
def test_the_gpu_reference_takes_the_fifth_light(gl_ctx):
    from viewer.gpupt import GpuReferenceRenderer

    sc = _parse(five_lights())
    with GpuReferenceRenderer(sc, width=W, height=H, max_depth=2, seed=1, ctx=gl_ctx) as g:
        g.step(16)
        ref = g.mean().astype(np.float64)
    _, expected = _floor_truth(sc)
    for i, j in PIXELS:
        np.testing.assert_allclose(ref[i, j], expected[i, j], rtol=0.02)
    on, _ = _floor_truth(sc)
    assert abs(ref[on].mean() / expected[on].mean() - 1.0) < 0.01


# seven lights (four shadowed, three not, one of them directional) over a ball on a floor
MANY = [("point", (1.5, 2.5, 1.0), (4.0, 3.0, 2.0)), ("point", (-1.0, 3.0, 0.5), (2.0, 2.0, 5.0)),
        ("directional", (0.3, -1.0, -0.2), (0.4, 0.5, 0.3)), ("point", (0.0, 1.5, 2.0), (1.0, 3.0, 1.0)),
        ("point", (-2.0, 1.0, -1.0), (6.0, 1.0, 1.0)), ("directional", (-0.5, -1.0, 0.4), (0.2, 0.3, 0.6)),
        ("point", (0.8, 4.0, -1.5), (5.0, 5.0, 2.0))]


def _light(kind, a, value) -> str:
    if kind == "point":
        return point_light(a, value)
    return table("[lights]", type="directional", direction=list(a), irradiance=list(value))


def many_lights(on: int | None, shadows=True) -> str:
    """The ball on the floor under MANY; every light but ``on`` dark (None: all lit)."""
    lights = [_light(k, a, v if on is None or i == on else (0.0, 0.0, 0.0)) for i, (k, a, v) in enumerate(MANY)]
    return scene(camera([0.0, 3.0, 4.0], [0.0, 0.3, 0.0], 45.0, 64, 48, up=[0.0, 1.0, 0.0]),
                 render(msaa=0, shadows=shadows), *lights, sphere_on_floor(),
                 material("ball", preset="gold", alpha=0.3),
                 material("floor", model="lambert", albedo=[0.6, 0.6, 0.6]))


def test_the_image_of_all_lights_is_the_sum_of_single_light_images(renderer):
    assert len(MANY) > SHADOW_LIGHTS
    whole = _raster(renderer, _parse(many_lights(None)))
    parts = [_raster(renderer, _parse(many_lights(i))) for i in range(len(MANY))]
    assert all(p.max() > 0.01 for p in parts)             # each light, the 5th to 7th too, adds light
    np.testing.assert_allclose(sum(parts), whole, rtol=1e-4, atol=1e-6)


def test_lights_beyond_the_shadow_maps_are_drawn_as_without_shadows(renderer):
    """The same light fifth in the list lights the floor as it does with shadows off, first in
    the list it casts the ball's shadow."""
    def one(index, shadows):
        lights = [point_light((0.5, 3.0, 0.5), [0.0] * 3)] * 5
        lights[index] = point_light((0.5, 3.0, 0.5), [10.0] * 3)
        text = scene(camera([0.0, 3.0, 4.0], [0.0, 0.3, 0.0], 45.0, 64, 48, up=[0.0, 1.0, 0.0]),
                     render(msaa=0, shadows=shadows), *lights, sphere_on_floor(),
                     material("ball", model="lambert", albedo=[0.5] * 3), material("floor", model="lambert",
                                                                                   albedo=[0.5] * 3))
        return _raster(renderer, _parse(text))

    unshadowed = one(0, False)
    shadowed = one(0, True)
    assert (unshadowed - shadowed).max() > 0.1           # the ball's shadow on the floor
    np.testing.assert_allclose(one(4, True), unshadowed, rtol=1e-5, atol=1e-7)


def test_the_note_names_the_unshadowed_lights():
    assert SHADOW_LIGHTS == 4 and MAX_LIGHTS == 16
    assert unshadowed_note(_parse(many_lights(None))) == \
        "lights 5-7 are drawn without shadows (the raster shadow-maps 4)"
    assert unshadowed_note(_parse(five_lights())) == "light 5 is drawn without shadows (the raster shadow-maps 4)"
    four = five_lights().replace(point_light(L5, I5), "")
    assert len(_parse(four).lights) == 4 and unshadowed_note(_parse(four)) is None
    # the scene format's page (written from viewer/commands/docgen.py, which imports no GL) says the same numbers
    from pathlib import Path

    page = (Path(__file__).resolve().parent.parent / "docs" / "scene-format.md").read_text()
    assert f"at most {MAX_LIGHTS} lights; the rasterizer shadow-maps the first {SHADOW_LIGHTS} " in page


def _n_lights(n: int) -> str:
    return scene(camera([0.0, 4.0, 4.0], [0.0, 0.0, 0.0], 45.0, 32, 24, up=[0.0, 1.0, 0.0]),
                 *[point_light((0.1 * i, 2.0, 0.0), [0.5, 0.5, 0.5]) for i in range(n)],
                 obj("plane", "floor", scale=3.0), material("floor", model="lambert", albedo=ALBEDO))


def test_the_validator_takes_the_maximum_and_refuses_one_more():
    assert len(_parse(_n_lights(MAX_LIGHTS)).lights) == MAX_LIGHTS
    with pytest.raises(ViewerError) as e:
        _parse(_n_lights(MAX_LIGHTS + 1))
    msg = str(e.value)
    assert "\n" not in msg and "lights" in msg and "17 lights" in msg and "at most 16" in msg, msg


def test_the_raster_draws_the_maximum(renderer):
    """Sixteen lights: the image is sixteen times one of them (each light slot drawn)."""
    text = _n_lights(MAX_LIGHTS).replace("[camera]", "[render]\nmsaa = 0\nshadows = false\n\n[camera]")
    sc = _parse(text)
    one = _parse(text)
    for k in range(1, MAX_LIGHTS):
        one.lights[k].intensity = np.zeros(3)
    whole, single = _raster(renderer, sc), _raster(renderer, one)
    # the lights lie 0.1 m apart: compare with the sum of each light's analytic Lambert value
    cam = sc.camera
    d = camera_rays(cam.position, cam.target, cam.up, cam.fov_y, cam.width, cam.height)
    t = hit_plane_y(cam.position, d, 0.0)
    p = cam.position + d * np.where(np.isfinite(t), t, 0.0)[..., None]
    on = np.isfinite(t) & (np.abs(p[..., 0]) < 2.9) & (np.abs(p[..., 2]) < 2.9)
    assert on.sum() > 0.6 * on.size
    expected = sum(lambert_point(ALBEDO, [0.5] * 3, (0.1 * i, 2.0, 0.0), p, np.array([0.0, 1.0, 0.0]))
                   for i in range(MAX_LIGHTS))
    np.testing.assert_allclose(whole[on], expected[on], rtol=1e-3)
    assert whole.mean() > 10 * single.mean()


def test_cli_render_says_once_which_lights_are_unshadowed(tmp_path, capsys):
    (tmp_path / "six.toml").write_text(_n_lights(6))
    rc = cli.main(["render", str(tmp_path / "six.toml"), "--out", str(tmp_path / "six.png")])
    err = capsys.readouterr().err
    assert rc == 0, err
    assert err.count("drawn without shadows") == 1, err
    assert "lights 5-6 are drawn without shadows (the raster shadow-maps 4)" in err


def test_cli_refuses_too_many_lights_in_one_line(tmp_path, capsys):
    (tmp_path / "many.toml").write_text(_n_lights(MAX_LIGHTS + 1))
    rc = cli.main(["render", str(tmp_path / "many.toml"), "--out", str(tmp_path / "many.png")])
    err = capsys.readouterr().err
    assert rc == 2
    assert err.count("\n") == 1 and "Traceback" not in err and "at most 16" in err, err
    assert not (tmp_path / "many.png").exists()


def test_the_window_says_once_which_lights_are_unshadowed(tmp_path, gl_ctx, renderer):
    from viewer.app.session import Session

    (tmp_path / "six.toml").write_text(_n_lights(6))
    s = Session(gl_ctx, str(tmp_path / "six.toml"), renderer=renderer, prefetch=False)
    try:
        said = [m.text for m in s.messages if "without shadows" in m.text]
        assert len(said) == 1 and said[0].endswith(": lights 5-6 are drawn without shadows (the raster shadow-maps 4)"), said
        assert s.open_scene(str(tmp_path / "six.toml"))            # opened again: said in the open line
        opened = s.messages[-1].text
        assert opened.startswith("opened ") and "lights 5-6 are drawn without shadows" in opened, opened
    finally:
        s.release()
