"""BRDF plots: the data (pure numpy, computed with the registry's Python twins) and a headless
drawing of them with Pillow.

The GUI (``viewer.app.plots_panel``) and ``brdf-viewer plot`` both call the data functions below,
so what is plotted is exactly what ``viewer.brdf`` computes:

* ``polar_lobe``: f(wi, wo) and f(wi, wo) cos(theta_o) in the plane of incidence (BRDF Explorer's
  polar plot). The plane is the one through the normal at azimuth ``phi`` (0 = the x-z plane
  that holds the tangent, 90 = the y-z plane that holds the bitangent: the two planes of an
  anisotropic model). wi = (sin t_i cos phi, sin t_i sin phi, cos t_i) and
  wo = (-sin t_o cos phi, -sin t_o sin phi, cos t_o) for t_o in [-90, 90] degrees: t_o > 0 lies
  on the mirror side (the mirror direction is t_o = theta_i), t_o < 0 on the side of the light
  (t_o = -theta_i is the retro-reflection direction). The integral of f cos(t_o) over the
  hemisphere of wo is the directional albedo.
* ``lobe_3d``: f cos(theta_o) over the hemisphere of wo as a surface (radius = value).
* ``albedo_curve``: directional albedo vs angle (the furnace curve), ``viewer.brdf.albedo``.
* ``fresnel_curves``: R_s, R_p and R vs the angle of incidence from ``viewer.brdf.fresnel``, with
  Brewster's angle atan(n2/n1) and, leaving the denser medium, the critical angle asin(n2/n1).
* ``bouguer_curve``: Bouguer's (Beer-Lambert) law T(d) = exp(-sigma_a d).
* ``sampling_histogram``: the model's importance sampler at a fixed direction: the histogram of
  sampled directions in (cos theta, phi) cells beside the pdf integrated over the same cells,
  their difference in standard deviations and the chi-square p-value, all from
  ``viewer.brdf.chi2`` (the test suite's chi-square test), plus a point cloud of samples.

``figure`` turns one of them into a ``Figure`` (labelled curves and marks), ``render_figure``
draws it as an RGB image and ``figure_json`` gives the plotted numbers (the PNG's
``brdf-viewer:plot`` text chunk).
"""

from __future__ import annotations

import functools
import json
import math
from dataclasses import dataclass, field

import numpy as np

from viewer import ViewerError
from viewer.brdf.sampling import LUMINANCE_REC709, luminance, reflect_z

KINDS = ("polar", "lobe", "albedo", "fresnel", "bouguer", "spectral", "sampling", "slice")
CHANNELS = ("rgb", "lum", "r", "g", "b")
PNG_KEY = "brdf-viewer:plot"
LUMINANCE = LUMINANCE_REC709  # the weights of 'lum' (docs/conventions.md: linear Rec.709 RGB)

_CHANNEL_NAMES = ("red", "green", "blue")
_CHANNEL_COLOURS = ((214, 39, 40), (44, 160, 44), (31, 119, 180))
_NEUTRAL = (25, 25, 25)


# ----------------------------------------------------------------------------- inputs

def as_params(p, model: str | None = None):
    """A validated ``Params``: a Params as it is, else a dict of values (with a ``model`` key,
    or ``model`` given) validated through the model's spec."""
    from viewer import brdf
    from viewer.brdf.spec import Params

    if isinstance(p, Params):
        return p
    raw = dict(p or {})
    name = raw.pop("model", model)
    if name is None:
        raise ViewerError("plot: no model given; allowed: " + ", ".join(brdf.names()))
    return brdf.get(name).params(**raw)


def _model(p):
    from viewer import brdf

    return brdf.get(p.model)


def fresnel_source(p) -> dict | None:
    """How a material's Fresnel reflectance is given, or None when it has none:
    {"type": "dielectric", "ior": n, "field": ...} | {"type": "conductor", "eta": (3,), "k": (3,)}
    | {"type": "schlick", "f0": (3,)}; "field" names the parameter(s)."""
    m = p.model
    if m == "microfacet":
        if p.fresnel == "dielectric":
            return {"type": "dielectric", "ior": float(p.ior), "field": "ior"}
        if p.fresnel == "conductor":
            return {"type": "conductor", "eta": np.asarray(p.eta, float), "k": np.asarray(p.k, float),
                    "field": "eta, k"}
        return {"type": "schlick", "f0": np.asarray(p.f0, float), "field": "f0"}
    if m == "mirror":
        if p.fresnel == "conductor":
            return {"type": "conductor", "eta": np.asarray(p.eta, float), "k": np.asarray(p.k, float),
                    "field": "eta, k"}
        if p.fresnel == "dielectric":
            return {"type": "dielectric", "ior": float(p.ior), "field": "ior"}
        return None
    if m == "layered":
        return {"type": "dielectric", "ior": float(p.coating.ior), "field": "coating.ior"}
    if m == "ashikhmin_shirley":
        return {"type": "schlick", "f0": np.asarray(p.rs, float), "field": "rs"}
    # any other (discovered) model: by its parameter names
    if "ior" in p and np.ndim(p["ior"]) == 0:
        return {"type": "dielectric", "ior": float(p["ior"]), "field": "ior"}
    if "eta" in p and "k" in p:
        return {"type": "conductor", "eta": np.asarray(p["eta"], float), "k": np.asarray(p["k"], float),
                "field": "eta, k"}
    return None


def absorption_source(p) -> dict | None:
    """The absorption coefficient of a material, or None: {"sigma_a": (3,), "unit": length unit,
    "thickness": layer thickness or None, "field": ...}."""
    if p.model == "layered":
        return {"sigma_a": np.asarray(p.coating.sigma_a, float), "unit": "um",
                "thickness": float(p.coating.thickness), "field": "coating.sigma_a"}
    if "sigma_a" in p and np.shape(p["sigma_a"]) == (3,):
        return {"sigma_a": np.asarray(p["sigma_a"], float), "unit": "m", "thickness": None, "field": "sigma_a"}
    return None


def applicable_kinds(p) -> tuple[str, ...]:
    """The plot kinds that apply to a material (polar, lobe and albedo apply to every model)."""
    kinds = ["polar", "lobe", "albedo"]
    if fresnel_source(p) is not None:
        kinds.append("fresnel")
    if absorption_source(p) is not None:
        kinds.append("bouguer")
    if spectral_source(p) is not None:
        kinds.append("spectral")
    if sampling_delta(p) is None:
        kinds.append("sampling")
        kinds.append("slice")  # the Rusinkiewicz slice (viewer/measured_plot.py)
    return tuple(kinds)


def spectral_source(p) -> str | None:
    """The spectral table (viewer.spectral) a material names, or None."""
    from viewer.spectral_plot import spectral_name

    return spectral_name(p)


def sampling_delta(p) -> str | None:
    """Why ``p``'s sampler has no density to histogram (a delta lobe: mirror, smooth glass, or
    a layered model over one), else None."""
    from viewer import brdf

    spec = brdf.get(p.model).spec
    rough_glass = spec.name == "dielectric" and float(p.get("alpha", 0.0)) > 0.0
    if spec.delta and not rough_glass:
        return f"model {p.model!r} samples a delta lobe (a discrete direction, no density)"
    for prm in spec.params:
        if prm.kind == "material" and sampling_delta(p[prm.name]) is not None:
            return f"its {prm.name} ({p[prm.name].model}) samples a delta lobe (a discrete direction, no density)"
    return None


def _models_with(test) -> list[str]:
    from viewer import brdf

    out = []
    for name in brdf.names():
        m = brdf.get(name)
        try:
            if test(m.params()) is not None:
                out.append(name)
        except ViewerError:
            pass
    return out


def check_kind_name(kind: str) -> None:
    """ViewerError (one line) when ``kind`` is not a plot kind."""
    if kind not in KINDS:
        raise ViewerError(f"--kind: {kind!r} is not a plot kind; allowed: {', '.join(KINDS)}")


def check_kind(p, kind: str) -> None:
    """ViewerError (one line) when ``kind`` is not a plot kind or does not apply to ``p``."""
    check_kind_name(kind)
    if kind in applicable_kinds(p):
        return
    if kind in ("sampling", "slice"):
        raise ViewerError(f"{kind} plot: {sampling_delta(p)}; the plots of {p.model!r}: "
                          f"{', '.join(applicable_kinds(p))}")
    what = {"fresnel": "no index of refraction (no Fresnel term)",
            "bouguer": "no absorption coefficient sigma_a",
            "spectral": "no spectral table (spectral = \"NAME\")"}[kind]
    if kind == "fresnel" and p.model == "mirror":
        what = "fresnel = 'none' (R = 1 at every angle)"
    if kind == "spectral":
        raise ViewerError(f"spectral plot: model {p.model!r} has {what}; set spectral to one of "
                          f"{', '.join(_spectral_names())} (or use a metal preset, e.g. gold)")
    needs = _models_with(fresnel_source if kind == "fresnel" else absorption_source)
    raise ViewerError(f"{kind} plot: model {p.model!r} has {what}; the plots of {p.model!r}: "
                      f"{', '.join(applicable_kinds(p))}; {kind} applies to: {', '.join(needs)}")


def _spectral_names():
    from viewer import spectral

    return spectral.materials()


