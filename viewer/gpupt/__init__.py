"""The GPU reference engine (OpenGL 4.1 fragment passes): the CPU engine's estimator in GLSL.

``GpuReferenceRenderer`` (``engine.py``) has the interface of
``viewer.pathtracer.ReferenceRenderer``; ``choose_engine`` (``select.py``) picks cpu or gpu."""

from viewer.gpupt.engine import GpuReferenceRenderer

__all__ = ["GpuReferenceRenderer"]
