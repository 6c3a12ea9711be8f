"""Properties every registered BRDF must have (parametrized over ``brdf.names()``): sampling matches
the pdf (chi-square), weights are f cos / pdf, directional albedo <= 1 (two independent estimators
that must agree: the furnace cross-check), reciprocity, and no NaN/Inf anywhere in range.

Sample counts: BRDF_CHI2_SAMPLES (default 1e6 per chi-square case)."""

from __future__ import annotations

import os
import zlib

import numpy as np
import pytest

from viewer import brdf
from viewer.brdf.chi2 import chi2_test

from brdf_harness import (albedo_sampler, is_delta, albedo_uniform, direction, param_grid,
                          random_params, random_upper, sidak, sweep_directions, test_param_sets,
                          write_chi2_images)

NAMES = brdf.names()
NON_DELTA = [n for n in NAMES if not brdf.get(n).spec.delta]
THETA_O = (0.0, 30.0, 60.0, 80.0)
PHI_O = 0.37  # off the bin edges and the tangent axes (anisotropic models)
CHI2_SAMPLES = int(float(os.environ.get("BRDF_CHI2_SAMPLES", "1e6")))
SIGNIFICANCE = 0.01

CHI2_CASES = [(n, label, t) for n in NON_DELTA for label in test_param_sets(brdf.get(n)) for t in THETA_O]
CHI2_ALPHA = sidak(SIGNIFICANCE, len(CHI2_CASES))
# the default run: every model and parameter set at an oblique and a grazing incidence (where
# lobes shift, clip at the horizon and refract most); normal and 60 degrees with -m slow. The
# significance stays corrected for all the cases, so a case fails alike in either run
CHI2_DEFAULT_THETA = (30.0, 80.0)
K_SIGMA = 5.0  # Monte Carlo tolerances: 5 standard errors (two-sided p ~ 6e-7 per comparison)


def _seed(*parts) -> int:
    """A stable seed per test case (independent of PYTHONHASHSEED)."""
    return zlib.crc32(repr(parts).encode())


# ----------------------------------------------------------------------------- chi-square


@pytest.mark.parametrize("name,label,theta_o", [c if c[2] in CHI2_DEFAULT_THETA else pytest.param(*c, marks=pytest.mark.slow)
                                               for c in CHI2_CASES])
def test_chi2_sample_matches_pdf(name, label, theta_o):
    model = brdf.get(name)
    p = test_param_sets(model)[label]
    wo = direction(theta_o, PHI_O)
    rng = np.random.default_rng(_seed(name, label, theta_o, "chi2"))
    res = chi2_test(model, p, wo, CHI2_SAMPLES, rng, CHI2_ALPHA, sphere=model.spec.transmissive)
    if not res.ok:
        folder = write_chi2_images(res, f"{name}_{label}_{int(theta_o)}") if res.observed is not None else "-"
        pytest.fail(f"{name} [{label}] theta_o={theta_o}: {res.message}; images in {folder}")


# ----------------------------------------------------------------------------- weight and pdf


def _param_sets(model, rng, n_random=4):
    sets = list(test_param_sets(model).values())
    sets += [random_params(model.spec, rng) for _ in range(n_random)]
    return sets


@pytest.mark.parametrize("name", NON_DELTA)
def test_weight_is_f_cos_over_pdf(name):
    model = brdf.get(name)
    rng = np.random.default_rng(_seed(name, "weight"))
    for p in _param_sets(model, rng):
        wo = random_upper(rng, 4000, 89.0)
        wi, w, pdf = model.sample(p, wo, rng.random((len(wo), 2)))
        if p.model == "layered" and is_delta(p.base):
            # a delta base makes the lobe mixed: its discrete samples weigh T a w_b against
            # (1 - P_coat) pdf_b while eval holds the coat alone (test_glsl_sampling checks them
            # through the lobe each sample drew), so such a set is left out here
            continue
        ok = pdf > 0
        assert np.all(w[~ok] == 0), f"{name}: weight != 0 where pdf == 0 ({p.to_plain()})"
        f = model.eval(p, wi[ok], wo[ok])
        expect = f * np.abs(wi[ok, 2:3]) / pdf[ok, None]
        np.testing.assert_allclose(w[ok], expect, rtol=1e-6, atol=1e-12,
                                   err_msg=f"{name}: weight != f |cos| / pdf for {p.to_plain()}")
        np.testing.assert_allclose(pdf[ok], model.pdf(p, wi[ok], wo[ok]), rtol=1e-6, atol=1e-12,
                                   err_msg=f"{name}: pdf from sample != pdf(wi, wo) for {p.to_plain()}")


