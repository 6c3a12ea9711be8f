"""The GPU engine's ``photon`` integrator (path tracing plus a progressive caustic photon map)
against closed forms and against the CPU engine's.

Oracles (tests/caustic_oracles.py): a point light over a perfect mirror lighting a Lambert wall
(direct light plus the mirror image of the light) and a directional light through an absorbing
glass slab onto a Lambert floor (Fresnel transmittance with every internal reflection and
Bouguer absorption). At a finite number of passes the estimator's expectation is the closed form
with the caustic averaged over each pass's gather disk (the uniform kernel's blur); the image
must match that within noise, and the unblurred closed form within noise plus that blur.

Noise: the pixels of one pass share its photons, so pixel errors are correlated; the statistics
use each pass as one sample (the per-pass image is the difference of the running sums): the
standard error of a mean over pixels is the spread of that mean over passes / sqrt(passes).
Per-pixel z-scores use each pixel's own spread over passes (passes are independent).
"""

import numpy as np
import pytest

from caustic_oracles import coated_mirrors, expected, glass_slab_scene, mirror_wall_scene, slab_under_sky
from viewer.reference_common import caustics

SIZE = 16
PASSES = 48
SKY_PASSES = 24   # the sky through the slab: a standard error of about 0.6% of the image mean
# max_depth: the slab's floor is lit once (the closed form has no floor -> slab -> floor light);
# the mirror wall's answer is the same at any depth (the wall never sees itself in the mirror)
ORACLES = {"mirror_wall": (mirror_wall_scene, 8), "glass_slab": (glass_slab_scene, 1)}


@pytest.fixture(scope="module")
def ctx(gl_ctx):
    return gl_ctx


def pass_images(r, n):
    """(n, H, W, 3) float64: the image of each of ``n`` passes (one sample per pixel each)."""
    out, prev = [], None
    for _ in range(n):
        r.step(1)
        s, _q, spp = r.state()
        s = np.asarray(s, np.float64)
        out.append(s if prev is None else s - prev)
        prev = s
    return np.stack(out)


_CACHE: dict = {}


def gpu_passes(ctx, name, integrator="photon"):
    key = (name, integrator)
    if key not in _CACHE:
        from viewer.gpupt import GpuReferenceRenderer

        make, depth = ORACLES[name]
        with GpuReferenceRenderer(make(SIZE), width=SIZE, height=SIZE, max_depth=depth, seed=3, ctx=ctx,
                                  integrator=integrator) as g:
            imgs = pass_images(g, PASSES)
            assert g.bad_values == 0
            r1 = g.photons.r1 if g.photons is not None else None
        _CACHE[key] = (imgs, r1)
    return _CACHE[key]


def mean_and_error(imgs, mask):
    """(mean over the masked pixels per channel, its standard error from the spread over passes)."""
    per_pass = imgs[:, mask].mean(axis=1)          # (n, 3)
    return per_pass.mean(axis=0), per_pass.std(axis=0, ddof=1) / np.sqrt(per_pass.shape[0])


@pytest.mark.parametrize("name", list(ORACLES))
def test_gpu_photon_matches_the_closed_form(ctx, name):
    imgs, r1 = gpu_passes(ctx, name)
    assert r1 is not None
    radii = [caustics.pass_radius(r1, i) for i in range(1, PASSES + 1)]
    exact, expect, mask = expected(name, SIZE, radii)
    assert mask.sum() > SIZE * SIZE // 3, "too few pixels away from the caustic's edges"
    m, se = mean_and_error(imgs, mask)
    ref = expect[mask].mean(axis=0)
    rel, rel_se = m / ref - 1.0, se / ref
    assert np.all(rel_se < 0.01), (name, rel_se)   # the power to see a 4% bias at 4 sigma
    assert np.all(np.abs(rel) < 4.0 * rel_se + 1e-3), (name, rel, rel_se)   # 1e-3: float32 sums
    # the unblurred closed form: within the noise plus the kernel's blur over these passes
    blur = np.abs(expect[mask].mean(axis=0) / exact[mask].mean(axis=0) - 1.0)
    rel_exact = m / exact[mask].mean(axis=0) - 1.0
    assert np.all(np.abs(rel_exact) < 4.0 * rel_se + blur + 1e-3), (name, rel_exact, blur)
    # per pixel: each pixel's mean against its expectation in units of its own standard error
    pm = imgs.mean(axis=0)[mask]
    pse = imgs.std(axis=0, ddof=1)[mask] / np.sqrt(PASSES)
    z = (pm - expect[mask]) / np.maximum(pse, 1e-6 * expect[mask])
    assert np.mean(z * z) < 1.6 and np.abs(z).max() < 5.5, (name, np.mean(z * z), np.abs(z).max())


