"""The material editor's rules without a widget toolkit: which parameters the editor shows for a
material (``shown_params``), the presets and ``.brdf`` files its picker offers, and the perceptual
roughness slider's mapping (alpha = r^2). The window's editor (``viewer.app.ui``, imgui) and the
notebook's (``viewer.notebook``, ipywidgets) both draw from these, so the two show the same
controls with the same ranges."""

from __future__ import annotations

import math

import numpy as np

from viewer import brdf
from viewer.brdf.spec import Params

# Fresnel-dependent parameters: shown only under the Fresnel variant that uses them
FRESNEL_USES = {"ior": ("dielectric",), "eta": ("conductor",), "k": ("conductor",), "f0": ("schlick",)}
PRESET_NONE = "(preset...)"


def preset_names(nested: bool = False) -> list[str]:
    """The presets the picker offers (a nested material cannot be one that nests another)."""
    from viewer.brdf.presets import PRESETS

    return sorted(n for n in PRESETS if not (nested and brdf.get(PRESETS[n]["model"]).spec.nests_material))


FILE_PREFIX = "file: "


def library_files() -> list[str]:
    """The picker's file materials: ``file: NAME.brdf`` for each .brdf file of the library folders."""
    from pathlib import Path

    from viewer.app.file_actions import BRDF_LIBRARY

    folders = [Path(brdf.__file__).resolve().parent.parent / "brdfs"] + [Path(f) for f in BRDF_LIBRARY]
    out = []
    for folder in dict.fromkeys(folders):
        out.extend(FILE_PREFIX + str(f) for f in sorted(folder.glob("*.brdf")))
    return out


def preset_params(name: str) -> Params:
    """A preset's material as validated parameters, the same as ``preset = "name"`` in a scene;
    a picker entry ``file: PATH`` is that .brdf file's material (its declared defaults)."""
    from viewer.brdf.presets import get_preset
    from viewer.brdf.spec import validate_params

    if name.startswith(FILE_PREFIX):
        return brdf.load(name[len(FILE_PREFIX):]).params()
    raw = get_preset(name)
    model = raw.pop("model")
    return validate_params(brdf.get(model).spec, raw, f"preset {name}", brdf.lookup_spec)


def shown_params(params: Params) -> list[str]:
    """The parameter names the editor shows for ``params``: those that do something in the
    chosen variant (``ior`` only under a dielectric Fresnel, ``eta`` / ``k`` only under a
    conductor one and not when a measured spectral table replaces them, ``f0`` only under
    Schlick; ``alpha_y`` not for the isotropic Blinn-Phong distribution)."""
    spec = brdf.spec_of(params)
    names = [p.name for p in spec.params]
    fresnel = params["fresnel"] if "fresnel" in names else None
    out = []
    for n in names:
        if fresnel is not None and n in FRESNEL_USES and fresnel not in FRESNEL_USES[n]:
            continue
        if n in ("eta", "k") and "spectral" in names and params["spectral"] != "none":
            continue
        if n == "alpha_y" and "distribution" in names and params["distribution"] == "blinn_phong":
            continue
        out.append(n)
    return out


def out_of_range(label: str, values, lo: float, hi: float) -> str:
    """"" when every number of ``values`` is finite and in [lo, hi]; else the one-line refusal
    naming the widget (``label``, as the student reads it) and its range."""
    for x in np.asarray(values, float).reshape(-1):
        if not math.isfinite(x):
            return f"{label}: {x:g} is not a number; allowed: {lo:g} to {hi:g}; the old value stays"
        if not lo <= x <= hi:
            return f"{label}: {x:g} is out of range; allowed: {lo:g} to {hi:g}; the old value stays"
    return ""


ROUGHNESS_LABEL = "roughness r"


def roughness_alpha(r: float, lo: float, hi: float) -> tuple[float | None, str]:
    """The alpha = r^2 of a roughness r the slider gave (typed or dragged) for an alpha range
    [lo, hi]: (alpha, "") or (None, the refusal naming the roughness slider and its r range)."""
    r_lo, r_hi = perceptual(lo), perceptual(hi)
    msg = out_of_range(ROUGHNESS_LABEL, [r], r_lo, r_hi)
    if msg:
        return None, msg.replace("; the old", f" (alpha = r^2 in [{lo:g}, {hi:g}]); the old")
    return float(r) ** 2, ""


def perceptual(alpha: float) -> float:
    """Perceptual roughness r of a Walter alpha (alpha = r^2)."""
    return math.sqrt(max(float(alpha), 0.0))