# ----------------------------------------------------------------------------- albedo / furnace


def _albedo_bound(model):
    bound = model.hook("ALBEDO_BOUND", 1.0)
    if bound > 1.0:
        assert model.hook("ALBEDO_BOUND_WHY", ""), f"{model.name}: ALBEDO_BOUND > 1 needs a why"
    return bound


def _spectral_bound(p, bound):
    """A tabulated material's RGB Fresnel is its spectrum's linear Rec.709 value, above 1 where the
    spectrum lies outside the gamut (gold's red, 1.038 at normal incidence; every wavelength
    reflects < 1): its albedo is bounded per channel by the table's maximum instead of 1."""
    name = p.get("spectral", "none")
    if name == "none":
        return bound
    from viewer.brdf import spectral_fresnel

    return np.maximum(bound, spectral_fresnel.table(name).max(axis=0))


@pytest.mark.parametrize("name", NAMES)
def test_albedo_at_most_one(name):
    """Directional albedo (the sampler's mean weight) <= 1 over the parameter grid, at several angles.
    Tolerance: K_SIGMA standard errors of the estimate (plus 1e-9 for exact estimators)."""
    model = brdf.get(name)
    bound = _albedo_bound(model)
    rng = np.random.default_rng(_seed(name, "albedo"))
    for p in param_grid(model):
        b = _spectral_bound(p, bound)
        for theta in (0.0, 60.0, 85.0, 89.9):
            wo = direction(theta, PHI_O)
            mean, se = albedo_sampler(model, p, wo, 20_000, rng)
            assert np.all(np.isfinite(mean)), f"{name}: albedo not finite for {p.to_plain()}"
            tol = K_SIGMA * se + 1e-9  # Monte Carlo tolerance
            assert np.all(mean <= b + tol), (
                f"{name}: albedo {mean} (se {se}) > {bound} at theta_o={theta} for {p.to_plain()}")


@pytest.mark.parametrize("name", NON_DELTA)
def test_furnace_two_estimators_agree(name):
    """E[weight] from the model's sampler equals the integral of f |cos| estimated with uniform
    directions (an estimator that does not use sample or pdf), within K_SIGMA combined standard errors."""
    model = brdf.get(name)
    rng = np.random.default_rng(_seed(name, "furnace"))
    sphere = model.spec.transmissive
    for label, p in test_param_sets(model).items():
        for theta in (0.0, 45.0, 80.0):
            wo = direction(theta, PHI_O)
            a, sa = albedo_sampler(model, p, wo, 100_000, rng)
            b, sb = albedo_uniform(model, p, wo, 400_000, rng, sphere=sphere)
            tol = K_SIGMA * np.sqrt(sa ** 2 + sb ** 2) + 1e-6  # combined Monte Carlo standard error
            assert np.all(np.abs(a - b) <= tol), (
                f"{name} [{label}] theta_o={theta}: sampler albedo {a} +- {sa} vs uniform {b} +- {sb}")


def test_lambert_albedo_is_albedo():
    model = brdf.get("lambert")
    p = model.params(albedo=[0.2, 0.5, 0.9])
    rng = np.random.default_rng(3)
    for theta in (0.0, 45.0, 85.0):
        a, _ = albedo_sampler(model, p, direction(theta), 10_000, rng)
        np.testing.assert_allclose(a, [0.2, 0.5, 0.9], rtol=1e-12)
        b, sb = albedo_uniform(model, p, direction(theta), 200_000, rng)
        assert np.all(np.abs(b - [0.2, 0.5, 0.9]) <= K_SIGMA * sb)


# ----------------------------------------------------------------------------- reciprocity


@pytest.mark.parametrize("name", NAMES)
def test_reciprocity(name):
    model = brdf.get(name)
    if not model.spec.reciprocal:
        assert model.spec.reciprocal_why.strip(), f"{name}: reciprocal=False needs reciprocal_why"
        return
    rng = np.random.default_rng(_seed(name, "recip"))
    for p in _param_sets(model, rng):
        wi = random_upper(rng, 5000, 89.9)
        wo = random_upper(rng, 5000, 89.9)
        a = model.eval(p, wi, wo)
        b = model.eval(p, wo, wi)
        np.testing.assert_allclose(a, b, rtol=1e-7, atol=1e-12 * max(1.0, float(np.abs(a).max())),
                                   err_msg=f"{name}: f(wi, wo) != f(wo, wi) for {p.to_plain()}")


# ----------------------------------------------------------------------------- NaN sweep


