"""Multiple scattering on the microsurface (viewer/brdf/microfacet_walk.py, the random walk of
Heitz et al. 2016) behind ``multiple_scattering = true`` on the microfacet model: white furnaces
of both estimators (the walk's sampling, the next-event eval), eval against sampling bin by bin,
the single-scattering limit, reciprocity within noise, the below-horizon visible normals, the
scene key and the reference renderer's furnace sphere."""

from __future__ import annotations

import math
import textwrap

import numpy as np
import pytest

from viewer import ViewerError, brdf
from viewer.brdf import microfacet, microfacet_walk as W
from viewer.brdf.microfacet_dist import Distribution

from scene_text import lone_sphere

MF = brdf.get("microfacet")


def _white(dist, alpha, **kw):
    # Schlick with f0 = 1 is F = 1 at every angle: the white furnace
    return MF.params(distribution=dist, alpha=alpha, fresnel="schlick", f0=1.0, multiple_scattering=True, **kw)


def _wo(cos, n, phi=0.3):
    s = math.sqrt(1 - cos * cos)
    return np.repeat([[s * math.cos(phi), s * math.sin(phi), cos]], n, axis=0)


def _cosine_dirs(rng, n):
    u = rng.random((n, 2))
    r = np.sqrt(u[:, 0])
    ph = 2 * np.pi * u[:, 1]
    return np.stack([r * np.cos(ph), r * np.sin(ph), np.sqrt(1 - u[:, 0])], axis=1)


@pytest.mark.parametrize("dist", ["ggx", "beckmann"])
@pytest.mark.parametrize("alpha", [0.5, 1.0])
def test_white_furnace_both_estimators(dist, alpha):
    """F = 1: nothing is absorbed, so the albedo is 1 at every wo. By sampling (the walk's weight)
    it is 1 up to the walks cut at MAX_EVENTS; by eval (single scattering analytic + the walk's
    next-event estimate of the rest, integrated over cosine-sampled wi) within 4 standard errors
    (+ 2e-3 for cells of the quadrature near grazing wi). Single scattering alone loses 5-70 %
    (its albedo is printed: the figure the reference was missing)."""
    rng = np.random.default_rng(7)
    p = _white(dist, alpha)
    n = 20000
    for cos in (1.0, 0.5, 0.15):
        wo = _wo(cos, n)
        wi, wt, pdf = MF.sample(p, wo, rng.random((n, 2)))
        assert np.all(pdf > 0) and np.all(wi[:, 2] > 0)
        assert abs(wt[:, 0].mean() - 1.0) < 1e-3, (cos, wt[:, 0].mean())
        wl = _cosine_dirs(rng, n)
        f = MF.eval(p, wl, wo)[:, 0] * np.pi
        fss = microfacet.eval_specular(p, wl, wo)[:, 0] * np.pi
        se = f.std() / math.sqrt(n)
        print(f"{dist} alpha {alpha} cos {cos}: single {fss.mean():.3f}, walk {f.mean():.4f} +- {se:.4f}")
        assert abs(f.mean() - 1.0) < 4 * se + 2e-3, (cos, f.mean(), se)
        assert fss.mean() < 0.97


def test_single_scattering_limit():
    """As alpha -> 0 the walk leaves after one event: eval equals the single-scattering BRDF, the
    sampled albedo of a conductor equals the single-scattering one."""
    rng = np.random.default_rng(3)
    p = MF.params(distribution="ggx", alpha=0.02, multiple_scattering=True)
    p0 = p.replace(multiple_scattering=False)
    n = 20000
    wo = _wo(0.6, n)
    wi, wt, _ = MF.sample(p, wo, rng.random((n, 2)))
    wi0, wt0, _ = MF.sample(p0, wo, rng.random((n, 2)))
    assert np.allclose(wt.mean(axis=0), wt0.mean(axis=0), rtol=2e-3)
    f = MF.eval(p, wi, wo)
    f0 = MF.eval(p0, wi, wo)
    assert np.median(np.abs(f - f0) / np.maximum(f0, 1e-12)) < 1e-6
    # walks that needed a second event are rare: 1 - single-scattering F = 1 albedo (~1e-4)
    _, _, events = W.sample(Distribution("ggx", 0.02), lambda c: np.ones((c.size, 3)), wo, rng.random((n, 2)))
    assert np.mean(events > 1) < 2e-3


