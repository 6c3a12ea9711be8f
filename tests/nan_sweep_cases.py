"""Parameter corners and direction pairs for the NaN sweep (tests/test_nan_sweep.py,
benchmarks/hardening.py).

``tests/brdf_harness.param_grid`` moves one parameter at a time to a range end; here every
parameter of a set sits at a corner at once (range ends, slider ends, a hair inside the ends,
the middle), choices and lobe counts vary, nested materials are corners of their own, and the
model's ``energy_conserving`` hook is *not* applied: the GUI lets a user set any in-range
value, so every in-range combination must shade without NaN, Inf or negative values.
"""

from __future__ import annotations

import math
import textwrap

import numpy as np

from viewer import brdf
from viewer.brdf.spec import Params

from brdf_harness import side_rng


def _corner_values(prm) -> list[float]:
    lo = prm.lo if prm.lo is not None else 0.0
    hi = prm.hi if prm.hi is not None else lo + 1e3
    span = hi - lo
    vals = [lo, hi, lo + 1e-6 * span, hi - 1e-6 * span, 0.5 * (lo + hi)]
    for v in (prm.ui_lo, prm.ui_hi):
        if v is not None:
            vals.append(v)
    if lo <= 1.0 < hi:  # an index of refraction just above 1, a weight just above 1
        vals.append(1.0 + 1e-6)
    if lo < 1.0 <= hi:
        vals.append(1.0)
    return sorted(set(float(np.float32(v)) if lo <= float(np.float32(v)) <= hi else float(v) for v in vals))


def _corner_fields(fields, rng, depth, in_table=False) -> dict:
    out = {}
    for prm in fields:
        k = prm.kind
        if k == "float" and prm.name == "thickness_top_nm":  # a side stream: the other corners stay
            out[prm.name] = float(side_rng(rng).choice(_corner_values(prm)))
        elif k == "float":
            out[prm.name] = float(rng.choice(_corner_values(prm)))
        elif k == "rgb":
            vals = _corner_values(prm)
            out[prm.name] = [float(rng.choice(vals)) for _ in range(3)] if rng.random() < 0.5 \
                else [float(rng.choice(vals))] * 3
        elif k == "choice" and prm.name == "reference":
            # the layered model's closed form: its random walk (viewer/brdf/layered_walk.py) over a
            # base that reflects more than it receives (Lafortune corners) sums a diverging series,
            # as the physical layer would (values past float32's range, not NaN)
            out[prm.name] = prm.default
        elif k == "choice" and prm.name == "spectral":  # a side stream: see brdf_harness.side_rng
            out[prm.name] = str(prm.choices[int(side_rng(rng).integers(len(prm.choices)))])
        elif k == "choice":
            out[prm.name] = str(prm.choices[int(rng.integers(len(prm.choices)))])
        elif k == "bool":  # a side stream, so that the other parameters' corners stay as they were
            out[prm.name] = bool(side_rng(rng).random() < 0.5)
        elif k == "path":
            out[prm.name] = prm.default  # a file (measured: the built-in example table)
        elif k == "table" and prm.name == "thin_film" and depth > 0:
            _corner_fields(prm.fields, rng, depth)  # the same draws; a nested base takes no film
            out[prm.name] = {"thickness_nm": 0.0}
        elif k == "table" and prm.name == "thin_film" and in_table:
            # a layered coating's film: a side stream, so the base drawn after it stays as it was
            out[prm.name] = _corner_fields(prm.fields, side_rng(rng), depth)
        elif k == "table":
            out[prm.name] = _corner_fields(prm.fields, rng, depth, in_table=True)
        elif k == "lobes":
            count = int(rng.choice([1, prm.max_items]))
            out[prm.name] = [_corner_fields(prm.fields, rng, depth) for _ in range(count)]
        elif k == "material":
            bases = [n for n in brdf.names() if not brdf.get(n).spec.nests_material]
            base = bases[int(rng.integers(len(bases)))]
            out[prm.name] = corner_params(base, rng, depth + 1)
        else:  # pragma: no cover
            raise AssertionError(k)
    return out