@pytest.mark.parametrize("name", list(ORACLES))
def test_gpu_path_misses_the_caustic(ctx, name):
    """The control: the path tracer alone finds no light through the delta surfaces from these
    delta lights (the oracle tells the estimators apart)."""
    imgs, _ = gpu_passes(ctx, name, "path")
    exact, _expect, mask = expected(name, SIZE)
    m, _se = mean_and_error(imgs, mask)
    assert np.all(m / exact[mask].mean(axis=0) - 1.0 < -0.2), name


def agreement(g, cimgs, name):
    """Per 4 x 4 block the difference of the two engines' means over its standard error (the
    spread over passes) is a standard normal; the image sums agree within 4 standard errors."""
    n = g.shape[0]
    nb = g.shape[1] // 4

    def blocks(imgs):
        return imgs.reshape(n, nb, 4, nb, 4, 3).mean(axis=(2, 4))

    bg, bc = blocks(g), blocks(cimgs)
    var = bg.var(axis=0, ddof=1) / n + bc.var(axis=0, ddof=1) / n
    z = (bg.mean(axis=0) - bc.mean(axis=0)) / np.sqrt(var + (1e-4 * bc.mean(axis=0)) ** 2 + 1e-30)
    assert np.mean(z * z) < 1.6 and np.abs(z).max() < 5.0, (name, np.mean(z * z), np.abs(z).max())
    mg, mc = g.mean(axis=0).sum(), cimgs.mean(axis=0).sum()
    se = np.sqrt(g.sum(axis=(1, 2, 3)).var(ddof=1) / n + cimgs.sum(axis=(1, 2, 3)).var(ddof=1) / n)
    assert abs(mg - mc) < 4.0 * se, (name, mg, mc, se)
    assert se < 0.02 * mc, (name, se / mc)      # the power to see an 8% difference


def cpu_passes(scene, depth, n, **options):
    from viewer.pathtracer import ReferenceRenderer

    with ReferenceRenderer(scene, width=SIZE, height=SIZE, max_depth=depth, seed=5, workers=0, integrator="photon",
                           **options) as c:
        imgs = pass_images(c, n)
        assert c.bad_values == 0
    return imgs


@pytest.mark.parametrize("name", list(ORACLES))
def test_gpu_photon_agrees_with_cpu_photon(ctx, name):
    """Both engines' photon estimators have the same expectation at every pass count (same
    photons per pass, radii, kernel and partition)."""
    g, _ = gpu_passes(ctx, name)
    make, depth = ORACLES[name]
    agreement(g, cpu_passes(make(SIZE), depth, PASSES), name)


def _gpu_photon_passes(ctx, scene, depth, n, **options):
    from viewer.gpupt import GpuReferenceRenderer

    with GpuReferenceRenderer(scene, width=SIZE, height=SIZE, max_depth=depth, seed=3, ctx=ctx, integrator="photon",
                              **options) as g:
        imgs = pass_images(g, n)
        assert g.bad_values == 0
    return imgs


@pytest.mark.slow   # the spectral variants compile for about 10 s on software GL, the CPU's spectral pass is slow
def test_gpu_spectral_photon_agrees_with_cpu(ctx):
    """The hero-wavelength estimator gathers the same photons (their RGB power upsampled, f at
    the path's wavelengths) and drops the same caustic paths as the CPU engine's."""
    for name, (make, depth) in ORACLES.items():
        agreement(_gpu_photon_passes(ctx, make(SIZE), depth, PASSES, spectral=True),
                  cpu_passes(make(SIZE), depth, PASSES, spectral=True), name + " (spectral)")


@pytest.mark.slow   # each step compiles its own programs (10-20 s on software GL)
@pytest.mark.parametrize("step", [1, 2, 9])
def test_gpu_photon_agrees_with_cpu_on_the_lecture_caustics(ctx, step):
    """The lecture's glass steps under the sky with its sun (photons from the environment map:
    emission by its importance sampling, the sun's caustics): mirror and glass spheres, the glass
    cube (total internal reflection), absorbing glass."""
    from viewer.scene.lecture import tour_scene

    agreement(_gpu_photon_passes(ctx, tour_scene(step), 6, PASSES), cpu_passes(tour_scene(step), 6, PASSES),
              f"lecture step {step}")