def check_channel(channel: str) -> None:
    if channel not in CHANNELS:
        raise ViewerError(f"--channel: {channel!r} is not a channel; allowed: {', '.join(CHANNELS)}")


def reduce_channel(rgb, channel: str) -> np.ndarray:
    """(..., 3) -> (...): one channel ('r', 'g', 'b') or the Rec.709 luminance ('lum', 'rgb')."""
    check_channel(channel)
    if channel in ("lum", "rgb"):
        return luminance(rgb)
    return np.asarray(rgb, dtype=np.float64)[..., "rgb".index(channel)]


# ----------------------------------------------------------------------------- data

def direction(theta_deg, phi_deg=0.0) -> np.ndarray:
    """Unit vector(s) at polar angle theta from +z (the normal) and azimuth phi from +x."""
    t = np.radians(np.asarray(theta_deg, dtype=np.float64))
    ph = np.radians(np.asarray(phi_deg, dtype=np.float64))
    t, ph = np.broadcast_arrays(t, ph)
    return np.stack([np.sin(t) * np.cos(ph), np.sin(t) * np.sin(ph), np.cos(t)], axis=-1)


def plane_directions(theta_o_deg, phi_deg=0.0) -> np.ndarray:
    """wo in the plane of incidence at signed angle theta_o (> 0: the mirror side, i.e. azimuth
    phi + 180)."""
    return direction(-np.asarray(theta_o_deg, dtype=np.float64), float(phi_deg))


def _check_theta_i(theta_i: float) -> float:
    theta_i = float(theta_i)
    if not (math.isfinite(theta_i) and 0.0 <= theta_i < 90.0):
        raise ViewerError(f"--theta-i: {theta_i:g} is out of range; allowed: degrees in [0, 90)")
    return theta_i


def _check_phi(phi: float) -> float:
    phi = float(phi)
    if not (math.isfinite(phi) and -360.0 <= phi <= 360.0):
        raise ViewerError(f"--phi: {phi:g} is out of range; allowed: degrees in [-360, 360]")
    return phi


def _delta_reflectance(p, cos_i: float) -> np.ndarray:
    """RGB reflectance of a delta mirror lobe at cos_i (the Fresnel term of the material)."""
    from viewer.brdf.fresnel import fresnel_conductor, fresnel_dielectric, fresnel_schlick

    src = fresnel_source(p)
    if src is None:
        return np.ones(3)
    if src["type"] == "dielectric":
        return np.full(3, fresnel_dielectric(cos_i, src["ior"]))
    if src["type"] == "conductor":
        return np.asarray(fresnel_conductor(cos_i, src["eta"], src["k"]), float)
    return np.asarray(fresnel_schlick(cos_i, src["f0"]), float)


def _eval(model, p, wi, wo):
    """f for a plot: a model's ``eval_mean`` where it has one (a stochastic eval averaged), else eval."""
    fn = getattr(model.module, "eval_mean", None)
    return model.eval(p, wi, wo) if fn is None else fn(p, np.ascontiguousarray(wi), np.ascontiguousarray(wo))


def polar_lobe(p, theta_i: float = 45.0, phi: float = 0.0, n: int = 721) -> dict:
    """The lobe in the plane of incidence (see the module docstring for the angles).

    Returns theta_o (degrees, sorted: a uniform grid of n points over [-90, 90] plus a dense one
    within 4 degrees of the mirror direction, so sharp peaks are resolved), wi (3,), wo (m, 3),
    f (m, 3), fcos (m, 3) = f cos(theta_o), and delta: a list of {theta_o, reflectance (3,)} for
    the delta lobes of a mirror or smooth dielectric (whose f is 0 as a function)."""
    p = as_params(p)
    theta_i, phi = _check_theta_i(theta_i), _check_phi(phi)
    model = _model(p)
    grid = np.linspace(-90.0, 90.0, int(n))
    dense = theta_i + np.linspace(-4.0, 4.0, 161)
    theta_o = np.unique(np.concatenate([grid, dense[(dense > -90.0) & (dense < 90.0)]]))
    wi = direction(theta_i, phi)
    wo = plane_directions(theta_o, phi)
    f = np.asarray(_eval(model, p, np.broadcast_to(wi, wo.shape), wo), dtype=np.float64)
    cos_o = np.maximum(np.cos(np.radians(theta_o)), 0.0)
    fcos = f * cos_o[:, None]
    delta = []
    if model.spec.delta and not np.any(f > 0):
        delta.append({"theta_o": theta_i, "reflectance": _delta_reflectance(p, math.cos(math.radians(theta_i)))})
    return {"theta_o": theta_o, "wi": wi, "wo": wo, "f": f, "fcos": fcos, "delta": delta,
            "theta_i": theta_i, "phi": phi}


def lobe_3d(p, theta_i: float = 45.0, phi_i: float = 0.0, n_theta: int = 46, n_phi: int = 97,
            channel: str = "lum") -> dict:
    """f(wi, wo) cos(theta_o) over the hemisphere of wo on an (n_theta, n_phi) grid
    (theta_o 0..90, phi_o 0..360 with the first column repeated last, so the surface closes).

    Returns theta, phi (degrees), wi, f and fcos (n_theta, n_phi, 3), value (n_theta, n_phi) =
    the chosen channel of fcos ('rgb' = luminance) and the surface x, y, z = value * wo."""
    p = as_params(p)
    theta_i, phi_i = _check_theta_i(theta_i), _check_phi(phi_i)
    check_channel(channel)
    model = _model(p)
    theta = np.linspace(0.0, 90.0, int(n_theta))
    phi = np.linspace(0.0, 360.0, int(n_phi))
    T, P = np.meshgrid(theta, phi, indexing="ij")
    wo = direction(T, P)
    wi = direction(theta_i, phi_i)
    flat = wo.reshape(-1, 3)
    f = np.asarray(_eval(model, p, np.broadcast_to(wi, flat.shape), flat), dtype=np.float64).reshape(T.shape + (3,))
    fcos = f * np.maximum(wo[..., 2], 0.0)[..., None]
    value = reduce_channel(fcos, channel)
    x, y, z = (value * wo[..., i] for i in range(3))
    delta = []
    if model.spec.delta and not np.any(f > 0):
        delta.append({"wo": reflect_z(wi),
                      "reflectance": _delta_reflectance(p, float(wi[2]))})
    return {"theta": theta, "phi": phi, "wi": wi, "wo": wo, "f": f, "fcos": fcos, "value": value,
            "x": x, "y": y, "z": z, "delta": delta, "theta_i": theta_i, "phi_i": phi_i, "channel": channel}


def albedo_curve(p, n: int = 46, n_side: int = 24, theta_max: float = 89.5) -> dict:
    """Directional albedo rho(theta) = integral of f cos over the hemisphere (the furnace test:
    a white environment of radiance 1 seen at angle theta reflects rho), from
    ``viewer.brdf.albedo.directional_albedo`` (the model's own sampler on a fixed stratified
    pattern: deterministic). theta is the angle of wo; for a reciprocal model it is also the
    albedo of light incident at theta. Returns theta (degrees), albedo, reflected and
    transmitted (each (n, 3))."""
    from viewer.brdf.albedo import directional_albedo

    p = as_params(p)
    theta = np.linspace(0.0, float(theta_max), int(n))
    refl, trans = directional_albedo(_model(p), p, np.cos(np.radians(theta)), n_side=int(n_side), split=True)
    return {"theta": theta, "albedo": refl + trans, "reflected": refl, "transmitted": trans,
            "transmissive": bool(_model(p).spec.transmissive)}


def _pseudo_brewster(eta, k) -> np.ndarray:
    """Angle (degrees) of minimal R_p of a conductor, per channel (0.01 degree grid)."""
    from viewer.brdf.fresnel import fresnel_conductor_polarized

    t = np.linspace(0.0, 90.0, 9001)
    _, rp = fresnel_conductor_polarized(np.cos(np.radians(t))[:, None], eta[None, :], k[None, :])
    return t[np.argmin(rp, axis=0)]


def _thin_film_curve(p, src, cos, inside):
    """(n, 3) RGB reflectance of the material's thin film (viewer/brdf/thin_film.py) against the
    angle, or None when it has none."""
    from viewer.brdf import thin_film

    if "thin_film" not in p or not thin_film.active(p) or src["type"] == "schlick":
        return None
    if src["type"] == "conductor":
        return thin_film.reflectance_rgb(p, cos, src["eta"], src["k"])
    ior = src["ior"]
    return thin_film.dielectric_reflectance_rgb(p, cos, 1.0 / ior if inside else ior)


