"""One statistical harness for every registered BRDF (Nori warptest / chi2test, Mitsuba ChiSquareTest;
the chi-square test itself lives in viewer.brdf.chi2, shared with the sampling plot).

Everything here takes a registry model (``brdf.get(name)``) and parameters, so a new model is tested
by being registered. Optional per-model hooks, looked up on the model's module:

  TEST_PARAMS        {label: overrides} parameter sets for the chi-square and furnace tests
                     (default: the defaults plus a rough and a sharp set derived from parameter names)
  energy_conserving  p -> p, the nearest parameters that conserve energy (e.g. kd + ks <= 1);
                     applied by ``random_params`` and ``param_grid``
  ALBEDO_BOUND       the model's known maximum directional albedo when it is above 1 (a published
                     model that is not energy conserving); ALBEDO_BOUND_WHY must say why
"""

from __future__ import annotations

import itertools
import math
import os
import tempfile

import numpy as np

from viewer import brdf
from viewer.brdf.chi2 import CHUNK, sample_chunks
from viewer.brdf.spec import Params

# ----------------------------------------------------------------------------- directions


def direction(theta_deg, phi_rad=0.0):
    """Unit vector at polar angle theta (degrees, from +z) and azimuth phi (radians)."""
    t = math.radians(theta_deg)
    return np.array([math.sin(t) * math.cos(phi_rad), math.sin(t) * math.sin(phi_rad), math.cos(t)])


def uniform_sphere(u):
    z = 1.0 - 2.0 * u[:, 0]
    r = np.sqrt(np.maximum(0.0, 1.0 - z * z))
    phi = 2.0 * np.pi * u[:, 1]
    return np.stack([r * np.cos(phi), r * np.sin(phi), z], axis=1)


def uniform_hemisphere(u):
    z = u[:, 0]
    r = np.sqrt(np.maximum(0.0, 1.0 - z * z))
    phi = 2.0 * np.pi * u[:, 1]
    return np.stack([r * np.cos(phi), r * np.sin(phi), z], axis=1)


def random_upper(rng, n, max_theta_deg=89.0):
    """Directions uniform in solid angle over the cap theta <= max_theta."""
    zmin = math.cos(math.radians(max_theta_deg))
    u = rng.random((n, 2))
    z = zmin + (1.0 - zmin) * u[:, 0]
    r = np.sqrt(np.maximum(0.0, 1.0 - z * z))
    phi = 2.0 * np.pi * u[:, 1]
    return np.stack([r * np.cos(phi), r * np.sin(phi), z], axis=1)


# ----------------------------------------------------------------------------- parameters


def _hook(model_or_name, attr, default=None):
    model = brdf.get(model_or_name) if isinstance(model_or_name, str) else model_or_name
    return model.hook(attr, default)


def plausible(p: Params) -> Params:
    """Apply the model's ``energy_conserving`` hook (and that of a nested material)."""
    model = brdf.get(p.model)
    for prm in model.spec.params:
        if prm.kind == "material":
            p = p.replace(**{prm.name: plausible(p[prm.name])})
    hook = _hook(model, "energy_conserving")
    return hook(p) if hook else p


def _range(prm):
    lo = prm.lo if prm.lo is not None else (prm.ui_lo if prm.ui_lo is not None else 0.0)
    hi = prm.hi if prm.hi is not None else (prm.ui_hi if prm.ui_hi is not None else lo + 10.0)
    return lo, hi


def _draw_float(prm, rng, size=None):
    lo, hi = _range(prm)
    if prm.log:
        # log-uniform; a range starting at 0 starts the log scale at the slider's low end instead
        llo = lo if lo > 0 else (prm.ui_lo if prm.ui_lo and prm.ui_lo > 0 else hi * 1e-4)
        return np.exp(rng.uniform(math.log(llo), math.log(hi), size))
    return rng.uniform(lo, hi, size)


