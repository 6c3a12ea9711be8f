"""Dielectric (smooth and rough glass), mirror and the layered (Weidlich-Wilkie) model."""

import numpy as np
import pytest

from viewer import brdf
from viewer.brdf.fresnel import fresnel_conductor, fresnel_dielectric
from viewer.brdf.chi2 import chi2_test

from brdf_harness import direction

GLASS = brdf.get("dielectric")
MIRROR = brdf.get("mirror")
LAYERED = brdf.get("layered")


def _wo(theta_deg, n, phi=0.3):
    """A direction at theta (degrees, > 90 = from inside) repeated n times."""
    return np.broadcast_to(direction(theta_deg, phi), (n, 3)).copy()


# ----------------------------------------------------------------------------- smooth glass

@pytest.mark.parametrize("ior", [1.333, 1.5, 2.42])
@pytest.mark.parametrize("theta", [0.0, 40.0, 75.0, 89.0, 150.0])
def test_smooth_reflection_fraction_is_fresnel(ior, theta):
    n = 200_000
    p = GLASS.params(ior=ior)
    wo = _wo(theta, n)
    wi, w, pdf = GLASS.sample(p, wo, np.random.default_rng(1).random((n, 2)))
    refl = wi[:, 2] * wo[:, 2] > 0
    R = fresnel_dielectric(abs(np.cos(np.radians(theta))), ior if theta < 90 else 1.0 / ior)
    assert abs(refl.mean() - R) < 5 * np.sqrt(R * (1 - R) / n) + 1e-9
    # pdf = probability of the chosen lobe; the two lobes' probabilities sum to 1 (R + T = 1)
    np.testing.assert_allclose(pdf[refl], R)
    np.testing.assert_allclose(pdf[~refl], 1.0 - R)
    # the reflected direction is the mirror direction; the refracted one obeys Snell's law
    np.testing.assert_allclose(wi[refl], wo[refl] * np.array([-1, -1, 1]), atol=1e-12)
    eta = ior if theta < 90 else 1.0 / ior
    if (~refl).any():
        sin_o = np.linalg.norm(wo[~refl, :2], axis=1)
        sin_i = np.linalg.norm(wi[~refl, :2], axis=1)
        np.testing.assert_allclose(sin_o, eta * sin_i, atol=1e-12)
    # throughput: 1 for reflection, 1 / eta^2 for transmission (radiance; pbrt-v4), so that
    # weight * eta^2 (importance / energy) gives R + T = 1 on average
    np.testing.assert_allclose(w[refl], 1.0)
    np.testing.assert_allclose(w[~refl], 1.0 / eta ** 2)
    energy = np.where(refl, 1.0, eta ** 2) * w[:, 0]
    assert energy.mean() == pytest.approx(1.0)
    # delta lobes: eval and pdf are 0 as functions
    assert np.all(GLASS.eval(p, wi, wo) == 0.0) and np.all(GLASS.pdf(p, wi, wo) == 0.0)


@pytest.mark.parametrize("ior", [1.333, 1.5, 2.42])
def test_total_internal_reflection_from_inside(ior):
    theta_c = np.degrees(np.arcsin(1.0 / ior))
    n = 10_000
    for beyond in (theta_c + 0.5, 80.0, 89.9):
        wo = _wo(180.0 - beyond, n)  # inside: wo.z < 0
        wi, w, pdf = GLASS.sample(GLASS.params(ior=ior), wo, np.random.default_rng(2).random((n, 2)))
        assert np.all(wi[:, 2] < 0)  # stays inside
        np.testing.assert_allclose(pdf, 1.0)
        np.testing.assert_allclose(w, 1.0)


def test_sigma_a_does_not_change_the_interface():
    n = 1000
    wo = _wo(30.0, n)
    u = np.random.default_rng(3).random((n, 2))
    a = GLASS.sample(GLASS.params(alpha=0.2), wo, u)
    b = GLASS.sample(GLASS.params(alpha=0.2, sigma_a=[50.0, 5.0, 0.5]), wo, u)
    for x, y in zip(a, b):
        np.testing.assert_array_equal(x, y)


# ----------------------------------------------------------------------------- rough glass

def _energy(p, theta, n=200_000, seed=4):
    """Directional albedo of reflection + transmission in importance terms (weights of the
    transmission lobe times eta^2 undo the radiance scaling), with its standard error."""
    wo = _wo(theta, n)
    wi, w, pdf = GLASS.sample(p, wo, np.random.default_rng(seed).random((n, 2)))
    eta = p.ior if wo[0, 2] > 0 else 1.0 / p.ior
    e = np.where(wi[:, 2] * wo[:, 2] < 0, eta ** 2, 1.0) * w[:, 0]
    return e.mean(), e.std() / np.sqrt(n)


