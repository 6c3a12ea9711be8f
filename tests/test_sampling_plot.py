"""The sampling plot (``plot MODEL --kind sampling``) shows exactly the chi-square test's numbers:
its histogram and integrated pdf equal ``chi2_test``'s for the same model, direction, samples
and seed, and its p-value is the test's."""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest

from viewer import ViewerError, brdf, plots
from viewer.brdf.chi2 import chi2_test


@pytest.mark.parametrize("model,overrides,theta", [("microfacet", {"alpha": 0.3}, 45.0),
                                                   ("dielectric", {"alpha": 0.3}, 30.0),
                                                   ("lambert", {}, 0.0)])
def test_sampling_plot_equals_the_chi2_harness(model, overrides, theta):
    m = brdf.get(model)
    p = m.params(**overrides)
    n, seed = 20_000, 7
    d = plots.sampling_histogram(p, theta, 0.0, samples=n, seed=seed)
    wo = plots.direction(theta, 0.0)
    res = chi2_test(m, p, wo, n, np.random.default_rng(seed), alpha=0.0, sphere=m.spec.transmissive)
    # the plot shows row 0 = the pole; the harness's row 0 is the lowest cos theta
    np.testing.assert_array_equal(d["observed"], res.observed[::-1])
    np.testing.assert_array_equal(d["expected"], res.expected[::-1])
    assert d["p_value"] == res.p_value and d["dof"] == res.dof and d["chi2"] == res.stat
    assert d["rows"] == (51 if m.spec.transmissive else 25) and d["cols"] == 50
    # a correct sampler: not rejected at 1e-3, the histogram sums to the successful samples
    assert d["p_value"] > 1e-3
    assert d["observed"].sum() + d["failed"] == n
    np.testing.assert_allclose(d["difference"], (d["observed"] - d["expected"]) / np.sqrt(np.maximum(d["expected"], 1)))
    pts = d["points"]
    assert len(pts) > 0.5 * 1500 and np.allclose(np.linalg.norm(pts, axis=1), 1.0)


def test_sampling_plot_rejects_a_wrong_sampler():
    """The p-value is the harness's, so a sampler that does not match its pdf shows p ~ 0."""
    m = brdf.get("microfacet")
    p = m.params(alpha=0.3)
    wrong = brdf.get("microfacet").params(alpha=0.4)

    class Mismatched:  # samples alpha 0.3, claims the pdf of alpha 0.4
        spec = m.spec

        @staticmethod
        def sample(_p, wo, u):
            return m.sample(p, wo, u)

        @staticmethod
        def pdf(_p, wi, wo):
            return m.pdf(wrong, wi, wo)

    from viewer.brdf.chi2 import chi2_from_counts, histogram, integrate_pdf

    obs, failed, problems = histogram(Mismatched, p, plots.direction(45.0), 20_000, np.random.default_rng(0), 25, 50, False)
    exp = 20_000 * integrate_pdf(Mismatched, p, plots.direction(45.0), 25, 50, False, n_samples=20_000)
    assert chi2_from_counts(obs, failed, problems, exp, 20_000, 1e-3).p_value < 1e-6


def test_sampling_plot_cli_and_delta_models(tmp_path):
    out, data = tmp_path / "s.png", tmp_path / "s.json"
    r = subprocess.run([sys.executable, "-m", "viewer", "plot", "lecture_ggx", "--kind", "sampling", "--out", str(out),
                        "--data", str(data), "--samples", "5000", "--theta-i", "60"],
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    d = json.loads(data.read_text())
    assert d["kind"] == "sampling" and d["info"]["samples"] == 5000 and d["info"]["theta_i"] == 60.0
    assert plots.read_plot_data(out)["info"]["p_value"] == d["info"]["p_value"]
    with pytest.raises(ViewerError, match="delta lobe"):
        plots.figure(brdf.get("mirror").params(), "sampling")
    assert "sampling" not in plots.applicable_kinds(brdf.get("dielectric").params())   # smooth glass
    assert "sampling" in plots.applicable_kinds(brdf.get("dielectric").params(alpha=0.2))
    with pytest.raises(ViewerError, match="--samples"):
        plots.sampling_histogram(brdf.get("lambert").params(), samples=10)
