"""Term views' scales: how a value of F, D, G, N.L or f cos maps to the false-colour ramp, its
inverse for colour-bar labels, and the ramp itself (the numpy twin of ``false_colour`` in
shaders/common/colour.glsl; the scales reach the shaders through generated/constants.glsl). No GL
here: the window, ``render`` and the tests share it.

F, G and N.L lie in [0, 1] and are shown linearly. D and f cos span orders of magnitude (a sharp
lobe's peak against its tail), so they are shown on t = log(1 + k v) / log(1 + k v_max): D with
k = 1 up to 100 (1/sr), f cos (the luminance of the BRDF times cos theta_i of the first light,
1/sr) with k = 10 up to 10. Values above v_max show as the top colour. Grey (0.25) marks pixels
where the term does not apply (not a microfacet model)."""

from __future__ import annotations

import math

import numpy as np

# view name -> (bar title, k, v_max); k = 0: linear on [0, v_max]
SCALES = {
    "F": ("F (Fresnel reflectance)", 0.0, 1.0),
    "D": ("D (normal distribution, 1/sr), log scale", 1.0, 100.0),
    "G": ("G (shadowing-masking)", 0.0, 1.0),
    "N.L": ("N.L (cos theta_i, first light)", 0.0, 1.0),
    "f cos": ("f cos theta_i (luminance, 1/sr), log scale", 10.0, 10.0),
}
NOT_APPLICABLE = 0.25  # the grey of pixels where a term does not apply


def to_t(view: str, v):
    _, k, vmax = SCALES[view]
    v = np.maximum(np.asarray(v, np.float64), 0.0)
    if k == 0.0:
        return np.clip(v / vmax, 0.0, 1.0)
    return np.clip(np.log1p(k * v) / math.log1p(k * vmax), 0.0, 1.0)


def from_t(view: str, t):
    """The value shown at ramp position ``t`` (the inverse of ``to_t`` on [0, 1])."""
    _, k, vmax = SCALES[view]
    t = np.asarray(t, np.float64)
    if k == 0.0:
        return t * vmax
    return np.expm1(t * math.log1p(k * vmax)) / k


def ticks(view: str) -> list[tuple[float, str]]:
    """(ramp position, label) for a colour bar: 0, 1/4, 1/2, 3/4, 1 for linear terms; decades
    for log ones."""
    _, k, vmax = SCALES[view]
    if k == 0.0:
        return [(float(t), f"{t * vmax:g}") for t in np.linspace(0.0, 1.0, 5)]
    vals = [0.0] + [10.0 ** e for e in range(-2, 3) if 10.0 ** e <= vmax]
    out = [(float(to_t(view, v)), f"{v:g}") for v in vals]
    keep = [out[0]]
    for t, s in out[1:]:  # drop decades crowded at the bottom of the bar
        if t - keep[-1][0] >= 0.12:
            keep.append((t, s))
    return keep


def _smoothstep(e0, e1, x):
    t = np.clip((x - e0) / (e1 - e0), 0.0, 1.0)
    return t * t * (3.0 - 2.0 * t)


def false_colour(t):
    """(..., 3) linear RGB of the term views' ramp (dark blue -> cyan -> yellow -> red)."""
    t = np.clip(np.asarray(t, np.float64), 0.0, 1.0)[..., None]
    a = np.array([0.05, 0.05, 0.35]) + (np.array([0.0, 0.8, 0.9]) - [0.05, 0.05, 0.35]) * _smoothstep(0.0, 0.35, t)
    b = a + (np.array([1.0, 0.9, 0.1]) - a) * _smoothstep(0.35, 0.7, t)
    return b + (np.array([0.9, 0.1, 0.05]) - b) * _smoothstep(0.7, 1.0, t)


def with_colour_bar(srgb: np.ndarray, view: str) -> np.ndarray:
    """The sRGB uint8 image (H, W, 3) with the view's colour bar and its numbers below it."""
    from viewer.image.colour import to_srgb8

    h, w = srgb.shape[:2]
    bar_h = max(8, h // 16)
    text_h = 14
    ramp = false_colour(np.linspace(0.0, 1.0, w))[None].repeat(bar_h, axis=0)
    bar = to_srgb8(ramp.astype(np.float32), 0.0, "none")
    pad = np.full((text_h + 4, w, 3), 24, np.uint8)
    out = np.concatenate([srgb, np.full((2, w, 3), 24, np.uint8), bar, pad], axis=0)
    try:
        from PIL import Image, ImageDraw

        im = Image.fromarray(out)
        d = ImageDraw.Draw(im)
        y = h + 2 + bar_h + 2
        for t, s in ticks(view):
            tw = d.textlength(s)
            x = min(max(0.0, t * (w - 1) - tw / 2), w - tw - 1)
            d.text((x, y), s, fill=(255, 255, 255))
        title = SCALES[view][0]
        d.text((max(2.0, (w - d.textlength(title)) / 2), h + 2 + max(0, (bar_h - 11) // 2)), title,
               fill=(0, 0, 0))
        out = np.asarray(im)
    except Exception:  # noqa: BLE001 - the numbers are a convenience; the bar is drawn anyway
        pass
    return out