def fresnel_curves(p, inside: bool = False, n: int = 181) -> dict:
    """R_s, R_p and R = (R_s + R_p) / 2 vs the angle of incidence theta (0..90 degrees, n points),
    each (n, 3), from ``viewer.brdf.fresnel``.

    Dielectric (n = ior): light from air (eta = n2/n1 = ior) or, with ``inside``, from inside
    the denser medium (eta = 1/ior): total internal reflection beyond the critical angle
    asin(n2/n1). Brewster's angle atan(n2/n1) has R_p = 0. Conductor (n + i k, from air): the
    pseudo-Brewster angle (minimal R_p). Schlick (f0): the Schlick curve plus the exact curves of
    the dielectric with the same f0, n = (1 + sqrt f0) / (1 - sqrt f0).
    Returns theta, Rs, Rp, R, (schlick), type, eta (3,) (relative index n2/n1), k (3,),
    brewster (3,), critical (3,) (NaN where none), brewster_label, field, inside."""
    from viewer.brdf.fresnel import (fresnel_conductor, fresnel_conductor_polarized, fresnel_dielectric,
                                     fresnel_dielectric_polarized, fresnel_schlick)

    p = as_params(p)
    check_kind(p, "fresnel")
    src = fresnel_source(p)
    theta = np.linspace(0.0, 90.0, int(n))
    if inside and src["type"] == "dielectric" and src["ior"] > 1.0:
        # R rises steeply just below the critical angle: sample it densely there
        crit = math.degrees(math.asin(1.0 / src["ior"]))
        theta = np.unique(np.concatenate([theta, crit - np.geomspace(1e-4, 2.0, 60), [crit]]))
    cos = np.cos(np.radians(theta))[:, None]
    out = {"theta": theta, "type": src["type"], "field": src["field"], "inside": bool(inside)}
    film = _thin_film_curve(p, src, cos[:, 0], inside)
    if film is not None:
        out["thin_film"] = film
    if src["type"] == "conductor":
        if inside:
            raise ViewerError(f"--inside: model {p.model!r} has a conductor Fresnel term (eta + i k, seen "
                              "from air); allowed: a dielectric interface (ior)")
        eta, k = src["eta"], src["k"]
        Rs, Rp = fresnel_conductor_polarized(cos, eta[None, :], k[None, :])
        out.update(Rs=Rs, Rp=Rp, R=fresnel_conductor(cos, eta[None, :], k[None, :]), eta=eta, k=k,
                   brewster=_pseudo_brewster(eta, k), critical=np.full(3, np.nan),
                   brewster_label="pseudo-Brewster")
        return out
    if src["type"] == "schlick":
        if inside:
            raise ViewerError(f"--inside: model {p.model!r} has a Schlick Fresnel term (f0, seen from "
                              "air); allowed: a dielectric interface (ior)")
        f0 = np.clip(src["f0"], 0.0, 0.999999)
        eta = (1.0 + np.sqrt(f0)) / (1.0 - np.sqrt(f0))
        out["schlick"] = fresnel_schlick(cos, src["f0"][None, :])
    else:
        eta = np.full(3, src["ior"])
        if inside:
            eta = 1.0 / eta
    Rs, Rp = fresnel_dielectric_polarized(cos, eta[None, :])
    critical = np.where(eta < 1.0, np.degrees(np.arcsin(np.minimum(eta, 1.0))), np.nan)
    out.update(Rs=Rs, Rp=Rp, R=fresnel_dielectric(cos, eta[None, :]), eta=eta, k=np.zeros(3),
               brewster=np.degrees(np.arctan(eta)), critical=critical, brewster_label="Brewster")
    return out


def bouguer_curve(p, d_max: float | None = None, n: int = 201) -> dict:
    """Bouguer's law T(d) = exp(-sigma_a d) per channel over d in [0, d_max] (n points).
    d_max defaults to 3 / (the smallest positive sigma_a), where every absorbing channel is
    below e^-3 = 5 %, and covers twice a layer's thickness. Returns d, T (n, 3), sigma_a,
    unit (of d), thickness (layered) or None."""
    p = as_params(p)
    check_kind(p, "bouguer")
    src = absorption_source(p)
    sigma = src["sigma_a"]
    if d_max is None:
        pos = sigma[sigma > 0]
        d_max = 3.0 / pos.min() if pos.size else 1.0
        if src["thickness"]:
            d_max = max(d_max, 2.0 * src["thickness"])
    d_max = float(d_max)
    if not (math.isfinite(d_max) and d_max > 0):
        raise ViewerError(f"d_max: {d_max:g} is out of range; allowed: a positive distance")
    d = np.linspace(0.0, d_max, int(n))
    return {"d": d, "T": np.exp(-sigma[None, :] * d[:, None]), "sigma_a": sigma, "unit": src["unit"],
            "thickness": src["thickness"], "field": src["field"]}


# ----------------------------------------------------------------------------- figures

@dataclass
class Curve:
    label: str
    x: np.ndarray
    y: np.ndarray
    color: tuple = _NEUTRAL
    style: str = "solid"  # solid | dashed | dotted
    extra: dict = field(default_factory=dict)  # more arrays at the same x (e.g. f without cos)


SAMPLING_ROWS, SAMPLING_COLS = 25, 50     # the chi-square test's cells (cos theta rows, phi columns)


def sampling_histogram(p, theta_i: float = 45.0, phi: float = 0.0, samples: int = 200_000, seed: int = 0,
                       points: int = 1500, rows: int = SAMPLING_ROWS, cols: int = SAMPLING_COLS) -> dict:
    """The sampler of ``p`` at the fixed direction ``wo`` = (theta_i, phi) against its pdf, with
    the test suite's chi-square functions (``viewer.brdf.chi2``) and the same cells: rows of
    cos theta (top row cos = 1; on the sphere for transmissive models, 2 rows + 1 from cos = 1
    down to -1) by columns of phi in [0, 360). Returns observed counts, expected counts (samples
    x the integrated pdf), their difference in standard deviations (o - e) / sqrt(max(e, 1)),
    the chi-square statistic, degrees of freedom and p-value, failed samples (pdf = 0), and
    ``points`` sampled directions (a second stream) for the point cloud. The histogram and pdf
    are what ``chi2_test(model, p, wo, samples, default_rng(seed), ...)`` computes."""
    from viewer import brdf
    from viewer.brdf.chi2 import chi2_from_counts, histogram, integrate_pdf

    p = as_params(p)
    theta_i, phi = _check_theta_i(theta_i), _check_phi(phi)
    samples, points = int(samples), int(points)
    if not 1000 <= samples <= 50_000_000:
        raise ViewerError(f"--samples: {samples} is out of range; allowed: 1000 to 50000000")
    model = brdf.get(p.model)
    sphere = bool(model.spec.transmissive)
    wo = direction(theta_i, phi)
    rng = np.random.default_rng(seed)
    r = 2 * rows + 1 if sphere else rows
    observed, failed, problems = histogram(model, p, wo, samples, rng, r, cols, sphere)
    expected = samples * integrate_pdf(model, p, wo, r, cols, sphere, n_samples=samples)
    res = chi2_from_counts(observed, failed, problems, expected, samples, alpha=0.0)
    o = observed.astype(np.float64)
    wi, _, pdf = model.sample(p, np.broadcast_to(wo, (points, 3)), np.random.default_rng([seed, 1]).random((points, 2)))
    cloud = wi[pdf > 0]
    # row 0 of the chi-square cells is cos theta = c0 (bottom): flip so row 0 = the pole
    return {"wo": wo, "theta_i": theta_i, "phi": phi, "sphere": sphere, "samples": samples, "seed": int(seed),
            "rows": r, "cols": cols, "observed": o[::-1], "expected": expected[::-1],
            "difference": ((o - expected) / np.sqrt(np.maximum(expected, 1.0)))[::-1],
            "chi2": res.stat, "dof": res.dof, "p_value": res.p_value, "failed": int(failed),
            "message": res.message, "points": cloud}


@dataclass
class Mark:
    """A labelled vertical line at x (Brewster, critical angle, thickness...)."""
    label: str
    x: float
    color: tuple = (90, 90, 90)


@dataclass
class Figure:
    kind: str
    model: str
    params: object
    title: str
    x_label: str
    y_label: str
    curves: list
    marks: list = field(default_factory=list)
    x_range: tuple = (0.0, 1.0)
    y_range: tuple = (0.0, 1.0)
    subtitle: str = ""
    notes: list = field(default_factory=list)
    info: dict = field(default_factory=dict)  # kind-specific values (theta_i, surface, delta...)


def _channel_groups(same) -> list[list[int]]:
    """The channels 0..2 grouped so that ``same(first of the group, c)`` holds for each member."""
    groups = []
    for c in range(3):
        for g in groups:
            if same(g[0], c):
                g.append(c)
                break
        else:
            groups.append([c])
    return groups


def _rgb_curves(x, rgb, label, channel, style="solid", color=None, extra=None) -> list:
    """Curves of one RGB quantity: one per channel for 'rgb' (one only when the channels are
    equal), or the chosen channel / luminance."""
    rgb = np.asarray(rgb, dtype=np.float64)
    extra = extra or {}
    if channel == "rgb":
        if np.allclose(rgb, rgb[:, :1], rtol=0, atol=1e-12):
            return [Curve(label, x, rgb[:, 0], color or _NEUTRAL, style, {k: v[:, 0] for k, v in extra.items()})]
        # channels with identical values share one curve ("green, blue")
        groups = _channel_groups(lambda a, c: np.allclose(rgb[:, a], rgb[:, c], rtol=0, atol=1e-12))
        return [Curve(f"{label} ({', '.join(_CHANNEL_NAMES[c] for c in g)})", x, rgb[:, g[0]],
                      _CHANNEL_COLOURS[g[0]], style, {k: v[:, g[0]] for k, v in extra.items()}) for g in groups]
    col = color or (_NEUTRAL if channel == "lum" else _CHANNEL_COLOURS["rgb".index(channel)])
    name = "luminance" if channel == "lum" else _CHANNEL_NAMES["rgb".index(channel)]
    return [Curve(f"{label} ({name})", x, reduce_channel(rgb, channel), col, style,
                  {k: reduce_channel(v, channel) for k, v in extra.items()})]


