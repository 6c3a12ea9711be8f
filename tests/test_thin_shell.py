"""Thin shells in the untraced raster: a dielectric of ior 1 (a soap bubble) lets what lies behind
it through, drawn over the opaque frame with dual-source blending (the renderer's shell pass,
forward.frag THIN_SHELL). Oracles: a shell that reflects nothing (ior 1, no film: R = 0
exactly) leaves the frame as it was; a film's shell lets (1 - R)^2 of the floor through, which
is at least 0.8 for a water film at the angles seen on a sphere's inner disc; a bubble over a
white floor under a constant sky vanishes (a white furnace: the floor is drawn at the sky's
radiance and the film loses nothing); and the floor's part of its pixels (a white floor's frame
minus a black one's) is what an analytic trace of the exact sphere with the numpy twin's film
reflectance gives, R of the far face where, in the upper half, that concave mirror looks down at
the floor (viewer/scene/ground.py)."""

import numpy as np
import pytest

from viewer.gl.programs import forward_variant
from viewer.scene import load_scene_text

CAMERA = """
[camera]
position = [0.0, 0.9, 4.0]
target   = [0.0, 0.6, 0.0]
fov_y    = 36.0
width    = 96
height   = 64
"""

SCENE = CAMERA + """
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


# ---- the shells' reflection of the floor (viewer/scene/ground.py): a face's reflected ray going
# down meets the scene's floor, shaded as the raster shades it, not the environment below the horizon

FLOOR_SCENE = CAMERA + """
[render]
ibl = "split_sum"
msaa = 1
shadows = false

[environment]
constant = [{sky}, {sky}, {sky}]

[[objects]]
mesh = "plane"
material = "floor"
scale = 6.0

[[objects]]
mesh = "sphere"
material = "shell"
scale = 0.6
translate = [0.0, 0.7, 0.0]

[materials.floor]
model = "lambert"
albedo = [{floor}, {floor}, {floor}]

[materials.shell]
model = "dielectric"
ior = 1.0
alpha = 0.0
thin_film = {{ ior = 1.33, thickness_nm = 300.0 }}
"""
SKY = 0.8
CENTRE, RADIUS, FLOOR_HALF = np.array([0.0, 0.7, 0.0]), 0.6, 6.0


def _floor_scene(floor: float):
    return load_scene_text(FLOOR_SCENE.format(sky=SKY, floor=floor))


def _pixel_rays(scene, w, h, offset=(0.0, 0.0)):
    """World-space unit directions through the pixel centres (+ offset in pixels), row 0 = top,
    from the camera's own view and projection matrices."""
    from viewer.scene.camera import OrbitCamera

    cam = OrbitCamera.from_scene(scene)
    inv = np.linalg.inv(cam.projection(w / h) @ cam.view())
    j, i = np.meshgrid(np.arange(w) + 0.5 + offset[0], np.arange(h) + 0.5 + offset[1])
    ndc = np.stack([2.0 * j / w - 1.0, 1.0 - 2.0 * i / h, np.ones_like(j), np.ones_like(j)], axis=-1)
    far = ndc @ inv.T
    d = far[..., :3] / far[..., 3:] - cam.position
    return cam.position, d / np.linalg.norm(d, axis=-1, keepdims=True)


def _on_floor(p, r):
    """Whether rays p + t r (t > 0) land on the floor (y = 0, |x|, |z| <= FLOOR_HALF)."""
    down = r[..., 1] < 0.0
    t = np.where(down, -p[..., 1] / np.where(down, r[..., 1], -1.0), -1.0)
    q = p + t[..., None] * r
    return down & (t > 0) & (np.abs(q[..., 0]) <= FLOOR_HALF) & (np.abs(q[..., 2]) <= FLOOR_HALF)