@pytest.mark.parametrize("dist", ["ggx", "beckmann"])
def test_eval_matches_sampling_per_bin(dist):
    """The walk's exit directions (sampling) against the next-event eval, in 6 x 6 cells of
    (cos^2 theta_i, phi_i): the F = 1 density of the walk's exits per cell (counts / n) and the
    integral of f cos over the cell by eval (cosine-sampled wi) are two independent unbiased
    estimates of the same numbers; their squared differences over the summed variances follow a
    chi-square with 36 dof: rejected at p < 1e-4 (a 2-cell shift of 1 % would fail)."""
    from scipy.stats import chi2

    rng = np.random.default_rng(11)
    p = _white(dist, 0.7).replace(alpha_y=0.4)  # anisotropic too
    n = 60000
    wo = _wo(0.4, n, phi=0.9)
    nb = 6

    def cell(w):
        a = np.minimum((w[:, 2] ** 2 * nb).astype(int), nb - 1)
        b = np.minimum(((np.arctan2(w[:, 1], w[:, 0]) % (2 * np.pi)) / (2 * np.pi) * nb).astype(int), nb - 1)
        return a * nb + b

    wi, wt, _ = MF.sample(p, wo, rng.random((n, 2)))
    cnt = np.bincount(cell(wi), weights=wt[:, 0], minlength=nb * nb)
    pa = cnt / n
    wl = _cosine_dirs(rng, n)
    g = MF.eval(p, wl, wo)[:, 0] * np.pi
    c = cell(wl)
    s1 = np.bincount(c, weights=g, minlength=nb * nb) / n
    s2 = np.bincount(c, weights=g * g, minlength=nb * nb) / n
    vb = np.maximum(s2 - s1 * s1, 0) / n
    # the walk's count variance from the pooled estimate (a cell the walk never reached has
    # observed variance 0, which would make any eval sample there look significant)
    pbar = np.clip(0.5 * (pa + s1), 0.0, 1.0)
    va = pbar * (1 - pbar) / n
    stat = float(np.sum((pa - s1) ** 2 / np.maximum(va + vb, 1e-300)))
    assert chi2.sf(stat, nb * nb) > 1e-4, stat
    assert abs(pa.sum() - 1) < 1e-3 and abs(s1.sum() - 1) < 0.02


def test_reciprocity_within_noise():
    """f(wi, wo) = f(wo, wi): the walk runs from wo, so the two orders are different estimators
    of one value (gold, GGX alpha 0.8): equal within 4 standard errors of 4000 walks each."""
    p = MF.params(distribution="ggx", alpha=0.8, multiple_scattering=True)
    d = microfacet.distribution(p)
    fr = lambda c: microfacet.fresnel_rgb(p, c)  # noqa: E731
    pairs = [((0.3, 0.1, 0.95), (-0.7, 0.2, 0.5)), ((0.9, 0.0, 0.2), (0.1, 0.6, 0.7)),
             ((0.5, 0.5, 0.4), (0.5, -0.5, 0.4))]
    for a, b in pairs:
        a = np.array(a) / np.linalg.norm(a)
        b = np.array(b) / np.linalg.norm(b)
        n = 4000
        A, B = np.repeat(a[None], n, 0), np.repeat(b[None], n, 0)
        rng = np.random.default_rng(5)
        x = W.eval_multiple(d, fr, A, B, rng)
        y = W.eval_multiple(d, fr, B, A, rng)
        se = np.sqrt(x.var(axis=0) / n + y.var(axis=0) / n)
        assert np.all(np.abs(x.mean(axis=0) - y.mean(axis=0)) < 4 * se + 1e-6), (a, b)
        assert np.all(x.mean(axis=0) > 0)


