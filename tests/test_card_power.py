"""The power of the report card's energy and reciprocity checks (``viewer.brdf.report_card``):
BRDFs a little over the energy bound fail and a little under pass, however sharp their lobe
(analytic albedos: a normalized Phong lobe, BRDF Explorer's published Cook-Torrance, a Lambert);
the albedo's noise is the spread of independent estimates; a 2% asymmetry fails reciprocity
while the float32 rounding of a sharp lobe passes; and the text output names a non-finite pair."""

import json
import math
from pathlib import Path

import numpy as np
import pytest

from viewer import brdf

DATA = Path(__file__).parent / "brdfs"

# gain (n + 2) / (2 pi) cos^n(R.L) / (N.L): f cos integrates to gain (n + 2) / (n + 1) for a view
# whose lobe lies above the horizon (normal incidence, 40 degrees: cos^1000 of 50 degrees is 0)
PHONG = """analytic
::begin parameters
float gain 0 2 1
float n 1 100000 1000
::end parameters
::begin shader
vec3 BRDF(vec3 L, vec3 V, vec3 N, vec3 X, vec3 Y)
{
    vec3 R = reflect(-V, N);
    return vec3(gain * (n + 2.0) / (2.0 * 3.14159265358979) * pow(max(dot(R, L), 0.0), n) / dot(N, L));
}
::end shader
"""

# BRDF Explorer's cooktorrance.brdf as published (m 0.1, f0 0.1, include_F and include_G on):
# Beckmann without its 1/pi, Schlick's Fresnel, G = 1/(N.V), over N.L. At normal incidence f cos
# integrates to f0 times the integral of 4 D (N.H) over half vectors: 4 pi f0 = 0.4 pi.
COOK_TORRANCE_PUBLISHED = """analytic
::begin parameters
float m 0.001 .3 .1
float f0 0 1 .1
::end parameters
::begin shader
vec3 BRDF(vec3 L, vec3 V, vec3 N, vec3 X, vec3 Y)
{
    vec3 H = normalize(L + V);
    float t = dot(N, H);
    float D = exp((t * t - 1) / (m * m * t * t)) / (m * m * t * t * t * t);
    float F = f0 + (1 - f0) * pow(1 - dot(V, H), 5);
    return vec3(t < 0 ? 0.0 : D * F / (dot(N, V) * dot(N, L)));
}
::end shader
"""

LAMBERT = """analytic
::begin parameters
float gain 0 2 1.02
::end parameters
::begin shader
vec3 BRDF(vec3 L, vec3 V, vec3 N, vec3 X, vec3 Y) { return vec3(gain / 3.14159265358979); }
::end shader
"""

# reciprocity: a Lambert times 1 + e (cos theta_L - cos theta_V) (e = 0.01), and a Phong lobe
# (no 1/N.L: reciprocal) times 1 + e (L - V).X, which is not 0 at mirror pairs (e = 0.005, as
# (L - V).X reaches 2): f(L, V) and f(V, L) differ by up to 2%
ASYMMETRIC = """analytic
::begin parameters
float e 0 1 0.01
float n 1 100000 1000
bool lobe 0
::end parameters
::begin shader
vec3 BRDF(vec3 L, vec3 V, vec3 N, vec3 X, vec3 Y)
{
    if (!lobe) return vec3(0.8 / 3.14159265358979 * (1.0 + e * (dot(N, L) - dot(N, V))));
    vec3 R = reflect(-V, N);
    float s = (n + 2.0) / (2.0 * 3.14159265358979) * pow(max(dot(R, L), 0.0), n);
    return vec3(s * (1.0 + e * dot(L - V, X)));
}
::end shader
"""

# reciprocal in exact arithmetic, but R = normalize(2 (N.V) N - V) rounds differently from its
# exchange: f(L, V) and f(V, L) differ by about 2.4e-7 n in float32 (2.4e-3 at n = 10^4)
PHONG_ROUNDED = """analytic
::begin parameters
float n 1 100000 10000
::end parameters
::begin shader
vec3 BRDF(vec3 L, vec3 V, vec3 N, vec3 X, vec3 Y)
{
    vec3 R = normalize(2.0 * dot(N, V) * N - V);
    return vec3((n + 2.0) / (2.0 * 3.14159265358979) * pow(max(dot(R, L), 0.0), n));
}
::end shader
"""


