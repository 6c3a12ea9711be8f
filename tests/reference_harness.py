"""What the reference engines' tests share (no test module imports another): the agreement
statistics of two engines on one scene, and the scenes several of them render.

``agreement`` / ``check``: two estimators of the same integral agree within noise when, per
``BLOCK`` x ``BLOCK`` block of pixels, the difference of the means divided by its standard error
(both engines' variance of the mean) is a standard normal (mean z^2 near 1, no |z| beyond 5) and
the image means agree within 0.5% (or 4 standard errors); see tests/test_gpu_engine.py.
"""

from __future__ import annotations

import tomllib

import numpy as np

from viewer.scene import SCENE_DIR, parse_scene

SIZE = 32
BLOCK = 4


def agreement(ctx, scene, spp, max_depth=8, size=SIZE, seed=1, **estimator):
    """Block z-scores and image means of the two engines (``estimator``: the options both take)."""
    from viewer.gpupt import GpuReferenceRenderer
    from viewer.pathtracer import ReferenceRenderer

    with GpuReferenceRenderer(scene, width=size, height=size, max_depth=max_depth, seed=seed, ctx=ctx,
                              **estimator) as g:
        g.step(spp)
        mg, vg, bad_g = g.mean().astype(np.float64), g.variance().astype(np.float64), g.bad_values
    with ReferenceRenderer(scene, width=size, height=size, max_depth=max_depth, seed=seed, workers=0,
                           **estimator) as c:
        c.step(spp)
        mc, vc, bad_c = c.mean().astype(np.float64), c.variance().astype(np.float64), c.bad_values
    nb = size // BLOCK

    def blk(a, scale=1.0):
        return a.reshape(nb, BLOCK, nb, BLOCK, 3).sum(axis=(1, 3)) * scale

    bm_g, bm_c = blk(mg, 1 / BLOCK**2), blk(mc, 1 / BLOCK**2)
    bv = blk(vg + vc, 1 / BLOCK**4)
    # pixels seeing only a constant background have zero variance in both; their means differ by
    # float32 rounding of the GPU's sums (about 1e-7 relative per addition): floor at 1e-5
    bv = bv + (1e-5 * bm_c) ** 2 + 1e-30
    z = (bm_g - bm_c) / np.sqrt(bv)
    total_c = mc.sum()
    return dict(z2=float(np.mean(z * z)), zmax=float(np.abs(z).max()),
                rel=float(mg.sum() / total_c - 1.0) if total_c > 0 else 0.0,
                sigma=float(np.sqrt(vg.sum() + vc.sum()) / total_c) if total_c > 0 else 0.0,
                bad=(bad_g, bad_c), mean_gpu=float(mg.mean()), mean_cpu=float(mc.mean()),
                var_gpu=float(vg.sum()), var_cpu=float(vc.sum()))


def check(a, name, mean_tol=0.005):
    assert a["bad"] == (0, 0), (name, a)
    assert a["mean_cpu"] > 0, (name, a)
    assert a["zmax"] < 5.0, (name, a)
    assert a["z2"] < 1.6, (name, a)
    assert abs(a["rel"]) < max(mean_tol, 4 * a["sigma"]), (name, a)


def under_grey_sky(scene):
    """The scene lit by a constant environment only (a point light or the sky's sun seen through
    smooth glass from a diffuse floor is a caustic neither engine samples well at this spp)."""
    scene.lights = []
    scene.environment.map = None
    scene.environment.constant = np.array([0.6, 0.65, 0.7])
    scene.environment.intensity = 1.0
    return scene


# A gold GGX sphere (alpha 0.15) alone under the studio map: the key, fill and rim panels are
# small and bright, the lobe is glossy, so neither strategy alone is good everywhere (BSDF
# sampling misses the panels seen through the lobe's tail, light sampling picks panels the
# lobe rejects) -- the case MIS is for. A convex object alone: max_depth 1 is the whole answer.
GLOSSY_STUDIO = """
[camera]
position = [0.0, 0.0, 3.2]
target = [0.0, 0.0, 0.0]
up = [0.0, 1.0, 0.0]
fov_y = 40.0
width = 24
height = 24

[environment]
map = "studio"

[[objects]]
mesh = "sphere"
material = "ball"

[materials.ball]
preset = "gold"
alpha = 0.15
"""

def glossy_studio():
    return parse_scene(tomllib.loads(GLOSSY_STUDIO), None, label="<glossy studio>", base_dir=SCENE_DIR)
