"""Thin shells in the untraced raster: a dielectric of ior 1 (a soap bubble) lets what lies behind
it through, drawn over the opaque frame with dual-source blending (the renderer's shell pass,
forward.frag THIN_SHELL). Oracles: a shell that reflects nothing (ior 1, no film: R = 0
exactly) leaves the frame as it was; a film's shell lets (1 - R)^2 of the floor through, which
is at least 0.8 for a water film at the angles seen on a sphere's inner disc."""

import numpy as np
import pytest

from viewer.gl.programs import forward_variant
from viewer.scene import load_scene_text

SCENE = """
[camera]
position = [0.0, 0.9, 4.0]
target   = [0.0, 0.6, 0.0]
fov_y    = 36.0
width    = 96
height   = 64

[render]
ibl = "{ibl}"
msaa = 1
ssr = {ssr}
shadows = false

[environment]
constant = [{sky}, {sky}, {sky}]

[[lights]]
type = "directional"
direction = [0.0, -1.0, 0.0]
irradiance = [3.0, 3.0, 3.0]

[[objects]]
mesh = "plane"
material = "floor"
scale = 6.0

[materials.floor]
model = "lambert"
albedo = {floor}

[materials.shell]
model = "dielectric"
ior = 1.0
alpha = 0.0
{film}
"""

BALL = """
[[objects]]
mesh = "sphere"
material = "shell"
scale = 0.6
translate = [0.0, 0.6, 0.0]
"""


def _scene(ball: bool, film: str = "", ibl: str = "split_sum", ssr: str = "false", sky: float = 0.6,
           floor: str = "[0.8, 0.4, 0.1]"):
    text = SCENE.format(ibl=ibl, ssr=ssr, film=film, sky=sky, floor=floor)
    if ball:
        text = text.replace("[materials.floor]", BALL + "\n[materials.floor]")
    return load_scene_text(text)


def _ball_mask(renderer):
    """The ball's pixels, from the same geometry with the ball an opaque white Lambert under a
    white sky over a black floor (1 on the ball, 0 on the floor)."""
    text = SCENE.format(ibl="split_sum", ssr="false", film="", sky=1.0, floor="[0.0, 0.0, 0.0]").replace("[materials.floor]", BALL + "\n[materials.floor]")
    text = text.replace('model = "dielectric"\nior = 1.0\nalpha = 0.0', 'model = "lambert"\nalbedo = [1.0, 1.0, 1.0]')
    text = text.replace("irradiance = [3.0, 3.0, 3.0]", "irradiance = [0.0, 0.0, 0.0]")
    return renderer.render_arrays(load_scene_text(text))[0][..., 0] > 0.8


@pytest.mark.parametrize("ibl,ssr", [("split_sum", "false"), ("off", "false"), ("split_sum", "true")])
def test_a_shell_that_reflects_nothing_leaves_the_frame_unchanged(renderer, ibl, ssr):
    with_ball = renderer.render_arrays(_scene(True, ibl=ibl, ssr=ssr))[0][..., :3]
    without = renderer.render_arrays(_scene(False, ibl=ibl, ssr=ssr))[0][..., :3]
    # R = 0 at ior 1, so the blend is dst x 1 + 0; 1e-4: the transmitted albedo table is
    # estimated by the model's own sampler (exact for a delta lobe) and float32 blending
    assert np.max(np.abs(with_ball - without)) < 1e-4


def test_a_soap_film_shell_shows_the_floor_through_it(renderer):
    film = "thin_film = { ior = 1.33, thickness_nm = 300.0 }"
    # a floor lit from straight above under a dim sky: what the ball shows there is the floor
    # seen through it, nearly all of it
    with_ball = renderer.render_arrays(_scene(True, film=film, sky=0.05))[0][..., :3]
    without = renderer.render_arrays(_scene(False, film=film, sky=0.05))[0][..., :3]
    disc = _ball_mask(renderer)
    floor = disc & (without[..., 0] > 0.3)  # where the lit floor lies behind the ball
    assert floor.sum() > 200  # the ball covers a good part of the floor
    ratio = np.median(with_ball[floor] / without[floor], axis=0)
    # each face lets 1 - R through: a water film's R is under 0.1 per channel at these angles,
    # so 0.8-1 of the floor arrives, plus the faces' reflections of the dim sky (0.05 R, under
    # 0.01 against a floor of 0.1-0.8; the light's reflection is a delta, drawn nowhere). Drawn
    # opaque, with the sky looked up straight through in place of the floor, it read 0.07.
    assert np.all(ratio > 0.8), ratio
    assert np.all(ratio < 1.05), ratio
    # over a black floor under a grey sky the ball shows only what its faces reflect: the
    # film's R, coloured by interference (300 nm of water: R about 2x larger in red than in
    # blue at normal incidence; an uncoated ior-1 shell reflects nothing)
    # (read where the black floor lies behind it, so nothing comes through)
    refl = renderer.render_arrays(_scene(True, film=film, floor="[0.0, 0.0, 0.0]"))[0][..., :3][floor].mean(axis=0)
    assert refl.max() > 1.3 * refl.min(), refl
    uncoated = renderer.render_arrays(_scene(True, floor="[0.0, 0.0, 0.0]"))[0][..., :3][floor]
    assert np.max(uncoated) < 1e-4


def test_a_shells_program_has_no_ssr_outputs():
    from viewer.scene import load_scene

    params = load_scene("soap_bubble").materials["bubble"]
    key, _, defines = forward_variant(params, shell=True)
    assert "THIN_SHELL" in defines and key.endswith(":shell")
    with pytest.raises(ValueError, match="SSR"):
        forward_variant(params, shell=True, ssr=True)
