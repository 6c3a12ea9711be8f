"""Microfacet distributions (viewer.brdf.microfacet_dist) and the microfacet BRDF.

Normalization of D, the weak white furnace of Smith masking, visible-normal sampling against its
pdf (chi-square), and the BRDF's own sampling and energy bounds."""

import numpy as np
import pytest
from scipy import integrate

from viewer import brdf
from viewer.brdf.microfacet_dist import G1_v_cavity, Distribution
from viewer.brdf.chi2 import chi2_test

from brdf_harness import direction

CASES = [("ggx", 0.05, 0.05), ("ggx", 0.3, 0.3), ("ggx", 1.0, 1.0), ("ggx", 0.1, 0.5),
         ("beckmann", 0.05, 0.05), ("beckmann", 0.3, 0.3), ("beckmann", 1.0, 1.0), ("beckmann", 0.6, 0.15),
         ("blinn_phong", 0.05, 0.05), ("blinn_phong", 0.3, 0.3), ("blinn_phong", 1.0, 1.0)]


def _sph(theta, phi):
    st = np.sin(theta)
    return np.stack([st * np.cos(phi), st * np.sin(phi), np.cos(theta)], axis=-1)


def _hemisphere_integral(fn, alpha, n_phi=40):
    """Integral of fn(m) over the upper hemisphere: adaptive quadrature in theta (with a break at
    the peak's width) for each of n_phi azimuths (periodic trapezoid rule, spectrally accurate)."""
    phis = (np.arange(n_phi) + 0.5) * 2 * np.pi / n_phi
    total = 0.0
    for phi in phis:
        def g(t):
            return float(fn(_sph(np.array([t]), np.array([phi])))[0]) * np.sin(t)
        pts = [min(np.arctan(a * alpha), 1.5) for a in (1.0, 3.0, 10.0)]
        v, _ = integrate.quad(g, 0.0, np.pi / 2, points=pts, limit=200, epsabs=1e-10, epsrel=1e-8)
        total += v
    return total * 2 * np.pi / n_phi


@pytest.mark.parametrize("name,ax,ay", CASES)
def test_D_is_normalized(name, ax, ay):
    # integral D(m) (m.n) dm = 1 (Heitz 2014, JCGT 3(2), eq. 4)
    d = Distribution(name, ax, ay)
    val = _hemisphere_integral(lambda m: d.D(m) * m[:, 2], min(ax, ay))
    assert val == pytest.approx(1.0, abs=2e-3)


@pytest.mark.parametrize("name,ax,ay", [c for c in CASES if c[0] != "blinn_phong"])
@pytest.mark.parametrize("theta_o", [0.0, 1.0, 1.5])
def test_weak_white_furnace_smith(name, ax, ay, theta_o):
    # the visible projected area of the microsurface equals that of the macrosurface:
    # integral G1(wo, m) D(m) max(0, wo.m) dm = cos(theta_o) (Heitz 2014, sec. 3.2, eq. 20 ff.)
    d = Distribution(name, ax, ay)
    wo = _sph(np.array([theta_o]), np.array([0.4]))[0]
    val = _hemisphere_integral(lambda m: d.G1(np.broadcast_to(wo, m.shape), m) * d.D(m)
                               * np.maximum(0.0, m @ wo), min(ax, ay))
    assert val == pytest.approx(np.cos(theta_o), abs=2e-3)


@pytest.mark.parametrize("theta_o", [0.3, 1.0])
def test_weak_white_furnace_v_cavity(theta_o):
    # Heitz 2014 sec. 4.3: the V-cavity masking function is a valid one (its microsurface projects
    # onto the macrosurface), so it passes the same test
    d = Distribution("beckmann", 0.3, 0.3)
    wo = _sph(np.array([theta_o]), np.array([0.0]))[0]
    val = _hemisphere_integral(lambda m: G1_v_cavity(np.broadcast_to(wo, m.shape), m) * d.D(m)
                               * np.maximum(0.0, m @ wo), 0.3)
    assert val == pytest.approx(np.cos(theta_o), abs=3e-3)


