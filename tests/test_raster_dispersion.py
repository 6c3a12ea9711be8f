"""Dispersion in the rasterizer's traced chains: a spectral dielectric refracts each colour channel
with its own index, the channel's spectral centroid of n(lambda) (viewer.spectral.channel_ior),
so a prism or a diamond shows colour fringes; against the spectral reference (hero wavelengths)."""

import textwrap
import tomllib

import numpy as np
import pytest

from viewer import spectral
from viewer.scene import parse_scene


def test_channel_ior_is_the_weighted_centroid_and_ordered():
    from viewer.spectral import colorimetry

    wl = colorimetry.tables()[0]
    w = colorimetry.weights()
    for name in ("BK7", "F2", "SF11", "SiO2", "H2O", "diamond", "sapphire"):
        n_rgb = spectral.channel_ior(name)
        n = spectral.ior(name, wl).real
        # independent sum: the definition written out with a trapezoid rule on the same grid
        for c in range(3):
            want = np.trapezoid(w[c] * n, wl) / np.trapezoid(w[c], wl)
            assert abs(n_rgb[c] - want) < 2e-4, (name, c)  # the 1 nm sum vs trapezoid: ends only
        # normal dispersion (n falls with wavelength): blue bends most
        assert n_rgb[2] > n_rgb[1] > n_rgb[0], (name, n_rgb)
        assert n.min() < n_rgb.min() and n_rgb.max() < n.max()
    # where the channels sit: SF11's red, green and blue indices are those of about 640, 545 and
    # 440 nm (the centroids of the Rec.709 weights: n is nearly linear over each channel)
    sf11 = spectral.channel_ior("SF11")
    at = spectral.ior("SF11", np.array([640.0, 545.0, 440.0])).real
    np.testing.assert_allclose(sf11, at, atol=1.5e-3)
    with pytest.raises(KeyError, match="unknown spectral material"):
        spectral.channel_ior("unobtainium")


def test_chain_eta_of_spectral_glass():
    from viewer.gl.raytrace import chain_eta

    s = _scene(PRISM)
    np.testing.assert_array_equal(chain_eta(s.materials["flint"]), spectral.channel_ior("SF11"))
    plain = _scene(PRISM.replace('spectral = "SF11"', "ior = 1.7"))
    np.testing.assert_array_equal(chain_eta(plain.materials["flint"]), [1.7, 1.7, 1.7])


PRISM = """
[camera]
position = [0.0, 0.15, 2.6]
target = [0.0, 0.0, 0.0]
up = [0.0, 1.0, 0.0]
fov_y = 30.0
width = 40
height = 40

[environment]
map = "studio"

[render]
ibl = "split_sum"
raytrace = true

[[objects]]
mesh = "prism"
material = "flint"
scale = 0.6
rotate_y_deg = 90.0

[materials.flint]
model = "dielectric"
spectral = "SF11"
"""


def _scene(text):
    return parse_scene(tomllib.loads(textwrap.dedent(text)), None)


def test_each_channel_refracts_with_its_own_index(renderer):
    # "rays split accordingly": channel c of the dispersive image equals channel c of an image
    # whose glass has the single index n_c, for each c (same chain, one channel each); and the
    # channels really part: the three single-index images differ inside the prism.
    s = _scene(PRISM)
    disp = renderer.render_arrays(s, width=40, height=40)[0]
    n_rgb = spectral.channel_ior("SF11")
    singles = []
    for c in range(3):
        one = _scene(PRISM.replace('spectral = "SF11"', f"ior = {float(n_rgb[c])!r}"))
        singles.append(renderer.render_arrays(one, width=40, height=40)[0])
        np.testing.assert_allclose(disp[..., c], singles[-1][..., c], atol=1e-5)
    part = np.abs(singles[2] - singles[0]).max(axis=-1)
    assert (part > 0.05).sum() > 10, "no pixel where red and blue leave the prism differently"
    d_line = _scene(PRISM.replace('spectral = "SF11"', "ior = 1.78472"))
    grey = renderer.render_arrays(d_line, width=40, height=40)[0]
    assert np.abs(disp - grey).max() > 0.05  # the fringes the single-index raster lacks