def _fmt_value(v) -> str:
    if isinstance(v, np.ndarray):
        if np.allclose(v, v[0]):
            return f"{v[0]:.3g}"
        return "[" + ", ".join(f"{x:.3g}" for x in v) + "]"
    if isinstance(v, float):
        return f"{v:.3g}"
    if isinstance(v, dict):
        return "{" + ", ".join(f"{k}={_fmt_value(x)}" for k, x in v.items()) + "}"
    if isinstance(v, list):
        return f"{len(v)} lobe" + ("" if len(v) == 1 else "s")
    return str(v)


def params_summary(p, limit: int = 110) -> str:
    parts = []
    for k, v in p.items():
        if hasattr(v, "model") and v.model:
            parts.append(f"{k}={v.model}")
        else:
            parts.append(f"{k}={_fmt_value(v)}")
    s = ", ".join(parts)
    return s if len(s) <= limit else s[: limit - 3] + "..."


def _nice_ceil(v: float) -> float:
    if not (v > 0 and math.isfinite(v)):
        return 1.0
    e = 10 ** math.floor(math.log10(v))
    for m in (1.0, 1.2, 1.5, 2.0, 2.5, 3.0, 4.0, 5.0, 6.0, 8.0, 10.0):
        if m * e >= v * (1 - 1e-9):
            return m * e
    return 10 * e


def figure(p, kind: str, *, theta_i: float = 45.0, phi: float = 0.0, channel: str = "rgb",
           inside: bool = False, log: bool = False, name: str | None = None, samples: int = 200_000,
           seed: int = 0, overlay=None) -> Figure:
    """The figure of one plot kind for one material (what ``brdf-viewer plot`` draws);
    ``samples`` and ``seed`` are the sampling plot's. ``overlay``: a second material drawn dashed
    over the polar and albedo plots (e.g. an analytic model over a measured one) and, for the
    slice, the residual image."""
    p = as_params(p)
    overlay = None if overlay is None else as_params(overlay)
    check_kind(p, kind)
    check_channel(channel)
    label = name or p.model
    sub = f"{p.model}: {params_summary(p)}"
    transform = (lambda y: np.log10(1.0 + np.asarray(y))) if log else (lambda y: np.asarray(y))
    ylog = "log10(1 + {})" if log else "{}"
    if kind == "polar":
        d = polar_lobe(p, theta_i, phi)
        curves = _rgb_curves(d["theta_o"], transform(d["fcos"]), "f cos", channel, extra={"f": d["f"]})
        if overlay is not None:
            d2 = polar_lobe(overlay, theta_i, phi)
            curves += _rgb_curves(d2["theta_o"], transform(d2["fcos"]), f"{overlay.model} f cos", channel, "dashed",
                                  extra={"f": d2["f"]})
        vmax = max([float(np.max(c.y)) for c in curves] + [float(np.max(transform(x["reflectance"])))
                                                         for x in d["delta"]] + [0.0])
        plane = "x-z (tangent)" if phi % 180 == 0 else ("y-z (bitangent)" if phi % 180 == 90 else f"phi = {phi:g} deg")
        notes = [f"wi at theta_i = {theta_i:g} deg; theta_o > 0: mirror side"]
        for x in d["delta"]:
            notes.append("delta lobe (mirror direction): R = " + _fmt_value(x["reflectance"]))
        return Figure("polar", p.model, p, f"{label}: lobe in the plane of incidence ({plane})",
                      "theta_o (deg)", ylog.format("f cos(theta_o) [1/sr]"), curves, [],
                      (-90.0, 90.0), (0.0, _nice_ceil(vmax * 1.05)), sub, notes,
                      {"theta_i": theta_i, "phi": phi, "delta": d["delta"], "channel": channel,
                       "transform": "log10(1+y)" if log else "", "wi": d["wi"]})
    if kind == "lobe":
        ch = "lum" if channel == "rgb" else channel
        d = lobe_3d(p, theta_i, phi, channel=ch)
        value = transform(d["value"])
        x, y, z = (value * d["wo"][..., i] for i in range(3))
        chn = "luminance" if ch == "lum" else _CHANNEL_NAMES["rgb".index(ch)]
        notes = [f"wi at theta_i = {theta_i:g} deg, phi_i = {phi:g} deg; radius = f cos ({chn})"]
        for dl in d["delta"]:
            notes.append("delta lobe (mirror direction): R = " + _fmt_value(dl["reflectance"]))
        vmax = max([float(np.max(value)) if value.size else 0.0]
                   + [float(np.max(transform(dl["reflectance"]))) for dl in d["delta"]])
        return Figure("lobe", p.model, p, f"{label}: 3D lobe f cos(theta_o)", "x (tangent)", "z (normal)",
                      [], [], (-1, 1), (0.0, _nice_ceil(vmax * 1.05) if vmax > 0 else 1.0), sub, notes,
                      {"theta_i": theta_i, "phi": phi, "channel": ch, "theta": d["theta"], "phi_grid": d["phi"],
                       "x": x, "y": y, "z": z, "value": value, "wi": d["wi"], "delta": d["delta"],
                       "transform": "log10(1+y)" if log else ""})
    if kind == "albedo":
        d = albedo_curve(p)
        curves = _rgb_curves(d["theta"], d["albedo"], "albedo", channel)
        from viewer import ms_compare

        if ms_compare.applies(p):  # single scattering, the raster's compensation, the random walk
            from viewer.brdf.microfacet import walks

            ms = ms_compare.albedos(p, np.cos(np.radians(d["theta"])), known={
                "walk" if walks(p) else "single": d["albedo"]})
            curves = _rgb_curves(d["theta"], ms["single"], "single scattering", channel, "dotted")
            curves += _rgb_curves(d["theta"], ms["compensated"], "compensated (raster)", channel, "dashed")
            curves += _rgb_curves(d["theta"], ms["walk"], "random walk (reference)", channel)
        if overlay is not None:
            d2 = albedo_curve(overlay)
            curves += _rgb_curves(d2["theta"], d2["albedo"], f"{overlay.model} albedo", channel, "dashed")
        if d["transmissive"]:
            curves += _rgb_curves(d["theta"], d["reflected"], "reflected", channel, "dashed")
            curves += _rgb_curves(d["theta"], d["transmitted"], "transmitted", channel, "dotted")
        vmax = max(float(np.max(c.y)) for c in curves)
        return Figure("albedo", p.model, p, f"{label}: directional albedo (furnace test)",
                      "theta (deg) of wo", "albedo rho(theta)", curves, [], (0.0, 90.0),
                      (0.0, 1.05 if vmax <= 1.03 else _nice_ceil(vmax * 1.02)), sub,
                      ["white furnace: radiance 1 from every direction reflects rho"], {"channel": channel})
    if kind == "fresnel":
        d = fresnel_curves(p, inside=inside)
        single = np.allclose(d["eta"], d["eta"][0]) and np.allclose(d["k"], d["k"][0])
        ch = channel
        if channel == "lum":
            ch = "rgb" if single else "g"  # R of a luminance is no Fresnel curve: use green
        curves = []
        cols = {"R_s": (31, 119, 180), "R_p": (255, 127, 14), "R": _NEUTRAL, "Schlick": (148, 103, 189)}
        styles = {"R_s": "dashed", "R_p": "dotted", "R": "solid", "Schlick": "solid"}
        series = [("R_s", d["Rs"]), ("R_p", d["Rp"]), ("R", d["R"])]
        if "schlick" in d:
            series.append(("Schlick", d["schlick"]))
        for lab, arr in series:
            if ch == "rgb" and not single:
                curves += _rgb_curves(d["theta"], arr, lab, "rgb", styles[lab])
            else:
                c = ch if ch != "rgb" else "r"
                idx = "rgb".index(c)
                suffix = "" if single else f" ({_CHANNEL_NAMES[idx]})"
                curves.append(Curve(lab + suffix, d["theta"], arr[:, idx], cols[lab], styles[lab]))
        if "thin_film" in d:  # the film's interference reflectance, one curve per channel
            curves += _rgb_curves(d["theta"], d["thin_film"], "thin film R", "rgb" if ch in ("rgb", "lum") else ch)
        marks = []
        if ch == "rgb" and not single:
            # channels with the same index share their marks
            groups = _channel_groups(lambda a, c: d["eta"][a] == d["eta"][c] and d["k"][a] == d["k"][c])
        else:
            groups = [["rgb".index(ch if ch != "rgb" else "r")]]
        for g in groups:
            c = g[0]
            many = len(groups) > 1
            colour = _CHANNEL_COLOURS[c] if many else (60, 60, 60)
            suffix = f" ({', '.join(_CHANNEL_NAMES[i] for i in g)})" if many else ""
            marks.append(Mark(f"{d['brewster_label']} {d['brewster'][c]:.1f}°{suffix}", float(d["brewster"][c]), colour))
            if np.isfinite(d["critical"][c]):
                marks.append(Mark(f"critical {d['critical'][c]:.1f}°{suffix}", float(d["critical"][c]),
                                  colour if many else (200, 30, 30)))
        if d["type"] == "conductor":
            medium = ("conductor n + ik = " + ", ".join(f"{e:.3g}+{kk:.3g}i" for e, kk in zip(d["eta"], d["k"]))
                      + "; pseudo-Brewster = angle of minimal R_p")
        elif d["type"] == "schlick":
            medium = f"Schlick f0 = {_fmt_value(p[d['field']] if d['field'] in p else d['eta'])}; exact " \
                     f"curves of the dielectric with that f0, n = {_fmt_value(d['eta'])}"
        else:
            n = 1.0 / d["eta"][0] if inside else d["eta"][0]
            medium = (f"from inside n = {n:.4g} to air (n2/n1 = {d['eta'][0]:.4g})" if inside
                      else f"from air to n = {n:.4g}")
        if "thin_film" in d:
            medium += (f"; thin film n = {p.thin_film.ior:.4g}, {p.thin_film.thickness_nm:g} nm "
                       "(Airy summation, RGB from 32 wavelengths); R_s, R_p, R: without the film")
        return Figure("fresnel", p.model, p, f"{label}: Fresnel reflectance ({d['field']})",
                      "angle of incidence (deg)", "reflectance", curves, marks, (0.0, 90.0), (0.0, 1.04), sub,
                      [medium], {"channel": ch, "inside": bool(inside), "type": d["type"],
                                 "brewster": d["brewster"], "critical": d["critical"], "eta": d["eta"], "k": d["k"]})
    if kind == "slice":
        from viewer.measured_plot import slice_figure

        return slice_figure(p, label, sub, overlay)
    if kind == "spectral":
        from viewer.spectral_plot import spectral_figure

        return spectral_figure(p, label, sub)
    if kind == "bouguer":
        d = bouguer_curve(p)
        curves = _rgb_curves(d["d"], d["T"], "T", channel)
        marks = []
        if d["thickness"]:
            marks.append(Mark(f"layer thickness {d['thickness']:g} {d['unit']}", d["thickness"]))
        unit = d["unit"]
        return Figure("bouguer", p.model, p, f"{label}: Bouguer's law T(d) = exp(-sigma_a d)",
                      f"distance d ({unit})", "transmittance T", curves, marks, (0.0, float(d["d"][-1])),
                      (0.0, 1.0), sub, [f"sigma_a = {_fmt_value(d['sigma_a'])} 1/{unit} ({d['field']})"],
                      {"channel": channel, "sigma_a": d["sigma_a"], "unit": unit})
    if kind == "sampling":
        d = sampling_histogram(p, theta_i, phi, samples=samples, seed=seed)
        span = "cos theta from 1 (top) to -1" if d["sphere"] else "cos theta from 1 (top) to 0"
        notes = [f"wo at theta = {theta_i:g} deg, phi = {phi:g} deg; {d['samples']} samples (seed {seed}); cells: "
                 f"{d['rows']} rows ({span}) x {d['cols']} columns of phi",
                 f"chi-square {d['chi2']:.1f}, {d['dof']} dof: p = {d['p_value']:.3g}; failed samples {d['failed']}"]
        return Figure("sampling", p.model, p, f"{label}: importance sampling against the pdf",
                      "phi (deg)", span, [], [], (0.0, 360.0), (0.0, 1.0), sub, notes, d)
    raise AssertionError(kind)


