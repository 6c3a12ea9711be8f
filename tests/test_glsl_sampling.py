"""GLSL sampling twins vs numpy: every registered model's ``brdf_sample`` / ``brdf_pdf``, run on the
GPU path (EGL, float32 render targets), over its parameter grid:

* GLSL pdf = numpy pdf at the same (float32-rounded) pairs;
* the same u gives the same wi as numpy (the warps are the same functions; numpy's
  split_uniform(u[:, 0]) = (u.z, u.x) for the models that split), the same failures, and a
  weight equal to numpy's;
* GLSL's weight = f |cos| / pdf with the GLSL eval and pdf, its pdf = brdf_pdf(wi, wo) for
  continuous samples, and delta samples flagged as the reference path tracer flags them;
* directions drawn in GLSL pass the chi-square test against the numpy pdf.

The default run takes every third grid point (plus the chi-square sets) and one chi-square case
per model; ``-m slow`` runs the whole grid and every chi-square case at 1e6 samples."""

from __future__ import annotations

import zlib

import numpy as np
import pytest

from viewer import brdf
from viewer.brdf.fresnel import fresnel_dielectric
from viewer.brdf.lobes import Lobe, drew_delta
from viewer.gl.brdf_glsl import glsl_u
from viewer.brdf.sampling import split_uniform

from brdf_harness import direction, param_grid, random_upper, sidak, test_param_sets, write_chi2_images
from viewer.brdf.chi2 import chi2_test
from glsl_eval import GLSLEvaluator, GLSLSampler

NAMES = brdf.names()
F32_ONE_MINUS = float(np.nextafter(np.float32(1.0), np.float32(0.0)))

# float32 tolerances (numpy computes in float64 from the same float32-rounded inputs):
# the pdfs are a few dozen float32 operations (measured: relative error <= 4e-6), so 1e-4
# relative leaves a wide margin; 1e-7 absolute covers values that round to 0 near the horizon.
PDF_RTOL, PDF_ATOL = 1e-4, 1e-7
# The same u: a direction is a handful of float32 operations on u (|error| <= 1e-5 measured, the
# worst in Beckmann's Newton-inverted CDF); a lobe choice u < P can flip when u is within float32
# rounding of P, and a sharp lobe amplifies u's rounding: a few in 10^4 samples may differ.
WI_ATOL = 1e-4
MAX_MISMATCH = 2e-3


def _seed(*parts) -> int:
    return zlib.crc32(repr(parts).encode())


@pytest.fixture(scope="module")
def evaluator(gl_ctx):
    return GLSLEvaluator(gl_ctx)


@pytest.fixture(scope="module")
def sampler(gl_ctx):
    return GLSLSampler(gl_ctx)


def _f32(a):
    return np.asarray(a, dtype=np.float32).astype(np.float64)


def _is_delta(p) -> bool:
    spec = brdf.get(p.model).spec
    return spec.delta and not (p.model == "dielectric" and p.alpha > 0)


def _uses_split(p) -> bool:
    """The numpy sample splits u[:, 0] into (choice, continuous) with split_uniform (the model's
    ``splits_u`` hook, which viewer.gl.brdf_glsl.glsl_u follows)."""
    hook = brdf.get(p.model).hook("splits_u")
    return bool(hook and hook(p))


# beyond the (energy-conserving) grid: a measured-fit style Lafortune lobe with |C| > 1
EXTRA = {"lafortune": [{"kd": [0.1, 0.1, 0.1], "lobes": [{"cx": -2.0, "cy": -2.0, "cz": 2.0, "n": 3.0}]}]}


def _grid(model, every):
    sets = param_grid(model)
    sets = sets[::every] + list(test_param_sets(model).values())
    return sets + [model.params(**kw) for kw in EXTRA.get(model.name, [])]


def _pairs(rng, n, transmissive):
    """wo and wi over the sphere's upper part (theta <= 89.5 deg), a few below; for transmissive
    models wo and wi on either side."""
    wo = random_upper(rng, n, 89.5)
    wi = random_upper(rng, n, 89.5)
    below_i = rng.random(n) < (0.5 if transmissive else 0.1)
    below_o = rng.random(n) < (0.3 if transmissive else 0.05)
    wi[below_i, 2] *= -1
    wo[below_o, 2] *= -1
    return _f32(wi), _f32(wo)


