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

from reference_harness import agreement, check, under_grey_sky
from viewer.scene.lecture import TOUR, tour_scene
from viewer.scene import builtin_scene_names, load_scene


@pytest.fixture(scope="module")
def ctx(gl_ctx):
    return gl_ctx


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
    from viewer.scene.camera import OrbitCamera

    sc = tour_scene(0)
    cam = OrbitCamera.from_scene(sc)
    rv = ReferenceView(ctx, scale=1.0, max_depth=3, engine="gpu", frame_budget_s=0.01)
    try:
        t0 = time.perf_counter()
        while rv.spp < 3 and time.perf_counter() - t0 < 600:
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
