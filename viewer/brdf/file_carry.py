"""A file BRDF's material after its ``.brdf`` file was saved with other parameters.

A material of model ``custom`` holds one value per declaration of its file. When the file is
saved while the window shows it (hot reload) its declarations may have changed: a parameter
added, removed, renamed or retyped (``float`` to ``bool`` to ``color``). ``carry_over`` makes the
material fit the file as it is now: a value whose name and kind still match is kept (a float
clamped into its new range, a colour into its channels' range), every other declaration starts
at its default, and values of names the file no longer declares are dropped. ``fits`` says
whether a material needs it, cheaply enough for every frame."""

from __future__ import annotations

import math

import numpy as np

from viewer import ViewerError
from viewer.brdf.spec import Params


def _number(v) -> bool:
    return isinstance(v, (int, float, np.integer, np.floating)) and not isinstance(v, (bool, np.bool_)) \
        and math.isfinite(float(v))


def agrees(param, value) -> bool:
    """``value`` has the kind of the spec's ``param`` (float, bool, rgb; ``file`` always)."""
    if param.kind == "float":
        return _number(value)
    if param.kind == "bool":
        return isinstance(value, (bool, np.bool_))
    if param.kind == "rgb":
        try:
            a = np.asarray(value, dtype=np.float64).reshape(-1)
        except (TypeError, ValueError):
            return False
        return a.size == 3 and bool(np.all(np.isfinite(a))) and not isinstance(value, (bool, str))
    return param.kind == "path"


def _fitted(param, value):
    if param.kind == "float":
        v = float(value)
        lo = -math.inf if param.lo is None else param.lo
        hi = math.inf if param.hi is None else param.hi
        return min(max(v, lo), hi)
    if param.kind == "rgb":
        a = np.asarray(value, dtype=np.float64).reshape(3)
        return [float(x) for x in np.clip(a, 0.0 if param.lo is None else param.lo,
                                          np.inf if param.hi is None else param.hi)]
    return bool(value)


def _inside(param, value) -> bool:
    if param.kind not in ("float", "rgb"):
        return True
    a = np.asarray(value, dtype=np.float64)
    return bool(np.all(a >= (-np.inf if param.lo is None else param.lo))
                and np.all(a <= (np.inf if param.hi is None else param.hi)))


def fits(params: Params, spec) -> bool:
    """The material holds exactly the spec's parameters, each of its kind and in its range."""
    names = [p.name for p in spec.params]
    if set(params) != set(names):
        return False
    return all(agrees(p, params[p.name]) and _inside(p, params[p.name]) for p in spec.params)


def carry_over(params: Params) -> Params:
    """``params`` (model ``custom``) fitted to its file as it is now (see the module's doc); the
    same object when it fits already. A file that no longer loads keeps the material as it was
    (the hot reloader shows the file's error)."""
    if params.model != "custom":
        return params
    from viewer import brdf

    try:
        model = brdf.CustomModel.of(params)
    except ViewerError:
        return params
    spec = model.spec
    if fits(params, spec):
        return params
    keep = {p.name: _fitted(p, params[p.name]) for p in spec.params
            if p.kind != "path" and p.name in params and agrees(p, params[p.name])}
    try:
        return model.params(file=params["file"], **keep)
    except ViewerError:  # a kept value the spec still refuses: the file's defaults
        return model.params(file=params["file"])
