"""Glass casts a translucent shadow in the raster (viewer/gl/shadow.py, shaders/passes/
shadow_glass.frag): the light under glass is the direct light times the interfaces' Fresnel
transmittance and Bouguer's exp(-sigma_a d) over the refracted path, against closed forms.

What the raster leaves out, and what the closed forms below therefore leave out too: the light
reflected back and forth inside the glass (a slab's direct transmittance (1 - R)^2 a is the first
term of (1 - R)^2 a / (1 - R^2 a^2); the rest is under R^2 = 0.17% of it for n = 1.5 at 30
degrees) and the caustic (light bent toward or away from a texel: an infinite slab bends none
away, and the centre of a sphere's shadow under light from straight above takes the straight
ray's share)."""

import textwrap

import numpy as np
import pytest

from viewer import brdf
from viewer.scene import load_scene

from render_util import camera_rays, hit_plane_y
from scene_text import camera, material, obj, render, scene, table

W = H = 64
SIGMA = [0.5, 2.0, 4.0]   # per metre: a warm (red-passing) absorbing glass


def _load(tmp_path, text, name="s"):
    p = tmp_path / f"{name}.toml"
    p.write_text(textwrap.dedent(text))
    return load_scene(str(p))


def _top_view(*parts, light_dir, irradiance=3.0):
    """The floor seen from straight above (no environment, no MSAA) under one directional
    light: a pixel's radiance is albedo / pi x E cos(theta) x what the light keeps."""
    return scene(camera([0.0, 4.0, 1e-3], [0.0, 0.0, 0.0], 40.0, W, H, up=[0.0, 0.0, -1.0]),
                 render(ibl="off", shadows=True, msaa=0),
                 table("[lights]", type="directional", direction=[float(v) for v in light_dir],
                       irradiance=[irradiance] * 3),
                 obj("plane", "floor", scale=3.0), material("floor", model="lambert", albedo=[0.8, 0.8, 0.8]),
                 *parts)


def _floor_xz(scene_):
    c = scene_.camera
    d = camera_rays(c.position, c.target, c.up, c.fov_y, W, H)
    t = hit_plane_y(c.position, d, 0.0)
    with np.errstate(invalid="ignore"):
        p = np.asarray(c.position, float) + d * t[..., None]
    return p[..., 0], p[..., 2]


def test_slab_shadow_is_the_exact_direct_transmittance(tmp_path, renderer):
    # A plane-parallel slab (the built-in cube scaled to 1.2 x 0.2 x 1.2, 0.9 to 1.1 above the
    # floor) under a directional light at theta = 30 degrees: the direct light through it keeps
    # T = (1 - R(30 deg))^2 exp(-sigma_a t / cos(theta_t)), sin(theta_t) = sin(30 deg) / 1.5 (two
    # interfaces at the same pair of angles; the path through the glass is the refracted one).
    # The light travels toward -x; the shadow's part outside the slab's own footprint (seen from
    # above) lies at x in [-0.1 - 1.1 tan 30, -0.1), the floor inside it a little from its edges.
    th = np.radians(30.0)
    text = _top_view(obj("cube", "glass", scale=[0.6, 0.1, 0.6], translate=[0.5, 1.0, 0.0]),
                     material("glass", model="dielectric", ior=1.5, sigma_a=SIGMA),
                     light_dir=[-np.sin(th), -np.cos(th), 0.0])
    sc = _load(tmp_path, text)
    img = renderer.render_arrays(sc, width=W, height=H)[0]
    x, z = _floor_xz(sc)
    lit_value = 0.8 / np.pi * 3.0 * np.cos(th)
    shadow = (x > -0.1 - 0.9 * np.tan(th) + 0.05) & (x < -0.1 - 0.05) & (np.abs(z) < 0.5)
    lit = (x < -0.1 - 1.1 * np.tan(th) - 0.1)
    assert shadow.sum() > 30 and lit.sum() > 30
    R = float(brdf.fresnel_dielectric(np.cos(th), 1.5))
    cos_t = np.sqrt(1.0 - (np.sin(th) / 1.5) ** 2)
    a = np.exp(-np.asarray(SIGMA) * 0.2 / cos_t)
    direct = (1.0 - R) ** 2 * a
    got = img[shadow].mean(axis=0) / lit_value
    print(f"slab at 30 deg: shadow / lit {got}, exact direct transmittance {direct}, "
          f"relative error {got / direct - 1.0}; with internal reflections it would be "
          f"{(1 - R) ** 2 * a / (1 - R ** 2 * a ** 2)}")
    np.testing.assert_allclose(img[lit], lit_value, rtol=1e-5)
    # the optical depth is stored as half floats (11-bit mantissa): tau ~ 1 to 5e-4 relative
    np.testing.assert_allclose(got, direct, rtol=1.5e-3)
    # the coloured shadow: its channel ratios are those of exp(-sigma_c d) (Fresnel is grey)
    np.testing.assert_allclose(got / got[0], a / a[0], rtol=1.5e-3)