def test_blinn_phong_smith_is_close():
    # blinn_phong borrows Beckmann's Lambda (Walter 2007 sec. 5.2): the furnace holds only roughly
    d = Distribution("blinn_phong", 0.3, 0.3)
    wo = _sph(np.array([1.0]), np.array([0.0]))[0]
    val = _hemisphere_integral(lambda m: d.G1(np.broadcast_to(wo, m.shape), m) * d.D(m)
                               * np.maximum(0.0, m @ wo), 0.3)
    assert val == pytest.approx(np.cos(1.0), rel=0.02)


class _NormalSampler:
    """Adapter so that the registry's chi-square harness tests m ~ sample_m against pdf_m."""

    def __init__(self, dist):
        self.d = dist

    def sample(self, p, wo, u):
        wo = np.broadcast_to(wo, (u.shape[0], 3))
        m = self.d.sample_m(wo, u)
        pdf = self.d.pdf_m(wo, m)
        return m, np.ones_like(m), pdf

    def pdf(self, p, wi, wo):
        wo = np.broadcast_to(wo, wi.shape)
        return self.d.pdf_m(wo, wi)

    def eval(self, p, wi, wo):
        return np.zeros_like(wi)


@pytest.mark.parametrize("name,ax,ay", [("ggx", 0.3, 0.3), ("ggx", 0.15, 0.6), ("beckmann", 0.3, 0.3),
                                        ("beckmann", 0.6, 0.15), ("blinn_phong", 0.4, 0.4)])
@pytest.mark.parametrize("theta_o", [10.0, 70.0])
def test_normal_sampling_matches_pdf(name, ax, ay, theta_o):
    # visible normals: D_wo(m) = G1(wo, m) D(m) max(0, wo.m) / cos_o (Heitz & d'Eon 2014, eq. 2)
    d = Distribution(name, ax, ay)
    res = chi2_test(_NormalSampler(d), None, direction(theta_o, 0.37), 150_000,
                    np.random.default_rng(7), 1e-4, rows=15, cols=30)
    assert res.ok, res.message


def test_visible_normal_pdf_integrates_to_one():
    for name in ("ggx", "beckmann"):
        d = Distribution(name, 0.3, 0.3)
        wo = _sph(np.array([1.1]), np.array([0.2]))[0]
        val = _hemisphere_integral(lambda m: d.pdf_m(np.broadcast_to(wo, m.shape), m), 0.3)
        assert val == pytest.approx(1.0, abs=2e-3)


# ----------------------------------------------------------------------------- the BRDF

MODEL = brdf.get("microfacet")


@pytest.mark.parametrize("kw", [
    dict(distribution="ggx", alpha_x=0.2, alpha_y=0.6),
    dict(distribution="beckmann", alpha=0.4, kd=[0.5, 0.5, 0.5], fresnel="dielectric"),
    dict(distribution="blinn_phong", shadowing="v_cavity", alpha=0.3, fresnel="schlick", f0=[0.9, 0.5, 0.2]),
])
@pytest.mark.parametrize("theta_o", [20.0, 75.0])
def test_brdf_sampling_matches_pdf(kw, theta_o):
    p = MODEL.params(**kw)
    res = chi2_test(MODEL, p, direction(theta_o, 0.37), 150_000, np.random.default_rng(3), 1e-4,
                    rows=15, cols=30)
    assert res.ok, res.message


def test_weight_is_f_cos_over_pdf():
    rng = np.random.default_rng(0)
    for kw in (dict(distribution="ggx", kd=[0.3, 0.3, 0.3]), dict(distribution="beckmann", alpha_x=0.1, alpha_y=0.4),
               dict(distribution="blinn_phong", shadowing="v_cavity")):
        p = MODEL.params(**kw)
        wo = np.broadcast_to(direction(40.0, 0.3), (20_000, 3))
        wi, w, pdf = MODEL.sample(p, wo, rng.random((20_000, 2)))
        ok = pdf > 0
        f = MODEL.eval(p, wi[ok], wo[ok])
        np.testing.assert_allclose(w[ok], f * wi[ok, 2:3] / pdf[ok, None], rtol=1e-10)
        np.testing.assert_allclose(MODEL.pdf(p, wi[ok], wo[ok]), pdf[ok], rtol=1e-10)