def side_rng(rng) -> np.random.Generator:
    """A generator seeded from ``rng``'s state without advancing it (stable across runs)."""
    import zlib

    return np.random.default_rng(zlib.crc32(repr(rng.bit_generator.state).encode()))


def _random_fields(fields, rng, depth):
    out = {}
    for prm in fields:
        k = prm.kind
        if k == "float":
            out[prm.name] = float(_draw_float(prm, rng))
        elif k == "rgb":
            out[prm.name] = [float(x) for x in _draw_float(prm, rng, 3)]
        elif k == "choice" and prm.name == "spectral":
            # half the sets keep the model's own Fresnel parameters in play; drawn from a side
            # stream so that the other parameters' draws are those they were before it existed
            side = side_rng(rng)
            pick = prm.choices[side.integers(1, len(prm.choices))] if side.random() < 0.5 else "none"
            out[prm.name] = str(pick)
        elif k == "choice":
            out[prm.name] = str(prm.choices[rng.integers(len(prm.choices))])
        elif k == "table" and prm.name == "thin_film" and depth > 0:
            _random_fields(prm.fields, rng, depth)  # the same draws; a nested base takes no film
            out[prm.name] = {"thickness_nm": 0.0}
        elif k == "table":
            out[prm.name] = _random_fields(prm.fields, rng, depth)
        elif k == "lobes":
            count = int(rng.integers(1, min(3, prm.max_items) + 1))
            out[prm.name] = [_random_fields(prm.fields, rng, depth) for _ in range(count)]
        elif k == "material":
            bases = [n for n in brdf.names() if not brdf.get(n).spec.nests_material]
            base = bases[rng.integers(len(bases))]
            out[prm.name] = random_params(brdf.get(base).spec, rng, _depth=depth + 1)
        elif k == "path":
            out[prm.name] = prm.default  # a file (measured: the built-in example table)
        elif k == "bool":
            # the default (no draw, so the other parameters' draws stay as they were): a switch such
            # as multiple_scattering makes eval a stochastic estimate, checked in its own tests
            out[prm.name] = bool(prm.default)
        else:
            raise AssertionError(k)
    return out


def random_params(spec, rng, _depth=0) -> Params:
    """Random valid parameters for any spec: rgb / float uniform in [lo, hi] (log-uniform where the
    parameter is ``log``), choices uniform, 1-3 random lobes, tables and nested materials recursively
    (a random model that does not nest itself). The model's ``energy_conserving`` hook is applied,
    so e.g. kd + ks <= 1 holds for phong, and every number is float32-representable."""
    if isinstance(spec, str):
        spec = brdf.get(spec).spec
    model = brdf.get(spec.name)
    raw = _random_fields(spec.params, rng, _depth)
    return _float32_values(plausible(model.params(**raw)), spec.params)


def _f32(x, prm):
    """x rounded to the nearest float32 inside [lo, hi]: the GPU twin then sees exactly the values
    numpy uses (a lobe C^n with n = 5000 turns one float32 rounding of C into 3e-4 relative)."""
    y = np.float32(x)
    if prm.lo is not None and y < prm.lo:
        y = np.nextafter(np.float32(prm.lo), np.float32(np.inf))
    if prm.hi is not None and y > prm.hi:
        y = np.nextafter(np.float32(prm.hi), np.float32(-np.inf))
    return y


def _float32_values(p, fields):
    out = {}
    for prm in fields:
        v = p[prm.name]
        if prm.kind == "float":
            v = float(_f32(v, prm))
        elif prm.kind == "rgb":
            v = np.array([float(_f32(x, prm)) for x in v])
        elif prm.kind == "table":
            v = _float32_values(v, prm.fields)
        elif prm.kind == "lobes":
            v = [_float32_values(item, prm.fields) for item in v]
        elif prm.kind == "material":
            v = _float32_values(v, brdf.get(v.model).spec.params)
        out[prm.name] = v
    return Params(p.model, out)


