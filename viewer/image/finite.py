"""Non-finite pixels: count them, find which objects make them, say so in one line.

A NaN or Inf in the rasterizer's image is a bug (a shader reading an unwritten target, a
division by zero); in front of a class it shows as magenta or black holes. ``render`` and the
window check every image they show and name the count and the culprits instead of carrying on
silently. Numpy only (no GL): the renderer is passed in as a function.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Callable, Sequence

import numpy as np


def nonfinite_mask(image) -> np.ndarray:
    """(H, W) True where any channel of the (H, W, C) image is NaN or +-Inf."""
    a = np.asarray(image)
    return ~np.isfinite(a).all(axis=-1)


def nonfinite_count(image) -> int:
    return int(np.count_nonzero(nonfinite_mask(image)))


def culprits(scene, render_linear: Callable[[object], np.ndarray]) -> list[str]:
    """The objects that give non-finite pixels when drawn alone (same camera, lights and
    environment): ``render_linear(scene)`` returns the linear image. ``["the background"]``
    when the empty scene already has them. An object that draws finite pixels once its material
    is a plain Lambert one is named by its material's BRDF (the model, or the ``.brdf`` file,
    returned NaN or Inf: the material's fault, not the renderer's). Costs one or two renders per
    object; call it only after ``nonfinite_count`` found something."""
    if nonfinite_count(render_linear(dataclasses.replace(scene, objects=[]))):
        return ["the background (environment)"]
    out = []
    for o in scene.objects:
        alone = dataclasses.replace(scene, objects=[o])
        if nonfinite_count(render_linear(alone)):
            params = scene.materials.get(o.material)
            model = material_model_name(params)
            # a Lambert material in its place: finite, the BRDF is at fault (a Lambert material that
            # is not finite stays not finite in its own place, and the object is named)
            if params is not None and _finite_as_lambert(alone, o, render_linear):
                out.append(f"the BRDF of material {o.material!r} ({model}) on {o.mesh}, which returns NaN or Inf "
                           "(the material's fault, not the renderer's)")
            else:
                out.append(f"{o.mesh} with material {o.material!r} ({model})")
    return out


def material_model_name(params) -> str:
    """``"microfacet"``, or for a ``.brdf`` material ``"custom inf.brdf"`` (its file's name)."""
    model = getattr(params, "model", None) or "?"
    file = params.get("file") if isinstance(params, dict) else None
    return f"{model} {Path(str(file)).name}" if file else model


def _finite_as_lambert(alone, obj, render_linear) -> bool:
    """Whether the object alone draws finite pixels with its material made a default Lambert one
    (same name, so only the BRDF differs)."""
    from viewer import brdf
    from viewer.brdf.spec import validate_params

    lambert = validate_params(brdf.get("lambert").spec, {}, "lambert")
    probe = dataclasses.replace(alone, materials={**alone.materials, obj.material: lambert})
    return nonfinite_count(render_linear(probe)) == 0


def nonfinite_message(image, source: str, found: Sequence[str] = (), switches: str = "") -> str | None:
    """One line naming the count, the fraction, the first pixel (x, y from the top left), where
    it came from (``source``: e.g. "the rasterizer"; ``found``: the objects ``culprits``
    named) and the render switches; None when every pixel is finite."""
    mask = nonfinite_mask(image)
    n = int(np.count_nonzero(mask))
    if not n:
        return None
    h, w = mask.shape
    y, x = (int(v[0]) for v in np.nonzero(mask))
    where = ("; from " + ", ".join(found)) if found else ""
    sw = f" ({switches})" if switches else ""
    return (f"{source}: {n} of {w * h} pixels ({100.0 * n / (w * h):.1f}%) are NaN or Inf, first at "
            f"x={x}, y={y}{where}{sw}")


def render_switches(scene) -> str:
    """The rasterizer switches that choose shader variants, for messages."""
    r = scene.render
    env = scene.environment
    light = ("map " + str(env.map)) if env.map is not None else (
        "no environment" if env.constant is None or not np.any(np.asarray(env.constant) * env.intensity > 0)
        else "constant environment")
    return f"ssr={'on' if r.ssr else 'off'}, ibl={r.ibl}, {light}"
