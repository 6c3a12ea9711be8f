"""Albedo tables on the GPU (viewer/gl/albedo_gpu.py) equal the numpy builder's
(viewer.brdf.albedo, the oracle) within the estimator's noise, and the renderer's image does not
change when it switches from one builder to the other."""

from __future__ import annotations

import numpy as np
import pytest

from viewer import brdf
from viewer.brdf.albedo import N_SIDE, PHIS, TABLE_SIZE, albedo_tables, stratified_u

from brdf_harness import param_grid, test_param_sets

NAMES = brdf.names()
K_SIGMA = 4.0


@pytest.fixture(scope="module")
def gpu_tables(gl_ctx):
    from viewer.gl.albedo_gpu import GPUAlbedoTables

    g = GPUAlbedoTables(gl_ctx)
    yield g
    g.release()


def _standard_error(model, p):
    """Standard error (TABLE_SIZE, 3) of each entry of the numpy estimator: the spread of the
    weights of its 4 x 576 samples divided by sqrt(2304) (the spread within an azimuth's
    multi-jittered set bounds the error from above: stratification only lowers it)."""
    cos_o = (np.arange(TABLE_SIZE) + 0.5) / TABLE_SIZE
    sin_o = np.sqrt(1.0 - cos_o ** 2)
    ws = []
    for seed, phi in enumerate(PHIS):
        u = stratified_u(N_SIDE, seed)
        wo = np.stack([sin_o * np.cos(phi), sin_o * np.sin(phi), cos_o], axis=-1)
        _, w, pdf = model.sample(p, np.repeat(wo, len(u), axis=0), np.tile(u, (TABLE_SIZE, 1)))
        ws.append(np.where(np.asarray(pdf)[:, None] > 0, w, 0.0).reshape(TABLE_SIZE, len(u), 3))
    w = np.concatenate(ws, axis=1)
    return w.std(axis=1) / np.sqrt(w.shape[1])


def _check(gpu_tables, model, p):
    r_n, t_n = albedo_tables(model, p)
    r_g, t_g = gpu_tables.tables(p)
    se = _standard_error(model, p)
    # K_SIGMA standard errors of the numpy estimate, plus 1e-5 for float32 sums of 2304 weights
    # (and entries whose weights are all equal, where the standard error is 0)
    tol = K_SIGMA * se + 1e-5
    for what, g, n in (("reflected", r_g, r_n), ("transmitted", t_g, t_n)):
        assert np.all(np.isfinite(g)), f"{model.name}: GPU {what} table not finite for {p.to_plain()}"
        bad = np.abs(g - n) > tol
        assert not bad.any(), (f"{model.name}: GPU {what} albedo differs from numpy's beyond {K_SIGMA} sigma at "
                               f"cos_o entries {np.flatnonzero(bad.any(axis=1))}: gpu {g[bad][:3]}, numpy "
                               f"{n[bad][:3]}, sigma {se[bad][:3]} ({p.to_plain()})")
    return float(np.max(np.abs(np.concatenate([r_g - r_n, t_g - t_n])) / np.concatenate([tol, tol])))


@pytest.mark.parametrize("name", NAMES)
def test_gpu_albedo_matches_numpy(gpu_tables, name):
    model = brdf.get(name)
    sets = test_param_sets(model)
    worst = max(_check(gpu_tables, model, p) for p in list(sets.values())[:2])
    print(f"{name}: max |gpu - numpy| = {worst:.3f} of the tolerance")


@pytest.mark.slow
@pytest.mark.parametrize("name", NAMES)
def test_gpu_albedo_matches_numpy_grid(gpu_tables, name):
    model = brdf.get(name)
    for p in list(test_param_sets(model).values()) + param_grid(model):
        _check(gpu_tables, model, p)


def test_renderer_uses_gpu_tables_same_image(renderer):
    """The environment-lit image with GPU tables equals the one with numpy tables: the tables
    agree to ~1e-6 (the same points), so the image may differ by float32 rounding only."""
    from viewer.scene import load_scene

    scene = load_scene("gallery")
    assert scene.render.ibl != "off"
    try:
        renderer.gpu_albedo = False
        b = renderer.render_arrays(scene, width=64, height=48)[0]
        numpy_tables = {n: renderer.albedo_tables(p) for n, p in scene.materials.items()}
        renderer.gpu_albedo = True
        renderer.reload_shaders()  # drops the cached tables (they are rebuilt from the GLSL samplers)
        a = renderer.render_arrays(scene, width=64, height=48)[0]
        assert renderer.albedo_gpu_error is None and renderer.tables.gpu_builder is not None
        for n, p in scene.materials.items():
            for g, c in zip(renderer.albedo_tables(p)[:3], numpy_tables[n][:3]):
                np.testing.assert_allclose(g, c, atol=1e-3, err_msg=n)
    finally:
        renderer.gpu_albedo = True
    assert np.all(np.isfinite(a))
    np.testing.assert_allclose(a, b, rtol=1e-3, atol=1e-4)
