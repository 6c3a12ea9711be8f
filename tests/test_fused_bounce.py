"""The whole bounce compiled (viewer/pathtracer/fused.py) against the integrator's numpy steps,
and the compiled pieces it rests on: its camera rays against ``Integrator.camera_rays`` on the
jitter numpy's ``Philox`` streams hold, Embree called ray by ray (``kernel_embree.DirectScene``)
against embreex's batched queries, the Philox numbers computed path by path
(``compiled.draw_paths``, ``compiled.stream_numbers5``) against numpy's ``Philox``, the compiled
Lambert against its twin.

Tolerances: the fused loop runs the numpy steps' arithmetic on the same random numbers and the
same ray queries, so images agree to a few float64 roundings (1e-12 relative: a formula error
or one random number out of place shows at 1e-3 and up); the random numbers, the camera rays
(the same operations in the same order on the same numbers) and Lambert's values are exact; Embree's two scenes may split a tie between triangles sharing an edge
differently and round a hit differently in float32, so hits are compared on all but a few in
ten thousand rays, to float32 roundoff.
"""

from __future__ import annotations

import textwrap

import numpy as np
import pytest

pytest.importorskip("numba")

from viewer import brdf  # noqa: E402
from viewer.pathtracer import compiled, kernel_embree  # noqa: E402
from viewer.pathtracer.fused import FusedBounce  # noqa: E402
from viewer.pathtracer.integrator import KEY_SALT, Integrator, philox, philox_key  # noqa: E402
from viewer.reference_common.setup import RenderSetup  # noqa: E402
from viewer.scene import load_scene  # noqa: E402

from scene_text import camera, environment, material, point_light, scene, sphere_on_floor, table  # noqa: E402


PLASTIC = {"model": "microfacet", "distribution": "ggx", "shadowing": "smith", "fresnel": "dielectric", "ior": 1.5,
           "alpha": 0.3, "kd": [0.62, 0.26, 0.1]}   # the default scene's ball: a diffuse base under a dielectric


def _scene(tmp_path, *, spectral="none", floor=None, ball=None):
    text = scene(camera([0.0, 1.2, 3.5], [0.0, 0.4, 0.0], 45.0, 32, 24),
                 environment(constant=[0.3, 0.35, 0.4]),
                 point_light([2.0, 3.0, 2.0], [20.0, 20.0, 20.0]),
                 table("[lights]", type="directional", direction=[-0.3, -1.0, -0.2], irradiance=[0.8, 0.7, 0.6]),
                 sphere_on_floor(height=0.5),
                 material("ball", **(ball or {"preset": "gold", "alpha": 0.25, "spectral": spectral})),
                 floor or material("floor", model="lambert", albedo=[0.6, 0.5, 0.4]))
    f = tmp_path / "s.toml"
    f.write_text(textwrap.dedent(text))
    return load_scene(f)


def _render(it, setup, seed=7):
    """Two blocks in one chunk, 3 samples: the fused path computes the camera rays and every
    bounce's numbers itself, the numpy steps draw them from numpy's ``Philox`` streams."""
    h = setup.height // 2
    out = it.render_blocks([(0, h, 0), (h, setup.height, 1)], [0, 1, 2], seed)
    return np.concatenate([s for s, _ in out]), np.concatenate([s2 for _, s2 in out])


@pytest.mark.parametrize("strategy, heuristic, roulette, spectral, kernel, ball", [
    ("mis", "power", True, "none", "embree", None), ("mis", "balance", True, "Au", "embree", None),
    ("bsdf", "power", True, "none", "embree", None), ("light", "power", False, "none", "embree", None),
    ("mis", "power", True, "none", "numba", None),   # numba's ray kernel: batched queries around the loop
    ("mis", "power", True, "none", "embree", PLASTIC)])
def test_the_fused_bounce_equals_the_numpy_steps(tmp_path, strategy, heuristic, roulette, spectral, kernel, ball):
    setup = RenderSetup.from_scene(_scene(tmp_path, spectral=spectral, ball=ball), max_depth=6, strategy=strategy,
                                   mis_heuristic=heuristic, kernel=kernel)
    setup.russian_roulette = roulette
    a, b = Integrator(setup), Integrator(setup)
    assert isinstance(a.fused, FusedBounce) and (a.fused.direct is None) == (kernel == "numba")
    b.fused = None                      # the numpy steps (with the same compiled models)
    sa, qa = _render(a, setup)
    sb, qb = _render(b, setup)
    assert sa.mean() > 0.05
    scale = max(1.0, float(np.abs(sb).max()))
    assert np.abs(sa - sb).max() <= 1e-12 * scale
    assert np.abs(qa - qb).max() <= 1e-12 * max(1.0, float(np.abs(qb).max()))
    assert a.bad_values == b.bad_values == 0