def _floor_share(scene, w, h, offset=(0.0, 0.0)):
    """Per pixel: what the floor adds to the shell's pixel per unit floor radiance, traced
    analytically on the exact sphere (the raster's model of a shell: each face passes 1 - R of
    what lies behind it and reflects R of what its mirror ray meets, the floor or the sky),
    (H, W, 3); with the mask of the pixels whose ray meets the sphere, the cosine there and the
    three floor hits (the front face's mirror ray, the far face's, the ray straight through)."""
    from viewer.brdf import thin_film

    o, d = _pixel_rays(scene, w, h, offset)
    oc = o - CENTRE
    b = d @ oc
    disc = b * b - (oc @ oc - RADIUS ** 2)
    hit = disc > 0.0
    s = np.sqrt(np.maximum(disc, 0.0))
    p_f = o + (-b - s)[..., None] * d
    p_b = o + (-b + s)[..., None] * d
    n_f = (p_f - CENTRE) / RADIUS
    n_b = -(p_b - CENTRE) / RADIUS               # the far face seen from inside: its normal points in
    cos = np.clip(-(d * n_f).sum(-1), 0.0, 1.0)  # the same at both faces of a sphere
    r_f = d - 2.0 * (d * n_f).sum(-1, keepdims=True) * n_f
    r_b = d - 2.0 * (d * n_b).sum(-1, keepdims=True) * n_b
    g_f, g_b, g_t = _on_floor(p_f, r_f), _on_floor(p_b, r_b), _on_floor(np.broadcast_to(o, d.shape), d)
    R = thin_film.dielectric_reflectance_rgb(scene.materials["shell"], cos.reshape(-1), 1.0).reshape(h, w, 3)
    share = R * g_f[..., None] + (1.0 - R) * (R * g_b[..., None] + (1.0 - R) * g_t[..., None])
    return share, hit, cos, (g_f, g_b, g_t)


def test_a_bubble_over_a_white_floor_in_a_constant_sky_is_invisible(renderer):
    # White furnace: a floor of albedo 1 under a sky of radiance L (no lights) is drawn at L (the
    # raster's floor: albedo / pi times the irradiance pi L), so whatever a lossless film
    # (R + T = 1) reflects or lets through, above the horizon or below, the floor or the sky, is
    # L: the bubble must vanish. A ground reflection with a wrong scale (the irradiance pi L not
    # divided by pi) is off by R (pi - 1) L, 0.1 L on average here. A smooth shell's R is the
    # model's own at each point and its T = 1 - R, so the sum is 1 to float32 rounding: 1e-4 L
    # (measured under 5e-5 L; through the albedo tables, whose sampler counts the reflected
    # fraction within 1 / 576 of its mean, it was 0.003 L).
    scene = _floor_scene(1.0)
    img = renderer.render_arrays(scene)[0][..., :3]
    _, hit, _, _ = _floor_share(scene, img.shape[1], img.shape[0])
    assert hit.sum() > 500
    bound = 1e-4 * SKY
    err = np.max(np.abs(img - SKY))
    print(f"white furnace: max |pixel - L| {err / SKY:.6f} L")
    assert err < bound


