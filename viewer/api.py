"""The Python API for scripts and notebooks (docs/python-api.md): the command line's ``render``
and ``reference`` as functions returning float32 (H, W, 3) arrays of linear radiance, row 0 = top.

``scene`` is a scene file path (``.toml``, or a ``.png`` written by the viewer), a built-in scene
name (``"default"``, ``"sphere"``, ...), TOML text (anything with a newline or an ``=``), or a
``viewer.scene.Scene``. ``overrides`` are ``--set`` assignments (``"materials.ball.alpha=0.2"``).
Bad input raises ``viewer.ViewerError`` with the CLI's one-line message.

The rasterizer's offscreen EGL context and renderer are made on the first ``render`` call and
kept for the next ones (compiled programs are reused, as in the window). ``reference`` starts
its pool of spawned worker processes per call and closes it before returning. In a notebook
that needs nothing; a script must call it under ``if __name__ == "__main__":`` (else one
``ViewerError`` names the fix) or pass ``workers=0``.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from viewer import ViewerError

# The reference engines (viewer.reference_common.select): "cpu", "gpu" and "auto", which takes the GPU engine
# on a hardware GPU and the CPU engine on software OpenGL or for a scene only it renders.
from viewer.reference_common.select import ENGINES as REFERENCE_ENGINES  # noqa: E402

_raster = None  # (context, renderer), made on the first render() call


def load(scene, overrides=(), width=None, height=None):
    """A validated ``Scene`` from any of the accepted kinds of ``scene`` (see the module), with
    ``overrides`` and the ``width`` / ``height`` camera overrides applied as the CLI applies them."""
    from viewer.scene import Scene, load_scene, load_scene_text, scene_to_data

    if isinstance(overrides, str):
        overrides = [overrides]
    assignments = list(overrides)
    for key, val in (("width", width), ("height", height)):
        if val is not None:
            assignments.append(f"camera.{key}={int(val)}")
    if isinstance(scene, Scene):
        if not assignments:
            return scene
        from viewer.scene import parse_scene

        return parse_scene(scene_to_data(scene), scene.path, assignments, label=scene.label,
                           base_dir=scene.base_dir)
    if isinstance(scene, Path):
        return load_scene(scene, assignments)
    if not isinstance(scene, str):
        raise ViewerError(f"scene: {type(scene).__name__} is not a scene; allowed: a scene file path, "
                          "a built-in scene name, TOML text or a viewer.scene.Scene")
    if "\n" in scene or "=" in scene:
        return load_scene_text(scene, assignments)
    return load_scene(scene, assignments)


def bparam_overrides(material: str, path) -> list[str]:
    """The ``KEY=VALUE`` assignments that set scene material ``material``'s values from a BRDF
    Explorer ``.bparam`` file (``--bparam MATERIAL=FILE``), for ``overrides``; the names the file's
    ``.brdf`` lacks are left out with one logged warning."""
    import logging

    from viewer.brdf import bparam

    lines, note = bparam.overrides(path, prefix=f"materials.{material}.")
    if note:
        logging.getLogger("viewer").warning("%s", note)
    return lines


def render(scene, width=None, height=None, overrides=()) -> np.ndarray:
    """Rasterize ``scene`` offscreen with the window's renderer: the same float32 (H, W, 3)
    array as ``brdf-viewer render SCENE --linear out.npy`` (bit for bit)."""
    global _raster
    from viewer.scene.camera import OrbitCamera

    sc = load(scene, overrides, width, height)
    if _raster is None:
        from viewer.gl.context import create_offscreen_context
        from viewer.gl.renderer import Renderer

        ctx = create_offscreen_context()
        _raster = (ctx, Renderer(ctx))
    ctx, renderer = _raster
    # make it current again: a reference call in between may have created and released a GL
    # context of its own (the engine choice does), which leaves none current on this thread
    ctx.__enter__()
    linear, _ = renderer.render_arrays(sc, OrbitCamera.from_scene(sc))
    return linear


def reference_engine(engine: str, scene=None) -> str:
    """The engine ``engine`` names on this machine for ``scene`` (a loaded Scene, or None) with
    "auto" resolved; ``ViewerError`` for an unknown name."""
    if engine not in REFERENCE_ENGINES:
        raise ViewerError(f"engine: {engine!r} is not a reference engine; allowed: "
                          + ", ".join(REFERENCE_ENGINES))
    from viewer.reference_common.select import choose_for_scenes

    return choose_for_scenes(engine, [] if scene is None else [scene])[0]


def _make_reference_renderer(engine: str, scene, camera, max_depth: int, seed: int, workers):
    """Start the reference renderer of the (resolved) ``engine``."""
    from viewer.reference_common.select import make_renderer

    return make_renderer(engine, scene, camera, max_depth=max_depth, seed=seed, workers=workers)


def reference(scene, spp=64, engine="auto", width=None, height=None, overrides=(), *, seed=0,
              max_depth=8, workers=None) -> np.ndarray:
    """Path-trace ``scene`` with ``spp`` samples per pixel: the same float32 (H, W, 3) array as
    ``brdf-viewer reference SCENE --spp N --seed S --linear out.npy`` (bit for bit for the same
    seed). ``max_depth`` scattering events per path (1 = direct light); ``workers`` processes
    (default: every core; 0 = render in this process, same image)."""
    from viewer.scene.camera import OrbitCamera

    if engine not in REFERENCE_ENGINES:
        reference_engine(engine)  # the one-line error
    if isinstance(spp, bool) or not isinstance(spp, (int, np.integer)) or spp < 1:
        raise ViewerError(f"spp: {spp!r} is out of range; allowed: an integer >= 1")
    if isinstance(max_depth, bool) or not isinstance(max_depth, (int, np.integer)) or max_depth < 1:
        raise ViewerError(f"max_depth: {max_depth!r} is out of range; allowed: an integer >= 1 "
                          "(1 = direct light only)")
    if workers is not None and (not isinstance(workers, (int, np.integer)) or workers < 0):
        raise ViewerError(f"workers: {workers!r} is out of range; allowed: an integer >= 0 (0 = no pool)")
    sc = load(scene, overrides, width, height)
    resolved = reference_engine(engine, sc)
    renderer = _make_reference_renderer(resolved, sc, OrbitCamera.from_scene(sc), int(max_depth),
                                        int(seed), workers)
    try:
        renderer.step(int(spp))
        return renderer.mean()
    finally:
        renderer.close()
