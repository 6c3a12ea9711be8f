"""The compiled steps of the reference path tracer (viewer/pathtracer/compiled.py) against their
numpy twins: the hit shading against ``viewer.geometry.soup``'s functions, the compiled GGX
conductor microfacet against ``viewer.brdf.microfacet`` on many random inputs (below the
horizon, grazing, anisotropic, spectral table and RGB eta, k), and a whole image rendered with
the compiled model against one rendered with the twin (same random numbers: equal to roundoff).

Tolerances: the compiled loops repeat the twins' arithmetic in the same order, so most values
agree bit for bit; the conductor Fresnel's complex square root (cmath in numba, npy_csqrt in
numpy) may round differently in the last place, and a relative 1e-12 bounds that with room (a
formula error shows at 1e-3 and up).
"""

from __future__ import annotations

import os
import textwrap

import numpy as np
import pytest

pytest.importorskip("numba")

from viewer import brdf  # noqa: E402
from viewer.brdf.lobes import Lobe  # noqa: E402
from viewer.brdf.presets import PRESETS  # noqa: E402
from viewer.geometry.soup import SceneGeometry  # noqa: E402
from viewer.pathtracer import compiled  # noqa: E402
from viewer.pathtracer.integrator import Integrator  # noqa: E402
from viewer.reference_common.setup import RenderSetup  # noqa: E402
from viewer.scene import load_scene  # noqa: E402

from scene_text import camera, environment, material, point_light, scene, sphere_on_floor  # noqa: E402

RTOL = 1e-12
GOLD_ETA, GOLD_K = [0.14, 0.43, 1.38], [3.70, 2.46, 1.91]


def _unit(rng, n):
    v = rng.normal(size=(n, 3))
    return v / np.linalg.norm(v, axis=1, keepdims=True)


def _close(a, b, rtol=RTOL):
    a, b = np.asarray(a, np.float64), np.asarray(b, np.float64)
    scale = max(1.0, float(np.abs(b).max()))
    assert np.array_equal(np.isfinite(a), np.isfinite(b))
    assert np.abs(np.where(np.isfinite(b), a - b, 0.0)).max() <= rtol * scale


def _geometry(rng, t=400):
    """Random triangles with random (some vanishing) vertex normals and tangents (some parallel
    to the normal, some with a negative bitangent sign)."""
    tris = rng.normal(size=(t, 3, 3)) * 3.0
    nrm = rng.normal(size=(t, 3, 3))
    nrm /= np.linalg.norm(nrm, axis=2, keepdims=True)
    nrm[:20] = [[1.0, 0.0, 0.0], [-1.0, 0.0, 0.0], [1.0, 0.0, 0.0]]  # interpolated n can vanish
    tan = np.concatenate([rng.normal(size=(t, 3, 3)), np.where(rng.random((t, 3, 1)) < 0.5, -1.0, 1.0)], axis=2)
    tan[20:40, :, :3] = nrm[20:40]                                    # tangent along n: the fallback
    ng = np.cross(tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0])
    ng /= np.linalg.norm(ng, axis=1, keepdims=True)
    mat = rng.integers(0, 3, t).astype(np.int32)
    return SceneGeometry(tris, ng, nrm, tan, np.zeros(t, np.int32), mat, ["a", "b", "c"])


def test_hit_shading_matches_the_numpy_twin():
    rng = np.random.default_rng(1)
    geom = _geometry(rng)
    trans = np.array([False, True, False])
    m = 20000
    prim = rng.integers(0, geom.n_triangles, m)
    prim[:200] = np.arange(200) % 40          # the vanishing normals and degenerate tangents
    u, v = rng.random(m), rng.random(m)
    flip = u + v > 1
    u, v = np.where(flip, 1 - u, u), np.where(flip, 1 - v, v)
    u[:100], v[:100] = 0.5, 0.0              # midpoint of the edge where n0 + n1 = 0
    d = _unit(rng, m)
    got = compiled.hit_shading(geom, trans, d, prim, u, v)
    want = compiled.hit_shading_numpy(geom, trans, d, prim, u, v)
    assert set(got) == set(want)
    for k in want:
        assert got[k].shape == want[k].shape, k
        _close(got[k], want[k])
    # the cases the twin's branches handle are present: a flipped back-face hit, a transmissive
    # hit (never flipped), a fallback tangent
    back = np.sum(d * want["ng_raw"], axis=1) > 0
    assert np.any(back & ~want["trans"]) and np.any(back & want["trans"])