def test_the_fused_bounce_traces_given_rays_with_drawn_numbers_as_the_numpy_steps(tmp_path):
    """``Integrator.trace`` (what ``warm`` runs): rays and a ``draw()`` from the caller."""
    setup = RenderSetup.from_scene(_scene(tmp_path), max_depth=6)
    a, b = Integrator(setup), Integrator(setup)
    b.fused = None
    rng = np.random.default_rng(5)
    n = 3000
    o = np.tile([0.0, 1.2, 3.5], (n, 1))
    d = np.array([0.0, -0.2, -1.0]) + rng.normal(size=(n, 3)) * 0.2
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    out = []
    for it in (a, b):
        g = np.random.default_rng(9)
        out.append(it.trace(o, d, lambda g=g: g.random((n, 5))))
    assert out[0].mean() > 0.05
    assert np.abs(out[0] - out[1]).max() <= 1e-12 * max(1.0, float(np.abs(out[1]).max()))


def test_the_compiled_camera_rays_are_the_integrators(tmp_path):
    """Each path's jitter is the first two numbers of its pixel in ``philox(seed, block,
    sample)``; the rays are ``Integrator.camera_rays``' to the last bit."""
    setup = RenderSetup.from_scene(_scene(tmp_path), max_depth=2)
    it = Integrator(setup)
    W = setup.width
    blocks, samples, seed = [(0, 5, 0), (5, setup.height, 2**40 + 3)], [0, 2, 7], 2**63 + 5
    rows, cols, jit = [], [], []
    for r0, r1, b in blocks:
        pix = np.arange((r1 - r0) * W)
        for si in samples:
            rows.append(r0 + pix // W)
            cols.append(pix % W)
            jit.append(philox(seed, b, si).random((pix.size, 2)))
    want_o, want_d = it.camera_rays(np.concatenate(rows), np.concatenate(cols), np.concatenate(jit))
    o, d, _ = it.fused.camera_rays(it, blocks, samples, philox_key(seed))
    assert o.shape == want_o.shape == (len(samples) * setup.height * W, 3)
    assert np.array_equal(o, want_o) and np.array_equal(d, want_d)


def test_a_seed_gives_the_same_image_and_another_seed_another(tmp_path):
    setup = RenderSetup.from_scene(_scene(tmp_path), max_depth=6)
    it = Integrator(setup)
    s1, _ = _render(it, setup, seed=3)
    s2, _ = _render(Integrator(setup), setup, seed=3)
    s3, _ = _render(it, setup, seed=4)
    assert np.array_equal(s1, s2)
    assert not np.array_equal(s1, s3)


def test_the_fused_bounce_only_where_every_step_has_a_compiled_stand_in(tmp_path):
    assert Integrator(RenderSetup.from_scene(_scene(tmp_path), max_depth=4)).fused is not None
    glass = material("floor", model="dielectric", ior=1.5)   # transmissive: the numpy steps
    assert Integrator(RenderSetup.from_scene(_scene(tmp_path, floor=glass), max_depth=4)).fused is None
    phong = material("floor", model="phong")                 # no compiled stand-in
    assert Integrator(RenderSetup.from_scene(_scene(tmp_path, floor=phong), max_depth=4)).fused is None
    from viewer.pathtracer.photons import integrator_for

    photon = RenderSetup.from_scene(_scene(tmp_path), max_depth=4, integrator="photon")
    assert integrator_for(photon).fused is None               # the photon integrator's own steps


def test_philox_numbers_computed_path_by_path_are_numpys():
    """``compiled.draw_paths``: the numbers of any live path at any bounce are exactly what the
    path's stream ``philox(seed, block, sample)`` gives it when every path draws every bounce."""
    rng = np.random.default_rng(11)
    seed, npix, dims, bounces = 2**63 + 12345, 1000, 5, 4
    keys = [(7, 0), (7, 1), (2**40 + 3, 9)]
    want = []
    for block, sample in keys:
        g = philox(seed, block, sample)
        g.random((npix, 2))                                   # the jitter
        want.append([g.random((npix, dims)) for _ in range(bounces)])
    stream = np.repeat(np.arange(len(keys)), npix)
    pix = np.tile(np.arange(npix), len(keys))
    c2 = np.array([b for b, _ in keys], np.uint64)
    c3 = np.array([s for _, s in keys], np.uint64)
    for b in range(bounces):
        act = np.sort(rng.choice(len(keys) * npix, 700, replace=False))
        rnd = np.full((len(keys) * npix, dims), -1.0)
        first = (np.full(len(keys), npix) * (2 + b * dims)).astype(np.uint64)
        compiled.draw_paths(act, seed & (2**64 - 1), KEY_SALT, stream, pix, c2, c3, first, rnd)
        got = rnd[act]
        ref = np.concatenate([w[b] for w in want])[act]
        assert np.array_equal(got, ref)
        assert np.all(np.delete(rnd, act, axis=0) == -1.0)      # other rows untouched


def test_five_numbers_computed_inline_are_numpys():
    """``compiled.stream_numbers5``: numbers q .. q + 4 of a stream, at every offset in a Philox
    block, with the block a neighbour computed reused or computed anew."""
    seed, c2, c3 = 2**64 - 7, 2**40 + 3, 9
    want = philox(seed, c2, c3).random(200)
    k0, k1 = np.uint64(seed), np.uint64(KEY_SALT)
    blk, words = np.uint64(2**64 - 1), (np.uint64(0),) * 4
    for q in list(range(0, 190, 5)) + [3, 6, 101, 102]:   # consecutive paths, then jumps
        *u, blk, words = compiled.stream_numbers5(np.uint64(q), np.uint64(c2), np.uint64(c3), k0, k1, blk, words)
        assert np.array_equal(u, want[q:q + 5])
        blk, words = np.uint64(blk), tuple(np.uint64(x) for x in words)   # (numba hands back Python ints)
    for q in (0, 2, 100, 198):
        u0, u1, _, _ = compiled.stream_numbers2(np.uint64(q), np.uint64(c2), np.uint64(c3), k0, k1,
                                                np.uint64(2**64 - 1), (np.uint64(0),) * 4)
        assert (u0, u1) == (want[q], want[q + 1])


def test_embree_ray_by_ray_matches_the_batched_queries(monkeypatch):
    rng = np.random.default_rng(12)
    tri = rng.normal(size=(300, 3, 3)) * 2.0
    n = 20000
    o = rng.normal(size=(n, 3)) * 4.0
    d = rng.normal(size=(n, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    tmax = np.where(rng.random(n) < 0.5, np.inf, rng.random(n) * 6.0)
    tmax[:50] = -1.0                                          # empty intervals
    direct = kernel_embree.EmbreeKernel(tri)
    assert direct.direct is not None
    monkeypatch.setattr(kernel_embree, "direct_scene", lambda verts: None)
    batched = kernel_embree.EmbreeKernel(tri)
    assert batched.direct is None
    for tmin in (0.0, 0.3):
        t1, p1, u1, v1 = direct.intersect(o, d, tmin, tmax)
        t2, p2, u2, v2 = batched.intersect(o, d, tmin, tmax)
        same = p1 == p2
        assert np.count_nonzero(~same) <= 3 and np.count_nonzero(p1 >= 0) > 1000
        assert np.all(p1[:50] == -1) and np.all(np.isinf(t1[:50]))
        # the two scenes' trees store the triangles differently: the same hit, rounded differently
        # in float32 (a relative 1e-5 is about 100 float32 roundings; a wrong hit is off by far more)
        hit = same & (p1 >= 0)
        assert np.abs(t1[hit] - t2[hit]).max() <= 1e-5 * max(1.0, float(t2[hit].max()))
        assert np.abs(u1[hit] - u2[hit]).max() <= 1e-5 and np.abs(v1[hit] - v2[hit]).max() <= 1e-5
        b1, b2 = direct.occluded(o, d, tmin, tmax), batched.occluded(o, d, tmin, tmax)
        assert np.array_equal(b1, b2) and 0 < b1.sum() < n


def test_compiled_lambert_equals_its_twin():
    lam = brdf.get("lambert")
    p = lam.params(albedo=[0.2, 0.5, 0.9])
    twin = lam.reference_model(p)
    model = compiled.compiled_model(p, twin)
    assert isinstance(model, compiled.CompiledLambert)
    rng = np.random.default_rng(13)
    n = 5000
    wi, wo = rng.normal(size=(n, 3)), rng.normal(size=(n, 3))
    wi /= np.linalg.norm(wi, axis=1, keepdims=True)
    wo /= np.linalg.norm(wo, axis=1, keepdims=True)
    wi[:20, 2] = 0.0                                          # on the horizon
    u = rng.random((n, 2))
    u[:10] = 0.5                                              # the disk's centre
    assert np.array_equal(model.eval(p, wi, wo), twin.eval(p, wi, wo))
    assert np.array_equal(model.pdf(p, wi, wo), twin.pdf(p, wi, wo))
    for got, want in zip(model.sample_lobe(p, wo, u), twin.sample_lobe(p, wo, u)):
        assert got.dtype == want.dtype and np.array_equal(got, want)
