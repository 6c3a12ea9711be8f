"""Caustics through dispersive glass: the photon map splits them by wavelength.

Under the spectral estimator, where a delta surface's values depend on the wavelength (SF11
flint's n(lambda)), each photon carries one wavelength bin drawn uniformly, is refracted with
n at that wavelength, and deposits N_BINS W(lambda) times its spectral estimate (W the bin's CIE
RGB weights), in both engines (viewer/reference_common/caustics.py ``spectral_photons``).

Oracles:

1. SF11's n(lambda) in the library is Schott's published Sellmeier fit (the independent truth
   the prism's geometry uses below).
2. A 60 degree SF11 prism under a directional light of irradiance 1 above a floor: the rays
   entering one face leave through the base (the library's n(lambda) of test 1; a 2-D problem: the light has no component along
   the prism's axis; a black board above the prism shades its other face, whose mirror
   reflection would land in the same place). Traced in closed form (Snell and the unpolarized Fresnel transmittance at
   both faces), every ray of one wavelength lands on the floor at a point affine in where it
   entered the face, and the entry points are uniform over the face, so the photons' centroid of
   channel c is sum_lambda W_c(lambda) T(lambda) x(lambda) / sum_lambda W_c(lambda) T(lambda)
   with x(lambda) the landing point of the ray through the face's middle, and the channel's
   power per pass is E A sum_lambda W_c T (A: the face's area across the beam). Blue bends more
   (n is larger): its centroid lies beyond green's, green's beyond red's.
3. Where the path tracer converges (the same prism under a constant sky), ``photon`` equals
   ``path`` in the spectral estimator.
4. The GPU engine's photons with wavelengths agree with the CPU engine's (block z-test).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from viewer import brdf
from viewer.reference_common import caustics
from viewer.reference_common.setup import RenderSetup
from viewer.reference_common.wavelengths import bin_wavelengths, bin_weights
from viewer.scene import load_scene_text

# Schott SF11 (the glass catalogue's Sellmeier coefficients; lambda in micrometres)
SF11_B = (1.73759695, 0.313747346, 1.89878101)
SF11_C = (0.013188707, 0.0623068142, 155.23629)

THETA = math.radians(-87.1)   # the light's direction in the xy plane: near the right face's minimum deviation
PRISM_SCALE, PRISM_Y = 0.3, 1.0
PASSES, PHOTONS = 8, 1 << 16


def sellmeier_sf11(lam_nm):
    l2 = (np.asarray(lam_nm, dtype=np.float64) / 1000.0) ** 2
    return np.sqrt(1.0 + sum(b * l2 / (l2 - c) for b, c in zip(SF11_B, SF11_C)))


OVERVIEW = ([-1.0, 3.0, 3.0], [-1.2, 0.3, 0.0], [0.0, 1.0, 0.0], 50.0)
#: straight down onto the floor where the caustic lands (x from -2.7 to -1.1 across the image)
ABOVE_CAUSTIC = ([-1.9, 2.5, 0.0], [-1.9, 0.0, 0.0], [0.0, 0.0, -1.0], 9.1)   # for a 16 x 4 image


def prism_text(env: str = "", light: bool = True, size: int = 32, view=OVERVIEW) -> str:
    lights = (f"""
[[lights]]
type = "directional"
direction = [{math.cos(THETA)}, {math.sin(THETA)}, 0.0]
irradiance = [1.0, 1.0, 1.0]
""" if light else "")
    # (with the light) a black board above the prism shades its left face
    board = ("""
[[objects]]
mesh = "cube"
material = "black"
scale = [0.5, 0.01, 1.2]
translate = [-0.516, 1.6, 0.0]
""" if light else "")
    return f"""
[camera]
position = {view[0]}
target = {view[1]}
up = {view[2]}
fov_y = {view[3]}
width = {size}
height = {size}
{env}
{lights}
[[objects]]
mesh = "plane"
material = "floor"
scale = 3.0