def _cli_main():
    from viewer.commands.cli import main

    return main


def _check(capsys, *argv, json_out=True):
    main = _cli_main()

    rc = main(["check", *[str(a) for a in argv], *(["--json"] if json_out else [])])
    out = capsys.readouterr().out
    return rc, (json.loads(out) if json_out else out)


def _file(tmp_path, name, text):
    p = tmp_path / name
    p.write_text(text)
    return p


def _energy(rep):
    e = rep["checks"]["energy"]
    return e, np.array(e["albedo"]), np.array(e["noise"]), np.array(e["tolerance"])


@pytest.mark.parametrize("gain, passes", [(1.05, False), (0.95, True)])
def test_a_sharp_phong_lobe_over_the_bound_fails_energy_and_under_it_passes(capsys, tmp_path, gain, passes):
    """n = 1000: the old card's independent-points error bar was wider than the 5% excess and
    its estimate at 0 degrees 0.93; now the estimate is within its noise of the analytic value."""
    path = _file(tmp_path, "phong.brdf", PHONG)
    _, rep = _check(capsys, path, "--set", f"gain={gain}")
    e, alb, noise, tol = _energy(rep)
    assert e["pass"] is passes
    exact = gain * 1002 / 1001
    k40 = e["theta_deg"].index(40)
    for k in (0, k40):
        assert np.all(np.abs(alb[k] - exact) <= 4 * noise[k] + 1e-4), (alb[k], noise[k])
    assert np.all(noise < 2e-3) and np.all(alb <= exact + 4 * noise + 1e-4)
    # what the check allowed above the bound: 4 standard errors plus the stated floor
    np.testing.assert_allclose(tol, 4 * noise + 1e-4, rtol=1e-12)


def test_the_published_cook_torrance_fails_energy_at_its_analytic_albedo(capsys, tmp_path):
    path = _file(tmp_path, "cooktorrance.brdf", COOK_TORRANCE_PUBLISHED)
    rc, rep = _check(capsys, path)
    e, alb, noise, _ = _energy(rep)
    assert rc == 1 and not e["pass"]
    assert np.all(np.abs(alb[0] - 0.4 * math.pi) <= 0.02 * 0.4 * math.pi)
    assert not rep["checks"]["finite"]["pass"]  # pow(1 - VdotH, 5) with VdotH a hair above 1


def test_the_built_in_microfacet_at_alpha_0_0025_passes_with_every_estimate_below_1_02(capsys):
    """The old card estimated 1.79 here (a lobe 0.005 rad wide between stratified cosine points)."""
    rc, rep = _check(capsys, "microfacet", "--set", "alpha=0.0025")
    e, alb, noise, _ = _energy(rep)
    assert rc == 0 and e["pass"]
    assert np.all(alb <= 1.02) and alb.min() > 0.3 and np.all(noise < 0.01)


def test_a_lambert_at_1_02_fails_and_the_built_in_lambert_at_1_passes(capsys, tmp_path):
    rc, rep = _check(capsys, _file(tmp_path, "lambert.brdf", LAMBERT))
    e, alb, noise, _ = _energy(rep)
    assert rc == 1 and not e["pass"]
    np.testing.assert_allclose(alb, 1.02, rtol=1e-5)  # the control variate integrates a constant exactly
    rc, rep = _check(capsys, "lambert", "--set", "albedo=1")
    e, alb, _, _ = _energy(rep)
    assert rc == 0 and e["pass"] and np.allclose(alb, 1.0, rtol=1e-9)


