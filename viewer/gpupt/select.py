"""Which reference engine to use: ``cpu`` (numpy + Embree, the oracle), ``gpu`` (GLSL) or
``auto``.

``auto``: a hardware GPU -> gpu. Software OpenGL (Mesa llvmpipe / softpipe, SwiftShader, ...)
shares the CPU cores with the CPU engine, so it is whichever measured faster on this machine:
a stored measurement (``engine.toml`` in the cache folder, keyed by the GL renderer string and
the number of cores) or, the first time, a short calibration (the built-in default scene at
128 x 128, 4 spp, both engines, warm) whose result is stored. No OpenGL at all -> cpu.
Both engines trace wavelengths (``needs_spectral``: a dispersive material or ``spectral=True``;
the GPU engine's ``SPECTRAL`` variant), so such a scene takes the ordinary choice. Scenes only the
cpu engine can trace (``viewer/gpupt/refusals.py``: measured tables, the multiple-scattering
random walk, thin films per wavelength or over height) take it under ``auto``; ``gpu`` refuses them.
"""

from __future__ import annotations

import os
import time
from pathlib import Path

# needs_spectral, uses_measured, uses_random_walk: public here too (the CLI, the window, tests)
from viewer.gpupt.refusals import cpu_only, needs_spectral, uses_measured, uses_random_walk

ENGINES = ("cpu", "gpu", "auto")
SOFTWARE_GL = ("llvmpipe", "softpipe", "swiftshader", "software", "lavapipe", "swrast")
CALIBRATION = dict(scene="default", size=128, spp=4)


def cache_dir() -> Path:
    from viewer.pathtracer.cache import cache_root

    return cache_root()


def gl_renderer_name(ctx) -> str:
    try:
        return str(ctx.info.get("GL_RENDERER", ""))
    except Exception:  # noqa: BLE001 - a context without info
        return ""


def is_software(renderer_name: str) -> bool:
    low = renderer_name.lower()
    return any(s in low for s in SOFTWARE_GL)


def _measure_file() -> Path:
    return cache_dir() / "engine.toml"


def _machine_key(renderer_name: str) -> str:
    return f"{renderer_name} | {os.cpu_count()} cores"


def stored_choice(renderer_name: str) -> dict | None:
    import tomllib

    try:
        data = tomllib.loads(_measure_file().read_text())
    except (OSError, ValueError):
        return None
    entry = data.get("machine", {}).get(_machine_key(renderer_name))
    if isinstance(entry, dict) and entry.get("faster") in ("cpu", "gpu"):
        return entry
    return None


def calibrate(ctx, workers=None) -> dict:
    """Samples/s of both engines on the calibration scene (warm: programs compiled, pool up)."""
    from viewer.gpupt.engine import GpuReferenceRenderer
    from viewer.pathtracer import ReferenceRenderer
    from viewer.scene import load_scene

    sc = load_scene(CALIBRATION["scene"])
    n, spp = CALIBRATION["size"], CALIBRATION["spp"]
    out = {}
    with GpuReferenceRenderer(sc, width=n, height=n, max_depth=8, seed=0, ctx=ctx) as g:
        g.step(1)
        t = time.perf_counter()
        g.step(spp)
        out["gpu"] = spp * n * n / (time.perf_counter() - t)
    with ReferenceRenderer(sc, width=n, height=n, max_depth=8, seed=0, workers=workers) as c:
        c.warm_up()
        c.step(1)
        t = time.perf_counter()
        c.step(spp)
        out["cpu"] = spp * n * n / (time.perf_counter() - t)
    return out


def store_choice(renderer_name: str, rates: dict) -> dict:
    import tomllib

    from viewer.io import atomic_write_bytes

    entry = {"faster": "gpu" if rates["gpu"] > rates["cpu"] else "cpu",
             "gpu_samples_per_second": float(rates["gpu"]), "cpu_samples_per_second": float(rates["cpu"])}
    path = _measure_file()
    try:
        data = tomllib.loads(path.read_text())
    except (OSError, ValueError):
        data = {}
    machines = data.get("machine", {}) if isinstance(data.get("machine"), dict) else {}
    machines[_machine_key(renderer_name)] = entry
    lines = ["# brdf-viewer: measured reference-engine speeds per machine (delete to measure again)"]
    for key, e in machines.items():
        lines.append(f'[machine."{key}"]'.replace("\\", "\\\\"))
        for k, v in e.items():
            lines.append(f'{k} = "{v}"' if isinstance(v, str) else f"{k} = {v!r}")
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        atomic_write_bytes(path, ("\n".join(lines) + "\n").encode())
    except OSError:
        pass  # a read-only cache: measure again next time
    return entry