def _plain(v):
    """JSON-friendly copy: arrays and numpy scalars as Python values, NaN and inf as None."""
    if isinstance(v, np.ndarray):
        return _plain(v.tolist())
    if isinstance(v, (np.floating, np.integer)):
        return _plain(v.item())
    if isinstance(v, dict):
        return {k: _plain(x) for k, x in v.items()}
    if isinstance(v, (list, tuple)):
        return [_plain(x) for x in v]
    if isinstance(v, float) and not math.isfinite(v):
        return None
    return v


def figure_json(fig: Figure) -> dict:
    """The plotted numbers: every curve's x and y (and extras), the marks, the parameters.
    NaN (e.g. no critical angle) is written as null."""
    return _plain({
        "kind": fig.kind, "model": fig.model, "params": fig.params.to_plain(), "title": fig.title,
        "x_label": fig.x_label, "y_label": fig.y_label, "x_range": list(fig.x_range), "y_range": list(fig.y_range),
        "curves": [dict({"label": c.label, "x": c.x, "y": c.y, "color": list(c.color), "style": c.style}, **c.extra)
                   for c in fig.curves],
        "marks": [{"label": m.label, "x": m.x} for m in fig.marks],
        "notes": fig.notes, "info": fig.info,
    })


# ----------------------------------------------------------------------------- drawing (Pillow)

@functools.lru_cache(maxsize=32)
def _font(size: int):
    from PIL import ImageFont

    for name in ("DejaVuSans.ttf", "/usr/share/fonts/truetype/dejavu/DejaVuSans.ttf"):
        try:
            return ImageFont.truetype(name, size), True
        except OSError:
            pass
    return ImageFont.load_default(size=size), False  # Aileron: no Greek letters


_GREEK = {"theta": "θ", "sigma": "σ", "rho": "ρ", "phi": "φ", "delta": "δ"}


def _pretty(text: str, unicode_ok: bool) -> str:
    if not unicode_ok:
        return text.replace("°", " deg")
    import re

    for word, g in _GREEK.items():
        text = re.sub(rf"\b{word}(_[a-z]+)?\b", lambda m, g=g: g + (m.group(1) or ""), text)
    return text


class _Canvas:
    """A supersampled RGB image with helpers; ``image()`` returns the box-filtered result."""

    def __init__(self, width, height, ss=3):
        from PIL import Image, ImageDraw

        self.ss = ss
        self.w, self.h = width * ss, height * ss
        self.im = Image.new("RGB", (self.w, self.h), (255, 255, 255))
        self.draw = ImageDraw.Draw(self.im)

    def s(self, v):
        return v * self.ss

    def font(self, px):
        return _font(int(round(px * self.ss)))

    def text(self, xy, text, px=13, fill=(30, 30, 30), anchor="la", unicode=True):
        font, ok = self.font(px)
        t = _pretty(text, ok) if unicode else text
        self.draw.text(xy, t, font=font, fill=fill, anchor=anchor)
        return self.draw.textbbox(xy, t, font=font, anchor=anchor)

    def text_size(self, text, px=13):
        font, ok = self.font(px)
        l, t, r, b = self.draw.textbbox((0, 0), _pretty(text, ok), font=font)
        return r - l, b - t

    def vtext(self, xy, text, px=13, fill=(30, 30, 30)):
        """Text rotated 90 degrees (reading upward), centred on xy."""
        from PIL import Image, ImageDraw

        font, ok = self.font(px)
        t = _pretty(text, ok)
        l, tp, r, b = self.draw.textbbox((0, 0), t, font=font)
        tmp = Image.new("L", (r - l + 4, b - tp + 4), 0)
        ImageDraw.Draw(tmp).text((2 - l, 2 - tp), t, font=font, fill=255)
        tmp = tmp.rotate(90, expand=True)
        x, y = int(xy[0] - tmp.width / 2), int(xy[1] - tmp.height / 2)
        self.im.paste(Image.new("RGB", tmp.size, fill), (x, y), tmp)

    def polyline(self, pts, color, width=2.0, style="solid", draw=None):
        draw = draw or self.draw
        pts = [tuple(map(float, q)) for q in pts]
        if len(pts) < 2:
            return
        w = max(1, int(round(width * self.ss)))
        if style == "solid":
            draw.line(pts, fill=color, width=w, joint="curve")
            return
        on, off = (9, 5) if style == "dashed" else (2.2, 3.5)
        on, off = on * self.ss * width / 2, off * self.ss * width / 2
        # walk along the polyline, emitting 'on' pieces
        seg, drawing, remaining = [pts[0]], True, on
        for a, b in zip(pts[:-1], pts[1:]):
            ax, ay = a
            bx, by = b
            length = math.hypot(bx - ax, by - ay)
            t = 0.0
            while length - t > remaining:
                t += remaining
                q = (ax + (bx - ax) * t / length, ay + (by - ay) * t / length)
                if drawing:
                    seg.append(q)
                    draw.line(seg, fill=color, width=w, joint="curve")
                seg = [q]
                drawing = not drawing
                remaining = off if not drawing else on
            remaining -= length - t
            if drawing:
                seg.append(b)
            else:
                seg = [b]
        if drawing and len(seg) > 1:
            draw.line(seg, fill=color, width=w, joint="curve")

    def image(self) -> np.ndarray:
        return np.asarray(self.im.reduce(self.ss), dtype=np.uint8).copy()


def _nice_ticks(lo, hi, target=6):
    span = hi - lo
    if not span > 0:
        return [lo]
    raw = span / target
    e = 10 ** math.floor(math.log10(raw))
    step = min((m * e for m in (1, 2, 2.5, 5, 10) if m * e >= raw), default=10 * e)
    if abs(span - 90) < 1e-9 and lo == 0:
        step = 10.0
    if abs(span - 180) < 1e-9:
        step = 30.0
    first = math.ceil(lo / step - 1e-9) * step
    ticks = []
    v = first
    while v <= hi + 1e-9 * span:
        ticks.append(0.0 if abs(v) < 1e-12 * span else v)
        v += step
    return ticks


def _tick_label(v, ticks):
    step = ticks[1] - ticks[0] if len(ticks) > 1 else 1.0
    digits = max(0, -int(math.floor(math.log10(step) + 1e-9))) if step < 1 else 0
    if step < 1 and abs(round(step * 10 ** digits) - step * 10 ** digits) > 1e-6:
        digits += 1
    return f"{v:.{digits}f}"