def _gold(spectral="none", ax=0.3, ay=None, **kw):
    m = brdf.get("microfacet")
    values = dict(distribution="ggx", shadowing="smith", fresnel="conductor", alpha_x=ax,
                  alpha_y=ax if ay is None else ay, eta=GOLD_ETA, k=GOLD_K, spectral=spectral)
    return m, m.params(**dict(values, **kw))


CASES = [("none", 0.3, None, {}), ("Au", 0.3, None, {}), ("none", 0.05, 0.4, {}), ("Au", 1.0, 0.02, {}),
         ("Cu", 0.002, None, {}),
         # the diffuse base over a dielectric (the default scene's plastic) and over a conductor
         ("none", 0.25, None, {"fresnel": "dielectric", "ior": 1.5, "kd": [0.62, 0.26, 0.1]}),
         ("none", 0.6, 0.1, {"fresnel": "dielectric", "ior": 2.4, "kd": [1.0, 0.0, 0.3]}),
         ("Au", 0.3, None, {"kd": [0.2, 0.5, 0.0]})]


@pytest.mark.parametrize("spectral, ax, ay, extra", CASES)
def test_compiled_microfacet_matches_the_twin(spectral, ax, ay, extra):
    rng = np.random.default_rng(2)
    model, p = _gold(spectral, ax, ay, **extra)
    cm = compiled.compiled_model(p, model)
    assert isinstance(cm, compiled.CompiledMicrofacet)
    n = 20000
    wi, wo = _unit(rng, n), _unit(rng, n)
    wi[:100, 2] = 1e-9          # grazing
    wo[100:200] = wi[100:200] * [-1, -1, 1]   # mirror pairs: h along the pole
    wo[200:300] = wi[200:300]                 # wi = wo
    _close(cm.eval(p, wi, wo), model.eval(p, wi, wo))
    _close(cm.pdf(p, wi, wo), model.pdf(p, wi, wo))
    # r stacked sets of directions against the same wo (as next-event estimation asks)
    wi2 = _unit(rng, 2 * n)
    _close(cm.eval(p, wi2, wo), model.eval(p, wi2, np.tile(wo, (2, 1))))
    u = rng.random((n, 2))
    u[:50] = [0.0, 0.0]
    u[50:100] = [1.0 - 1e-16, 0.999999]
    got, want = cm.sample_lobe(p, wo, u), model.sample_lobe(p, wo, u)
    for g, w in zip(got[:3], want[:3]):
        _close(g, w)
    assert np.array_equal(got[3], want[3]) and got[3].dtype == want[3].dtype
    diffuse = Lobe.DIFFUSE if extra.get("kd") else Lobe.NONE
    assert np.all(got[3] == np.uint8(Lobe.REFLECTION | Lobe.GLOSSY | diffuse))


def test_compiled_model_only_where_it_applies():
    model, p = _gold()
    assert compiled.compiled_model(p, model) is not None
    gold = model.params(**{k: v for k, v in PRESETS["gold"].items() if k != "model"})
    assert compiled.compiled_model(gold, model) is not None
    for change in ({"kd": [0.2, 0.2, 0.2]}, {"fresnel": "dielectric"}):
        assert compiled.compiled_model(_gold(**change)[1], model) is not None, change
    for change in ({"distribution": "beckmann"}, {"fresnel": "schlick"}, {"multiple_scattering": True},
                   {"shadowing": "v_cavity"}):
        assert compiled.compiled_model(_gold(**change)[1], model) is None, change
    lam = brdf.get("lambert")      # Lambert has its own (tests/test_fused_bounce.py)
    assert isinstance(compiled.compiled_model(lam.params(), lam), compiled.CompiledLambert)
    phong = brdf.get("phong")
    assert compiled.compiled_model(phong.params(), phong) is None