def _extremes(prm):
    lo, hi = _range(prm)
    vals = [lo, hi]
    for v in (prm.ui_lo, prm.ui_hi):
        if v is not None and v not in vals:
            vals.append(v)
    return vals


def param_grid(model) -> list[Params]:
    """Defaults; each float at its range ends (and slider ends); each rgb all-lo, all-hi and mixed
    per component; each choice; lobes at their field extremes and at the maximum count; nested
    materials with every non-nesting model's defaults; all-lo and all-hi combinations. Every set
    passes through the model's ``energy_conserving`` hook."""
    spec = model.spec
    base = model.params()
    sets = [base]

    def add(**kw):
        try:
            sets.append(base.replace(**kw))
        except Exception as e:  # a combination the spec refuses is a harness bug
            raise AssertionError(f"{spec.name}: grid point {kw} refused: {e}") from e

    lo_all, hi_all = {}, {}
    for prm in spec.params:
        k = prm.kind
        if k == "float":
            for v in _extremes(prm):
                add(**{prm.name: float(v)})
            lo_all[prm.name], hi_all[prm.name] = _range(prm)
        elif k == "rgb":
            lo, hi = _range(prm)
            for combo in [(lo, lo, lo), (hi, hi, hi), (lo, hi, 0.5 * (lo + hi)), (hi, lo, lo)]:
                add(**{prm.name: np.array(combo, dtype=float)})
            lo_all[prm.name] = np.full(3, lo)
            hi_all[prm.name] = np.full(3, hi)
        elif k == "choice":
            for c in prm.choices:
                add(**{prm.name: c})
        elif k == "table":
            for f in prm.fields:
                if f.kind in ("float", "rgb"):
                    for v in _extremes(f):
                        sub = dict(base[prm.name])
                        sub[f.name] = float(v) if f.kind == "float" else np.full(3, v)
                        add(**{prm.name: Params("", sub)})
        elif k == "lobes":
            default_lobe = base[prm.name][0]
            for f in prm.fields:
                for v in _extremes(f):
                    add(**{prm.name: [default_lobe.replace(**{f.name: float(v)})]})
            add(**{prm.name: [default_lobe] * prm.max_items})
        elif k == "material":
            for n in brdf.names():
                if not brdf.get(n).spec.nests_material:
                    add(**{prm.name: brdf.get(n).params()})
    if lo_all:
        add(**lo_all)
        add(**hi_all)
        # every choice combination at the high end (e.g. oren_nayar qualitative with sigma = 90)
        # (a spectral material is a Fresnel table: its choices are in the grid above, not crossed)
        choices = [prm for prm in spec.params if prm.kind == "choice" and prm.name != "spectral"]
        for combo in itertools.product(*[prm.choices for prm in choices]):
            add(**hi_all, **{prm.name: c for prm, c in zip(choices, combo)})
    return [plausible(p) for p in sets]


# rough / sharp sets derived from parameter names when a module has no TEST_PARAMS
_ROUGH_SHARP = {
    "alpha": (0.5, 0.1), "alpha_x": (0.5, 0.1), "alpha_y": (0.5, 0.1), "roughness": (0.7, 0.3),
    "shininess": (5.0, 500.0), "nu": (5.0, 500.0), "nv": (5.0, 500.0), "sigma": (60.0, 10.0),
}


def test_param_sets(model) -> dict[str, Params]:
    """{label: params} for the chi-square and furnace tests: the module's TEST_PARAMS, or the
    defaults plus a 'rough' and a 'sharp' set derived from known parameter names."""
    hook = _hook(model, "TEST_PARAMS")
    if hook is not None:
        return {label: plausible(model.params(**kw)) for label, kw in hook.items()}
    out = {"default": plausible(model.params())}
    names = set(model.spec.names)
    for i, label in enumerate(("rough", "sharp")):
        kw = {n: v[i] for n, v in _ROUGH_SHARP.items() if n in names}
        if kw:
            try:
                out[label] = plausible(model.params(**kw))
            except Exception:
                pass
    return out