def _header(cv, fig, width):
    cv.text((cv.s(width / 2), cv.s(10)), fig.title, px=17, anchor="ma")
    if fig.subtitle:
        cv.text((cv.s(width / 2), cv.s(32)), fig.subtitle, px=11, fill=(90, 90, 90), anchor="ma", unicode=False)
    for i, note in enumerate(fig.notes):
        cv.text((cv.s(width / 2), cv.s(50 + 14 * i)), note, px=11, fill=(70, 70, 70), anchor="ma")


def _legend(cv, items, box, corner, px=12, draw=True):
    """items: [(label, color, style)]; box: the plot rect (x0, y0, x1, y1) in canvas pixels.
    Returns the legend's rect."""
    if not items:
        return None
    pad, line_len, gap = cv.s(6), cv.s(28), cv.s(4)
    sizes = [cv.text_size(lbl, px) for lbl, _, _ in items]
    row_h = max(cv.s(px + 4), max(h for _, h in sizes) + gap)
    w = line_len + cv.s(8) + max(tw for tw, _ in sizes) + 2 * pad
    h = row_h * len(items) + 2 * pad
    x0, y0, x1, y1 = box
    m = cv.s(8)
    lx = x0 + m if corner[1] == "l" else x1 - m - w
    ly = y0 + m if corner[0] == "t" else y1 - m - h
    if draw:
        cv.draw.rectangle([lx, ly, lx + w, ly + h], fill=(255, 255, 255), outline=(170, 170, 170), width=cv.s(1))
        for i, (lbl, col, style) in enumerate(items):
            cy = ly + pad + row_h * i + row_h / 2
            cv.polyline([(lx + pad, cy), (lx + pad + line_len, cy)], col, 2.0, style)
            cv.text((lx + pad + line_len + cv.s(8), cy), lbl, px=px, anchor="lm")
    return (lx, ly, lx + w, ly + h)


def _curve_pixels(fig, to_px, step):
    """Points along every curve in canvas pixels, at most ``step`` apart."""
    xs, ys = [], []
    for c in fig.curves:
        px, py = to_px(np.asarray(c.x, float), np.asarray(c.y, float))
        seg = np.hypot(np.diff(px), np.diff(py))
        k = np.maximum(1, np.ceil(seg / step)).astype(int)
        for a in range(int(k.max()) if k.size else 0):
            f = a / k
            use = a < k
            xs.append((px[:-1] + np.diff(px) * f)[use])
            ys.append((py[:-1] + np.diff(py) * f)[use])
        xs.append(px[-1:])
        ys.append(py[-1:])
    if not xs:
        return np.zeros(0), np.zeros(0)
    return np.concatenate(xs), np.concatenate(ys)


def _place_labels(cv, labels, box, px_pts, py_pts, obstacles):
    """Positions (x, y, w, h) for mark labels next to their vertical lines, where they cover the
    fewest curve points and no other label or the legend."""
    x0, y0, x1, y1 = box
    placed = []
    for lx, text in labels:
        tw, th = cv.text_size(text, 12)
        th += cv.s(4)
        best = None
        ys = np.arange(y0 + cv.s(6), y1 - th - cv.s(4), max(1.0, th / 3))
        for side in (1, -1):
            tx = lx + cv.s(5) if side > 0 else lx - cv.s(5) - tw
            if tx < x0 + cv.s(2) or tx + tw > x1 - cv.s(2):
                continue
            for ty in ys:
                r = (tx - cv.s(3), ty - cv.s(3), tx + tw + cv.s(3), ty + th + cv.s(3))
                hits = np.count_nonzero((px_pts >= r[0]) & (px_pts <= r[2]) & (py_pts >= r[1]) & (py_pts <= r[3]))
                over = sum(1 for o in obstacles + [p[4] for p in placed]
                           if o and not (r[2] < o[0] or r[0] > o[2] or r[3] < o[1] or r[1] > o[3]))
                score = hits + 1000 * over + (ty - y0) / (y1 - y0) * 0.5 + (0.25 if side < 0 else 0)
                if best is None or score < best[0]:
                    best = (score, tx, ty, tw, th, r)
        if best is None:
            best = (0, lx + cv.s(5), y0 + cv.s(6), tw, th, None)
        placed.append((best[1], best[2], best[3], best[4], best[5]))
    return placed


def _best_corner(fig, to_px, box):
    """The plot corner where the fewest curve points lie (for the legend)."""
    x0, y0, x1, y1 = box
    cw, ch = (x1 - x0) * 0.45, (y1 - y0) * 0.4
    counts = {}
    for corner in ("tr", "tl", "br", "bl"):
        cx0 = x0 if corner[1] == "l" else x1 - cw
        cy0 = y0 if corner[0] == "t" else y1 - ch
        n = 0
        for c in fig.curves:
            px, py = to_px(np.asarray(c.x), np.asarray(c.y))
            n += int(np.sum((px >= cx0) & (px <= cx0 + cw) & (py >= cy0) & (py <= cy0 + ch)))
        counts[corner] = n
    return min(counts, key=lambda k: (counts[k], ("tr", "tl", "br", "bl").index(k)))


def _clipped_layer(cv):
    """A transparent layer over the canvas; ``_paste_clipped`` puts it back inside a rect."""
    from PIL import Image, ImageDraw

    layer = Image.new("RGBA", cv.im.size, (0, 0, 0, 0))
    return layer, ImageDraw.Draw(layer)


def _paste_clipped(cv, layer, box):
    from PIL import Image, ImageChops

    mask = Image.new("L", cv.im.size, 0)
    mask.paste(255, tuple(int(round(v)) for v in box))
    alpha = ImageChops.multiply(layer.getchannel("A"), mask)
    cv.im.paste(layer.convert("RGB"), (0, 0), alpha)


def _draw_cartesian(cv, fig, width, height):
    left, right, top, bottom = 78, 24, 58 + 14 * len(fig.notes), 56
    x0, y0, x1, y1 = cv.s(left), cv.s(top), cv.s(width - right), cv.s(height - bottom)
    box = (x0, y0, x1, y1)
    (xa, xb), (ya, yb) = fig.x_range, fig.y_range

    def to_px(x, y):
        return x0 + (np.asarray(x) - xa) / (xb - xa) * (x1 - x0), y1 - (np.asarray(y) - ya) / (yb - ya) * (y1 - y0)

    d = cv.draw
    xt, yt = _nice_ticks(xa, xb, 9), _nice_ticks(ya, yb, 5)
    for v in xt:
        px, _ = to_px(v, ya)
        d.line([(px, y0), (px, y1)], fill=(232, 232, 232), width=cv.s(1))
        d.line([(px, y1), (px, y1 + cv.s(5))], fill=(60, 60, 60), width=cv.s(1))
        cv.text((px, y1 + cv.s(8)), _tick_label(v, xt), px=12, anchor="ma")
    for v in yt:
        _, py = to_px(xa, v)
        d.line([(x0, py), (x1, py)], fill=(232, 232, 232), width=cv.s(1))
        d.line([(x0 - cv.s(5), py), (x0, py)], fill=(60, 60, 60), width=cv.s(1))
        cv.text((x0 - cv.s(8), py), _tick_label(v, yt), px=12, anchor="rm")
    d.rectangle([x0, y0, x1, y1], outline=(60, 60, 60), width=cv.s(1))
    cv.text(((x0 + x1) / 2, y1 + cv.s(28)), fig.x_label, px=14, anchor="ma")
    cv.vtext((cv.s(16), (y0 + y1) / 2), fig.y_label, px=14)
    layer, ld = _clipped_layer(cv)
    # marks: dashed vertical lines, labels staggered from the top
    for i, m in enumerate(fig.marks):
        px, _ = to_px(m.x, ya)
        cv.polyline([(px, y0), (px, y1)], m.color + (255,), 1.5, "dashed", draw=ld)
    for c in fig.curves:
        px, py = to_px(c.x, c.y)
        cv.polyline(list(zip(px, py)), tuple(c.color) + (255,), 2.2, c.style, draw=ld)
    _paste_clipped(cv, layer, box)
    items = [(c.label, c.color, c.style) for c in fig.curves]
    legend = _legend(cv, items, box, _best_corner(fig, to_px, box)) if items else None
    pts = _curve_pixels(fig, to_px, cv.s(2))
    spots = _place_labels(cv, [(float(to_px(m.x, ya)[0]), m.label) for m in fig.marks], box, *pts, [legend])
    for m, (tx, ty, tw, th, _) in zip(fig.marks, spots):
        cv.draw.rectangle([tx - cv.s(2), ty - cv.s(2), tx + tw + cv.s(2), ty + th], fill=(255, 255, 255))
        cv.text((tx, ty), m.label, px=12, fill=m.color, anchor="lt")


def _shown(fig, v) -> float:
    """A value as the figure plots it (log10(1 + v) with --log)."""
    return float(np.log10(1.0 + v)) if fig.info.get("transform") else float(v)


