"""What the spectral engine tests share (no test module imports another): rendering one scene
with a given engine and mode, the block z-score statistics of two estimates of the same image
(``reference_harness.agreement``'s, for any pair of estimates -- GPU against CPU, spectral
against RGB, an engine against an exact image -- and any image size), and the scenes.

Two estimators of the same integral agree within noise when, per ``BLOCK`` x ``BLOCK`` block of
pixels, the difference of the means over its standard error (both estimates' variance of the
mean) is a standard normal: mean z^2 near 1 and no |z| beyond 5 (P < 6e-7 per value for a
normal), and the image means agree within the stated tolerance or 4 standard errors.
"""

from __future__ import annotations

import tomllib
from dataclasses import dataclass

import numpy as np

from viewer.scene import SCENE_DIR, parse_scene

BLOCK = 4


@dataclass
class Estimate:
    mean: np.ndarray          # (H, W, 3) float64
    var: np.ndarray           # (H, W, 3) variance of the mean
    bad: int                  # bad values the engine counted
    spectral: bool
    spp: int


def gpu(ctx, scene, spp, size=(24, 16), max_depth=8, seed=1, spectral=None, **estimator) -> Estimate:
    from viewer.gpupt import GpuReferenceRenderer

    with GpuReferenceRenderer(scene, width=size[0], height=size[1], max_depth=max_depth, seed=seed, ctx=ctx,
                              spectral=spectral, **estimator) as g:
        g.step(spp)
        return Estimate(g.mean().astype(np.float64), g.variance().astype(np.float64), g.bad_values,
                        g.is_spectral, spp)


def cpu(scene, spp, size=(24, 16), max_depth=8, seed=1, spectral=None, **estimator) -> Estimate:
    from viewer.pathtracer import ReferenceRenderer

    with ReferenceRenderer(scene, width=size[0], height=size[1], max_depth=max_depth, seed=seed, workers=0,
                           spectral=spectral, **estimator) as c:
        c.step(spp)
        return Estimate(c.mean().astype(np.float64), c.variance().astype(np.float64), c.bad_values,
                        c.is_spectral, spp)


