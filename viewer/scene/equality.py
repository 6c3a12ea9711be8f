"""Structural equality of the scene model's values (``Scene``, its parts, ``Environment``): below
both ``viewer.scene.model`` and ``viewer.scene.environment``, which compare with it."""

from __future__ import annotations

from dataclasses import fields, is_dataclass

import numpy as np


def equal(a, b, skip=()) -> bool:
    """Structural equality that understands numpy arrays, Params and dataclasses.
    Float arrays compare with a relative tolerance of 1e-12 (a normalized direction that is
    normalized again may move by an ulp)."""
    if type(a) is not type(b):
        if not (isinstance(a, (int, float)) and isinstance(b, (int, float))
                and not isinstance(a, bool) and not isinstance(b, bool)):
            return False
    if is_dataclass(a):
        # a dataclass inside a list skips what it skips on its own (its class's EQ_SKIP)
        skip = skip or getattr(type(a), "EQ_SKIP", ())
        return all(equal(getattr(a, f.name), getattr(b, f.name)) for f in fields(a) if f.name not in skip)
    if isinstance(a, np.ndarray):
        return a.shape == b.shape and bool(np.allclose(a, b, rtol=1e-12, atol=1e-15))
    if isinstance(a, dict):
        if getattr(a, "model", None) != getattr(b, "model", None):
            return False
        return a.keys() == b.keys() and all(equal(a[k], b[k]) for k in a)
    if isinstance(a, (list, tuple)):
        return len(a) == len(b) and all(equal(x, y) for x, y in zip(a, b))
    return a == b