def corner_params(name: str, rng, depth: int = 0) -> Params:
    """Random corner parameters of model ``name`` (every value in range, validated)."""
    model = brdf.get(name)
    return model.params(**_corner_fields(model.spec.params, rng, depth))


def corner_sets(name: str, n: int, seed: int) -> list[Params]:
    """``n`` corner sets for ``name`` plus the defaults, fixed by ``seed``."""
    rng = np.random.default_rng([seed, sum(map(ord, name))])
    out = [brdf.get(name).params()]
    while len(out) < n + 1:
        out.append(corner_params(name, rng))
    return out


def _unit(v):
    v = np.asarray(v, dtype=np.float64)
    return v / np.linalg.norm(v, axis=-1, keepdims=True)


def _dir(cos, phi):
    s = math.sqrt(max(0.0, 1.0 - cos * cos))
    return [s * math.cos(phi), s * math.sin(phi), cos]


def direction_pairs(rng, n_random: int = 256) -> tuple[np.ndarray, np.ndarray]:
    """(wi, wo), each (N, 3): every pair of a set of special directions (normal, grazing at
    cos = 1e-3, 1e-6, 1e-12, 1e-30, exactly 0, just below, below, along the tangent axes where
    anisotropy changes, off-axis azimuths), the special relations wi = wo, wi = mirror(wo),
    wi = -wo (a zero half vector), both at the horizon facing each other; directions of length
    1 +- 1e-7 (what float32 rounding and interpolated normals produce); and random pairs."""
    cosines = (1.0, 1.0 - 1e-12, 0.999, 0.7, 0.3, 1e-3, 1e-6, 1e-12, 1e-30, 0.0, -1e-12, -1e-6, -0.3, -1.0)
    phis = (0.0, math.pi / 2, math.pi, 0.3, 2.2, -1.1)
    base = np.unique(np.array([_dir(c, p) for c in cosines for p in phis]), axis=0)
    wi = np.repeat(base, len(base), axis=0)
    wo = np.tile(base, (len(base), 1))
    extra_wi, extra_wo = [], []
    for d in base:
        mirror = np.array([-d[0], -d[1], d[2]])
        for a, b in ((d, d), (mirror, d), (-d, d), (d, -d)):
            extra_wi.append(a)
            extra_wo.append(b)
    for c in (0.0, 1e-7, 1e-30):  # a horizon pair facing each other: h = (0, 0, ~0)
        extra_wi.append(_dir(c, 0.0))
        extra_wo.append(_dir(c, math.pi))
    r = rng.normal(size=(n_random, 2, 3))
    r /= np.linalg.norm(r, axis=-1, keepdims=True)
    r[:, :, 2] = np.abs(r[:, :, 2]) * np.where(rng.random((n_random, 2)) < 0.1, -1, 1)
    wi = np.concatenate([wi, np.array(extra_wi), r[:, 0]])
    wo = np.concatenate([wo, np.array(extra_wo), r[:, 1]])
    # lengths off by float32 rounding (every 7th pair a bit long, every 11th a bit short)
    k = np.arange(len(wi))
    scale = np.where(k % 7 == 0, 1.0 + 1e-7, np.where(k % 11 == 0, 1.0 - 1e-7, 1.0))[:, None]
    return wi * scale, wo * scale


SAMPLE_U = np.array([[0.0, 0.0], [0.5, 0.5], [1 - 2 ** -53, 1 - 2 ** -53], [0.0, 1 - 2 ** -53],
                     [1 - 2 ** -53, 0.0], [0.25, 0.75], [1e-300, 0.5], [0.5, 1e-300],
                     [1 - 2 ** -24, 0.3], [0.3, 1 - 2 ** -24]])


