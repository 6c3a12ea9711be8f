"""The CPU reference path tracer. It never imports GL. The scene's triangle soup and its BVH
are in ``viewer.geometry`` (shared with the rasterizer and the GPU engine); what it shares with
the GPU engine (the interface, the setup, the environment light, the cache) in ``viewer.reference_common``.

* ``kernel_embree``  ray queries with Embree (``EmbreeKernel``); ``kernel_numba`` the same
                     interface without Embree (``NumbaKernel``)
* ``integrator``     wavefront path tracing in numpy (NEE, MIS, Russian roulette, Bouguer)
* ``compiled``       numba stand-ins for its hot steps, each tested against its numpy twin
* ``fused``          the whole bounce in one compiled loop, for scenes whose every step has a
                     compiled stand-in (the same estimator and random numbers)
* ``progressive``    ``ReferenceRenderer``: deterministic progressive accumulation on a
                     process pool, cancellable

Typical use::

    from viewer.pathtracer import ReferenceRenderer
    r = ReferenceRenderer(scene, width=128, height=128, max_depth=8, seed=0)
    r.step(64)                     # 64 samples per pixel
    img, var = r.mean(), r.variance()
    r.close()
"""

from viewer.pathtracer.progressive import ReferenceRenderer

__all__ = ["ReferenceRenderer"]
