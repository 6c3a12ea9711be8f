"""The two reference engines share one interface (``ReferenceEngine``), one options object
(``EstimatorOptions``) and one way from sums to mean and variance (viewer/reference_common/estimator.py)."""

from __future__ import annotations

import inspect

import numpy as np
import pytest

from viewer import ViewerError
from viewer.gpupt.engine import GpuReferenceRenderer
from viewer.pathtracer import ReferenceRenderer
from viewer.reference_common.estimator import EstimatorOptions, ReferenceEngine, mean_of, variance_of_mean

METHODS = ("step", "mean", "variance", "state", "resume", "reset", "warm_up", "close")


@pytest.mark.parametrize("cls", [ReferenceRenderer, GpuReferenceRenderer])
def test_both_engines_have_the_interface(cls):
    for name in METHODS:
        want = inspect.signature(getattr(ReferenceEngine, name))
        got = inspect.signature(getattr(cls, name))
        assert list(got.parameters) == list(want.parameters), (cls.__name__, name)
    assert cls.engine in ("cpu", "gpu")


def test_a_cpu_engine_is_a_reference_engine():
    from viewer.scene import load_scene

    with ReferenceRenderer(load_scene("sphere"), width=4, height=3, workers=0,
                           strategy="bsdf", russian_roulette=False) as r:
        assert isinstance(r, ReferenceEngine)
        assert r.options == EstimatorOptions("bsdf", "power", False)
        r.reset(load_scene("sphere"), width=4, height=3, mis_heuristic="balance")
        assert r.options == EstimatorOptions("bsdf", "balance", False)   # the rest as before


def test_options_are_checked_and_updated():
    o = EstimatorOptions()
    assert o.as_kwargs() == {"strategy": "mis", "mis_heuristic": "power", "russian_roulette": True,
                             "integrator": "path"}
    assert o.updated() == o and o.updated(strategy="light").strategy == "light"
    assert o.updated(russian_roulette=False).russian_roulette is False
    with pytest.raises(ViewerError, match="not a sampling strategy"):
        EstimatorOptions("nee")
    with pytest.raises(ViewerError, match="not a heuristic"):
        o.updated(mis_heuristic="max")


def test_mean_and_variance_of_sums_are_numpy_s():
    """Against numpy's own mean and ddof=1 variance of the samples, with a sample count per
    pixel (the GPU engine's) and one for the image (the CPU engine's)."""
    rng = np.random.default_rng(5)
    x = rng.normal(2.0, 3.0, size=(7, 2, 3, 3))               # 7 samples of a 2 x 3 RGB image
    total, total2 = x.sum(axis=0), (x * x).sum(axis=0)
    np.testing.assert_allclose(mean_of(total, 7), x.mean(axis=0), rtol=1e-6)
    np.testing.assert_allclose(variance_of_mean(total, total2, 7), x.var(axis=0, ddof=1) / 7, rtol=1e-5)
    n = np.array([[0, 1, 2], [3, 7, 7]], float)[:, :, None]   # per pixel: the first n samples
    k = np.arange(7)[:, None, None, None] < n[None]
    total, total2 = (x * k).sum(axis=0), (x * x * k).sum(axis=0)
    m, v = mean_of(total, n), variance_of_mean(total, total2, n)
    assert np.all(m[0, 0] == 0) and np.all(np.isinf(v[0, :2]))   # no sample: 0; fewer than 2: inf
    np.testing.assert_allclose(m[1, 1], x[:, 1, 1].mean(axis=0), rtol=1e-6)
    np.testing.assert_allclose(v[1, 0], x[:3, 1, 0].var(axis=0, ddof=1) / 3, rtol=1e-5)
    assert mean_of(np.full((1, 1, 3), 1e300), 1).max() == np.finfo(np.float32).max   # saturates
    assert np.isinf(variance_of_mean(np.ones((1, 1, 3)), np.full((1, 1, 3), np.inf), 4)).all()