@pytest.mark.parametrize("dist", ["ggx", "beckmann"])
def test_visible_normals_below_the_horizon(dist):
    """The walk's rays going up hit normals seen from below: the sampled normals' mean equals the
    quadrature of m D_w(m) over the hemisphere, and D_w integrates to 1 (w.z < 0)."""
    rng = np.random.default_rng(2)
    d = Distribution(dist, 0.7, 0.4)
    for wz in (-0.3, -0.8):
        s = math.sqrt(1 - wz * wz)
        w = np.array([[0.6 * s, 0.8 * s, wz]])
        m = W.sample_visible_normal(d, np.repeat(w, 100000, 0), rng.random((100000, 2)))
        assert np.all(np.sum(m * w, axis=1) > -1e-9) and np.all(m[:, 2] > 0)
        q = rng.normal(size=(400000, 3))
        q /= np.linalg.norm(q, axis=1, keepdims=True)
        q[:, 2] = np.abs(q[:, 2])
        dv = W.d_visible(d, np.repeat(w, q.shape[0], 0), q) * 2 * np.pi
        assert abs(dv.mean() - 1) < 0.03   # uniform-direction quadrature of a peaked density
        # the ratio estimator cancels most of the quadrature's own error
        assert np.allclose(m.mean(axis=0), (dv[:, None] * q).mean(axis=0) / dv.mean(), atol=0.008)


def test_scene_key_and_messages(tmp_path):
    from viewer.scene import load_scene

    with pytest.raises(ViewerError, match="multiple_scattering: expected true or false"):
        MF.params(multiple_scattering="yes")
    path = tmp_path / "s.toml"
    path.write_text(textwrap.dedent("""
        [[objects]]
        mesh = "sphere"
        material = "m"
        [materials.m]
        model = "microfacet"
        alpha = 0.6
        multiple_scattering = true
        """))
    sc = load_scene(path)
    assert sc.materials["m"]["multiple_scattering"] is True
    assert microfacet.walks(sc.materials["m"])
    assert not microfacet.walks(sc.materials["m"].replace(distribution="blinn_phong"))


def test_reference_furnace_sphere(tmp_path):
    """The CPU reference, a rough F = 1 sphere (GGX alpha 1) in a white environment: with the walk
    every ring of the sphere's disc (the view at normal incidence, halfway and towards grazing)
    is 1 within noise (4 standard errors of the ring's mean + 5e-3 for the tessellation's cut
    directions); with single scattering alone the sphere's mean is below 0.8. Rings, not pixels:
    a walk's weights are heavy-tailed, and a pixel's variance estimated from 16 samples is too
    often far too small (one pixel in about a hundred then sits 5-7 of its estimated standard
    errors off, which a change of random stream moves from pixel to pixel); a ring's, summed
    over dozens of pixels, is not."""
    from viewer.pathtracer import ReferenceRenderer
    from viewer.scene import load_scene

    path = tmp_path / "f.toml"
    path.write_text(lone_sphere(dict(model="microfacet", distribution="ggx", alpha=1.0, fresnel="schlick",
                                     f0=1.0, multiple_scattering=True), 24, 24))
    sc = load_scene(path)
    means = {}
    for ms in (True, False):
        sc.materials["m"]["multiple_scattering"] = ms
        r = ReferenceRenderer(sc, width=24, height=24, max_depth=4, seed=1, workers=0)
        r.step(16)
        m, var = r.mean()[..., 0], r.variance()[..., 0]
        r.close()
        assert r.bad_values == 0
        yy, xx = np.mgrid[0:24, 0:24]
        inner = (yy - 11.5) ** 2 + (xx - 11.5) ** 2 < 6.0 ** 2   # well inside the sphere's disc
        means[ms] = float(m[inner].mean())
        if ms:
            rad = np.sqrt((yy - 11.5) ** 2 + (xx - 11.5) ** 2)
            for lo, hi in ((0.0, 2.5), (2.5, 4.5), (4.5, 6.0)):
                ring = (rad >= lo) & (rad < hi)
                se_ring = math.sqrt(float(var[ring].sum())) / ring.sum()
                assert abs(float(m[ring].mean()) - 1.0) <= 4 * se_ring + 5e-3, (lo, hi, float(m[ring].mean()), se_ring)
            se = math.sqrt(float(var[inner].sum())) / inner.sum()   # of the mean over the disc
            assert abs(means[ms] - 1.0) <= 4 * se + 5e-3, (means[ms], se)
    print("furnace sphere mean, walk / single scattering:", means)
    assert means[False] < 0.8


