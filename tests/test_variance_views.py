"""The Monte Carlo error views (``viewer.image.variance``) against independent truths: the standard
error the view shows from one render's running variance equals the spread of the pixel means of
renders with independent seeds; relative error and samples needed follow from it; the estimated
RMSE falls as spp^-1/2."""

from __future__ import annotations

import numpy as np
import pytest

from viewer.image import variance as V
from viewer.pathtracer import ReferenceRenderer

from reference_harness import glossy_studio

K, N = 12, 16   # independent seeds, samples per pixel each


@pytest.fixture(scope="module")
def renders():
    scene = glossy_studio()
    scene.camera.width = scene.camera.height = 16
    means, views = [], []
    with ReferenceRenderer(scene, workers=0, seed=0, max_depth=1) as r:
        for k in range(K):
            r.seed = 1000 + k
            r.reset(scene)
            r.step(N)
            means.append(r.mean().astype(np.float64))
            views.append(V.standard_error(r.variance()) ** 2)
    return np.array(means), np.array(views)


def test_standard_error_view_equals_the_spread_over_independent_seeds(renders):
    means, views = renders
    across = means.var(axis=0, ddof=1).mean(axis=-1)    # per pixel, over seeds (mean over channels)
    shown = views.mean(axis=0)                           # what the view shows, averaged over the runs
    lit = shown > 0
    assert lit.sum() > 150
    ratio = across[lit].sum() / shown[lit].sum()
    # Both estimate the same variance of the mean: `across` from K = 12 independent renders
    # (11 degrees of freedom per pixel), `shown` from each render's own 16 samples. Over ~220
    # pixels a Gaussian estimate would scatter by ~3%; the heavy tail of the studio map (small
    # bright panels seen through a glossy lobe) widens that (0.88-1.03 over four sets of
    # seeds), so 25% is the bound. The per-pixel median of the ratio is chi2(11)/11's median,
    # 0.94, when both agree.
    assert 0.75 < ratio < 1.25, ratio
    med = float(np.median(across[lit] / shown[lit]))
    assert 0.75 < med < 1.15, med
    # and the view is of the mean, not of one sample (that would be N = 16 times larger)
    assert ratio * N > 4


def test_relative_error_and_samples_needed_follow_from_it():
    rng = np.random.default_rng(0)
    mean = rng.random((8, 9, 3)) + 0.1
    var = rng.random((8, 9, 3)) * 1e-3
    se = V.error_view("standard error", mean, var, 10)
    np.testing.assert_allclose(se, np.sqrt(var.mean(axis=-1)))
    rel = V.error_view("relative error", mean, var, 10)
    np.testing.assert_allclose(rel, se / (mean.mean(axis=-1) + 0.01))
    need = V.error_view("samples needed", mean, var, 10, target=0.01)
    np.testing.assert_allclose(need, 10 * (rel / 0.01) ** 2)
    # at the target equal to the current error, exactly the samples taken
    np.testing.assert_allclose(V.samples_needed(mean[:1, :1], var[:1, :1], 10, float(rel[0, 0])), 10.0)
    with pytest.raises(ValueError):
        V.error_view("bias", mean, var, 10)


def test_estimated_rmse_falls_as_one_over_sqrt_spp():
    scene = glossy_studio()
    scene.camera.width = scene.camera.height = 12
    curve = V.ConvergenceCurve("mis")
    with ReferenceRenderer(scene, workers=0, seed=4, max_depth=1) as r:
        for _ in range(6):
            r.step(r.spp or 4)  # 4, 8, 16, ... 128 spp
            curve.add(r.spp, V.rmse_estimate(r.variance()))
    assert curve.spp == [4, 8, 16, 32, 64, 128]
    # the slope of a Monte Carlo estimator's error on log-log axes is -1/2; the variance
    # estimates themselves scatter, so the fit over 5 doublings is held to +-0.15
    assert abs(curve.fitted_slope() + 0.5) < 0.15, curve.rmse
    x, y = curve.slope_line()
    assert x[0] == 4 and y[-1] == curve.rmse[-1] and y[0] == pytest.approx(curve.rmse[-1] * np.sqrt(32))