def _arrow(cv, a, b, color, width=2.0, head=10):
    cv.draw.line([a, b], fill=color, width=max(1, int(cv.s(width))))
    ang = math.atan2(b[1] - a[1], b[0] - a[0])
    h = cv.s(head)
    pts = [b, (b[0] - h * math.cos(ang - 0.4), b[1] - h * math.sin(ang - 0.4)),
           (b[0] - h * math.cos(ang + 0.4), b[1] - h * math.sin(ang + 0.4))]
    cv.draw.polygon(pts, fill=color)


def _draw_polar(cv, fig, width, height):
    top = 58 + 14 * len(fig.notes)
    radius_px = min((width - 120) / 2, height - top - 70)
    cx, cy = cv.s(width / 2), cv.s(top + 24 + radius_px)
    R = cv.s(radius_px)
    rmax = fig.y_range[1]
    d = cv.draw
    # rings and spokes
    rt = [v for v in _nice_ticks(0.0, rmax, 4) if v > 0]
    for v in rt:
        rr = R * v / rmax
        d.arc([cx - rr, cy - rr, cx + rr, cy + rr], 180, 360, fill=(215, 215, 215), width=cv.s(1))
        cv.text((cx + rr + cv.s(2), cy + cv.s(4)), _tick_label(v, rt), px=11, fill=(110, 110, 110), anchor="ma")
    for a in range(-90, 91, 15):
        t = math.radians(a)
        ex, ey = cx + R * math.sin(t), cy - R * math.cos(t)
        d.line([(cx, cy), (ex, ey)], fill=(225, 225, 225), width=cv.s(1))
        lx, ly = cx + (R + cv.s(16)) * math.sin(t), cy - (R + cv.s(14)) * math.cos(t)
        cv.text((lx, ly), f"{a}°", px=11, fill=(90, 90, 90), anchor="mm")
    d.arc([cx - R, cy - R, cx + R, cy + R], 180, 360, fill=(120, 120, 120), width=cv.s(1))
    d.line([(cx - R - cv.s(20), cy), (cx + R + cv.s(20), cy)], fill=(60, 60, 60), width=cv.s(2))
    cv.text((cx - R + cv.s(4), cy + cv.s(4)), "surface", px=11, fill=(90, 90, 90), anchor="la")
    cv.text((cx, cy + cv.s(22)), f"radius: {fig.y_label}", px=12, fill=(50, 50, 50), anchor="ma")
    # incident and mirror directions
    ti = math.radians(fig.info["theta_i"])
    far = (cx - R * 1.0 * math.sin(ti), cy - R * 1.0 * math.cos(ti))
    _arrow(cv, far, (cx - cv.s(6) * math.sin(ti), cy - cv.s(6) * math.cos(ti)), (230, 120, 0), 2.0, 12)
    mid = (cx - 0.72 * R * math.sin(ti), cy - 0.72 * R * math.cos(ti))
    cv.text((mid[0] - cv.s(8) * math.cos(ti), mid[1] + cv.s(8) * math.sin(ti)),
            f"light (wi), theta_i = {fig.info['theta_i']:g}°", px=12, fill=(200, 100, 0),
            anchor="rt" if ti > math.radians(12) else "lm")
    mirror = (cx + R * math.sin(ti), cy - R * math.cos(ti))
    cv.polyline([(cx, cy), mirror], (150, 150, 150), 1.2, "dotted")
    if not fig.info.get("delta"):
        mm = (cx + 0.93 * R * math.sin(ti), cy - 0.93 * R * math.cos(ti))
        cv.text((mm[0] + cv.s(6) * math.cos(ti), mm[1] + cv.s(6) * math.sin(ti)), "mirror", px=11,
                fill=(120, 120, 120), anchor="lt")
    # lobe curves
    layer, ld = _clipped_layer(cv)
    lines = []
    for c in fig.curves:  # every fill first: a fill drawn later would overwrite the lines it covers
        t = np.radians(np.asarray(c.x))
        r = R * np.clip(np.asarray(c.y), 0, None) / rmax
        pts = list(zip(cx + r * np.sin(t), cy - r * np.cos(t)))
        ld.polygon(pts, fill=tuple(c.color) + (28,))
        lines.append((pts, c))
    for pts, c in lines:
        cv.polyline(pts, tuple(c.color) + (255,), 2.2, c.style, draw=ld)
    _paste_clipped(cv, layer, (0, 0, cv.w, cy + 1))
    for dl in fig.info.get("delta", []):
        refl = np.asarray(dl["reflectance"], float)
        rr = R * min(1.0, _shown(fig, np.max(refl)) / rmax)
        t = math.radians(dl["theta_o"])
        tip = (cx + rr * math.sin(t), cy - rr * math.cos(t))
        _arrow(cv, (cx, cy), tip, (120, 40, 160), 3.0, 14)
        mid = (cx + 0.55 * rr * math.sin(t), cy - 0.55 * rr * math.cos(t))
        cv.text((mid[0] + cv.s(10) * math.cos(t), mid[1] + cv.s(10) * math.sin(t)),
                "delta lobe, R = " + _fmt_value(refl), px=12, fill=(120, 40, 160), anchor="lt")
    items = [(c.label, c.color, c.style) for c in fig.curves]
    box = (cv.s(10), cv.s(top), cv.w - cv.s(10), cy)
    _legend(cv, items, box, "tr" if fig.info["theta_i"] > 20 else "tl")


_VIRIDIS = np.array([[68, 1, 84], [59, 82, 139], [33, 145, 140], [94, 201, 98], [253, 231, 37]], float)


def _colormap(t):
    t = np.clip(np.asarray(t, float), 0, 1) * (len(_VIRIDIS) - 1)
    i = np.minimum(np.floor(t).astype(int), len(_VIRIDIS) - 2)
    f = (t - i)[..., None]
    return _VIRIDIS[i] * (1 - f) + _VIRIDIS[i + 1] * f


def _draw_lobe(cv, fig, width, height, elevation=25.0, azimuth=-75.0):
    top = 58 + 14 * len(fig.notes)
    el, az = math.radians(elevation), math.radians(azimuth)
    view = np.array([math.cos(el) * math.cos(az), math.cos(el) * math.sin(az), math.sin(el)])  # toward viewer
    right = np.array([-math.sin(az), math.cos(az), 0.0])
    up = np.cross(view, right)
    x, y, z = (np.asarray(fig.info[k], float) for k in "xyz")
    value = np.asarray(fig.info["value"], float)
    rmax = fig.y_range[1]
    P = np.stack([x, y, z], axis=-1) / rmax  # unit-ish
    scale = cv.s(min((width - 200) / 2.4, (height - top - 40) / 1.6))
    cx, cy = cv.s((width - 90) / 2), cv.s(top + 20) + scale * 1.1

    def proj(q):
        q = np.asarray(q, float)
        return cx + scale * (q @ right), cy - scale * (q @ up)

    d = cv.draw
    # ground disc, axes
    ring = np.stack([np.cos(np.linspace(0, 2 * np.pi, 181)), np.sin(np.linspace(0, 2 * np.pi, 181)),
                     np.zeros(181)], -1)
    gx, gy = proj(ring)
    d.polygon(list(zip(gx, gy)), fill=(240, 240, 240), outline=(170, 170, 170))
    for lab, vec in (("x (tangent)", [1.15, 0, 0]), ("y", [0, 1.15, 0]), ("z (normal)", [0, 0, 1.15])):
        a, b = proj(np.zeros(3)), proj(np.array(vec, float))
        _arrow(cv, (a[0], a[1]), (b[0], b[1]), (110, 110, 110), 1.2, 8)
        cv.text((b[0] + cv.s(4), b[1]), lab, px=11, fill=(90, 90, 90), anchor="lm")
    # shaded quads, far to near (painter's algorithm)
    quads = np.stack([P[:-1, :-1], P[1:, :-1], P[1:, 1:], P[:-1, 1:]], axis=2)  # (nt-1, np-1, 4, 3)
    qv = (value[:-1, :-1] + value[1:, :-1] + value[1:, 1:] + value[:-1, 1:]) / 4
    qf = quads.reshape(-1, 4, 3)
    qv = qv.ravel()
    depth = qf.mean(axis=1) @ view
    n = np.cross(qf[:, 2] - qf[:, 0], qf[:, 3] - qf[:, 1])
    nn = np.linalg.norm(n, axis=-1)
    light = np.array([0.3, -0.5, 0.8]) / np.linalg.norm([0.3, -0.5, 0.8])
    shade = np.where(nn > 0, np.abs(n @ light) / np.maximum(nn, 1e-30), 0.6)
    vmax = float(value.max()) if value.size else 0.0
    colours = _colormap(qv / vmax if vmax > 0 else qv) * (0.55 + 0.45 * shade)[:, None]
    layer, ld = _clipped_layer(cv)
    for i in np.argsort(depth):
        if qv[i] <= 0 and vmax > 0 and np.allclose(qf[i], 0):
            continue
        px, py = proj(qf[i])
        col = tuple(int(c) for c in colours[i])
        ld.polygon(list(zip(px, py)), fill=col + (235,), outline=tuple(int(c * 0.75) for c in col) + (255,))
    _paste_clipped(cv, layer, (0, 0, cv.w, cv.h))
    # incident direction (toward the light) and delta lobes
    wi = np.asarray(fig.info["wi"], float)
    a, b = proj(wi * 1.08), proj(wi * 0.05)
    _arrow(cv, (a[0], a[1]), (b[0], b[1]), (230, 120, 0), 2.0, 12)
    cv.text((a[0], a[1] + cv.s(6)), f"light (wi), theta_i = {fig.info['theta_i']:g}°", px=12,
            fill=(200, 100, 0), anchor="ma")
    for dl in fig.info.get("delta", []):
        tip = proj(np.asarray(dl["wo"], float) * min(1.0, _shown(fig, np.max(dl["reflectance"])) / rmax))
        o = proj(np.zeros(3))
        _arrow(cv, (o[0], o[1]), (tip[0], tip[1]), (120, 40, 160), 3.0, 14)
        cv.text((tip[0] + cv.s(6), tip[1]), "delta lobe, R = " + _fmt_value(np.asarray(dl["reflectance"])), px=12,
                fill=(120, 40, 160), anchor="lm")
    # colour bar
    bx0, bx1 = cv.s(width - 70), cv.s(width - 52)
    by0, by1 = cv.s(top + 30), cv.s(height - 50)
    for j in range(int(by1 - by0)):
        t = 1 - j / max(1, by1 - by0 - 1)
        d.line([(bx0, by0 + j), (bx1, by0 + j)], fill=tuple(int(c) for c in _colormap(t)))
    d.rectangle([bx0, by0, bx1, by1], outline=(90, 90, 90), width=cv.s(1))
    for v in _nice_ticks(0.0, vmax if vmax > 0 else 1.0, 4):
        yy = by1 - (by1 - by0) * v / (vmax if vmax > 0 else 1.0)
        d.line([(bx1, yy), (bx1 + cv.s(4), yy)], fill=(60, 60, 60), width=cv.s(1))
        cv.text((bx1 + cv.s(6), yy), f"{v:.3g}", px=11, anchor="lm")
    cv.vtext((cv.s(width - 84), (by0 + by1) / 2), "f cos(theta_o)" + (" (log10(1+y))" if fig.info.get("transform") else ""),
             px=12)


