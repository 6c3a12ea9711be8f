"""Environment occlusion in traced frames (``[render] raytrace = true``; the ENV_OCCLUSION variant,
shaders/common/specular_chain.glsl rt_occluded_irradiance): the diffuse environment term traced
for occlusion in the scene's BVH, against the closed form of a sphere's configuration factor.

A differential area under a sphere of radius R whose centre lies at distance D, at angle theta
from the area's normal, the sphere wholly above the area's plane, sees it cover the cosine-
weighted fraction (R / D)^2 cos(theta) of its hemisphere. Derivation (Nusselt's unit-sphere
analogue): the sphere subtends a cone of half-angle alpha, sin(alpha) = R / D; the cosine-weighted
fraction is the area of the cone's trace on the unit hemisphere projected onto the base plane,
over pi; that trace is a circle of radius sin(alpha) whose plane is tilted by theta, so its
projection is an ellipse of area pi sin(alpha)^2 cos(theta). This is the configuration factor
of a plane element to a sphere in the heat-transfer catalogues (Howell, "A Catalog of Radiation
Heat Transfer Configuration Factors": element to sphere, F = (R / D)^2 cos(theta)). With
D cos(theta) = h, the centre's height, it is R^2 h / D^3, and (R / h)^2 directly under the
centre. Under a constant environment L a Lambert floor of albedo rho next to a black sphere
therefore reflects rho L (1 - R^2 h / D^3)."""

import textwrap

import numpy as np

from viewer.scene import load_scene

from render_util import camera_rays, hit_plane_y, hit_sphere
from scene_text import camera, environment, material, obj, render, scene

W, H = 64, 40
R_BALL, H_BALL, RHO = 0.5, 1.0, 0.5


def _scene(tmp_path, raytrace=True):
    text = scene(camera([0.0, 1.0, 3.0], [0.0, 0.0, 0.0], 40.0, W, H, up=[0.0, 1.0, 0.0]),
                 environment(constant=[1.0, 1.0, 1.0]),
                 render(ibl="split_sum", shadows=True, msaa=0, raytrace=raytrace, raytrace_occlusion=True),
                 obj("plane", "floor", scale=6.0),
                 obj("sphere", "black", scale=R_BALL, translate=[0.0, H_BALL, 0.0]),
                 # a traced frame needs a mirror or smooth glass: a 1 cm mirror bead behind the
                 # camera, whose share of the floor's hemisphere is under 1e-5
                 obj("sphere", "bead", scale=0.01, translate=[0.0, 0.05, 5.5]),
                 material("floor", model="lambert", albedo=[RHO] * 3),
                 material("black", model="lambert", albedo=[0.0, 0.0, 0.0]),
                 material("bead", model="mirror", fresnel="none"))
    p = tmp_path / "occlusion.toml"
    p.write_text(textwrap.dedent(text))
    return load_scene(str(p))


def _floor_points(sc):
    c = sc.camera
    d = camera_rays(c.position, c.target, c.up, c.fov_y, W, H)
    t = hit_plane_y(c.position, d, 0.0)
    ball = hit_sphere(c.position, d, (0.0, H_BALL, 0.0), R_BALL)
    with np.errstate(invalid="ignore"):
        p = np.asarray(c.position, float) + d * t[..., None]
    return p, np.isfinite(t) & ~np.isfinite(ball)


def test_floor_under_a_sphere_sees_the_closed_form_sky(tmp_path, renderer):
    sc = _scene(tmp_path)
    img = renderer.render_arrays(sc, width=W, height=H)[0].mean(axis=-1)
    p, floor = _floor_points(sc)
    rho = np.hypot(p[..., 0], p[..., 2])
    D3 = (rho ** 2 + H_BALL ** 2) ** 1.5
    sky = 1.0 - R_BALL ** 2 * H_BALL / D3
    # pixels a little inside the floor (the ball's silhouette and the horizon left out), where
    # the ball covers more than 1% of the sky
    near = floor & (rho < 1.4) & (np.abs(p[..., 0]) < 2.0)
    assert near.sum() > 300
    got = img[near] / RHO
    under = floor & (rho < 0.2)
    assert under.sum() >= 8
    print(f"directly under the ball ({under.sum()} px): visible sky {img[under].mean() / RHO:.4f}, "
          f"closed form 1 - (R/h)^2 = {1 - (R_BALL / H_BALL) ** 2:.4f} (within rho < 0.2: "
          f"{sky[under].mean():.4f}); {near.sum()} px near it: mean error {np.mean(got - sky[near]):+.4f}, "
          f"rms {np.sqrt(np.mean((got - sky[near]) ** 2)):.4f}")
    # 16 stratified rays a pixel, a new rotation each: a pixel's estimate is k / 16, its noise
    # about 0.04 (the measured rms below), 0.04 / sqrt(N) on a mean of N pixels; the icosphere's
    # facets shift the covered fraction by under 1e-3. Bounds: 3 standard errors and 1e-3 on the
    # means, 0.06 on the per-pixel rms.
    assert abs(img[under].mean() / RHO - sky[under].mean()) < 3 * 0.04 / np.sqrt(under.sum()) + 1e-3
    assert abs(np.mean(got - sky[near])) < 3 * 0.04 / np.sqrt(near.sum()) + 1e-3
    assert np.sqrt(np.mean((got - sky[near]) ** 2)) < 0.06
    # untraced, the split sum sees the whole sky everywhere (no occlusion)
    sc.render.raytrace = False
    flat = renderer.render_arrays(sc, width=W, height=H)[0].mean(axis=-1)
    np.testing.assert_allclose(flat[near], RHO, rtol=1e-4)


def test_occlusion_is_compiled_into_traced_frames_only(tmp_path, renderer):
    sc = _scene(tmp_path)
    keys = renderer.forward_keys(sc)
    assert all(":envocc" in k for k in keys.values()), keys
    assert all(":envocc" not in k for k in renderer.forward_keys(sc, raytrace=False).values())
    sc.environment.constant = [0.0, 0.0, 0.0]   # nothing to occlude
    assert all(":envocc" not in k for k in renderer.forward_keys(sc).values())
