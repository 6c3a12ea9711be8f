"""The GPU reference engine (OpenGL 4.1 fragment passes): the CPU engine's estimator in GLSL.

``GpuReferenceRenderer`` (``engine.py``) has the interface ``viewer.reference_common.estimator.ReferenceEngine``;
``viewer.reference_common.select`` picks cpu or gpu and makes either."""

from viewer.gpupt.engine import GpuReferenceRenderer

__all__ = ["GpuReferenceRenderer"]