def _draw_grid(cv, a, box, signed=False, vmax=None):
    """An (rows, cols) array as cells in ``box`` (canvas pixels): grey ramp from 0 to vmax, or
    red (positive) / blue (negative) up to +-vmax."""
    x0, y0, x1, y1 = box
    rows, cols = a.shape
    if vmax is None:
        vmax = float(np.abs(a).max()) or 1.0
    t = np.clip(a / vmax, -1.0, 1.0)
    if signed:
        rgb = np.stack([1 - np.clip(-t, 0, 1), 1 - np.abs(t), 1 - np.clip(t, 0, 1)], axis=-1)
    else:
        rgb = np.repeat((1.0 - t)[..., None], 3, axis=-1)
    from PIL import Image

    img = Image.fromarray((rgb * 255 + 0.5).astype(np.uint8)).resize((int(x1 - x0), int(y1 - y0)), Image.NEAREST)
    cv.im.paste(img, (int(x0), int(y0)))
    cv.draw.rectangle([x0, y0, x1, y1], outline=(90, 90, 90), width=cv.s(1))
    return vmax


def _draw_sampling(cv, fig, width, height):
    """Two by two: histogram | integrated pdf, difference | point cloud."""
    d = fig.info
    top = cv.s(62 + 14 * len(fig.notes))
    gap_x, gap_y = cv.s(36), cv.s(44)
    left = cv.s(40)
    gw = (cv.s(width) - left - cv.s(16) - gap_x) / 2
    gh = (cv.s(height) - top - cv.s(16) - gap_y - cv.s(30)) / 2
    vmax = max(float(np.max(d["observed"])), float(np.max(d["expected"])), 1e-12)
    panels = (("histogram of samples", d["observed"], False, vmax),
              ("integrated pdf x samples", d["expected"], False, vmax),
              ("difference (o - e) / sqrt(e)", d["difference"], True, max(3.0, float(np.abs(d["difference"]).max()))))
    for i, (title, a, signed, vm) in enumerate(panels):
        x0 = left + (i % 2) * (gw + gap_x)
        y0 = top + cv.s(16) + (i // 2) * (gh + gap_y)
        box = (x0, y0, x0 + gw, y0 + gh)
        _draw_grid(cv, np.asarray(a, float), box, signed, vm)
        cv.text((x0 + gw / 2, y0 - cv.s(15)), title, px=12, anchor="la" if False else "ma")
        scale = f"white 0 .. black {vm:.3g} samples" if not signed else f"blue -{vm:.3g} .. red +{vm:.3g} sigma"
        cv.text((x0 + gw / 2, box[3] + cv.s(4)), scale + "; phi 0 .. 360 deg across", px=10, fill=(80, 80, 80),
                anchor="ma")
        if i % 2 == 0:
            cv.vtext((x0 - cv.s(14), y0 + gh / 2), fig.y_label, px=10)
    # point cloud: the hemisphere (sphere) seen obliquely, as the 3D lobe
    x0 = left + gw + gap_x
    y0 = top + cv.s(16) + gh + gap_y
    el, az = math.radians(25.0), math.radians(-75.0)
    view = np.array([math.cos(el) * math.cos(az), math.cos(el) * math.sin(az), math.sin(el)])
    right = np.array([-math.sin(az), math.cos(az), 0.0])
    up = np.cross(view, right)
    scale = min(gw / 2.3, gh / (2.2 if d["sphere"] else 1.45))
    cx, cy = x0 + gw / 2, y0 + (gh / 2 if d["sphere"] else gh * 0.68)

    def proj(q):
        q = np.asarray(q, float)
        return cx + scale * (q @ right), cy - scale * (q @ up)

    ang = np.linspace(0, 2 * np.pi, 181)
    ring = np.stack([np.cos(ang), np.sin(ang), np.zeros_like(ang)], -1)
    gx, gy = proj(ring)
    cv.draw.polygon(list(zip(gx, gy)), fill=(242, 242, 242), outline=(170, 170, 170))
    pts = np.asarray(d["points"], float).reshape(-1, 3)
    depth = pts @ view
    px, py = proj(pts)
    r = cv.s(1.5)
    near = (depth - depth.min()) / max(float(np.ptp(depth)), 1e-12) if len(pts) else depth
    for j in np.argsort(depth):
        base = np.array((31, 119, 180) if pts[j, 2] >= 0 else (214, 39, 40), float)
        col = tuple(int(c) for c in base * (0.55 + 0.45 * near[j]) + 255 * 0.0)
        cv.draw.ellipse([px[j] - r, py[j] - r, px[j] + r, py[j] + r], fill=col)
    wo = np.asarray(d["wo"], float)
    a, b = proj(wo * 1.15), proj(np.zeros(3))
    _arrow(cv, (a[0], a[1]), (b[0], b[1]), (230, 120, 0), 2.0, 12)
    cv.text((a[0], a[1] - cv.s(4)), "wo", px=12, fill=(200, 100, 0), anchor="md")
    cv.text((x0 + gw / 2, y0 - cv.s(15)), f"{len(pts)} sampled directions wi"
            + (" (red: transmitted)" if d["sphere"] else ""), px=12, anchor="ma")


def render_figure(fig: Figure, width: int = 900, height: int = 600, ss: int = 3) -> np.ndarray:
    """The figure drawn with Pillow as (height, width, 3) uint8 sRGB, anti-aliased by drawing at
    ``ss`` x the size and box-filtering down."""
    if not (200 <= width <= 4000 and 150 <= height <= 4000):
        raise ViewerError(f"--width/--height: {width}x{height} is out of range; allowed: width 200..4000, "
                          "height 150..4000")
    cv = _Canvas(width, height, ss)
    _header(cv, fig, width)
    if fig.kind == "polar":
        _draw_polar(cv, fig, width, height)
    elif fig.kind == "lobe":
        _draw_lobe(cv, fig, width, height)
    elif fig.kind == "spectral":
        from viewer.spectral_plot import draw_spectral

        draw_spectral(cv, fig, width, height)
    elif fig.kind == "sampling":
        _draw_sampling(cv, fig, width, height)
    elif fig.kind == "slice":
        from viewer.measured_plot import draw_slice

        draw_slice(cv, fig, width, height)
    else:
        _draw_cartesian(cv, fig, width, height)
    return cv.image()


def write_plot(fig: Figure, out, data_path=None, width: int = 900, height: int = 600):
    """Write the PNG (atomically; the plotted numbers as JSON in its ``brdf-viewer:plot`` text
    chunk) and, optionally, the same JSON to ``data_path``."""
    from viewer.io import atomic_write_bytes, write_png

    img = render_figure(fig, width, height)
    data = figure_json(fig)
    write_png(out, img, {PNG_KEY: json.dumps(data, separators=(",", ":"))})
    if data_path is not None:
        atomic_write_bytes(data_path, (json.dumps(data, indent=1) + "\n").encode())
    return img


def read_plot_data(png_path) -> dict:
    """The plotted numbers stored in a plot PNG (``brdf-viewer:plot``)."""
    from viewer.io import read_png_text

    text = read_png_text(png_path)
    if PNG_KEY not in text:
        raise ViewerError(f"{png_path}: no {PNG_KEY} text chunk (not written by brdf-viewer plot)")
    return json.loads(text[PNG_KEY])


# shared with viewer.spectral_plot (public names for the drawing helpers it reuses)
CHANNEL_COLOURS = _CHANNEL_COLOURS
nice_ticks = _nice_ticks
tick_label = _tick_label
nice_ceil = _nice_ceil
colormap = _colormap