def check_python(name: str, p: Params, wi, wo, rng) -> list[str]:
    """Problems of the numpy twin at ``p``: eval and pdf at every pair, sample at every wo with
    special and random u. Empty when eval, pdf, weight and pdf of sample are finite and >= 0,
    sampled directions are finite and unit where pdf > 0, weight = 0 where pdf = 0."""
    model = brdf.get(name)
    bad = []
    with np.errstate(all="ignore"):  # a NaN is reported below, not as a warning
        f = model.eval(p, wi, wo)
        pdf = model.pdf(p, wi, wo)
        uniq = np.unique(wo, axis=0)
        wo_s = np.repeat(uniq, len(SAMPLE_U), axis=0)
        u_s = np.tile(SAMPLE_U, (len(uniq), 1))
        wo_r = np.repeat(uniq, 8, axis=0)
        u_r = rng.random((len(wo_r), 2))
        samples = [model.sample(p, wo_s, u_s), model.sample(p, wo_r, u_r)]
    for what, a in (("eval", f), ("pdf", pdf)):
        if not np.all(np.isfinite(a)):
            i = int(np.argwhere(~np.isfinite(np.atleast_2d(a.T).T))[0][0])
            bad.append(f"{what} not finite at wi={wi[i].tolist()} wo={wo[i].tolist()}")
        elif not np.all(a >= 0):
            i = int(np.argwhere(np.atleast_2d(a.T).T < 0)[0][0])
            bad.append(f"{what} negative ({np.atleast_2d(a.T).T[i]}) at wi={wi[i].tolist()} wo={wo[i].tolist()}")
    for (wo_, u_), (swi, w, spdf) in zip(((wo_s, u_s), (wo_r, u_r)), samples):
        for what, a in (("sample weight", w), ("sample pdf", spdf)):
            if not np.all(np.isfinite(a)) or not np.all(a >= 0):
                rows = ~np.all(np.isfinite(np.atleast_2d(a.T).T) & (np.atleast_2d(a.T).T >= 0), axis=-1) \
                    if a.ndim > 1 else ~(np.isfinite(a) & (a >= 0))
                i = int(np.argwhere(rows)[0][0])
                bad.append(f"{what} bad ({a[i]}) at wo={wo_[i].tolist()} u={u_[i].tolist()}")
        ok = spdf > 0
        if not np.all(np.isfinite(swi[ok])) or not np.allclose(np.linalg.norm(swi[ok], axis=1), 1.0, atol=1e-6):
            bad.append("sampled wi not finite / not unit where pdf > 0")
        if not np.all(w[~ok] == 0):
            bad.append("sample weight != 0 where pdf == 0")
    return bad


SWEEP_SCENE = textwrap.dedent("""
    [camera]
    position = [0.0, 0.3, 3.0]
    width = {w}
    height = {h}
    fov_y = 40.0
    [environment]
    map = "studio"
    [render]
    ibl = "{ibl}"
    ssr = {ssr}
    shadows = true
    msaa = 0
    [[lights]]
    type = "point"
    position = [1.0, 2.0, 2.0]
    intensity = [5.0, 5.0, 5.0]
    [[lights]]
    type = "directional"
    direction = [-0.3, -1.0, -0.2]
    irradiance = [1.0, 1.0, 1.0]
    [[objects]]
    mesh = "sphere"
    material = "ball"
    [[objects]]
    mesh = "plane"
    material = "floor"
    translate = [0.0, -1.0, 0.0]
    scale = 3.0
    [materials.ball]
    model = "lambert"
    [materials.floor]
    model = "lambert"
    """)


def sweep_scene(w, h, ibl="split_sum", ssr=False):
    """The sweep's scene: a sphere over a floor under the studio map, a point and a directional
    light; the tests put each parameter corner on the ball."""
    import tomllib

    from viewer.scene import parse_scene

    return parse_scene(tomllib.loads(SWEEP_SCENE.format(w=w, h=h, ibl=ibl, ssr=str(ssr).lower())), None)
