"""Which reference engine to use: ``cpu`` (numpy + Embree, the oracle), ``gpu`` (GLSL) or
``auto``, and ``make_renderer``, which makes one of the chosen engine (each engine is imported
only there, when it is the one asked for).

``auto``: a hardware GPU -> gpu. Software OpenGL (Mesa llvmpipe / softpipe, SwiftShader, ...)
shares the CPU cores with the CPU engine and measured up to 10x slower than it on many-model
scenes, so there it is cpu. No OpenGL at all -> cpu.
Both engines trace wavelengths (``needs_spectral``: a dispersive material or ``spectral=True``;
the GPU engine's ``SPECTRAL`` variant), so such a scene takes the ordinary choice. Scenes only the
cpu engine can trace (``viewer/reference_common/refusals.py``: measured tables, the multiple-scattering
random walk, thin films per wavelength or over height) take it under ``auto``; ``gpu`` refuses them.
"""

from __future__ import annotations

# needs_spectral, uses_measured, uses_random_walk: public here too (the CLI, the window, tests)
from viewer.reference_common.refusals import cpu_only, needs_spectral, uses_measured, uses_random_walk

ENGINES = ("cpu", "gpu", "auto")
SOFTWARE_GL = ("llvmpipe", "softpipe", "swiftshader", "software", "lavapipe", "swrast")


def gl_renderer_name(ctx) -> str:
    try:
        return str(ctx.info.get("GL_RENDERER", ""))
    except Exception:  # noqa: BLE001 - a context without info
        return ""


def is_software(renderer_name: str) -> bool:
    low = renderer_name.lower()
    return any(s in low for s in SOFTWARE_GL)


def choose_engine(requested: str = "auto", ctx=None):
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
        # Software GL runs the GPU engine on the same CPU cores: on a small scene it measured 1.2x
        # faster, but on the gallery 10x slower, and its program for a many-model scene compiles
        # for up to a minute on the window's thread. So auto keeps the cpu engine there;
        # --engine gpu still runs it.
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


def engine_options(takes, options: dict) -> dict:
    """The estimator ``options`` that the callable ``takes`` (an engine's constructor or its
    ``reset``) has parameters for: an engine without the photon map has no ``integrator`` and
    renders ``path``; its setup says which it rendered."""
    import inspect

    params = inspect.signature(takes).parameters
    if any(p.kind is inspect.Parameter.VAR_KEYWORD for p in params.values()):
        return dict(options)
    return {k: v for k, v in options.items() if k in params}


def make_renderer(engine: str, scene, camera=None, width=None, height=None, max_depth=8, seed=0,
                  workers=None, ctx=None, spectral: bool | None = None, **estimator):
    """A progressive reference renderer of the chosen engine ("cpu" or "gpu"). ``spectral``:
    trace wavelengths (None: where a material is dispersive); both engines do.
    ``estimator``: the estimator's options (strategy, mis_heuristic, russian_roulette, integrator:
    "path", "photon" or "auto", chosen per scene by ``caustics.choose_integrator``)."""
    if engine == "gpu":
        limit = cpu_only(scene, spectral)
        if limit is not None:
            from viewer import ViewerError

            raise ViewerError(limit.refusal)
        from viewer.gpupt.engine import GpuReferenceRenderer

        return GpuReferenceRenderer(scene, camera, width, height, max_depth=max_depth, seed=seed, ctx=ctx,
                                    spectral=spectral, **engine_options(GpuReferenceRenderer, estimator))
    from viewer import brdf
    from viewer.pathtracer import ReferenceRenderer

    for m in scene.materials.values():
        if brdf.is_file(m):  # the cpu engine evaluates numpy twins: refused in one line without one
            brdf.model_of(m).of(m).numpy_model()
    return ReferenceRenderer(scene, camera, width, height, max_depth=max_depth, seed=seed, workers=workers,
                             spectral=spectral, **estimator)


def choose_for_scenes(requested: str, scenes=(), spectral: bool | None = None, ctx=None):
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
    return choose_engine(requested, ctx=ctx)