SWEEP_U = np.array([[0.0, 0.0], [0.5, 0.5], [1 - 2 ** -53, 1 - 2 ** -53], [0.0, 1 - 2 ** -53],
                    [1 - 2 ** -53, 0.0], [0.25, 0.75], [0.999, 0.001], [1e-12, 0.5]])


def _check_finite(name, p, what, a, nonneg=True):
    assert np.all(np.isfinite(a)), f"{name}: {what} not finite for {p.to_plain()}"
    if nonneg:
        assert np.all(a >= 0), f"{name}: {what} negative for {p.to_plain()}"


@pytest.mark.parametrize("name", NAMES)
def test_no_nan_at_extremes(name):
    """eval / pdf / sample finite and >= 0 for the parameter grid (extremes) and random parameters,
    at normal, grazing (cos = 1e-6 and 0) and back-facing directions."""
    model = brdf.get(name)
    rng = np.random.default_rng(_seed(name, "nan"))
    d = sweep_directions()
    wi = np.repeat(d, len(d), axis=0)
    wo = np.tile(d, (len(d), 1))
    wo_s = np.repeat(d, len(SWEEP_U), axis=0)
    u_s = np.tile(SWEEP_U, (len(d), 1))
    u_r = rng.random((len(d) * 64, 2))
    wo_r = np.repeat(d, 64, axis=0)
    for p in param_grid(model) + [random_params(model.spec, rng) for _ in range(10)]:
        _check_finite(name, p, "eval", model.eval(p, wi, wo))
        _check_finite(name, p, "pdf", model.pdf(p, wi, wo))
        for wo_, u_ in ((wo_s, u_s), (wo_r, u_r)):
            wi_, w_, pdf_ = model.sample(p, wo_, u_)
            _check_finite(name, p, "sample weight", w_)
            _check_finite(name, p, "sample pdf", pdf_)
            ok = pdf_ > 0
            _check_finite(name, p, "sampled wi", wi_[ok], nonneg=False)
            assert np.allclose(np.linalg.norm(wi_[ok], axis=1), 1.0, atol=1e-6), f"{name}: wi not unit"
            assert np.all(w_[~ok] == 0), f"{name}: weight != 0 where pdf == 0"


@pytest.mark.parametrize("name", NAMES)
def test_random_params_are_valid(name):
    model = brdf.get(name)
    rng = np.random.default_rng(_seed(name, "random"))
    for _ in range(20):
        p = random_params(model.spec, rng)
        again = model.params(**{k: v for k, v in p.to_plain().items() if k != "model"})
        assert again.model == name


# ----------------------------------------------------------------------------- model identities


@pytest.mark.parametrize("variant", ["full", "qualitative"])
def test_oren_nayar_sigma0_is_lambert(variant):
    on, lam = brdf.get("oren_nayar"), brdf.get("lambert")
    rng = np.random.default_rng(7)
    wi, wo = random_upper(rng, 2000, 89.99), random_upper(rng, 2000, 89.99)
    a = on.eval(on.params(albedo=[0.3, 0.6, 0.9], sigma=0.0, variant=variant), wi, wo)
    b = lam.eval(lam.params(albedo=[0.3, 0.6, 0.9]), wi, wo)
    np.testing.assert_array_equal(a, b)


def test_lafortune_phong_lobe_equals_normalized_phong():
    """Cx = Cy = -C, Cz = C with C^n = ks (n + 2) / (2 pi) is the normalized Phong lobe."""
    laf, ph = brdf.get("lafortune"), brdf.get("phong")
    n, ks = 50.0, 0.6
    c = (ks * (n + 2) / (2 * np.pi)) ** (1 / n)
    p1 = laf.params(kd=0.2, lobes=[{"cx": -c, "cy": -c, "cz": c, "n": n}])
    p2 = ph.params(kd=0.2, ks=ks, shininess=n)
    rng = np.random.default_rng(8)
    wi, wo = random_upper(rng, 3000), random_upper(rng, 3000)
    np.testing.assert_allclose(laf.eval(p1, wi, wo), ph.eval(p2, wi, wo), rtol=1e-10)


@pytest.mark.parametrize("name", ["phong", "blinn_phong"])
@pytest.mark.parametrize("n", [1.0, 10.0, 1000.0])
def test_normalized_lobe_albedo_is_ks_at_normal_incidence(name, n):
    """Lafortune & Willems 1994 / Giesen 2009: the lobe alone reflects exactly ks at normal incidence."""
    model = brdf.get(name)
    p = model.params(kd=0.0, ks=1.0, shininess=n)
    a, se = albedo_sampler(model, p, direction(0.0), 200_000, np.random.default_rng(9))
    assert np.all(np.abs(a - 1.0) <= K_SIGMA * se + 1e-9), (a, se)
