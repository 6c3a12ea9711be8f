"""The GPU reference engine (viewer/gpupt) against the CPU engine, the independent oracle.

Two estimators of the same integral agree within noise when (1) per 4 x 4 block of pixels the
difference of the means divided by its standard error (both engines' variance of the mean) is
a standard normal: mean z^2 near 1, no |z| beyond 5 (P < 6e-7 per value for a normal; 192
values per image); (2) the image means agree within 0.5%, with enough samples that a 0.5%
bias would stand 4 standard errors out (the test asserts that power too). Random numbers differ
(pcg4d hash on the GPU, Philox on the CPU), so only the statistics can agree.
Small images (32 x 32) keep the default run short; the full sweep over every built-in scene
and lecture step is marked slow.
"""

import numpy as np
import pytest

from viewer.lecture import TOUR, tour_scene
from viewer.scene import builtin_scene_names, load_scene

SIZE = 32
BLOCK = 4


@pytest.fixture(scope="module")
def ctx(gl_ctx):
    return gl_ctx


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


# the default run: a lit Lambert sphere, glass and mirror under a sky map, rough metals under an
# environment map, absorbing glass under a grey sky
CASES = {
    "sphere": (lambda: load_scene("sphere"), 256),
    "lecture_glass": (lambda: tour_scene(1), 128),
    "lecture_microfacet": (lambda: tour_scene(4), 128),
    "lecture_absorbing_glass": (lambda: under_grey_sky(tour_scene(9)), 128),
}


@pytest.mark.parametrize("name", list(CASES))
def test_gpu_agrees_with_cpu(ctx, name):
    make, spp = CASES[name]
    a = agreement(ctx, make(), spp)
    check(a, name)
    assert a["sigma"] < 0.005 / 4, (name, a)  # the mean test has the power to see a 0.5% bias


def test_same_seed_same_image_whatever_the_bands(ctx):
    """The samples of a pixel are hashes of (pixel, sample index, seed): time-sliced bands
    (``step_for``) and whole passes (``step``) give bit-identical sums."""
    from viewer.gpupt import GpuReferenceRenderer

    sc = tour_scene(0)
    with GpuReferenceRenderer(sc, width=24, height=16, max_depth=3, seed=4, ctx=ctx) as a:
        a.step(3)
        ref = a.mean()
    with GpuReferenceRenderer(sc, width=24, height=16, max_depth=3, seed=4, ctx=ctx) as b:
        b.rows_per_pass = 5
        while b.spp < 3:
            b.step_for(1e-4)     # one band of rows per call
        s, _, n = b.sums()
        assert np.all(n == 3)
        assert np.array_equal(b.mean(), ref)
    with GpuReferenceRenderer(sc, width=24, height=16, max_depth=3, seed=5, ctx=ctx) as c:
        c.step(3)
        assert not np.array_equal(c.mean(), ref)


@pytest.mark.slow
@pytest.mark.parametrize("name", builtin_scene_names())
def test_gpu_agrees_with_cpu_builtin_scenes(ctx, name):
    check(agreement(ctx, load_scene(name), 512), name)


@pytest.mark.slow
@pytest.mark.parametrize("step", range(len(TOUR)))
def test_gpu_agrees_with_cpu_lecture_steps(ctx, step):
    check(agreement(ctx, tour_scene(step), 512), f"lecture step {step}")


def test_reference_view_time_slices_the_gpu_engine_and_uses_the_cache(ctx):
    """The window's reference view with the GPU engine: each update renders about its frame
    budget on the calling (GUI) thread, the image refines, and a view left and returned to
    starts from the cache with the samples it had."""
    import time

    from viewer.app.reference_view import ReferenceView
    from viewer.camera import OrbitCamera

    sc = tour_scene(0)
    cam = OrbitCamera.from_scene(sc)
    rv = ReferenceView(ctx, scale=1.0, max_depth=3, engine="gpu", frame_budget_s=0.01)
    try:
        t0 = time.perf_counter()
        while rv.spp < 3 and time.perf_counter() - t0 < 60:
            rv.update(sc, cam, (24, 16))
        assert rv.engine == "gpu" and rv.spp >= 3 and rv.error == ""
        img, spp = rv.latest()
        assert img.shape == (16, 24, 3) and np.all(np.isfinite(img)) and img.max() > 0
        assert rv.samples_per_second > 0
        other = tour_scene(1)
        rv.update(other, OrbitCamera.from_scene(other), (24, 16))   # leave: the first view is stored
        rv.update(sc, cam, (24, 16))                                # and back: it starts from there
        assert rv.spp >= spp
    finally:
        rv.close()