@pytest.mark.slow   # the layered program compiles for about 10 s on software GL
def test_gpu_photon_agrees_with_cpu_on_coated_mirrors(ctx):
    """A glossy coat over a mirror stores photons and sends them on through its delta lobe (the
    photon pass's later rounds); the CPU engine does the same in one loop."""
    sc = coated_mirrors(SIZE)
    agreement(_gpu_photon_passes(ctx, sc, 8, PASSES), cpu_passes(coated_mirrors(SIZE), 8, PASSES), "coated mirrors")


def test_gpu_photon_and_path_agree_where_both_converge(ctx):
    """Under a constant sky the floor beneath the slab sees the sky through the glass: caustic
    paths, which the photon integrator takes from the photon map only (the path tracer drops a
    sky reached by a delta sample after a smooth vertex) and the path tracer alone finds as well
    (a broad light). The two image means agree within their noise; counting those paths twice
    (no exclusion) put the photon image 19% above the path one here (40 standard errors at 32
    passes)."""
    from viewer.gpupt import GpuReferenceRenderer

    sc = slab_under_sky(SIZE)
    totals = {}
    for integrator in ("photon", "path"):
        with GpuReferenceRenderer(sc, width=SIZE, height=SIZE, max_depth=8, seed=2, ctx=ctx,
                                  integrator=integrator) as g:
            t = pass_images(g, SKY_PASSES).sum(axis=(1, 2, 3))
            assert g.bad_values == 0
            if integrator == "photon":
                assert g.photons.stored > 0
        totals[integrator] = (t.mean(), t.std(ddof=1) / np.sqrt(SKY_PASSES))
    (mp, sp), (mq, sq) = totals["photon"], totals["path"]
    rel, se = mp / mq - 1.0, np.hypot(sp, sq) / mq
    assert se < 0.01, se
    # 0.005: the photon estimate's blur across the slab's edge (energy moved, not made: measured
    # 0.06% at 64 passes)
    assert abs(rel) < 4.0 * se + 0.005, (rel, se)


def test_photon_passes_are_the_same_whatever_the_bands(ctx):
    """A pass's photons depend on the seed and the pass only: time-sliced bands of rows
    (``step_for``, the photon map built once per pass) give the image whole passes give."""
    from viewer.gpupt import GpuReferenceRenderer

    sc = mirror_wall_scene(12)
    with GpuReferenceRenderer(sc, width=12, height=12, max_depth=2, seed=4, ctx=ctx, integrator="photon") as a:
        a.step(2)
        ref = a.mean()
        assert a.photons.pass_index == 2 and a.photons.stored > 0
    with GpuReferenceRenderer(sc, width=12, height=12, max_depth=2, seed=4, ctx=ctx, integrator="photon") as b:
        b.rows_per_pass = 5
        while b.spp < 2:
            b.step_for(1e-4)
        assert np.array_equal(b.mean(), ref)


def test_window_bands_never_wait_for_the_photon_map(ctx, monkeypatch):
    """``step_for`` (the window's) runs no numpy of the photon map on its own thread: emission
    and the hash grid run on the engine's worker thread, and while the next pass's map is not
    ready the call returns at once with nothing added (the frame goes on). The image is the
    same as whole passes give (test_photon_passes_are_the_same_whatever_the_bands)."""
    import threading

    from viewer.gpupt import GpuReferenceRenderer

    caller = threading.get_ident()
    seen = {"emit": set(), "grid": set()}
    gate = threading.Event()
    emit, build = caustics.emit_photons, caustics.build_grid

    def slow_emit(*a, **k):
        seen["emit"].add(threading.get_ident())
        gate.wait(20.0)          # held until the test lets it go (a waiting step_for would stall 20 s)
        return emit(*a, **k)

    def grid(*a, **k):
        seen["grid"].add(threading.get_ident())
        return build(*a, **k)

    monkeypatch.setattr(caustics, "emit_photons", slow_emit)
    monkeypatch.setattr(caustics, "build_grid", grid)
    sc = mirror_wall_scene(12)
    with GpuReferenceRenderer(sc, width=12, height=12, max_depth=2, seed=4, ctx=ctx, integrator="photon") as b:
        b.rows_per_pass = 5
        assert b.step_for(1e-4) == 0 and b.spp == 0          # pass 1's emission is held: nothing, at once
        assert not gate.is_set()
        gate.set()
        while b.spp < 2:
            b.step_for(1e-4)
        got = b.mean()
    assert seen["emit"] and caller not in seen["emit"], seen
    assert seen["grid"] and caller not in seen["grid"], seen
    monkeypatch.setattr(caustics, "emit_photons", emit)
    with GpuReferenceRenderer(sc, width=12, height=12, max_depth=2, seed=4, ctx=ctx, integrator="photon") as a:
        a.step(2)
        assert np.array_equal(a.mean(), got)