def test_a_bubble_reflects_the_floor_in_its_upper_half(renderer):
    # The floor's part of each pixel: a white floor's frame minus a black floor's, both under the
    # same sky L (no lights): the floor's radiance is albedo L, so the difference is L times the
    # analytic share of _floor_share. In the bubble's upper half the far face, a concave mirror,
    # looks down at the floor and reflects R of it there; reflecting the environment below the
    # horizon instead (the studio map's dark floor in the lecture's step) left a difference of 0.
    w, h = 96, 64
    white = renderer.render_arrays(_floor_scene(1.0), width=w, height=h)[0][..., :3].astype(np.float64)
    black = renderer.render_arrays(_floor_scene(0.0), width=w, height=h)[0][..., :3].astype(np.float64)
    scene = _floor_scene(1.0)
    share, hit, cos, (g_f, g_b, g_t) = _floor_share(scene, w, h)
    # pixels whose three floor hits are the same over the pixel's extent (an edge crossing the
    # pixel: its centre's alone decides) and away from the rim (cos > 0.3: the mesh's polygonal
    # silhouette, and the steep part of R where the table's linear steps are coarse)
    keep = hit & (cos > 0.3)
    for dx, dy in ((-0.5, -0.5), (0.5, -0.5), (-0.5, 0.5), (0.5, 0.5)):
        _, ht, _, gs = _floor_share(scene, w, h, (dx, dy))
        keep &= ht & (g_f == gs[0]) & (g_b == gs[1]) & (g_t == gs[2])
    upper = keep & g_b & ~g_t            # the far face reflects the floor, the sky lies behind
    lower = keep & g_t                   # the floor seen through
    assert upper.sum() > 100 and lower.sum() > 100, (upper.sum(), lower.sum())
    diff = white - black
    err = np.abs(diff - SKY * share)
    print(f"upper half: {upper.sum()} px, floor share {np.mean(diff[upper]) / SKY:.4f} (analytic "
          f"{np.mean(share[upper]):.4f}), max err {err[upper].max() / SKY:.4f} L; lower: {lower.sum()} px, "
          f"max err {err[lower].max() / SKY:.4f} L")
    # the upper half's analytic share: R of the far face (water: 0.05 on average here)
    assert np.mean(share[upper]) > 0.03
    # per pixel: the tessellated sphere (a 5 times subdivided icosphere, vertices 2 deg apart):
    # its fragments lie on flat triangles under the sphere and their normals are interpolated,
    # which moves cos by about 1e-3, and this film's R changes by at most 1.4 per unit of cos (the
    # twin, cos > 0.3), at both faces: 0.005 L (measured 0.0007 L); the region's mean within
    # 0.002 L (measured under 1e-4 L). The reflection was missing by 0.05 L on average.
    assert err[upper].max() < 0.005 * SKY
    assert err[lower].max() < 0.005 * SKY
    assert abs(np.mean(diff[upper]) - SKY * np.mean(share[upper])) < 0.002 * SKY


def test_the_ground_is_the_largest_lambert_plane_as_placed():
    # viewer/scene/ground.py against the objects' own model matrices: points of the plane mesh's
    # [-1, 1]^2 mapped to the world lie on the ground, points just outside do not (a plane turned
    # 30 degrees about +y, scaled unevenly); a larger plane of another model, and a cube, are not
    # the ground; a scene without a Lambert plane has none
    from viewer.scene.ground import ground_plane

    base = FLOOR_SCENE.format(sky=SKY, floor=0.5)
    text = base.replace('scale = 6.0\n', 'scale = [2.0, 1.0, 0.5]\ntranslate = [0.3, -0.2, 0.7]\nrotate_y_deg = 30.0\n')
    text += ('\n[[objects]]\nmesh = "plane"\nmaterial = "shiny"\nscale = 50.0\n'
             '\n[[objects]]\nmesh = "cube"\nmaterial = "floor"\nscale = 90.0\n'
             '\n[materials.shiny]\nmodel = "mirror"\n')
    scene = load_scene_text(text)
    g = ground_plane(scene)
    floor = next(o for o in scene.objects if o.material == "floor" and o.mesh == "plane")
    assert g is not None and g.origin[1] == -0.2 and np.allclose(g.albedo, 0.5)
    m = floor.model_matrix()
    rng = np.random.default_rng(3)
    for k, inside in ((0.98, True), (1.02, False)):
        # points on the edges of the square of half-side k, and (inside) any point within it
        u = rng.uniform(-1.0, 1.0, (200, 2))
        edge = np.where(rng.random(200)[:, None] < 0.5, np.stack([np.sign(u[:, 0]), u[:, 1]], 1),
                        np.stack([u[:, 0], np.sign(u[:, 1])], 1)) * k
        w = (m @ np.stack([edge[:, 0], np.zeros(200), edge[:, 1], np.ones(200)]))[:3]
        assert np.all(g.contains(w[0], w[2]) == inside)
    assert ground_plane(load_scene_text(base.replace('model = "lambert"\nalbedo = [0.5, 0.5, 0.5]',
                                                     'model = "mirror"'))) is None
