"""Which plots apply to a material: its Fresnel, absorption and spectral sources, whether its
sampler has a density, and the checks of a plot kind and channel (one-line ``ViewerError``)."""

from __future__ import annotations

import math

import numpy as np

from viewer import ViewerError
from viewer.brdf import thin_film
from viewer.brdf.sampling import LUMINANCE_REC709, luminance

KINDS = ("polar", "lobe", "albedo", "fresnel", "bouguer", "spectral", "sampling", "slice", "theta_h", "theta_d",
         "theta_v", "terms")
CHANNELS = ("rgb", "lum", "r", "g", "b")
PNG_KEY = "brdf-viewer:plot"
LUMINANCE = LUMINANCE_REC709  # the weights of 'lum' (docs/conventions.md: linear Rec.709 RGB)


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


def model_of(p):
    from viewer import brdf

    return brdf.get(p.model)


def fresnel_source(p) -> dict | None:
    """How a material's Fresnel reflectance is given, or None when it has none:
    {"type": "dielectric", "ior": n, "field": ...} | {"type": "conductor", "eta": (3,), "k": (3,)}
    | {"type": "schlick", "f0": (3,)}; "field" names the parameter(s). The model's own
    ``fresnel_source`` hook says it (viewer.brdf.spec.HOOKS; by parameter names by default)."""
    return model_of(p).fresnel_source(p)


def absorption_source(p) -> dict | None:
    """The absorption coefficient of a material, or None: {"sigma_a": (3,), "unit": length unit,
    "thickness": layer thickness or None, "field": ...}."""
    coat = p.get("coating")
    if coat is not None and "sigma_a" in coat:   # a coating's absorption (the layered model)
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
        kinds.append("slice")  # the Rusinkiewicz slice (viewer/plots/measured.py)
        kinds += ["theta_h", "theta_d", "theta_v"]  # BRDF Explorer's slices (viewer/plots/theta.py)
    if has_terms(p):
        kinds.append("terms")
    return tuple(kinds)


def has_terms(p) -> bool:
    """The material's model decomposes into D, F, G: its ``terms`` hook (a ``.brdf`` file's: the
    file defines them) answers at one direction pair."""
    s, c = math.sin(math.radians(30.0)), math.cos(math.radians(30.0))
    return model_of(p).terms(p, np.array([[s, 0.0, c]]), np.array([[-s, 0.0, c]])) is not None


def spectral_name(p) -> str | None:
    """The spectral table a material names (its own, a layered coating's, or its base's)."""
    if p.get("spectral", "none") != "none":
        return p.spectral
    coat = p.get("coating")
    if coat is not None and coat.get("spectral", "none") != "none":
        return coat.spectral
    base = p.get("base")
    if base is not None and hasattr(base, "get") and base.get("spectral", "none") != "none":
        return base.spectral
    return None


def film_owner(p):
    """The parameter table holding the material's active thin film (the material or its layered
    coating), or None."""
    if isinstance(p, str) or not hasattr(p, "get"):
        return None
    for owner in (p, p.get("coating")):
        if owner is not None and hasattr(owner, "get") and thin_film.at_point(owner):
            if p.get("fresnel") in ("schlick", "none"):
                return None
            return owner
    return None


def spectral_source(p) -> str | None:
    """The spectral table (viewer.spectral) a material names, "thin film" for a material with an
    active thin film (its R(theta, lambda) is the film's), or None."""
    return "thin film" if film_owner(p) is not None else spectral_name(p)


def sampling_delta(p) -> str | None:
    """Why ``p``'s sampler has no density to histogram (a delta lobe: mirror, smooth glass, or
    a layered model over one), else None."""
    from viewer import brdf

    model = brdf.get(p.model)
    spec = model.spec
    if model.is_delta(p):
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
    if kind == "terms":
        raise ViewerError(f"terms plot: model {p.model!r} has no D, F, G decomposition; it applies to the "
                          f"microfacet model and to .brdf files defining float D, F and G(vec3 L, vec3 V, vec3 N, "
                          f"vec3 X, vec3 Y); the plots of {p.model!r}: {', '.join(applicable_kinds(p))}")
    if kind in ("sampling", "slice", "theta_h", "theta_d", "theta_v"):
        raise ViewerError(f"{kind} plot: {sampling_delta(p)}; the plots of {p.model!r}: "
                          f"{', '.join(applicable_kinds(p))}")
    what = {"fresnel": "no index of refraction (no Fresnel term)",
            "bouguer": "no absorption coefficient sigma_a",
            "spectral": "no spectral table (spectral = \"NAME\")"}[kind]
    if kind == "fresnel" and p.get("fresnel") == "none":
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