[[objects]]
mesh = "prism"
material = "flint"
scale = [{PRISM_SCALE}, {PRISM_SCALE}, 1.0]
translate = [0.0, {PRISM_Y}, 0.0]

{board}
[materials.floor]
model = "lambert"
albedo = [0.5, 0.5, 0.5]

[materials.black]
model = "lambert"
albedo = [0.0, 0.0, 0.0]

[materials.flint]
model = "dielectric"
spectral = "SF11"
"""


# ----------------------------------------------------------------------------- the closed form

def _refract(d, n, eta):
    """Snell: d unit travelling, n the unit normal against d, eta = n_from / n_to; None: TIR."""
    c = -float(np.dot(n, d))
    k = 1.0 - eta * eta * (1.0 - c * c)
    return None if k < 0 else eta * d + (eta * c - math.sqrt(k)) * n


def _transmittance(ci, ct, n1, n2):
    rs = (n1 * ci - n2 * ct) / (n1 * ci + n2 * ct)
    rp = (n2 * ci - n1 * ct) / (n2 * ci + n1 * ct)
    return 1.0 - 0.5 * (rs * rs + rp * rp)


def prism_corners():
    """The prism's section (apex, lower left, lower right; counter-clockwise) in the xy plane."""
    tri = np.array([[0.0, 1.0], [-math.sqrt(0.75), -0.5], [math.sqrt(0.75), -0.5]])
    return tri * PRISM_SCALE + [0.0, PRISM_Y]


def landing(n):
    """(x on the floor, transmittance) of the ray of index ``n`` entering the right face (apex
    to lower right) at its middle and leaving through the base."""
    tri = prism_corners()
    d = np.array([math.cos(THETA), math.sin(THETA)])
    a, b = tri[2], tri[0]                                # right face: lower right -> apex (ccw)
    p = 0.5 * (a + b)
    e = b - a
    out = np.array([e[1], -e[0]]) / np.linalg.norm(e)   # outward normal of a ccw edge
    dn = _refract(d, out, 1.0 / n)
    T = _transmittance(-np.dot(out, d), -np.dot(out, dn), 1.0, n)
    # inside: to the base (y = the lower corners' y), whose outward normal is -y
    yb = tri[1][1]
    t = (yb - p[1]) / dn[1]
    q = p + t * dn
    assert tri[1][0] <= q[0] <= tri[2][0], "the middle ray leaves through the base"
    base_out = np.array([0.0, -1.0])
    d2 = _refract(dn, -base_out, n)
    assert d2 is not None, "no total internal reflection at the base"
    T *= _transmittance(np.dot(base_out, dn), np.dot(base_out, d2), n, 1.0)
    return q[0] - q[1] * d2[0] / d2[1], T


def right_face_area():
    """The right face's area across the beam (length 2 along z)."""
    tri = prism_corners()
    e = tri[0] - tri[2]
    out = np.array([e[1], -e[0]]) / np.linalg.norm(e)
    d = np.array([math.cos(THETA), math.sin(THETA)])
    return float(np.linalg.norm(e)) * abs(float(np.dot(out, d))) * 2.0


def flint_index():
    """n at every bin of SF11 as the renderers use it (``brdf.params_at``; the first test holds
    it to the published Sellmeier fit)."""
    p = load_scene_text(prism_text()).materials["flint"]
    return np.array([brdf.params_at(p, [v] * 3)["ior"] for v in bin_wavelengths()])


def predicted_centroids():
    """(centroid x per channel, power per channel per pass) of the photons through the right face."""
    n = flint_index()
    xs, ts = np.array([landing(v) for v in n]).T
    w = bin_weights() * ts[:, None]                     # (420, 3): W_c(lambda) T(lambda)
    return (w * xs[:, None]).sum(axis=0) / w.sum(axis=0), right_face_area() * w.sum(axis=0)


# ----------------------------------------------------------------------------- the tests