def choose_engine(requested: str = "auto", ctx=None, workers=None, calibrate_if_needed: bool = True):
    """(engine "cpu" | "gpu", reason) for ``requested`` in ENGINES. ``ctx``: a GL context to
    ask (default: a headless one is made for the question)."""
    from viewer import ViewerError

    if requested not in ENGINES:
        raise ViewerError(f"--engine: {requested!r} is not an engine; allowed: {', '.join(ENGINES)}")
    if requested == "cpu":
        return "cpu", "asked for"
    own = ctx is None
    if own:
        from viewer.gl.context import GLUnavailable, create_offscreen_context

        try:
            ctx = create_offscreen_context()
        except GLUnavailable as e:
            if requested == "gpu":
                raise
            return "cpu", f"no OpenGL 4.1 ({str(e).split(';')[0]})"
    try:
        if requested == "gpu":
            return "gpu", "asked for"
        name = gl_renderer_name(ctx)
        if not is_software(name):
            return "gpu", f"hardware GPU ({name})"
        # Software GL runs the GPU engine on the same CPU cores: a short calibration on a small
        # scene measured it 1.2x faster, but on the gallery it was 10x slower, and its program for
        # a many-model scene compiles for up to a minute on the window's thread. So auto keeps the
        # cpu engine there; --engine gpu still runs it.
        return "cpu", f"software OpenGL ({name}): the cpu engine (--engine gpu runs the GLSL one on the CPU)"
    finally:
        if own:
            from viewer.gpupt.engine import release_programs

            release_programs(ctx)
            ctx.release()


def without_twin(scene) -> str | None:
    """Why the cpu engine cannot render ``scene``'s ``.brdf`` file materials (a file whose numpy
    twin is missing or not to be run: the cpu engine evaluates twins only), in one line; None
    when it can. The window's reference takes the gpu engine for such a scene, as ``auto`` does."""
    from viewer import ViewerError, brdf

    used = {o.material for o in scene.objects}
    for name, m in scene.materials.items():
        if not brdf.is_file(m) or name not in used:
            continue
        try:
            brdf.get("custom").of(m).numpy_model()
        except ViewerError as e:
            return str(e)
    return None


def make_renderer(engine: str, scene, camera=None, width=None, height=None, max_depth=8, seed=0,
                  workers=None, ctx=None, spectral: bool | None = None, **estimator):
    """A progressive reference renderer of the chosen engine ("cpu" or "gpu"). ``spectral``:
    trace wavelengths (None: where a material is dispersive); both engines do.
    ``estimator``: the estimator's options (strategy, mis_heuristic, russian_roulette), which
    both engines take."""
    if engine == "gpu":
        limit = cpu_only(scene, spectral)
        if limit is not None:
            from viewer import ViewerError

            raise ViewerError(limit.refusal)
        from viewer.gpupt.engine import GpuReferenceRenderer

        return GpuReferenceRenderer(scene, camera, width, height, max_depth=max_depth, seed=seed, ctx=ctx,
                                    spectral=spectral, **estimator)
    from viewer import brdf
    from viewer.pathtracer import ReferenceRenderer

    for m in scene.materials.values():
        if brdf.is_file(m):  # the cpu engine evaluates numpy twins: refused in one line without one
            brdf.model_of(m).of(m).numpy_model()
    return ReferenceRenderer(scene, camera, width, height, max_depth=max_depth, seed=seed, workers=workers,
                             spectral=spectral, **estimator)


def choose_for_scenes(requested: str, scenes=(), spectral: bool | None = None, ctx=None, workers=None):
    """(engine, reason) for ``requested`` and the scenes it will render: ``auto`` takes the cpu
    engine for a scene only it renders (measured tables, the microfacet random walk), else
    ``choose_engine``'s choice (``gpu`` asked for such a scene fails in ``make_renderer``); a scene
    that needs wavelengths takes the ordinary choice (both engines trace them). ``spectral`` is
    kept for the callers' sake."""
    from viewer import brdf

    if requested == "auto":
        if any(any(brdf.is_file(m) for m in s.materials.values()) for s in scenes):
            return "gpu", "a .brdf file material: the gpu engine runs its GLSL (on software OpenGL too)"
        for s in scenes:
            limit = cpu_only(s, spectral)
            if limit is not None:
                return "cpu", limit.reason
    return choose_engine(requested, ctx=ctx, workers=workers)
