"""Fresnel reflectance (viewer.brdf.fresnel) and the metal / dielectric presets."""

import numpy as np
import pytest

from viewer import brdf
from viewer.brdf.fresnel import (fresnel_conductor, fresnel_conductor_polarized, fresnel_dielectric,
                                 fresnel_dielectric_polarized, fresnel_dielectric_transmittance,
                                 fresnel_schlick)
from viewer.brdf.presets import METALS, PRESETS, metal_f0

COS = np.linspace(0.0, 1.0, 201)


@pytest.mark.parametrize("n", [1.0, 1.333, 1.5, 2.42, 3.0])
def test_dielectric_normal_incidence(n):
    assert fresnel_dielectric(1.0, n) == pytest.approx(((n - 1) / (n + 1)) ** 2, abs=1e-15)


@pytest.mark.parametrize("n,k", [(0.14, 3.70), (1.47, 7.79), (2.0, 0.0), (3.0, 3.3)])
def test_conductor_normal_incidence(n, k):
    expect = ((n - 1) ** 2 + k * k) / ((n + 1) ** 2 + k * k)
    assert fresnel_conductor(1.0, n, k) == pytest.approx(expect, abs=1e-14)


@pytest.mark.parametrize("n", [1.333, 1.5, 2.42])
def test_brewster_angle_kills_p(n):
    cos_b = np.cos(np.arctan(n))  # Brewster: tan(theta_B) = n_t / n_i
    Rs, Rp = fresnel_dielectric_polarized(cos_b, n)
    assert Rp < 1e-20 and Rs > 0.0
    # and from the inside (eta = 1/n), Brewster's angle is atan(1/n)
    _, Rp_in = fresnel_dielectric_polarized(np.cos(np.arctan(1.0 / n)), 1.0 / n)
    assert Rp_in < 1e-20


@pytest.mark.parametrize("n", [1.333, 1.5, 2.42])
def test_total_internal_reflection(n):
    theta_c = np.arcsin(1.0 / n)
    theta = np.linspace(theta_c + 1e-6, np.pi / 2, 50)
    assert np.all(fresnel_dielectric(np.cos(theta), 1.0 / n) == 1.0)
    assert np.all(fresnel_dielectric_transmittance(np.cos(theta), 1.0 / n) == 0.0)
    # negative cos_i means "from the other side": the same as eta -> 1/eta
    assert np.all(fresnel_dielectric(-np.cos(theta), n) == 1.0)
    below = np.linspace(0.0, theta_c - 1e-3, 50)
    assert np.all(fresnel_dielectric(np.cos(below), 1.0 / n) < 1.0)


def test_grazing_goes_to_one():
    for n in (1.1, 1.5, 3.0):
        assert fresnel_dielectric(1e-7, n) > 0.999
    assert np.all(fresnel_conductor(1e-7, np.array([0.14, 1.5]), np.array([3.7, 7.0])) > 0.999)


def test_s_dominates_p():
    for n in (0.5, 1.0 / 1.5, 1.2, 1.5, 2.5):
        Rs, Rp = fresnel_dielectric_polarized(COS, n)
        assert np.all(Rs >= Rp - 1e-15)
    for n, k in [(0.14, 3.7), (1.5, 0.5), (3.0, 3.3), (0.5, 0.0)]:
        Rs, Rp = fresnel_conductor_polarized(COS, n, k)
        assert np.all(Rs >= Rp - 1e-15)


@pytest.mark.parametrize("eta", [0.6, 1.0 / 1.5, 1.0, 1.2, 1.5, 2.42])
def test_conductor_with_zero_k_is_dielectric(eta):
    # (rtol 1e-7: right at the critical angle R is ill-conditioned and the two formulas round apart)
    np.testing.assert_allclose(fresnel_conductor(COS[1:], eta, 0.0), fresnel_dielectric(COS[1:], eta),
                               rtol=1e-7, atol=1e-14)


def test_transmittance_is_one_minus_reflectance():
    for eta in (0.5, 1.0 / 1.5, 1.5, 2.42):
        np.testing.assert_allclose(fresnel_dielectric_transmittance(COS, eta), 1.0 - fresnel_dielectric(COS, eta),
                                   atol=1e-13)


def test_schlick_close_to_exact_for_glass():
    # Schlick 1994's approximation: exact at normal incidence and at grazing; for n = 1.5 its
    # largest error is ~0.036 near 85 degrees, and below 0.005 within 40 degrees of the normal.
    f0 = ((1.5 - 1) / 2.5) ** 2
    exact = fresnel_dielectric(COS, 1.5)
    approx = fresnel_schlick(COS, f0)
    assert abs(approx[-1] - exact[-1]) < 1e-15
    assert np.max(np.abs(approx - exact)) < 0.04
    near = COS > np.cos(np.radians(40))
    assert np.max(np.abs(approx[near] - exact[near])) < 5e-3


def test_broadcasting_and_scalars():
    assert isinstance(fresnel_dielectric(0.5, 1.5), float)
    assert isinstance(fresnel_conductor(0.5, 0.2, 3.0), float)
    assert isinstance(fresnel_schlick(0.5, 0.04), float)
    r = fresnel_conductor(COS[:, None], np.array([0.14, 0.43, 1.38]), np.array([3.7, 2.46, 1.91]))
    assert r.shape == (COS.size, 3)
    assert fresnel_dielectric(COS[:, None], np.array([1.2, 1.5])).shape == (COS.size, 2)
    # the registry re-exports them (the public BRDF interface of docs/python-api.md)
    assert brdf.fresnel_dielectric(1.0, 1.5) == pytest.approx(0.04)
    assert brdf.fresnel_conductor(1.0, 1.5, 0.0) == pytest.approx(0.04)


def test_metal_presets_have_familiar_colours():
    f0 = {name: metal_f0(name) for name in METALS}
    gold = f0["gold"]
    assert gold[0] > 0.9 and 0.7 < gold[1] < 0.85 and 0.3 < gold[2] < 0.45
    copper = f0["copper"]
    assert copper[0] > 0.9 and 0.55 < copper[1] < 0.7 and copper[2] < copper[1]
    assert np.all(f0["silver"] > 0.95)
    assert np.all(np.abs(f0["aluminium"] - 0.92) < 0.02)
    for grey in ("chromium", "iron"):
        assert np.all(np.abs(f0[grey] - 0.56) < 0.03)
    ti = f0["titanium"]
    assert 0.4 < ti[2] < ti[1] < ti[0] < 0.6


@pytest.mark.parametrize("name", sorted(PRESETS))
def test_presets_validate(name):
    table = dict(PRESETS[name])
    model = table.pop("model")
    p = brdf.get(model).params(**table)
    assert p.model == model