def test_sf11_index_is_the_published_sellmeier_fit():
    p = load_scene_text(prism_text()).materials["flint"]
    lam = np.array([400.0, 486.1, 587.6, 656.3, 700.0])
    ours = np.array([brdf.params_at(p, [v] * 3)["ior"] for v in lam])
    # 5e-4: the library's table of n(lambda) is interpolated between its samples (3.0e-4 off the
    # fit at 400 nm, 1e-7 at the d line); the prism below uses the library's n, this ties it to Schott's
    assert np.allclose(ours, sellmeier_sf11(lam), atol=5e-4), (ours, sellmeier_sf11(lam))
    assert abs(float(sellmeier_sf11(587.56)) - 1.78472) < 1e-4


def _cpu_prism_photons(text, passes=PASSES):
    from viewer.pathtracer.photons import integrator_for

    setup = RenderSetup.from_scene(load_scene_text(text), width=32, height=32, max_depth=4, integrator="photon")
    setup.extra.update(spectral=True, photons_per_pass=PHOTONS)
    assert caustics.spectral_photons(setup)
    it = integrator_for(setup)
    return [it.caustics.photons(7, i) for i in range(1, passes + 1)]


def test_prism_splits_its_caustic_by_wavelength():
    """Centroids and power of the caustic per channel against the closed form, each within four
    standard errors (the spread of the passes' values); blue lands beyond green beyond red."""
    want_x, want_power = predicted_centroids()
    sums = []
    for pos, _dirs, flux, _n in _cpu_prism_photons(prism_text()):
        rgb = caustics.flux_to_rgb(flux[:, 0], flux[:, 1].astype(np.int64))
        x = pos[:, 0]
        sel = (x > -3.0) & (x < -1.0) & (pos[:, 1] < 1e-6)   # on the floor where the right face's rays land (-2.5 .. -1.3)
        sums.append(np.concatenate([rgb[sel].sum(axis=0), (rgb[sel] * x[sel, None]).sum(axis=0)]))
    sums = np.array(sums)                                     # (passes, 6)
    power = sums[:, :3].mean(axis=0)
    power_se = sums[:, :3].std(axis=0, ddof=1) / math.sqrt(PASSES)
    assert np.all(np.abs(power - want_power) < 4.0 * power_se + 1e-3 * want_power), (power, want_power, power_se)
    # the centroid is a ratio of means: its standard error by the delta method over passes
    cx = sums[:, 3:].mean(axis=0) / power
    resid = sums[:, 3:] - cx * sums[:, :3]
    cx_se = resid.std(axis=0, ddof=1) / math.sqrt(PASSES) / power
    assert np.all(np.abs(cx - want_x) < 4.0 * cx_se + 1e-3), (cx, want_x, cx_se)
    red, green, blue = cx
    assert blue < green - 4 * cx_se[1] and green < red - 4 * cx_se[0], cx   # the light bends toward -x
    assert want_x[0] - want_x[2] > 0.2                           # the colours are far apart: the test sees them


def test_rgb_photons_do_not_split():
    """The control: without wavelengths (the RGB estimator) the prism's photons refract with one
    index, so the three channels' centroids coincide."""
    from viewer.pathtracer.photons import integrator_for

    setup = RenderSetup.from_scene(load_scene_text(prism_text()), width=32, height=32, max_depth=4,
                                   integrator="photon")
    setup.extra["photons_per_pass"] = PHOTONS
    assert not caustics.spectral_photons(setup)
    pos, _d, flux, _n = integrator_for(setup).caustics.photons(7, 1)
    sel = (pos[:, 0] > -3.0) & (pos[:, 0] < -1.0) & (pos[:, 1] < 1e-6)
    cx = (flux[sel] * pos[sel, :1]).sum(axis=0) / flux[sel].sum(axis=0)
    assert np.ptp(cx) < 1e-9


def _image_passes(make, n):
    out, prev = [], None
    with make() as r:
        for _ in range(n):
            r.step(1)
            s = np.asarray(r.state()[0], np.float64)
            out.append(s if prev is None else s - prev)
            prev = s
        assert r.bad_values == 0
    return np.stack(out)