def _albedo(p, theta_o, n=200_000, seed=1):
    wo = np.broadcast_to(direction(theta_o, 0.3), (n, 3))
    _, w, _ = MODEL.sample(p, wo, np.random.default_rng(seed).random((n, 2)))
    return w.mean(axis=0), w.std(axis=0) / np.sqrt(n)


@pytest.mark.parametrize("dist", ["ggx", "beckmann", "blinn_phong"])
@pytest.mark.parametrize("fresnel", ["dielectric", "conductor", "schlick"])
def test_albedo_at_most_one_with_diffuse(dist, fresnel):
    # kd = 1 with the Fresnel-weighted diffuse base: albedo <= 1 over roughness and angle
    for alpha in (0.05, 0.5, 1.0):
        for theta_o in (0.0, 45.0, 80.0, 89.0):
            p = MODEL.params(distribution=dist, fresnel=fresnel, alpha=alpha, kd=[1.0, 1.0, 1.0],
                             ior=3.0, eta=[3.0, 3.0, 3.0], k=[0.0, 0.0, 0.0], f0=[0.25, 0.25, 0.25])
            mean, se = _albedo(p, theta_o, n=40_000)
            assert np.all(mean <= 1.0 + 5 * se + 1e-3), (alpha, theta_o, mean)


def test_white_furnace_smooth_mirror_limit():
    # F = 1 (Schlick f0 = 1), small alpha, Smith: nothing is lost at normal incidence
    p = MODEL.params(fresnel="schlick", f0=[1.0, 1.0, 1.0], alpha=0.01)
    mean, se = _albedo(p, 0.0)
    assert np.all(np.abs(mean - 1.0) < 1e-3)
    # rough: single scattering loses energy, never gains it
    p = MODEL.params(fresnel="schlick", f0=[1.0, 1.0, 1.0], alpha=1.0)
    mean, se = _albedo(p, 60.0)
    assert np.all(mean < 1.0) and np.all(mean > 0.35)  # GGX alpha = 1 loses ~half (Kulla-Conty 2017)


def test_anisotropy_follows_the_tangent():
    # alpha_x > alpha_y: the highlight spreads along x, so moving wi along x keeps more of it
    p = MODEL.params(alpha_x=0.5, alpha_y=0.05)
    wo = direction(0.0)
    wi_x, wi_y = direction(20.0, 0.0), direction(20.0, np.pi / 2)
    assert MODEL.eval(p, wi_x, wo)[1] > 10 * MODEL.eval(p, wi_y, wo)[1]


def test_blinn_phong_alpha_one_is_uniform_cosine():
    from viewer.brdf.microfacet_dist import D_blinn_phong
    m = _sph(np.linspace(0, 1.5, 7), np.zeros(7))
    np.testing.assert_allclose(D_blinn_phong(m, 1.0), 1.0 / np.pi)


def test_extremes_are_finite():
    rng = np.random.default_rng(5)
    wi = rng.normal(size=(5000, 3))
    wi /= np.linalg.norm(wi, axis=1, keepdims=True)
    wo = np.roll(wi, 1, axis=0)
    wo[:10, 2] = 0.0
    wi[10:20] = np.array([0.0, 0.0, 1.0])
    for dist in ("ggx", "beckmann", "blinn_phong"):
        for shadowing in ("smith", "v_cavity"):
            for a in (1e-4, 1.0):
                for fresnel in ("dielectric", "conductor", "schlick"):
                    p = MODEL.params(distribution=dist, shadowing=shadowing, alpha=a, fresnel=fresnel,
                                     ior=1.0, k=[0.0, 0.0, 0.0], kd=[1.0, 1.0, 1.0])
                    assert np.all(np.isfinite(MODEL.eval(p, wi, wo)))
                    assert np.all(np.isfinite(MODEL.pdf(p, wi, wo)))
                    s_wi, w, pdf = MODEL.sample(p, wo, rng.random((5000, 2)))
                    assert np.all(np.isfinite(w)) and np.all(np.isfinite(pdf)) and np.all(np.isfinite(s_wi))