def test_sphere_shadow_under_light_from_above(tmp_path, renderer):
    # A glass ball of radius r = 0.4 lit from straight above. The vertical ray at distance rho
    # from the axis meets it at sin(theta_i) = rho / r, crosses it along the refracted chord
    # 2 r cos(theta_t) (sin(theta_t) = sin(theta_i) / 1.5) and leaves at theta_t inside, whose
    # transmittance equals the entry's: T = (1 - R(theta_i))^2 exp(-sigma_a 2 r cos(theta_t)),
    # drawn where the straight ray meets the floor (the caustic left out). The straight chord
    # 2 r cos(theta_i) would be 8% shorter at rho = 0.2 (blue: 0.78 x the shadow).
    r = 0.4
    text = _top_view(obj("sphere", "glass", scale=r, translate=[0.0, 1.0, 0.0]),
                     material("glass", model="dielectric", ior=1.5, sigma_a=SIGMA),
                     light_dir=[0.0, -1.0, 0.0])
    # seen from the side of the ball, close: its own image does not hide the centre of its shadow
    text = text.replace("position = [0.0, 4.0, 0.001]", "position = [0.0, 1.2, 1.6]").replace(
        "fov_y = 40.0", "fov_y = 20.0")
    sc = _load(tmp_path, text)
    img = renderer.render_arrays(sc, width=W, height=H)[0]
    x, z = _floor_xz(sc)
    rho = np.sqrt(x ** 2 + z ** 2)
    inner = rho < 0.2
    lit = (rho > 0.6) & np.isfinite(rho)
    assert inner.sum() > 20
    lit_value = 0.8 / np.pi * 3.0
    ci = np.sqrt(1.0 - (rho[inner] / r) ** 2)
    ct = np.sqrt(1.0 - (1.0 - ci ** 2) / 1.5 ** 2)
    R = brdf.fresnel_dielectric(ci, 1.5)
    expect = ((1.0 - R) ** 2)[:, None] * np.exp(-np.asarray(SIGMA)[None, :] * (2.0 * r * ct)[:, None])
    got = img[inner] / lit_value
    err = np.abs(got / expect - 1.0)
    print(f"sphere from above, {inner.sum()} pixels within rho < 0.2: relative error mean {err.mean(axis=0)}, "
          f"max {err.max(axis=0)}")
    if lit.any():
        np.testing.assert_allclose(img[lit], lit_value, rtol=1e-4)
    # the icosphere's facets (5 subdivisions: the analytic normal is used, the face's position
    # lies up to 1e-3 r inside), the shadow texels' bilinear filtering (a texel is 0.008 wide, the
    # transmittance changes up to 2% over one for blue at rho = 0.2, linearly: the filter's error
    # is second order) and tau in half floats: 0.5% per pixel, 0.2% on average
    assert err.max() < 0.005 and err.mean() < 0.002


def test_scene_without_glass_compiles_no_glass_shadow(tmp_path, renderer):
    # scenes without transmissive objects draw with the programs they had (no glass atlas, no
    # GLASS_SHADOW variant): their images cannot change
    from viewer.gl.shadow import glass_shadows

    opaque = _load(tmp_path, _top_view(obj("sphere", "ball", scale=0.4, translate=[0.0, 1.0, 0.0]),
                                       material("ball", model="lambert", albedo=[0.5, 0.5, 0.5]),
                                       light_dir=[0.0, -1.0, 0.0]), "opaque")
    assert not glass_shadows(opaque)
    assert not any(k.endswith(":gshadow") or ":gshadow:" in k for k in renderer.forward_keys(opaque).values())
    renderer.render(opaque, width=16, height=16)
    assert renderer.passes.shadows.glass_atlas is None
    glass = _load(tmp_path, _top_view(obj("sphere", "ball", scale=0.4, translate=[0.0, 1.0, 0.0]),
                                      material("ball", model="dielectric", ior=1.5),
                                      light_dir=[0.0, -1.0, 0.0]), "glass")
    assert glass_shadows(glass)
    assert all(":gshadow" in k for k in renderer.forward_keys(glass).values())
    glass.render.shadows = False
    assert not glass_shadows(glass)


@pytest.mark.parametrize("opaque_first", [True, False])
def test_glass_behind_an_opaque_caster_adds_nothing(tmp_path, renderer, opaque_first):
    # the glass faces are depth-tested against the opaque casters: an opaque plate above the glass
    # slab leaves the floor under both in the plate's full shadow, and the plate itself unshadowed
    plate = obj("cube", "plate", scale=[0.8, 0.02, 0.8], translate=[0.0, 2.0, 0.0])
    slab = obj("cube", "glass", scale=[0.6, 0.1, 0.6], translate=[0.0, 1.0, 0.0])
    parts = (plate, slab) if opaque_first else (slab, plate)
    text = _top_view(*parts, material("glass", model="dielectric", ior=1.5, sigma_a=SIGMA),
                     material("plate", model="lambert", albedo=[0.5, 0.5, 0.5]), light_dir=[0.0, -1.0, 0.0])
    sc = _load(tmp_path, text)
    img = renderer.render_arrays(sc, width=W, height=H)[0]
    # from straight above the camera sees the plate: lit fully (0.5 / pi x 3)
    mid = img[H // 2 - 3:H // 2 + 3, W // 2 - 3:W // 2 + 3]
    np.testing.assert_allclose(mid, 0.5 / np.pi * 3.0, rtol=1e-5)
