"""Environment light of a ``.brdf`` file material in the raster.

A file's lobe is unknown, so no split sum is tabulated for it: its environment light is
importance sampled per pixel (``shaders/passes/forward.frag``, ``ibl_sampled`` with
``u_ibl_own``) with the file's own sampler (``brdf_sample``: the generic mixture of
``viewer.gl.brdf_glsl``, exact pdf) and filtered lookups (Colbert and Krivanek 2007). Two things
make that image the built-in's where the built-in is the same BRDF:

* the constant part. ``constant_part`` is the largest constant c under the file's f (its
  smallest value over a grid of direction pairs). In split-sum mode the raster draws
  c E(n) with the irradiance, as a built-in diffuse lobe is drawn, and samples only
  f - c: a control variate (for any c the sum is the same integral), so a Lambertian file has
  nothing left to sample and draws the built-in Lambert's image, noise-free.
* the frames. Each frame draws new sample sets; a still view averages ``SETTLE_FRAMES`` of them
  (the window: ``viewer.app.view_frames``; offscreen: ``Renderer.render_arrays``, which
  renders ``settle_frames(scene)`` frames), so the speckle of 16 samples per pixel settles.

No GL here beyond the file's evaluator, which ``viewer.brdf`` runs.
"""

from __future__ import annotations

import json

import numpy as np

from viewer import brdf

#: frames a still view of a file material under sampled environment light averages (16 samples
#: per pixel each): the pixel noise of one frame over sqrt(64) = an eighth (measured on the
#: shipped Cook-Torrance under a constant environment: 5.6% one frame, 0.7% settled)
SETTLE_FRAMES = 64

#: samples per pixel and frame (forward.frag's IBL_SAMPLES); the filtered lookups of a file
#: material are chosen for all the samples its settled image averages, FRAME_SAMPLES x the frames
#: (Colbert and Krivanek's N: a sample stands for 1 / (N pdf) steradians)
FRAME_SAMPLES = 16

_FLOORS: dict = {}


def _grid():
    """Direction pairs (wi, wo) over the upper hemisphere (views from normal incidence to 85
    degrees at three azimuths, light directions on 12 x 16 cells), shading frame z = normal."""
    tv = np.radians([0.0, 15.0, 30.0, 45.0, 60.0, 75.0, 85.0])
    pv = np.radians([0.0, 45.0, 90.0])
    ti = np.radians((np.arange(12) + 0.5) * 90.0 / 12)
    pi = np.radians(np.arange(16) * 360.0 / 16)
    wo = np.stack([np.sin(tv)[:, None] * np.cos(pv)[None], np.sin(tv)[:, None] * np.sin(pv)[None],
                   np.cos(tv)[:, None] * np.ones_like(pv)[None]], axis=-1).reshape(-1, 3)
    wi = np.stack([np.sin(ti)[:, None] * np.cos(pi)[None], np.sin(ti)[:, None] * np.sin(pi)[None],
                   np.cos(ti)[:, None] * np.ones_like(pi)[None]], axis=-1).reshape(-1, 3)
    return np.repeat(wi[None], len(wo), 0).reshape(-1, 3), np.repeat(wo, len(wi), 0)


def _floor(params) -> tuple[np.ndarray, bool]:
    """(c, f is c at every pair of the grid), cached by the file and the parameter values."""
    from viewer import brdf

    from viewer import ViewerError

    try:
        model = brdf.get("custom").of(params)
        key = (str(model.bfile.path), json.dumps(params.to_plain(), sort_keys=True), id(model))
        hit = _FLOORS.get(key)
        if hit is not None:
            return hit
        wi, wo = _grid()
        f = np.asarray(model.eval(params, wi, wo), float)
    except ViewerError:  # (a ShaderError is one)
        # a file saved with a mistake (the last good program keeps drawing, the error is shown
        # where it compiles): no constant part taken out, averaged; not cached (it may be fixed)
        return np.zeros(3), False
    if f.ndim == 1:
        f = np.repeat(f[:, None], 3, axis=1)
    finite = np.isfinite(f)
    f = np.maximum(np.where(finite, f, np.inf), 0.0)
    c = f.min(axis=0)
    c = np.where(np.isfinite(c), c, 0.0)
    flat = bool(finite.all() and np.all(f == c[None, :]))
    if len(_FLOORS) > 256:
        _FLOORS.clear()
    _FLOORS[key] = (c, flat)
    return c, flat


def constant_part(params) -> np.ndarray:
    """(3,) the largest constant under a file material's f: per channel its smallest finite value
    over ``_grid`` (the raster draws negative f as 0, so never below 0). A grid misses the true
    minimum by a little at most; the raster's sum stays the same integral for any c (it samples
    f - c), so that costs a little noise, no bias."""
    return _floor(params)[0]


def is_constant(params) -> bool:
    """The file's f is its constant part at every pair of the grid (a Lambertian file): what is
    left to sample is 0 there, and a view of it needs no averaging (the raster still samples
    f - c, so a file that differs between the grid's pairs is drawn without bias, with noise)."""
    return _floor(params)[1]


def sampled_file_env(scene) -> bool:
    """The scene has a file material whose environment light the raster samples and a still view
    averages over frames: the environment lights the scene in split-sum or fis mode (brute force
    averages frames of its own), unless in split-sum mode every such file is a constant
    (``is_constant``)."""
    if scene.render.ibl not in ("split_sum", "fis") or scene.environment.is_black:
        return False  # (the frame's environment switch of ``program_set.frame_switches``)
    files = {o.material for o in scene.objects if brdf.is_file(scene.materials[o.material])}
    # split sum: a Lambertian file's whole light is its constant part, nothing is left to average
    return any(scene.render.ibl != "split_sum" or not is_constant(scene.materials[m]) for m in files)


def settle_frames(scene) -> int:
    """How many frames a still raster view of ``scene`` averages: ``SETTLE_FRAMES`` where a file
    material's environment light is sampled (``sampled_file_env``), else 1."""
    return SETTLE_FRAMES if sampled_file_env(scene) else 1