test_param_sets.__test__ = False  # not a pytest test


# ----------------------------------------------------------------------------- estimators


def albedo_sampler(model, p, wo, n, rng):
    """Directional albedo E[weight] with the model's own sampler: (mean (3,), standard error (3,))."""
    s1 = np.zeros(3)
    s2 = np.zeros(3)
    for _, w, _ in sample_chunks(model, p, wo, n, rng):
        s1 += w.sum(axis=0)
        s2 += (w * w).sum(axis=0)
    mean = s1 / n
    var = np.maximum(s2 / n - mean * mean, 0.0)
    return mean, np.sqrt(var / n)


def albedo_uniform(model, p, wo, n, rng, sphere=False):
    """Independent estimator: f |cos| / pdf with uniform (hemi)sphere directions."""
    s1 = np.zeros(3)
    s2 = np.zeros(3)
    done = 0
    while done < n:
        m = min(CHUNK, n - done)
        u = rng.random((m, 2))
        wi = uniform_sphere(u) if sphere else uniform_hemisphere(u)
        inv_pdf = 4.0 * np.pi if sphere else 2.0 * np.pi
        v = model.eval(p, wi, np.broadcast_to(wo, (m, 3))) * np.abs(wi[:, 2:3]) * inv_pdf
        s1 += v.sum(axis=0)
        s2 += (v * v).sum(axis=0)
        done += m
    mean = s1 / n
    var = np.maximum(s2 / n - mean * mean, 0.0)
    return mean, np.sqrt(var / n)


def write_chi2_images(result, label) -> str:
    """The histogram, the integrated pdf and their difference as PNGs in a new temp folder."""
    from PIL import Image

    folder = tempfile.mkdtemp(prefix=f"chi2_{label}_")
    o, e = result.observed.astype(float), result.expected
    scale = max(o.max(), e.max(), 1e-12)

    def save(a, name, signed=False):
        if signed:
            m = max(np.abs(a).max(), 1e-12)
            rgb = np.stack([np.clip(a / m, 0, 1), np.zeros_like(a), np.clip(-a / m, 0, 1)], axis=-1)
        else:
            g = np.clip(a / scale, 0, 1)
            rgb = np.stack([g, g, g], axis=-1)
        img = (rgb[::-1] * 255).astype(np.uint8)  # row 0 = top = cos theta 1
        Image.fromarray(img).resize((img.shape[1] * 8, img.shape[0] * 8), Image.NEAREST).save(
            os.path.join(folder, name))

    save(o, "histogram.png")
    save(e, "expected_pdf.png")
    save((o - e) / np.sqrt(np.maximum(e, 1.0)), "difference_sigma.png", signed=True)
    np.savez(os.path.join(folder, "chi2.npz"), observed=o, expected=e)
    return folder


def sidak(alpha, n_tests):
    """Per-test significance so that n_tests independent tests reject wrongly with probability alpha."""
    return 1.0 - (1.0 - alpha) ** (1.0 / max(n_tests, 1))


def sweep_directions():
    """Unit directions at normal, oblique, grazing (cos = 1e-6 and 0) and back-facing angles."""
    dirs = []
    for cos in (1.0, 0.5, 1e-6, 0.0, -1e-6, -0.5, -1.0):
        s = np.sqrt(max(0.0, 1.0 - cos * cos))
        for phi in (0.0, 0.37, np.pi / 2, 2.5):
            dirs.append([s * np.cos(phi), s * np.sin(phi), cos])
    return np.unique(np.array(dirs), axis=0)


def is_delta(p) -> bool:
    """Whether a material is a pure delta lobe (mirror, smooth glass)."""
    spec = brdf.get(p.model).spec
    return spec.delta and not (p.model == "dielectric" and p.get("alpha", 0.0) > 0)
