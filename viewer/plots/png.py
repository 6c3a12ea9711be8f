"""The plot as a file: the PNG (atomically written) with the plotted numbers as JSON in its
``brdf-viewer:plot`` text chunk, optionally the same JSON beside it, and reading them back."""

from __future__ import annotations

import json
import math

import numpy as np

from viewer import ViewerError
from viewer.plots.draw import render_figure
from viewer.plots.figure_types import Figure

PNG_KEY = "brdf-viewer:plot"


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


def write_plot(fig: Figure, out, data_path=None, width: int = 900, height: int = 600):
    """Write the PNG (atomically; the plotted numbers as JSON in its ``brdf-viewer:plot`` text
    chunk) and, optionally, the same JSON to ``data_path``."""
    from viewer.base.io import atomic_write_bytes, write_png

    img = render_figure(fig, width, height)
    data = figure_json(fig)
    write_png(out, img, {PNG_KEY: json.dumps(data, separators=(",", ":"))})
    if data_path is not None:
        atomic_write_bytes(data_path, (json.dumps(data, indent=1) + "\n").encode())
    return img


def read_plot_data(png_path) -> dict:
    """The plotted numbers stored in a plot PNG (``brdf-viewer:plot``)."""
    from viewer.base.io import read_png_text

    text = read_png_text(png_path)
    if PNG_KEY not in text:
        raise ViewerError(f"{png_path}: no {PNG_KEY} text chunk (not written by brdf-viewer plot)")
    return json.loads(text[PNG_KEY])