def _tir_rtol(p, wi, wo):
    """Extra relative tolerance of a rough dielectric's transmitted pdf near total internal
    reflection: T at the microfacet depends on cos_t = sqrt(1 - sin_t^2), so a float32 error
    d ~ 1e-7 in the microfacet cosine om moves T by about om d / (eta^2 cos_t^2) relative (the
    rasterizer's eval uses double precision for this reason; the sampling twin stays in float)."""
    extra = np.zeros(len(wi))
    if p.model != "dielectric" or p.alpha <= 0:
        return extra
    s = np.where(wo[:, 2] < 0, -1.0, 1.0)
    eta = np.where(s > 0, p.ior, 1.0 / p.ior)
    fo = wo * np.stack([np.ones_like(s), np.ones_like(s), s], axis=1)
    fi = wi * np.stack([np.ones_like(s), np.ones_like(s), s], axis=1)
    trans = fi[:, 2] < 0
    h = fi * np.where(trans, eta, 1.0)[:, None] + fo
    h /= np.maximum(np.linalg.norm(h, axis=1, keepdims=True), 1e-300)
    om = np.abs(np.sum(fo * h, axis=1))
    cos_t2 = 1.0 - (1.0 - om * om) / (eta * eta)
    return np.where(trans, 1e-6 / np.maximum(cos_t2, 1e-12), 0.0)


# A measured material's half-vector density is piecewise constant over theta_h bins: a half vector
# within float32 rounding of a bin edge may land in either bin in the two twins (the pdf then jumps
# by the ratio of neighbouring bins, ~4%). Measured: a pair under a layered coat (two refractions)
# came 3.6e-5 bin widths from an edge and flipped; such pairs (within 1e-4 bin widths) are left out
# of the pdf comparison, and they must stay rare.
BIN_EDGE = 1e-4


def _near_bin_edge(p, wi, wo):
    from viewer.brdf import layered, merl
    from viewer.brdf.sampling import normalize

    near = np.zeros(len(wi), dtype=bool)
    if p.model == "layered" and p.base.model == "measured":
        wi, wo = layered.refract_in(wi, p.coating.ior), layered.refract_in(wo, p.coating.ior)
    elif p.model != "measured":
        return near
    h = normalize(wi + wo)
    th = np.arctan2(np.hypot(h[:, 0], h[:, 1]), h[:, 2])
    x = np.sqrt(np.clip(th, 0.0, merl.HALF_PI) / merl.HALF_PI) * merl.N_TH
    k = np.round(x)   # interior edges only: below bin 0 and above the last one both twins clamp
    return (np.abs(x - k) < BIN_EDGE) & (k >= 1) & (k <= merl.N_TH - 1)


def _check_pdf(name, p, evaluator, rng, n=2000):
    model = brdf.get(name)
    wi, wo = _pairs(rng, n, model.spec.transmissive)
    ref = model.pdf(p, wi, wo)
    got = evaluator.eval(p, wi, wo, what=2)[:, 0]
    assert np.all(np.isfinite(got)) and np.all(got >= 0), f"{name}: GLSL pdf NaN/Inf/negative for {p.to_plain()}"
    tol = (PDF_RTOL + _tir_rtol(p, wi, wo)) * np.abs(ref) + PDF_ATOL
    edge = _near_bin_edge(p, wi, wo)
    assert edge.mean() <= 0.01, f"{name}: {edge.sum()} of {n} pairs at a bin edge (expected ~{2 * BIN_EDGE:.0e})"
    bad = (np.abs(got - ref) > tol) & ~edge
    if bad.any():
        i = int(np.argmax(bad))
        pytest.fail(f"{name}: {bad.sum()} of {n} GLSL pdfs differ; first wi={wi[i]}, wo={wo[i]}, "
                    f"glsl={got[i]:.7g}, numpy={ref[i]:.7g}, params={p.to_plain()}")


