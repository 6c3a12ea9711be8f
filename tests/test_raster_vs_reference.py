"""Direct light (max depth 1) with a point light: the rasterizer and the reference path tracer
agree per pixel within the reference's standard errors, for every BRDF family. Both shade with
the same BRDF (GLSL twin vs numpy twin, proven equal elsewhere), so any disagreement is a
transport or geometry bug (camera, normals, frames, light falloff, shadows).

Both images are box-filtered pixels (docs/conventions.md): the reference jitters its camera
samples over the pixel square, and the raster is rendered with supersample=4 (a 4 x 4 grid of
shading points per pixel, averaged). With MSAA the raster shades once at the pixel centre, which
differs from the box average by curvature (measured here: +6.5e-4 relative on a Lambert sphere,
~0.8 SE at 512 spp); the 4 x 4 grid leaves 1/16 of that."""

import math
import textwrap

import numpy as np
import pytest

from viewer import brdf
from viewer.scene.camera import OrbitCamera
from viewer.scene import load_scene

from render_util import camera_rays, hit_plane_y, hit_sphere, sphere_interior
from scene_text import camera, material, point_light, scene, sphere_on_floor

pathtracer = pytest.importorskip("viewer.pathtracer")

W = H = 48
SPP = 64

SCENE = """
[camera]
position = [0.0, 0.6, 3.6]
target = [0.0, 0.0, 0.0]
fov_y = 40.0
width = {W}
height = {H}

[render]
msaa = 4
shadows = true

[[lights]]
type = "point"
position = [2.0, 3.0, 3.0]
intensity = [12.0, 12.0, 12.0]

[[objects]]
mesh = "sphere"
material = "m"
"""


def _scene_with_material(tmp_path, params):
    import tomllib

    from viewer.scene import parse_scene

    data = tomllib.loads(SCENE.format(W=W, H=H))
    data["materials"] = {"m": params.to_plain()}  # nested tables (layered) as data, not text
    return parse_scene(data, tmp_path / "s.toml")


def _compare(raster, mean, var, mask, label):
    se = np.sqrt(var)
    diff = raster - mean
    zero = se[mask] == 0
    # where every reference sample was identical (unlit: exactly 0) the raster must match to
    # float32 arithmetic precision
    assert np.all(np.abs(diff[mask][zero]) <= 1e-5 + 1e-4 * np.abs(mean[mask][zero])), label
    z = diff[mask][~zero] / se[mask][~zero]
    # Under agreement z ~ Student t with SPP-1 dof: P(|z| > 3) ~ 0.4%. Allow 1.5% (a per-pixel
    # 'all within 3 SE' would fail by chance on ~0.3% of thousands of pixels); and no pixel past
    # 8 SE, which chance does not produce (a bug shows as a systematic offset or outliers).
    frac = float(np.mean(np.abs(z) > 3)) if z.size else 0.0
    assert frac < 0.015, f"{label}: {frac:.2%} of pixels beyond 3 SE (max |z| {np.abs(z).max():.1f})"
    assert z.size == 0 or np.abs(z).max() < 8, f"{label}: max |z| {np.abs(z).max():.1f}"
    return frac


@pytest.mark.parametrize("name", brdf.names())
def test_direct_light_agrees_per_pixel(tmp_path, renderer, name):
    model = brdf.get(name)
    scene = _scene_with_material(tmp_path, model.params())
    cam = OrbitCamera.from_scene(scene)
    raster = renderer.render_arrays(scene, cam, supersample=4)[0]
    ref = pathtracer.ReferenceRenderer(scene, camera=cam, max_depth=1, seed=11, workers=2)
    try:
        ref.step(SPP)
        mean, var = ref.mean(), ref.variance()
    finally:
        ref.close()
    mask = sphere_interior(scene.camera)
    assert mask.sum() > 400
    if model.spec.delta and name in ("mirror",) or (name == "dielectric" and model.params().alpha == 0):
        # a delta lobe reflects a point light in one direction only: both renderers give 0
        assert np.abs(raster[mask]).max() < 1e-6 and np.abs(mean[mask]).max() < 1e-6
        return
    _compare(raster, mean, var, mask, name)


SHADOW_SCENE = scene(camera([0.0, 3.0, 4.5], [0.0, 0.3, 0.0], 45.0, 64, 48),
                     point_light([1.0, 4.0, 0.5], [30.0, 30.0, 30.0]),
                     sphere_on_floor("white", "white", height=0.8),
                     material("white", model="lambert", albedo=[0.7, 0.7, 0.7]))


def test_shadows_agree_with_reference(tmp_path, renderer):
    path = tmp_path / "s.toml"
    path.write_text(SHADOW_SCENE)
    scene = load_scene(path)
    cam = OrbitCamera.from_scene(scene)
    raster = renderer.render_arrays(scene, cam, supersample=4)[0]
    ref = pathtracer.ReferenceRenderer(scene, camera=cam, max_depth=1, seed=5, workers=2)
    try:
        ref.step(SPP)
        mean, var = ref.mean(), ref.variance()
    finally:
        ref.close()
    c = scene.camera
    # floor pixels whose whole square sees the plane, away from the sphere's silhouette, the
    # plane's border and the shadow edge (PCF blurs the raster's edge over ~3 shadow texels)
    mask = np.ones((c.height, c.width), bool)
    light = np.array([1.0, 4.0, 0.5])
    for off in ((0, 0), (1, 0), (0, 1), (1, 1), (0.5, 0.5)):
        d = camera_rays(c.position, c.target, c.up, c.fov_y, c.width, c.height, off)
        tp = hit_plane_y(c.position, d, 0.0)
        ts = hit_sphere(c.position, d, (0, 0.8, 0), 0.5)
        p = c.position + d * np.where(np.isfinite(tp), tp, 0)[..., None]
        mask &= np.isfinite(tp) & ~np.isfinite(ts) & (np.abs(p[..., 0]) < 2.8) & (np.abs(p[..., 2]) < 2.8)
        seg = light - p
        s = np.clip(np.sum((np.array([0, 0.8, 0]) - p) * seg, axis=-1) / np.sum(seg * seg, axis=-1), 0, 1)
        dist = np.linalg.norm(p + seg * s[..., None] - np.array([0, 0.8, 0]), axis=-1)
        mask &= np.abs(dist - 0.5) > 0.5 * 0.08
    assert mask.sum() > 1000
    _compare(raster, mean, var, mask, "lambert sphere over plane")