@pytest.mark.parametrize("theta", [0.0, 45.0, 80.0, 135.0, 170.0])
def test_rough_glass_energy(theta):
    for alpha in (0.01, 0.2, 0.6, 1.0):
        mean, se = _energy(GLASS.params(alpha=alpha, ior=1.5), theta, n=60_000)
        assert mean <= 1.0 + 5 * se, (alpha, mean)
    # nearly smooth: reflection + transmission = 1 (nothing lost to masking)
    mean, se = _energy(GLASS.params(alpha=0.01, ior=1.5), theta)
    assert mean == pytest.approx(1.0, abs=3e-3)


@pytest.mark.parametrize("theta", [20.0, 70.0, 120.0, 160.0])
@pytest.mark.parametrize("alpha", [0.1, 0.5])
def test_rough_glass_sampling_matches_pdf(theta, alpha):
    p = GLASS.params(alpha=alpha, ior=1.5)
    res = chi2_test(GLASS, p, direction(theta, 0.37), 150_000, np.random.default_rng(5), 1e-4,
                    rows=11, cols=24, sphere=True)
    assert res.ok, res.message


def test_rough_glass_weight_is_f_cos_over_pdf():
    rng = np.random.default_rng(6)
    p = GLASS.params(alpha=0.3, ior=1.7)
    for theta in (30.0, 150.0):
        wo = _wo(theta, 20_000)
        wi, w, pdf = GLASS.sample(p, wo, rng.random((20_000, 2)))
        ok = pdf > 0
        f = GLASS.eval(p, wi[ok], wo[ok])
        np.testing.assert_allclose(w[ok], f * np.abs(wi[ok, 2:3]) / pdf[ok, None], rtol=1e-10)
        np.testing.assert_allclose(GLASS.pdf(p, wi[ok], wo[ok]), pdf[ok], rtol=1e-10)


def test_rough_glass_generalized_reciprocity():
    # radiance mode: f(wi, wo) / eta_o^2 = f(wo, wi) / eta_i^2 across the interface (Veach 1997,
    # eq. 5.36: radiance entering the denser medium grows by eta^2); reflection is reciprocal
    rng = np.random.default_rng(7)
    p = GLASS.params(alpha=0.4, ior=1.5)
    a = rng.normal(size=(2000, 3))
    a /= np.linalg.norm(a, axis=1, keepdims=True)
    b = rng.normal(size=(2000, 3))
    b /= np.linalg.norm(b, axis=1, keepdims=True)
    a[:, 2] = np.abs(a[:, 2])   # outside (index 1)
    b[:, 2] = -np.abs(b[:, 2])  # inside (index 1.5): transmission
    np.testing.assert_allclose(GLASS.eval(p, a, b) / 1.5 ** 2, GLASS.eval(p, b, a), rtol=1e-6, atol=1e-300)
    b[:, 2] = np.abs(b[:, 2])   # both outside: reflection
    np.testing.assert_allclose(GLASS.eval(p, a, b), GLASS.eval(p, b, a), rtol=1e-6)


# ----------------------------------------------------------------------------- mirror

def test_mirror_sample():
    n = 100
    wo = _wo(50.0, n)
    for kw, F in [(dict(fresnel="none"), 1.0), (dict(fresnel="dielectric", ior=1.5), fresnel_dielectric(np.cos(np.radians(50)), 1.5)),
                  (dict(fresnel="conductor"), None)]:
        p = MIRROR.params(**kw)
        wi, w, pdf = MIRROR.sample(p, wo, np.random.default_rng(0).random((n, 2)))
        np.testing.assert_allclose(wi, wo * np.array([-1, -1, 1]))
        np.testing.assert_allclose(pdf, 1.0)
        if F is None:
            F = fresnel_conductor(np.cos(np.radians(50)), p.eta, p.k)
        np.testing.assert_allclose(w, np.broadcast_to(F, (n, 3)))
        assert np.all(MIRROR.eval(p, wi, wo) == 0) and np.all(MIRROR.pdf(p, wi, wo) == 0)


# ----------------------------------------------------------------------------- layered