def test_the_albedo_noise_is_the_spread_of_independent_estimates(tmp_path):
    """The reported standard error against the standard deviation of 12 estimates with different
    seeds (of the sharp Phong lobe at 40 degrees, where stratified points as if independent gave
    the old card an error bar ten times too wide); the estimates' mean is the analytic value."""
    from viewer.brdf.report_card import albedo_curve

    m = brdf.load(_file(tmp_path, "phong.brdf", PHONG))
    p = m.params()
    runs = [albedo_curve(m, p, thetas=(40,), seed=10 + s) for s in range(12)]
    est = np.array([a[0, 0] for a, _ in runs])
    noise = np.array([n[0, 0] for _, n in runs])
    ratio = est.std(ddof=1) / math.sqrt(np.mean(noise ** 2))
    # the standard deviation of 12 draws is within a factor 1.6 of the true one with probability
    # 0.999 (chi-square, 11 degrees of freedom); a noise too small or too large by 2x fails
    assert 0.5 < ratio < 2.0, ratio
    assert abs(est.mean() - 1002 / 1001) < 4 * noise.mean() / math.sqrt(12) + 1e-5


@pytest.mark.parametrize("lobe", [False, True])
def test_a_two_percent_asymmetry_fails_reciprocity(capsys, tmp_path, lobe):
    path = _file(tmp_path, "asym.brdf", ASYMMETRIC)
    e = 0.005 if lobe else 0.01
    rc, rep = _check(capsys, path, "--set", f"lobe={int(lobe)}", "--set", f"e={e}")
    r = rep["checks"]["reciprocity"]
    assert rc == 1 and not r["pass"] and r["tolerance"] == 1e-3
    assert r["max_rel_error"] == pytest.approx(0.0198, abs=5e-4)
    wi, wo = np.array(r["example"]["wi"]), np.array(r["example"]["wo"])
    assert abs(np.linalg.norm(wi) - 1) < 1e-9 and abs(np.linalg.norm(wo) - 1) < 1e-9
    f = np.array(r["example"]["f"])
    fr = np.array(r["example"]["f_exchanged"])
    assert np.all(np.abs(f - fr) / np.maximum(f, fr) > 1e-3)
    if not lobe:  # f(L, V) / f(V, L) is (1 + e d) / (1 - e d), d = cos theta_L - cos theta_V
        d = wi[2] - wo[2]
        np.testing.assert_allclose(f / fr, (1 + e * d) / (1 - e * d), rtol=1e-5)


def test_the_float32_rounding_of_a_sharp_lobe_passes_reciprocity(capsys, tmp_path):
    from viewer.brdf.report_card import pairs, reciprocity

    m = brdf.load(_file(tmp_path, "rounded.brdf", PHONG_ROUNDED))
    p = m.params()
    wi, wo = pairs()
    r = reciprocity(m, p, wi, wo, np.asarray(m.eval(p, wi, wo), float))
    # the rounding differences are above the relative tolerance: only the rounding term passes them
    assert r["pass"] and r["max_rel_error"] > 1e-3 and r["rounding"] > r["max_rel_error"]


def test_the_text_output_names_a_non_finite_pair_and_prints_the_albedo_per_angle(capsys):
    rc, out = _check(capsys, DATA / "nan.brdf", json_out=False)
    assert rc == 1
    lines = out.splitlines()
    i = next(k for k, line in enumerate(lines) if line.strip().startswith("finite"))
    assert "FAIL" in lines[i] and "count" in lines[i]
    assert lines[i + 1].strip().startswith("f is NaN or Inf at wi (") and ", wo (" in lines[i + 1]
    assert "pow(max(1 - VdotH, 0), 5)" in out and "a hair above 1" in out
    j = next(k for k, line in enumerate(lines) if line.strip().startswith("energy"))
    assert lines[j + 1].split()[:2] == ["theta", "albedo"]
    rows = [line.split() for line in lines[j + 2:j + 21]]
    assert [int(r[0]) for r in rows] == [0, 5, 10, 15, 20, 25, 30, 35, 40, 45, 50, 55, 60, 65, 70, 75, 80,
                                         85, 89]
    assert all(len(r) >= 10 for r in rows)  # theta, albedo, noise and tolerance (R G B each)