def test_albedo_plot_shows_three_albedos():
    """plot --kind albedo of a microfacet material: single scattering, the raster's compensation
    and the random walk. White GGX alpha 1: single scattering at normal incidence is
    1 - ln 2 = 0.307 (f cos integrates in closed form: D = 1/pi, Lambda(wi) = (1/cos - 1)/2),
    the walk 1 (nothing is absorbed), and so is the compensation."""
    from viewer import plots

    p = _white("ggx", 1.0)
    fig = plots.figure(p, "albedo", channel="r")
    by = {c.label.split(" (")[0]: c.y for c in fig.curves}
    assert set(by) == {"single scattering", "compensated, environment", "compensated, lights", "random walk"}
    assert abs(by["single scattering"][0] - (1 - math.log(2))) < 0.01
    assert np.all(np.abs(by["random walk"] - 1.0) < 2e-3)
    # the compensation's E_ss is the lobe's own F = 1 albedo (viewer/brdf/ms_compensation.py): with F = 1 it
    # returns what single scattering loses, 1 within the two albedo estimates' sampling (the plot's
    # curve and ms_compensation's table use different sample sets); the lights' term (Kulla-Conty)
    # returns the same energy with F = 1
    for name in ("compensated, environment", "compensated, lights"):
        assert np.all(by[name] > by["single scattering"]), name
        assert np.all(np.abs(by[name] - 1.0) < 0.01), (name, np.abs(by[name] - 1.0).max())


def _ms_scene(tmp_path):
    from viewer.scene import load_scene

    path = tmp_path / "ms.toml"
    path.write_text(textwrap.dedent("""
        [[objects]]
        mesh = "sphere"
        material = "m"
        [materials.m]
        model = "layered"
        base = { model = "microfacet", alpha = 0.7, multiple_scattering = true }
        """))
    return load_scene(path)


def test_engines_only_cpu_has_the_walk(tmp_path, capsys):
    """auto takes the cpu engine for a scene with the walk (also nested in a layered base) and
    prints why; --engine gpu refuses with one line."""
    from viewer.reference_common.select import choose_for_scenes, make_renderer, uses_random_walk

    sc = _ms_scene(tmp_path)
    assert uses_random_walk(sc)
    engine, why = choose_for_scenes("auto", [sc], spectral=None, ctx=None)   # what the CLI prints
    assert engine == "cpu"
    assert why.startswith("a material has a random walk (microfacet multiple_scattering"), why
    with pytest.raises(ViewerError, match="--engine gpu has no random walk") as e:
        make_renderer("gpu", sc)
    assert "\n" not in str(e.value)
    sc.materials["m"]["base"]["multiple_scattering"] = False
    assert not uses_random_walk(sc)


# ----------------------------------------------------------------------------- dielectric walk

def _dielectric_walk_setup(alpha, ior=1.5):
    from viewer.brdf import dielectric as dm
    from viewer.brdf.microfacet_dist import Distribution

    p = brdf.get("dielectric").params(ior=ior, alpha=alpha)
    return p, Distribution("ggx", alpha, alpha), (lambda c, e: dm.film_or_fresnel(p, c, e))


def _particle_ss_albedo(p, wo, n, seed):
    """R + T of the single-scattering rough dielectric (the dielectric model's sampler; its
    radiance-mode weight times (n_wi / n_wo)^2 is the particle weight)."""
    rng = np.random.default_rng(seed)
    w = np.tile(wo, (n, 1))
    wi, wt, _ = brdf.get("dielectric").sample(p, w, rng.random((n, 2)))
    n_o = 1.0 if wo[2] > 0 else p.ior
    n_i = np.where(wi[:, 2] > 0, 1.0, p.ior)
    return float((wt[:, 0] * (n_i / n_o) ** 2).mean())