def _scene(tmp_path):
    text = scene(camera([0.0, 1.2, 3.5], [0.0, 0.4, 0.0], 45.0, 24, 16),
                 environment(constant=[0.3, 0.35, 0.4]),
                 point_light([2.0, 3.0, 2.0], [20.0, 20.0, 20.0]),
                 sphere_on_floor(height=0.5),
                 material("ball", preset="gold", alpha=0.3),
                 material("floor", model="lambert", albedo=[0.5, 0.5, 0.5]))
    f = tmp_path / "s.toml"
    f.write_text(textwrap.dedent(text))
    return load_scene(f)


class _TwinIntegrator(Integrator):
    COMPILED_MODELS = False


def test_image_with_the_compiled_model_equals_the_twins(tmp_path):
    """The same estimator and random numbers: the images agree to roundoff, pixel by pixel."""
    setup = RenderSetup.from_scene(_scene(tmp_path), max_depth=6)
    a, b = Integrator(setup), _TwinIntegrator(setup)
    assert isinstance(a.models[0], compiled.CompiledMicrofacet)
    assert not isinstance(b.models[0], compiled.CompiledMicrofacet)
    sa, _ = a.render_block(0, setup.height, range(4), 7, 0)
    sb, _ = b.render_block(0, setup.height, range(4), 7, 0)
    assert sa.mean() > 0.01
    assert np.abs(sa - sb).max() <= 1e-9 * max(1.0, np.abs(sb).max())
    assert a.bad_values == b.bad_values == 0


def test_constant_environment_sampling_matches_the_twin():
    from viewer.reference_common.envmap import EnvironmentLight

    rng = np.random.default_rng(3)
    env = EnvironmentLight(constant=[0.2, 0.3, 0.4], intensity=1.5)
    n = 20000
    u = rng.random((n, 2))
    u[:20] = 0.5                      # the disk's centre (a = b = 0)
    u[20:40, 0] = 0.5                 # a = 0
    nrm = _unit(rng, n)
    nrm[:100] = [0.0, 0.0, -1.0]      # the frame's pole on the other side
    two = rng.random(n) < 0.3
    got = compiled.constant_env_sample(env, u, nrm, two)
    want = env.sample(u, nrm, two)
    for g, w in zip(got, want):
        _close(g, w)


def test_embree_rays_match_the_twin():
    rng = np.random.default_rng(4)
    n = 5000
    o, d = rng.normal(size=(n, 3)) * 10, _unit(rng, n)
    tmax = np.where(rng.random(n) < 0.3, np.inf, rng.random(n) * 5)
    tmax[:10] = 0.0                   # empty intervals
    for tmin in (0.0, 0.25):
        got = compiled.embree_rays(o, d, np.array([1.0, -2.0, 0.5]), tmin, tmax, 1e30)
        want = compiled.embree_rays_numpy(o, d, np.array([1.0, -2.0, 0.5]), tmin, tmax, 1e30)
        for g, w in zip(got, want):
            assert g.dtype == w.dtype and np.array_equal(g, w)


def test_without_numba_the_twins_run(monkeypatch):
    """numba missing: the Embree engine still renders (each step by its numpy twin)."""
    rng = np.random.default_rng(5)
    monkeypatch.setattr(compiled, "HAVE_NUMBA", False)
    geom = _geometry(rng, 50)
    d, prim = _unit(rng, 100), rng.integers(0, 50, 100)
    u, v = rng.random(100) * 0.5, rng.random(100) * 0.5
    got = compiled.hit_shading(geom, np.array([False, True, False]), d, prim, u, v)
    want = compiled.hit_shading_numpy(geom, np.array([False, True, False]), d, prim, u, v)
    assert all(np.array_equal(got[k], want[k]) for k in want)
    model, p = _gold()
    assert compiled.compiled_model(p, model) is None