def blocks(a, block=BLOCK, scale=1.0):
    h, w = a.shape[:2]
    return a.reshape(h // block, block, w // block, block, -1).sum(axis=(1, 3)) * scale


def agreement(a: Estimate, b: Estimate, block=BLOCK) -> dict:
    """Block z-scores and image means of two estimates (b is the reference for ``rel``)."""
    n = block * block
    bm_a, bm_b = blocks(a.mean, block, 1 / n), blocks(b.mean, block, 1 / n)
    bv = blocks(a.var + b.var, block, 1 / n**2)
    # pixels seeing only a constant background have zero variance in an RGB engine; their means
    # differ by float32 rounding of the GPU's sums (about 1e-7 relative per addition): floor at 1e-5
    bv = bv + (1e-5 * np.abs(bm_b)) ** 2 + 1e-30
    z = (bm_a - bm_b) / np.sqrt(bv)
    # mean z^2 over the blocks with noise: blocks of black background (no variance in either
    # estimate, z = 0) would only dilute it
    noisy = blocks(a.var + b.var, block) > 0
    total = b.mean.sum()
    return dict(z2=float(np.mean(z[noisy] ** 2)) if noisy.any() else 0.0, zmax=float(np.abs(z).max()),
                n_z=int(noisy.sum()),
                rel=float(a.mean.sum() / total - 1.0) if total > 0 else 0.0,
                sigma=float(np.sqrt(a.var.sum() + b.var.sum()) / total) if total > 0 else 0.0,
                bad=(a.bad, b.bad), mean_a=float(a.mean.mean()), mean_b=float(b.mean.mean()))


def check(s, name, mean_tol=0.005):
    """Agreement within noise: no bad value, |z| < 5 everywhere, mean z^2 < 1.6 (with a few
    hundred blocks x channels the mean of z^2 has a standard deviation near 0.1; 1.6 leaves room
    for the heavy tails of low-spp variance estimates), and the image means within ``mean_tol``
    or 4 standard errors."""
    assert s["bad"] == (0, 0), (name, s)
    assert s["mean_b"] > 0, (name, s)
    assert s["zmax"] < 5.0, (name, s)
    assert s["z2"] < 1.6, (name, s)
    assert abs(s["rel"]) < max(mean_tol, 4 * s["sigma"]), (name, s)


def toml_scene(text: str, label: str):
    return parse_scene(tomllib.loads(text), None, label=label, base_dir=SCENE_DIR)


_CAMERA = """
[camera]
position = [0.0, 1.2, 4.0]
target = [0.0, 0.4, 0.0]
up = [0.0, 1.0, 0.0]
fov_y = 40.0
width = 24
height = 16

[render]
ibl = "off"
"""

# RGB materials only, under white point and directional light (no environment): the spectral
# estimator upsamples every colour, so one bounce round-trips exactly (the same scene as the CPU
# engine's RGB / spectral test)
RGB_BODY = """
[[lights]]
type = "point"
position = [2.0, 4.0, 3.0]
intensity = [12.0, 12.0, 12.0]

[[lights]]
type = "directional"
direction = [-0.3, -1.0, -0.2]
irradiance = [0.6, 0.6, 0.6]

[[objects]]
mesh = "sphere"
material = "red"
translate = [-0.6, 0.5, 0.0]
scale = 0.5

[[objects]]
mesh = "sphere"
material = "plastic"
translate = [0.6, 0.5, 0.0]
scale = 0.5

[[objects]]
mesh = "plane"
material = "floor"
scale = 3.0

[materials.red]
model = "lambert"
albedo = [0.8, 0.15, 0.05]

[materials.plastic]
model = "microfacet"
fresnel = "dielectric"
ior = 1.5
alpha = 0.3
kd = [0.1, 0.45, 0.7]

[materials.floor]
model = "oren_nayar"
albedo = [0.3, 0.5, 0.2]
sigma = 20.0
"""
RGB_SCENE = _CAMERA + RGB_BODY


# Every spectral category under a grey sky (a constant environment: no point light seen through
# glass, whose caustic on the floor neither engine samples well at a few spp): an SF11 prism
# (smooth, dispersive: the hero alone past it), rough BK7 with absorption (dispersive with
# next-event estimation, 4x hero share, Bouguer per wavelength), rough gold (a spectral table at
# four wavelengths), varnished gold (a layered material whose nested base is spectral) and an
# RGB floor.
DISPERSIVE_SCENE = """
[camera]
position = [0.0, 1.0, 3.6]
target = [0.0, 0.45, 0.0]
up = [0.0, 1.0, 0.0]
fov_y = 42.0
width = 24
height = 16

[render]
ibl = "off"

[environment]
constant = [0.6, 0.65, 0.7]

[[objects]]
mesh = "prism"
material = "flint"
scale = 0.45
translate = [-0.9, 0.5, 0.0]
rotate_y_deg = 90.0

[[objects]]
mesh = "sphere"
material = "frosted"
translate = [-0.1, 0.4, 0.3]
scale = 0.4

[[objects]]
mesh = "sphere"
material = "gold"
translate = [0.7, 0.4, 0.0]
scale = 0.4

[[objects]]
mesh = "sphere"
material = "varnish"
translate = [0.3, 0.25, 0.9]
scale = 0.25

[[objects]]
mesh = "plane"
material = "floor"
scale = 3.0

[materials.flint]
model = "dielectric"
spectral = "SF11"

[materials.frosted]
model = "dielectric"
spectral = "BK7"
alpha = 0.3
sigma_a = [0.4, 0.1, 1.2]

[materials.gold]
preset = "gold"

[materials.varnish]
preset = "varnished_gold"

[materials.floor]
model = "lambert"
albedo = [0.5, 0.45, 0.4]
"""

# A white furnace: lossless materials (a white Lambert floor, smooth SF11 and diamond spheres:
# dispersive, hero-only past them) in a constant white environment: the radiance is 1 everywhere,
# at every wavelength, so every pixel's RGB is 1 (within the colour noise of four wavelengths).
FURNACE_SCENE = """
[camera]
position = [0.0, 1.0, 3.6]
target = [0.0, 0.45, 0.0]
up = [0.0, 1.0, 0.0]
fov_y = 42.0
width = 24
height = 16

[render]
ibl = "off"

[environment]
constant = [1.0, 1.0, 1.0]

[[objects]]
mesh = "sphere"
material = "flint"
translate = [-0.5, 0.5, 0.0]
scale = 0.5

[[objects]]
mesh = "sphere"
material = "diamond"
translate = [0.6, 0.4, 0.2]
scale = 0.4

[[objects]]
mesh = "plane"
material = "floor"
scale = 3.0

[materials.flint]
model = "dielectric"
spectral = "SF11"

[materials.diamond]
model = "dielectric"
spectral = "diamond"

[materials.floor]
model = "lambert"
albedo = [1.0, 1.0, 1.0]
"""

# A polished gold sphere filling a 3 x 3 image in a white constant environment: a camera ray
# reflects once at near-normal incidence (the view spans 3 degrees)
GOLD_MIRROR_SCENE = """
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
"""
