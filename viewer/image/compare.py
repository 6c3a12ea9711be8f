"""Raster against reference: difference maps and error metrics (`brdf-viewer compare`).

Both images are linear radiance (H, W, 3). Metrics, per channel and as the mean over channels:
  RMSE          sqrt(mean((raster - reference)^2))
  relative MSE  mean((raster - reference)^2 / (reference^2 + eps)), eps = 1e-2 (Rousselle et al.
                2011's relMSE; the eps keeps black pixels from dominating)
  mean          mean of each image (the difference of means shows a bias at a glance)

Scene agreement (``agreement``, the per-scene raster-vs-reference figures of the tests and
benchmarks/scenes_vs_reference.py), on the mean over channels:
  mean rel      |mean(raster) - mean(reference)| / mean(reference), the image's overall bias
  block p90     the 90th percentile over 8 x 8 pixel blocks of |block mean difference| /
                max(block mean of the reference, 0.1 x the reference's image mean): where the
                raster is locally wrong, not hidden by averaging; the floor keeps dark blocks
                (noise over almost nothing) from counting as 100% errors
"""

from __future__ import annotations

import numpy as np

REL_MSE_EPS = 1e-2


def metrics(raster: np.ndarray, reference: np.ndarray) -> dict:
    r = np.asarray(raster, np.float64)
    ref = np.asarray(reference, np.float64)
    if r.shape != ref.shape:
        raise ValueError(f"image shapes differ: {r.shape} vs {ref.shape}")
    d2 = (r - ref) ** 2
    rmse = np.sqrt(d2.mean(axis=(0, 1)))
    rel = (d2 / (ref ** 2 + REL_MSE_EPS)).mean(axis=(0, 1))
    out = {
        "rmse": float(np.sqrt(d2.mean())),
        "relative_mse": float(rel.mean()),
        "rmse_per_channel": [float(x) for x in rmse],
        "relative_mse_per_channel": [float(x) for x in rel],
        "mean_raster_per_channel": [float(x) for x in r.mean(axis=(0, 1))],
        "mean_reference_per_channel": [float(x) for x in ref.mean(axis=(0, 1))],
        "relative_mse_eps": REL_MSE_EPS,
    }
    return out


def ramp(t: np.ndarray) -> np.ndarray:
    """A perceptually ordered ramp (black -> blue -> magenta -> orange -> white), t in [0, 1]:
    every heat map (differences, Monte Carlo error views) uses it."""
    stops = np.array([[0.0, 0.0, 0.0], [0.1, 0.1, 0.6], [0.7, 0.1, 0.6], [1.0, 0.6, 0.1], [1.0, 1.0, 1.0]])
    x = np.clip(t, 0.0, 1.0) * (len(stops) - 1)
    i = np.minimum(x.astype(int), len(stops) - 2)
    f = (x - i)[..., None]
    return stops[i] * (1 - f) + stops[i + 1] * f


def error_map(raster: np.ndarray, reference: np.ndarray, relative: bool = False) -> np.ndarray:
    """(H, W) per-pixel error: |raster - reference| averaged over channels; relative: divided
    by the reference's mean over channels + ``REL_MSE_EPS``."""
    ref = np.asarray(reference, np.float64)
    err = np.abs(np.asarray(raster, np.float64) - ref).mean(axis=-1)
    return err / (ref.mean(axis=-1) + REL_MSE_EPS) if relative else err


def auto_scale(err: np.ndarray) -> float:
    """The heat map's top: the 99th percentile, so a few outliers do not wash the map out."""
    return float(np.percentile(err, 99)) or float(err.max()) or 1.0


def heat_map(raster: np.ndarray, reference: np.ndarray, relative: bool = False, scale: float | None = None):
    """(sRGB uint8 image with a colour bar below it, the scale that maps to the top of the bar).

    The error per pixel is |raster - reference| averaged over channels (relative: divided by the
    reference's mean over channels + 1e-2). The scale defaults to the 99th percentile, so a few
    outliers do not wash the map out; it is printed under the bar and returned."""
    err = error_map(raster, reference, relative)
    if scale is None:
        scale = auto_scale(err)
    rgb = ramp(err / scale)
    h, w = err.shape
    bar_h = max(8, h // 16)
    bar = ramp(np.linspace(0.0, 1.0, w))[None, :, :].repeat(bar_h, axis=0)
    img = np.concatenate([rgb, np.ones((2, w, 3)), bar], axis=0)
    srgb = np.where(img <= 0.0031308, 12.92 * img, 1.055 * np.power(img, 1 / 2.4) - 0.055)
    out = (np.clip(srgb, 0, 1) * 255 + 0.5).astype(np.uint8)
    try:  # label the bar with its scale (Pillow's default bitmap font)
        from PIL import Image, ImageDraw

        im = Image.fromarray(out)
        ImageDraw.Draw(im).text((2, h + 2), f"0 .. {scale:.3g}" + (" (relative)" if relative else ""),
                                fill=(255, 255, 255))
        out = np.asarray(im)
    except Exception:  # noqa: BLE001 - the label is a convenience; the scale is in metrics.json
        pass
    return out, scale


def agreement(raster: np.ndarray, reference: np.ndarray, block: int = 8) -> dict:
    """``{"mean_rel", "block_p90", "block_rel"}`` of two (H, W, 3) images (see the module's
    docstring); a partial block at the right / bottom edge is left out."""
    r = np.asarray(raster, np.float64).mean(axis=-1)
    ref = np.asarray(reference, np.float64).mean(axis=-1)
    if r.shape != ref.shape:
        raise ValueError(f"image shapes differ: {r.shape} vs {ref.shape}")
    m = float(ref.mean())
    h, w = (r.shape[0] // block) * block, (r.shape[1] // block) * block
    if h == 0 or w == 0:
        raise ValueError(f"image {r.shape} smaller than one {block} x {block} block")

    def blocks(x):
        return x[:h, :w].reshape(h // block, block, w // block, block).mean(axis=(1, 3))

    br, bref = blocks(r), blocks(ref)
    rel = np.abs(br - bref) / np.maximum(bref, 0.1 * max(m, 1e-12))
    return {"mean_rel": float(abs(r.mean() - m) / max(m, 1e-12)), "block_p90": float(np.percentile(rel, 90)),
            "block_rel": rel}