@pytest.mark.parametrize("alpha", [0.05, 0.1, 0.3, 0.6, 1.0])
@pytest.mark.parametrize("side", [1.0, -1.0])
def test_dielectric_walk_conserves_energy(alpha, side):
    # a lossless interface returns every walk on one side or the other: R + T = 1 from outside
    # and inside at every incidence (walks still on the surface after MAX_EVENTS would count 0;
    # none of these 20,000 do). The single-scattering model loses energy there (measured below
    # and printed on failure for contrast)
    p, dist, frt = _dielectric_walk_setup(alpha)
    for mu in (1.0, 0.5, 0.15):
        wo = np.array([np.sqrt(1 - mu * mu), 0.0, side * mu])
        rng = np.random.default_rng(7)
        n = 20_000
        wi, wt, ev = W.sample_dielectric(dist, 1.5, frt, np.tile(wo, (n, 1)), rng.random((n, 2)), rng)
        assert np.all(ev >= 1)
        np.testing.assert_allclose(wt, 1.0, atol=1e-12)
        assert np.all(np.abs(np.linalg.norm(wi, axis=1) - 1.0) < 1e-9)
        if alpha >= 0.3 and side < 0 and mu <= 0.5:
            assert _particle_ss_albedo(p, wo, 20_000, 1) < 0.95   # what the walk fixes


@pytest.mark.parametrize("alpha", [0.3, 0.6])
def test_dielectric_walk_eval_integrates_to_its_sampler(alpha):
    # the next-event estimator (every order) integrated over the sphere (uniform directions,
    # 200,000) gives R + T = 1, and its upper-hemisphere part the sampler's reflected fraction,
    # within 4 standard errors each (the eval and the sampler are separate code paths)
    p, dist, frt = _dielectric_walk_setup(alpha)
    rng = np.random.default_rng(3)
    n = 200_000
    for wo0 in ([0.6, 0.0, 0.8], [0.6, 0.0, -0.8], [0.98, 0.0, -0.2]):
        wo = np.tile(np.array(wo0) / np.linalg.norm(wo0), (n, 1))
        v = rng.normal(size=(n, 3))
        v /= np.linalg.norm(v, axis=1, keepdims=True)
        g = W.eval_dielectric_multiple(dist, 1.5, frt, v, wo, rng, first=True)[:, 0] \
            * np.abs(v[:, 2]) * 4.0 * np.pi
        se = g.std() / np.sqrt(n)
        assert abs(g.mean() - 1.0) < 4 * se, (wo0, g.mean(), se)
        r = g * (v[:, 2] > 0)
        wi, _, _ = W.sample_dielectric(dist, 1.5, frt, wo, rng.random((n, 2)), rng)
        frac = (wi[:, 2] > 0).mean()
        se_r = np.hypot(r.std() / np.sqrt(n), np.sqrt(frac * (1 - frac) / n))
        assert abs(r.mean() - frac) < 4 * se_r, (wo0, r.mean(), frac, se_r)


def test_dielectric_walk_first_order_is_the_dielectric_model():
    # the walk's first event toward wi has the expectation of the dielectric model's single
    # scattering (Walter et al. 2007 with the height-correlated G2 of both kinds) in particle
    # units, f (n_wi / n_wo)^2, for pairs on every combination of sides (4 standard errors of
    # 100,000 walks each)
    p, dist, frt = _dielectric_walk_setup(0.3)
    rng = np.random.default_rng(11)
    n = 100_000
    pairs = [([0.3, 0.1, 0.9], [0.2, -0.3, 0.8]), ([0.3, 0.1, 0.9], [0.2, -0.3, -0.8]),
             ([0.3, 0.1, -0.9], [-0.5, 0.2, 0.6]), ([0.3, 0.1, -0.9], [-0.5, 0.2, -0.6]),
             ([0.8, 0.0, -0.3], [-0.8, 0.1, -0.4])]
    for wo0, wi0 in pairs:
        wo0 = np.array(wo0) / np.linalg.norm(wo0)
        wi0 = np.array(wi0) / np.linalg.norm(wi0)
        wis, wos = np.tile(wi0, (n, 1)), np.tile(wo0, (n, 1))
        all_ = W.eval_dielectric_multiple(dist, 1.5, frt, wis, wos, rng, first=True)[:, 0]
        ms = W.eval_dielectric_multiple(dist, 1.5, frt, wis, wos, rng)[:, 0]
        got = all_.mean() - ms.mean()
        se = np.hypot(all_.std(), ms.std()) / np.sqrt(n)
        n_o = 1.0 if wo0[2] > 0 else 1.5
        n_i = 1.0 if wi0[2] > 0 else 1.5
        want = brdf.get("dielectric").eval(p, wis[:1], wos[:1])[0, 0] * (n_i / n_o) ** 2
        assert abs(got - want) < 4 * se + 1e-4 * want, (wo0, wi0, got, want, se)
