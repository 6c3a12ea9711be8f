"""Coat-base interreflections of the layered model: the geometric series of the diffuse bounces
under the coat (closed form), checked by white furnaces in both twins, an independent quadrature
of the coat's internal reflectance, and a stochastic random walk through the layer."""

import numpy as np
import pytest
from scipy import integrate

from viewer import brdf
from viewer.brdf import layered as layered_mod
from viewer.brdf.albedo import directional_albedo
from viewer.brdf.fresnel import fresnel_dielectric

LAYERED = brdf.get("layered")
IORS = (1.0, 1.2, 1.5, 2.0, 3.0)          # the coat ior's range is [1, 3]
ALPHAS = (0.001, 0.01, 0.1, 0.3, 0.6, 1.0)  # the coat alpha's range is [0.001, 1]
COS_O = np.array([0.05, 0.3, 0.7, 1.0])


def _white(ior, alpha, sigma_a=(0.0, 0.0, 0.0), thickness=10.0, albedo=(1.0, 1.0, 1.0)):
    return LAYERED.params(coating=dict(ior=ior, alpha=alpha, thickness=thickness, sigma_a=list(sigma_a)),
                          base=dict(model="lambert", albedo=list(albedo)))


_MU, _MW = np.polynomial.legendre.leggauss(256)
_MU, _MW = 0.5 * (_MU + 1.0), 0.5 * _MW


def _base_term_albedo(p, mu_o, eval_fn):
    """Integral of the base term's f cos over wi: for a Lambert base it depends on cos_i only
    (isotropic), so a 1D Gauss-Legendre quadrature over cos_i (times 2 pi) is exact enough; the
    coat lobe (sharp at small alpha) is subtracted and measured by its own sampler instead."""
    wi = np.stack([np.sqrt(1 - _MU ** 2), np.zeros_like(_MU), _MU], axis=-1)
    wo = np.broadcast_to(np.array([np.sqrt(1 - mu_o ** 2), 0.0, mu_o]), wi.shape).copy()
    f = eval_fn(p, wi, wo)[:, 0] - layered_mod.eval_coat(p, wi, wo)[:, 0]
    return 2 * np.pi * float(np.sum(_MW * f * _MU))


def _coat_albedo(ior, alpha):
    black = _white(ior, alpha, albedo=(0.0, 0.0, 0.0))
    return directional_albedo(LAYERED, black, COS_O, n_side=32, phis=(0.0,))[:, 0]


@pytest.mark.parametrize("ior", IORS)
def test_white_furnace_lossless_coat_over_white_base(ior):
    # everything that enters comes back out: 1 within the coat-albedo table's error (< 1e-2);
    # before the series, 0.43 at normal incidence for ior 1.5 and 0.30 for ior 2 (measured)
    for alpha in ALPHAS:
        p = _white(ior, alpha)
        e = _coat_albedo(ior, alpha)
        a = e + np.array([_base_term_albedo(p, m, LAYERED.eval) for m in COS_O])
        assert np.all(a > 0.95) and np.all(a < 1.01), (ior, alpha, a)


def test_white_furnace_glsl_twin(gl_ctx):
    # the GLSL twin evaluated at the same quadrature nodes: the same albedo within 1e-3
    from glsl_eval import GLSLEvaluator

    ev = GLSLEvaluator(gl_ctx)

    def glsl_eval(p, wi, wo):
        return ev.eval(p, wi.astype(np.float32).astype(np.float64), wo.astype(np.float32).astype(np.float64))

    for ior in (1.2, 1.5, 3.0):
        for alpha in (0.001, 0.3, 1.0):
            p = _white(ior, alpha)
            e = _coat_albedo(ior, alpha)
            for k, m in enumerate(COS_O):
                a_np = e[k] + _base_term_albedo(p, m, LAYERED.eval)
                a_gl = e[k] + _base_term_albedo(p, m, glsl_eval)
                assert a_gl > 0.95 and abs(a_gl - a_np) < 1e-3, (ior, alpha, m, a_gl, a_np)