def _bp_albedo(alpha, mu, G_fn, n=300):
    """F = 1 albedo of the blinn_phong microfacet lobe at cos_o = mu, midpoint quadrature over wi."""
    d = Distribution("blinn_phong", alpha)
    t = (np.arange(n) + 0.5) / n * np.pi / 2
    ph = (np.arange(n) + 0.5) / n * np.pi
    T, P = np.meshgrid(t, ph, indexing="ij")
    wi = np.stack([np.sin(T) * np.cos(P), np.sin(T) * np.sin(P), np.cos(T)], -1).reshape(-1, 3)
    wo = np.broadcast_to(np.array([np.sqrt(1 - mu * mu), 0.0, mu]), wi.shape)
    h = wi + wo
    h /= np.linalg.norm(h, axis=-1, keepdims=True)
    w = d.D(h) / (4 * mu) * np.sin(T.ravel()) * (np.pi / 2 / n) * (np.pi / n) * 2
    return float(np.sum(G_fn(d, wi, wo, h) * w))


def _g_smith(d, wi, wo, h):
    return d.G2(wi, wo, h)


def _g_capped(d, wi, wo, h):
    from viewer.brdf.microfacet_dist import G_v_cavity
    return np.minimum(d.G2(wi, wo, h), G_v_cavity(wi, wo, h))


@pytest.mark.parametrize("alpha,mu", [(0.5, 0.05), (1.0, 0.1), (0.8, 0.15)])
def test_blinn_smith_cap_table_recomputed(alpha, mu):
    # the table's t = (A_s - 1) / (A_s - A_c) recomputed by an independent (coarser) quadrature
    from viewer.brdf.microfacet_dist import blinn_smith_cap_weight
    a_s, a_c = _bp_albedo(alpha, mu, _g_smith), _bp_albedo(alpha, mu, _g_capped)
    assert a_s > 1.0
    assert float(blinn_smith_cap_weight(alpha, mu)) == pytest.approx((a_s - 1) / (a_s - a_c), abs=0.01)


def test_blinn_smith_cap_only_where_albedo_exceeds_one():
    from viewer.brdf.microfacet_dist import G_blinn_smith
    # uncapped albedo below 1 (0.99 at alpha 0.3, cos 0.05): G is the plain Smith G (the old
    # everywhere-cap gave 0.75 here)
    a_s = _bp_albedo(0.3, 0.05, _g_smith)
    assert a_s < 1.0
    assert _bp_albedo(0.3, 0.05, G_blinn_smith) == pytest.approx(a_s, rel=1e-9)
    assert _bp_albedo(0.3, 0.05, _g_capped) < 0.8
    # where it would exceed 1 (1.3-1.5 at alpha 1, grazing) the blended cap brings it to ~1:
    # at most 1 + 0.01 (the table's bilinear interpolation between its nodes), and the loss of
    # the old cap is gone (0.73)
    for alpha, mu in [(1.0, 0.05), (0.75, 0.0625), (0.45, 0.01), (0.9, 0.2)]:
        a = _bp_albedo(alpha, mu, G_blinn_smith)
        assert 0.97 < a < 1.01, (alpha, mu, a)


def test_transmission_g2_is_the_beta_function():
    # Heitz 2014 sec. 5.3: G2 = integral_0^1 C^lam_o (1 - C)^lam_i dC, checked by quadrature;
    # it reduces to G1 = 1 / (1 + lam_i) when lam_o = 0 and is below the reflection form
    from viewer.brdf.microfacet_dist import smith_g2_height_correlated_transmission as g2t
    wo = np.array([[0.2, 0.0, 0.98]])
    wo /= np.linalg.norm(wo)
    wi = np.array([[0.3, 0.1, -0.9]])
    wi /= np.linalg.norm(wi)
    m = np.array([[0.0, 0.0, 1.0]])
    for lo, li in [(0.0, 0.7), (0.3, 0.3), (2.5, 0.05), (40.0, 3.0)]:
        ref, _ = integrate.quad(lambda c: c ** lo * (1 - c) ** li, 0, 1, epsabs=1e-13)
        got = float(g2t(np.array([li]), np.array([lo]), wi, wo, m)[0])
        assert got == pytest.approx(ref, rel=1e-9)
        assert got <= 1.0 / (1.0 + lo + li) + 1e-15
    assert float(g2t(np.array([0.7]), np.array([0.0]), wi, wo, m)[0]) == pytest.approx(1 / 1.7)