BASES = [{"model": "lambert", "albedo": [1.0, 1.0, 1.0]},
         {"model": "lambert", "albedo": [0.5, 0.1, 0.1]},
         {"model": "microfacet", "alpha": 0.3}]


def _layered(**coating):
    base = coating.pop("base", BASES[1])
    c = {"ior": 1.5, "alpha": 0.1, "thickness": 10.0, "sigma_a": [0.0, 0.0, 0.0]}
    c.update(coating)
    return LAYERED.params(coating=c, base=base)


@pytest.mark.parametrize("base", BASES)
def test_layered_reduces_to_base_without_coating(base):
    # coating ior = 1 (no Fresnel, no refraction) and sigma_a = 0: f = f_base exactly
    rng = np.random.default_rng(8)
    wi = rng.normal(size=(3000, 3))
    wi /= np.linalg.norm(wi, axis=1, keepdims=True)
    wo = np.roll(wi, 7, axis=0)
    p = _layered(ior=1.0, alpha=0.2, base=base)
    b = brdf.get(base["model"])
    pb = b.params(**{k: v for k, v in base.items() if k != "model"})
    np.testing.assert_allclose(LAYERED.eval(p, wi, wo), b.eval(pb, wi, wo), rtol=1e-6, atol=1e-300)
    np.testing.assert_allclose(LAYERED.pdf(p, wi, wo), b.pdf(pb, wi, wo), rtol=1e-6, atol=1e-300)


@pytest.mark.parametrize("base", BASES)
def test_layered_albedo_at_most_one(base):
    for ior in (1.0, 1.5, 3.0):
        for alpha in (0.001, 0.3, 1.0):
            p = _layered(ior=ior, alpha=alpha, base=base)
            for theta in (0.0, 60.0, 85.0):
                n = 30_000
                _, w, _ = LAYERED.sample(p, _wo(theta, n), np.random.default_rng(9).random((n, 2)))
                mean, se = w.mean(axis=0), w.std(axis=0) / np.sqrt(n)
                assert np.all(mean <= 1.0 + 5 * se), (ior, alpha, theta, mean)


def test_layered_absorption_darkens_per_channel():
    rng = np.random.default_rng(10)
    wi = np.abs(rng.normal(size=(500, 3))) * np.array([1, 1, 1])
    wi /= np.linalg.norm(wi, axis=1, keepdims=True)
    wo = np.roll(wi, 3, axis=0)
    clear = LAYERED.eval(_layered(base=BASES[0]), wi, wo)
    tinted = LAYERED.eval(_layered(base=BASES[0], sigma_a=[0.0, 0.05, 0.2]), wi, wo)
    assert np.allclose(tinted[:, 0], clear[:, 0])
    assert np.all(tinted[:, 1] < clear[:, 1]) and np.all(tinted[:, 2] < tinted[:, 1])


@pytest.mark.parametrize("base", BASES[1:])
@pytest.mark.parametrize("theta", [10.0, 70.0])
def test_layered_sampling_matches_pdf(base, theta):
    p = _layered(alpha=0.2, base=base)
    res = chi2_test(LAYERED, p, direction(theta, 0.37), 150_000, np.random.default_rng(11), 1e-4,
                    rows=15, cols=30)
    assert res.ok, res.message


def test_layered_is_reciprocal():
    rng = np.random.default_rng(12)
    wi = np.abs(rng.normal(size=(2000, 3)))
    wi /= np.linalg.norm(wi, axis=1, keepdims=True)
    wo = np.abs(rng.normal(size=(2000, 3)))
    wo /= np.linalg.norm(wo, axis=1, keepdims=True)
    for base in BASES:
        p = _layered(base=base, sigma_a=[0.01, 0.02, 0.03])
        np.testing.assert_allclose(LAYERED.eval(p, wi, wo), LAYERED.eval(p, wo, wi), rtol=1e-10)


def test_layered_over_a_mirror_base():
    # a delta base is reached through sample only: pdf = (1 - P_coat) * 1, throughput T_i T_o F
    p = LAYERED.params(coating={"ior": 1.5, "alpha": 0.1, "thickness": 0.0},
                       base={"model": "mirror", "fresnel": "none"})
    n = 20_000
    wi, w, pdf = LAYERED.sample(p, _wo(30.0, n), np.random.default_rng(13).random((n, 2)))
    assert np.all(np.isfinite(w)) and np.all(np.isfinite(pdf))
    mean = w.mean(axis=0)
    assert np.all(mean <= 1.0 + 1e-6) and np.all(mean > 0.8)