SKY = """
[environment]
constant = [1.0, 1.0, 1.0]
"""


#: straight down onto the prism and the floor around it (for the sky)
ABOVE_PRISM = ([0.0, 3.0, 0.0], [0.0, 0.0, 0.0], [0.0, 0.0, -1.0], 25.0)


@pytest.mark.slow   # 2 x 64 spectral passes: 7-40 s by the load (one worker); at 24 passes counting the glass's light twice was only 3.5 standard errors off
def test_spectral_photon_equals_path_under_a_sky():
    """Under a constant sky (a broad light the path tracer finds through the prism) the floor's
    light through the glass is the photon map's under ``photon`` and the path tracer's under
    ``path``: the image sums agree within four standard errors."""
    from viewer.pathtracer import ReferenceRenderer

    sc = load_scene_text(prism_text(SKY, light=False, size=16, view=ABOVE_PRISM))
    totals = {}
    for name in ("photon", "path"):
        imgs = _image_passes(lambda: ReferenceRenderer(sc, width=16, height=16, max_depth=6, seed=4, workers=0,
                                                       integrator=name, spectral=True), 64)
        t = imgs.sum(axis=(1, 2, 3))
        totals[name] = (t.mean(), t.std(ddof=1) / math.sqrt(t.size))
    (mp, sp), (mq, sq) = totals["photon"], totals["path"]
    se = math.hypot(sp, sq)
    assert se < 0.015 * mq, (se, mq)   # the power to see that 6.3% at 4 standard errors
    assert abs(mp - mq) < 4.0 * se + 0.005 * mq, (mp, mq, se)   # 0.005: the kernel's blur across the caustic's edges
    # (counting the caustic paths twice, no exclusion, put the photon image 6.3% above the path one)


def test_gpu_photons_with_wavelengths_agree_with_cpu(gl_ctx):
    """The GPU engine's photon pass with wavelengths (PHOTON_WAVELENGTHS) against the CPU
    engine's, on the floor where the prism's caustic lands, seen from above (16 x 4 pixels, the
    colours' centroids about 5 pixels apart): per 4 x 4 block and channel, the difference of the
    means over its standard error (from the spread over passes) stays under 4.5, and the image
    sums agree within 4 standard errors."""
    from viewer.gpupt import GpuReferenceRenderer
    from viewer.pathtracer import ReferenceRenderer

    sc = load_scene_text(prism_text(size=16, view=ABOVE_CAUSTIC))
    # 16 passes: the same test with RGB photons on the GPU side (no split) gave max |z| 5.5 at 12
    n = 16
    g = _image_passes(lambda: GpuReferenceRenderer(sc, width=16, height=4, max_depth=4, seed=3, ctx=gl_ctx,
                                                   integrator="photon", spectral=True), n)
    c = _image_passes(lambda: ReferenceRenderer(sc, width=16, height=4, max_depth=4, seed=5, workers=0,
                                                integrator="photon", spectral=True), n)
    bg, bc = (x.reshape(n, 1, 4, 4, 4, 3).mean(axis=(2, 4)) for x in (g, c))
    var = bg.var(axis=0, ddof=1) / n + bc.var(axis=0, ddof=1) / n
    z = (bg.mean(axis=0) - bc.mean(axis=0)) / np.sqrt(var + (1e-4 * np.abs(bc.mean(axis=0))) ** 2 + 1e-30)
    assert np.abs(z).max() < 4.5, z
    sg, scp = g.sum(axis=(1, 2, 3)), c.sum(axis=(1, 2, 3))
    se = math.sqrt(sg.var(ddof=1) / n + scp.var(ddof=1) / n)
    assert abs(sg.mean() - scp.mean()) < 4.0 * se, (sg.mean(), scp.mean(), se)
    assert se < 0.1 * scp.mean()