@pytest.mark.parametrize("transmissive, channels, with_share", [(False, 3, False), (True, 3, False), (False, 4, True)])
def test_next_event_candidates_match_the_twin(transmissive, channels, with_share):
    rng = np.random.default_rng(6)
    k, m = 3000, 5000
    wl, ww, ng = _unit(rng, k), _unit(rng, k), _unit(rng, k)
    sel = rng.choice(m, k, replace=False)
    p, eps = rng.normal(size=(m, 3)), rng.random(m) * 1e-3
    T, f = rng.random((k, channels)), rng.random((k, channels))
    f[:300] = 0.0                                    # no positive channel: not a candidate
    fac = rng.random((k, channels)) * 10
    share = rng.random(k) * 4 if with_share else None
    for extra in (None, rng.random(k) < 0.8):
        got = compiled.nee_candidates(wl, ww, ng, sel, p, eps, T, f, fac, share, extra, transmissive)
        want = compiled.nee_candidates_numpy(wl, ww, ng, sel, p, eps, T, f, fac, share, extra, transmissive)
        assert np.array_equal(got[0], want[0]) and 0 < got[0].sum() < k
        _close(got[1], want[1])
        _close(got[2], want[2])


def test_embree_hits_match_the_twin():
    rng = np.random.default_rng(7)
    n = 5000
    res = {"primID": np.where(rng.random(n) < 0.3, -1, rng.integers(0, 100, n)).astype(np.int32),
           "tfar": (rng.random(n) * 10).astype(np.float32), "u": rng.random(n).astype(np.float32),
           "v": rng.random(n).astype(np.float32)}
    live = rng.random(n) < 0.9
    got, want = compiled.embree_hits(res, live, 0.25), compiled.embree_hits_numpy(res, live, 0.25)
    for g, w in zip(got, want):
        assert g.dtype == w.dtype and np.array_equal(g, w)


def test_blocks_traced_together_give_each_blocks_own_sums(tmp_path):
    """A chunk of several blocks (``render_blocks``, one wavefront) gives every block exactly the
    sums it gets alone: each path keeps its block's and sample's stream."""
    setup = RenderSetup.from_scene(_scene(tmp_path), max_depth=6)
    it = Integrator(setup)
    blocks = [(0, 5, 0), (5, 10, 1), (10, 16, 2)]
    together = it.render_blocks(blocks, [3, 4], 11)
    assert it.sample_of_path.tolist() == sum(([s] * (r1 - r0) * setup.width for r0, r1, _ in blocks
                                             for s in (3, 4)), [])
    for (r0, r1, b), (s, s2) in zip(blocks, together):
        a, a2 = it.render_block(r0, r1, [3, 4], 11, b)
        assert np.array_equal(s, a) and np.array_equal(s2, a2)
        assert s.shape == (r1 - r0, setup.width, 3) and s.sum() > 0


NO_SCIPY_LINALG = """
import threading
import numpy as np
seen = []
def other():   # another thread importing scipy's linear algebra meanwhile is never refused
    import scipy.linalg
    seen.append(scipy.linalg.__name__)
t = threading.Thread(target=other)
t.start()
from viewer.pathtracer import compiled
t.join()
print("scipy.linalg from the other thread:", seen)
import numba
@numba.njit
def dot(a, b):
    return np.dot(a, b)   # BLAS: numba imports scipy.linalg when this compiles
print("dot", dot(np.arange(3.0), np.ones(3)))
"""


def test_numba_array_math_loads_without_scipy_linalg(tmp_path):
    """``compiled`` keeps scipy's linear algebra (0.2 CPU s, a thread pool) out of numba's array
    math in the importing thread only: another thread's import of it succeeds, and a numba
    function that needs BLAS still compiles afterwards. A fresh process, since this test's own
    process may hold scipy.linalg already."""
    import subprocess
    import sys
    from pathlib import Path

    code = textwrap.dedent(NO_SCIPY_LINALG)
    env = dict(os.environ, PYTHONPATH=str(Path(__file__).resolve().parents[1]))
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300, env=env)
    assert r.returncode == 0, r.stderr
    assert "scipy.linalg from the other thread: ['scipy.linalg']" in r.stdout and "dot 3.0" in r.stdout, r.stdout

    alone = ("import sys\nfrom viewer.pathtracer import compiled\nimport numba.np.arraymath as a\n"
             "print('scipy.linalg' in sys.modules, a._HAVE_BLAS)\n")
    r = subprocess.run([sys.executable, "-c", alone], capture_output=True, text=True, timeout=300, env=env)
    assert r.returncode == 0 and r.stdout.split() == ["False", "False"], (r.stdout, r.stderr)