@pytest.mark.parametrize("ior", [1.33, 1.5, 2.4])
def test_internal_reflectance_against_quadrature(ior):
    # smooth coat: K = integral_0^1 F(mu, 1 / ior) exp(-2 tau / mu) 2 mu dmu with the Fresnel
    # reflectance seen from inside (total internal reflection included), by adaptive quadrature;
    # tolerance 2e-3: the coat albedo is a 24-entry table interpolated linearly (F's curvature
    # near grazing incidence)
    tau = np.array([0.0, 0.05, 0.5])
    p = _white(ior, 0.001, sigma_a=tau / 10.0, thickness=10.0)
    got = layered_mod.internal_reflectance(p)
    for c in range(3):
        mu_c = np.sqrt(1 - 1 / ior ** 2)
        ref = sum(integrate.quad(lambda mu: fresnel_dielectric(mu, 1.0 / ior) * np.exp(-2 * tau[c] / mu) * 2 * mu,
                                 a, b, limit=200)[0] for a, b in ((1e-12, mu_c), (mu_c, 1.0)))
        assert got[c] == pytest.approx(ref, abs=2e-3)
    assert got[0] == pytest.approx(1 - (1 - 2 * integrate.quad(lambda m: fresnel_dielectric(m, ior) * m, 0, 1)[0])
                                   / ior ** 2, abs=2e-3)


def _random_walk(ior, rho, tau, mu_o, n, rng):
    """Independent truth for a smooth coat over a Lambert base: follow n photons arriving along
    -wo (cos mu_o) through the layer and return the fraction that leaves (any direction):
    reflect at the top with F(mu_o), else refract in; absorption exp(-tau / mu) on each pass;
    the base absorbs 1 - rho and otherwise re-emits a cosine-distributed direction; at the top
    from inside, reflected with F(mu, 1 / ior) (total internal reflection included), else out."""
    out = fresnel_dielectric(mu_o, ior) * n  # specular reflection at the coat (expected value)
    mu_t = np.sqrt(1 - (1 - mu_o ** 2) / ior ** 2)
    alive = n * (1 - fresnel_dielectric(mu_o, ior))
    w = np.full(int(round(alive)), 1.0)
    w *= np.exp(-tau / mu_t)  # down to the base
    total_out = 0.0
    for _ in range(200):
        if w.size == 0:
            break
        w = w[rng.random(w.size) < rho]          # base: survive with probability rho
        mu = np.sqrt(rng.random(w.size))          # cosine-distributed up direction
        w = w * np.exp(-tau / mu)                 # up to the coat
        refl = rng.random(w.size) < fresnel_dielectric(mu, 1.0 / ior)
        total_out += float(np.sum(w[~refl]))
        w = w[refl] * np.exp(-tau / mu[refl])     # reflected back down
    return (out + total_out) / n, np.sqrt(n) / n


@pytest.mark.parametrize("ior,rho,tau", [(1.5, 1.0, 0.0), (1.5, 0.8, 0.0), (2.0, 0.9, 0.1), (3.0, 0.7, 0.02)])
def test_closed_form_equals_random_walk(ior, rho, tau):
    # smooth coat (alpha 0.001): the closed form's albedo against the stochastic random walk
    # through the layer, within 4 standard errors of the walk (200k photons)
    rng = np.random.default_rng(3)
    p = _white(ior, 0.001, sigma_a=[tau / 10.0] * 3, thickness=10.0, albedo=[rho] * 3)
    for mu_o in (0.3, 1.0):
        walk, se = _random_walk(ior, rho, tau, mu_o, 200_000, rng)
        closed = layered_mod.coat_albedo(p, mu_o) + _base_term_albedo(p, mu_o, LAYERED.eval)
        assert closed == pytest.approx(walk, abs=4 * se + 2e-3), (mu_o, closed, walk)


def test_interreflection_tables_for_every_base():
    # a glossy base gets its interreflections too (its own albedos: viewer/brdf/layered.py
    # base_bounce_tables); a Lambert base's tables are rho and rho K exactly
    p = LAYERED.params(base=dict(model="microfacet", alpha=0.3))
    E, A, rk = layered_mod.base_bounce_tables(p)
    assert np.all(rk > 0.05) and np.all(A > 0) and np.all(A <= E + 1e-12)
    q = _white(1.5, 0.1, albedo=(0.0, 0.5, 1.0))
    E, A, rk = layered_mod.base_bounce_tables(q)
    K = layered_mod.internal_reflectance(q)
    np.testing.assert_allclose(rk, np.array([0.0, 0.5, 1.0]) * K, rtol=1e-12)
    np.testing.assert_allclose(E, np.tile([0.0, 0.5, 1.0], (layered_mod.BASE_TABLE, 1)))