def _check_twin(name, p, evaluator, sampler, rng, n=2000):
    model = brdf.get(name)
    transmissive = model.spec.transmissive
    wo = random_upper(rng, n, 89.0)
    if transmissive:
        wo[: n // 3, 2] *= -1  # from inside the glass
    wo = _f32(wo)
    u2 = np.minimum(_f32(rng.random((n, 2))), F32_ONE_MINUS)
    if _uses_split(p):
        u3 = glsl_u(p, u2)
        assert np.array_equal(u3[:, [2, 0]], np.stack(split_uniform(u2[:, 0]), axis=1))
    else:
        u3 = np.concatenate([u2, rng.random((n, 1))], axis=1)  # u.z must be ignored
    u3 = np.minimum(_f32(u3), F32_ONE_MINUS)
    if _uses_split(p):
        u2 = u2.copy()
        # the float32-rounded split parts may differ from split_uniform's exact ones by an ulp:
        # numpy samples from the rounded parts (pick its u[:, 0] so that it splits into them)
        u2[:, 0] = (np.floor(u3[:, 2] * 65536) + u3[:, 0]) / 65536
    wi_g, w_g, pdf_g, lobe_g = sampler.sample(p, wo, u3)
    wi_n, w_n, pdf_n, lobe_n = model.sample_lobe(p, wo, u2)
    disc = drew_delta(lobe_g)
    where = f"{name} {p.to_plain()}"
    assert np.all(np.isfinite(wi_g)) and np.all(np.isfinite(w_g)) and np.all(np.isfinite(pdf_g)), where
    assert np.all(pdf_g >= 0) and np.all(w_g >= 0), where
    assert np.all(w_g[pdf_g <= 0] == 0), f"{where}: weight != 0 where pdf = 0"
    # -- the same u gives the same sample (nested rough-glass bases split u.x twice in numpy)
    nested_split = p.model == "layered" and _uses_split(p.base)
    if not nested_split:
        both = (pdf_g > 0) & (pdf_n > 0)
        fail_differs = (pdf_g > 0) != (pdf_n > 0)
        wi_differs = both & (np.abs(wi_g - wi_n).max(axis=1) > WI_ATOL)
        mismatch = (fail_differs | wi_differs).mean()
        assert mismatch <= MAX_MISMATCH, (f"{where}: {mismatch:.2%} of samples differ from numpy's for the "
                                          f"same u ({fail_differs.sum()} fail on one side only)")
        # weights: f cos / pdf at directions that agree to WI_ATOL; a sharp lobe turns that
        # difference into a relative change of its weight, so the same fraction may differ
        same = both & ~wi_differs
        w_bad = same & np.any(np.abs(w_g - w_n) > 1e-3 * np.abs(w_n) + 1e-6, axis=1)
        assert w_bad.mean() <= MAX_MISMATCH, f"{where}: {w_bad.sum()} GLSL weights != numpy's for the same u"
        # the lobe drawn (viewer/brdf/lobes.py): where the two drew the same direction, the same
        # side and kind (a choice that flips within rounding draws another direction: not here)
        l_bad = same & (lobe_g != lobe_n)
        assert not l_bad.any(), (f"{where}: {l_bad.sum()} GLSL lobes != numpy's for the same u, e.g. "
                                 f"{Lobe(int(lobe_g[l_bad][0]))!r} vs {Lobe(int(lobe_n[l_bad][0]))!r}")
    # -- weight = f |cos| / pdf with the GLSL eval and pdf; pdf = brdf_pdf(wi) unless discrete
    ok = pdf_g > 0
    wi, woo = _f32(wi_g[ok]), wo[ok]
    if _is_delta(p):
        assert np.all(disc[ok]), f"{where}: a delta material's sample not flagged discrete"
        assert np.all(evaluator.eval(p, wi, woo, what=2)[:, 0] == 0), f"{where}: delta pdf != 0"
        return
    f = evaluator.eval(p, wi, woo)
    pe = evaluator.eval(p, wi, woo, what=2)[:, 0]
    cont = ~disc[ok]
    if p.model != "layered" or not _is_delta(p.base):
        assert np.all(cont), f"{where}: {int((~cont).sum())} continuous samples flagged discrete"
    extra = _tir_rtol(p, wi, woo)
    # wi came back rounded to float32: f and pdf at the rounded wi move by at most a few 1e-6
    # relative, except where a sharp lobe's value changes fast (within the 1e-4 margin here)
    rt = 1e-4 + extra[cont]
    assert np.all(np.abs(pdf_g[ok][cont] - pe[cont]) <= rt * pe[cont] + PDF_ATOL), \
        f"{where}: the sampled pdf != brdf_pdf(wi, wo)"
    expect = f[cont] * np.abs(wi[cont, 2:3]) / pe[cont, None]
    bad = np.abs(w_g[ok][cont] - expect) > rt[:, None] * np.abs(expect) + 1e-6
    assert bad.mean() <= MAX_MISMATCH, f"{where}: {bad.any(axis=1).sum()} weights != f |cos| / pdf"


def _grid_cases(every):
    return [(n, every) for n in NAMES]


@pytest.mark.parametrize("name", NAMES)
def test_glsl_pdf_and_sample_twins(name, evaluator, sampler):
    model = brdf.get(name)
    rng = np.random.default_rng(_seed(name, "twins"))
    for p in _grid(model, every=3):
        _check_pdf(name, p, evaluator, rng, n=1000)
        _check_twin(name, p, evaluator, sampler, rng, n=1000)


@pytest.mark.slow
@pytest.mark.parametrize("name", NAMES)
def test_glsl_pdf_and_sample_twins_full_grid(name, evaluator, sampler):
    model = brdf.get(name)
    rng = np.random.default_rng(_seed(name, "twins-full"))
    for p in _grid(model, every=1):
        _check_pdf(name, p, evaluator, rng, n=10000)
        _check_twin(name, p, evaluator, sampler, rng, n=10000)


# ----------------------------------------------------------------------------- chi-square

class _GPUSampled:
    """A model whose ``sample`` draws on the GPU (u.z a fresh uniform) and whose ``pdf`` is
    numpy's: what the chi-square harness needs to test GLSL samples against the numpy pdf."""

    def __init__(self, model, sampler, rng):
        self.model, self.sampler, self.rng = model, sampler, rng
        self.spec = model.spec

    def sample(self, p, wo, u):
        u3 = np.concatenate([u, self.rng.random((len(u), 1))], axis=1)
        u3 = np.minimum(_f32(u3), F32_ONE_MINUS)
        wi, w, pdf, _ = self.sampler.sample(p, _f32(wo), u3)
        return wi, w, pdf

    def pdf(self, p, wi, wo):
        return self.model.pdf(p, wi, wo)


THETA_O = (0.0, 30.0, 60.0, 80.0)
PHI_O = 0.37
CHI2_ALL = [(n, label, t) for n in NAMES for label, p in test_param_sets(brdf.get(n)).items()
            if not _is_delta(p) for t in THETA_O]
# the default run: one case per model, its parameter sets and angles taken in turn
CHI2_DEFAULT = []
for _n in NAMES:
    _cases = [c for c in CHI2_ALL if c[0] == _n]
    if _cases:
        CHI2_DEFAULT.append(_cases[zlib.crc32(_n.encode()) % len(_cases)])
CHI2_ALPHA = sidak(0.01, len(CHI2_ALL))


def _chi2(sampler, name, label, theta_o, n):
    model = brdf.get(name)
    p = test_param_sets(model)[label]
    rng = np.random.default_rng(_seed(name, label, theta_o, "glsl-chi2"))
    gpu = _GPUSampled(model, sampler, np.random.default_rng(_seed(name, label, theta_o, "u.z")))
    res = chi2_test(gpu, p, direction(theta_o, PHI_O), n, rng, CHI2_ALPHA, sphere=model.spec.transmissive)
    print(f"{name} [{label}] theta_o={theta_o}: {res.message}")
    if not res.ok:
        folder = write_chi2_images(res, f"glsl_{name}_{label}_{int(theta_o)}") if res.observed is not None else "-"
        pytest.fail(f"GLSL {name} [{label}] theta_o={theta_o}: {res.message}; images in {folder}")


@pytest.mark.parametrize("name,label,theta_o", CHI2_DEFAULT)
def test_glsl_samples_chi2(sampler, name, label, theta_o):
    _chi2(sampler, name, label, theta_o, 200_000)


@pytest.mark.slow
@pytest.mark.parametrize("name,label,theta_o", CHI2_ALL)
def test_glsl_samples_chi2_all(sampler, name, label, theta_o):
    _chi2(sampler, name, label, theta_o, 1_000_000)


# ----------------------------------------------------------------------------- delta lobes

@pytest.mark.parametrize("name,params", [
    ("mirror", {"fresnel": "conductor"}), ("mirror", {"fresnel": "dielectric", "ior": 1.7}),
    ("dielectric", {"ior": 1.5}), ("dielectric", {"ior": 2.4}),
    ("layered", {"base": {"model": "mirror", "fresnel": "none"}}),
])
def test_glsl_delta_lobes(sampler, name, params):
    """Delta lobes as numpy and the reference path tracer treat them: the mirror's direction
    with pdf 1 and weight F; smooth glass reflecting with pdf R (weight 1) or refracting to the
    other side with pdf 1 - R (weight 1 / eta^2); the layered coat over a mirror mixing a
    continuous coat lobe with a discrete base lobe, flagged as such."""
    model = brdf.get(name)
    p = model.params(**params)
    rng = np.random.default_rng(_seed(name, params, "delta"))
    n = 4000
    wo = random_upper(rng, n, 89.0)
    if model.spec.transmissive:
        wo[: n // 2, 2] *= -1
    wo = _f32(wo)
    u3 = np.minimum(_f32(rng.random((n, 3))), F32_ONE_MINUS)
    wi, w, pdf, lobe = sampler.sample(p, wo, u3)
    disc = drew_delta(lobe)
    if name == "mirror":
        np.testing.assert_allclose(wi, wo * [-1, -1, 1], atol=1e-7)
        assert np.all(pdf == 1.0) and np.all(disc)
        np.testing.assert_allclose(w, model.sample(p, wo, u3[:, :2])[1], rtol=1e-5, atol=1e-7)
    elif name == "dielectric":
        wi_n, w_n, pdf_n = model.sample(p, wo, u3[:, :2])
        eta = np.where(wo[:, 2] > 0, p.ior, 1.0 / p.ior)
        R = fresnel_dielectric(np.abs(wo[:, 2]), eta)
        refl = wi[:, 2] * wo[:, 2] > 0
        # a choice u < R may flip within float32 rounding of R
        same = np.abs(u3[:, 0] - R) > 1e-5
        assert np.all(refl[same] == (u3[same, 0] < R[same]))
        np.testing.assert_allclose(wi[same], wi_n[same], atol=1e-5)
        # R in float32: near the critical angle (wo inside) R's slope amplifies cos_o's rounding
        np.testing.assert_allclose(pdf[same], pdf_n[same], rtol=1e-4, atol=1e-7)
        np.testing.assert_allclose(w[same], w_n[same], rtol=1e-5, atol=1e-7)
        t = ~refl & (pdf > 0)
        assert t.any() and np.allclose(w[t], (1.0 / eta[t] ** 2)[:, None], rtol=1e-6)
        assert np.all(disc)
        ok = pdf > 0  # the side each drew: transmission exactly where wi went through
        assert np.array_equal((lobe[ok] & Lobe.TRANSMISSION) != 0, ~refl[ok])
        assert np.array_equal((lobe[ok] & Lobe.REFLECTION) != 0, refl[ok])
    else:
        coat = u3[:, 2] < fresnel_dielectric(wo[:, 2], p.coating.ior)
        ok = pdf > 0
        assert np.all(disc[ok & ~coat]) and not np.any(disc[ok & coat])
        # the base lobe is the mirror direction (refraction in and out of a flat layer undoes itself)
        np.testing.assert_allclose(wi[ok & ~coat], wo[ok & ~coat] * [-1, -1, 1], atol=1e-5)
