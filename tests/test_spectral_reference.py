"""The spectral reference (hero-wavelength sampling) against the RGB reference, exact spectral
integrals and Snell's law per wavelength."""

from __future__ import annotations

import math

import numpy as np
import pytest

from spectral_harness import RGB_BODY
from viewer import spectral
from viewer.scene import load_scene

SCENE_RGB = """
[camera]
position = [0.0, 1.2, 4.0]
target = [0.0, 0.4, 0.0]
up = [0.0, 1.0, 0.0]
fov_y = 40.0
width = 24
height = 24

[render]
ibl = "off"

""" + RGB_BODY


def _render(path, spectral_on, spp, max_depth=1, overrides=()):
    from viewer.pathtracer import ReferenceRenderer

    sc = load_scene(path, overrides)
    r = ReferenceRenderer(sc, max_depth=max_depth, seed=5, workers=0, spectral=spectral_on)
    try:
        r.step(spp)
        assert r.bad_values == 0
        return r.mean(), r.variance(), r.is_spectral
    finally:
        r.close()


def test_spectral_matches_rgb_reference_on_an_rgb_scene(tmp_path):
    """RGB albedos under white point and directional light, direct light only: the upsampled
    spectra round-trip, so the spectral image equals the RGB one within noise. Per pixel the
    difference over its standard error is ~N(0, 1): at most 1% of the channels beyond 4 sigma,
    and the image means agree to 4 standard errors."""
    f = tmp_path / "rgb.toml"
    f.write_text(SCENE_RGB)
    a, va, sa = _render(f, False, 24)
    b, vb, sb = _render(f, True, 24)
    assert not sa and sb
    se = np.sqrt(va + vb)
    lit = se > 0
    z = np.abs(a - b)[lit] / se[lit]
    assert np.mean(z > 4.0) < 0.01, np.sort(z)[-10:]
    n = a.shape[0] * a.shape[1]
    se_mean = np.sqrt((va + vb).sum(axis=(0, 1))) / n
    diff = a.mean(axis=(0, 1)) - b.mean(axis=(0, 1))
    assert np.all(np.abs(diff) < 4 * se_mean + 1e-6), (diff, se_mean)


def test_gold_mirror_is_the_spectral_integral(tmp_path):
    """A polished gold sphere in a white constant environment: a camera ray reflects once, so
    the pixel at the sphere's centre (normal incidence) estimates to_rgb(R(0, lambda)) of the
    Johnson & Christy table, unclipped: (1.037, 0.728, 0.365). 64 spp x 4 wavelengths: the
    standard error per channel is ~1.5%; the RGB table holds the same value (unclipped)."""
    f = tmp_path / "gold.toml"
    f.write_text("""
[camera]
position = [0.0, 0.0, 6.0]
target = [0.0, 0.0, 0.0]
fov_y = 3.0
width = 3
height = 3
[environment]
constant = [1.0, 1.0, 1.0]
[render]
ibl = "off"
[[objects]]
mesh = "sphere"
material = "gold"
[materials.gold]
preset = "polished_gold"
""")
    img, var, on = _render(f, True, 64)
    assert on
    from viewer.brdf import spectral_fresnel as sf

    want = spectral.to_rgb(sf.spectral_reflectance("Au", 1.0), sf.GRID_NM)
    got = img.reshape(-1, 3).mean(axis=0)
    se = np.sqrt(var.reshape(-1, 3).sum(axis=0)) / 9
    np.testing.assert_array_less(np.abs(got - want), 4 * se + 2e-3)
    assert got[0] > 1.0  # beyond the Rec.709 gamut, as the spectrum says


def test_dispersive_material_switches_the_reference_to_spectral(tmp_path):
    from viewer.scene.materials import scene_is_dispersive

    f = tmp_path / "glass.toml"
    f.write_text(SCENE_RGB + """
[materials.glass]
model = "dielectric"
spectral = "SF11"
""")
    over = ["objects.1.material=glass"]
    sc = load_scene(f, over)
    assert scene_is_dispersive(sc)
    assert sc.materials["glass"].ior == pytest.approx(1.7847, abs=1e-3)
    assert not scene_is_dispersive(load_scene(f))
    img, _, on = _render(f, None, 2, max_depth=4, overrides=over)
    assert on and np.all(np.isfinite(img)) and img.max() > 0


def _deviation(n, apex, theta1):
    """Minimum-free prism deviation by Snell's law at both faces (angles in radians)."""
    t2 = math.asin(math.sin(theta1) / n)
    t3 = apex - t2
    t4 = math.asin(n * math.sin(t3))
    return theta1 + t4 - apex


@pytest.mark.parametrize("name", ["SF11", "BK7", "diamond"])
def test_prism_deviation_per_wavelength(name):
    """A 40 degree prism, light entering at 50 degrees: the spectral integrator's refraction
    (the dielectric model sampled with the parameters at one wavelength, ``params_at``) through
    both faces deviates the ray by Snell's law with n(lambda) of the table, and blue bends more."""
    from viewer import brdf
    from viewer.brdf import params_at

    model = brdf.get("dielectric")
    base = model.params(spectral=name)
    apex, theta1 = math.radians(40.0), math.radians(50.0)
    devs = []
    for lam in (420.0, 500.0, 589.3, 680.0):
        p = params_at(base, [lam] * 3)
        n = spectral.ior(name, lam).real
        assert p.ior == pytest.approx(n, abs=1e-12)
        # the prism's section in the x-z plane, apex up: outward normals of the two faces
        n1 = np.array([-math.cos(apex / 2), 0.0, math.sin(apex / 2)])
        n2 = np.array([math.cos(apex / 2), 0.0, math.sin(apex / 2)])
        t1 = np.array([math.sin(apex / 2), 0.0, math.cos(apex / 2)])    # along face 1, to the apex
        d1 = math.cos(theta1) * -n1 + math.sin(theta1) * t1

        def refract(d, normal):
            """The model's sampled refraction (u[0] near 1 picks transmission) in a frame whose
            z is the face's outward normal; returns the new direction of travel (world)."""
            x = np.array([normal[2], 0.0, -normal[0]])
            y = np.array([0.0, 1.0, 0.0])
            wo = -np.array([d @ x, d @ y, d @ normal])
            wi, w, _ = model.sample(p, wo, np.array([1.0 - 1e-12, 0.5]))
            assert wi[2] * wo[2] < 0 and np.all(w > 0)                   # through the face
            return wi[0] * x + wi[1] * y + wi[2] * normal

        out_w = refract(refract(d1, n1), n2)
        dev = math.acos(np.clip(np.dot(out_w, d1), -1.0, 1.0))
        assert dev == pytest.approx(_deviation(n, apex, theta1), abs=1e-9), lam
        devs.append(dev)
    assert all(a > b for a, b in zip(devs, devs[1:]))   # normal dispersion: blue deviates most
