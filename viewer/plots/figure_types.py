"""What a figure is, apart from how it is made (``viewer.plots.figures``) and drawn
(``viewer.plots.draw``, the kinds' own drawings in ``spectral`` and ``measured``): ``Figure``,
its ``Curve``s and ``Mark``s, and ``fmt_value`` (a parameter value in a label)."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from viewer.plots.canvas import NEUTRAL


@dataclass
class Curve:
    label: str
    x: np.ndarray
    y: np.ndarray
    color: tuple = NEUTRAL
    style: str = "solid"  # solid | dashed | dashdot (short dashes) | dotted
    extra: dict = field(default_factory=dict)  # more arrays at the same x (e.g. f without cos)


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


def fmt_value(v) -> str:
    if isinstance(v, np.ndarray):
        if np.allclose(v, v[0]):
            return f"{v[0]:.3g}"
        return "[" + ", ".join(f"{x:.3g}" for x in v) + "]"
    if isinstance(v, float):
        return f"{v:.3g}"
    if isinstance(v, dict):
        return "{" + ", ".join(f"{k}={fmt_value(x)}" for k, x in v.items()) + "}"
    if isinstance(v, list):
        return f"{len(v)} lobe" + ("" if len(v) == 1 else "s")
    return str(v)
