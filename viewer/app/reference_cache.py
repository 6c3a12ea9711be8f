"""The reference cache (``viewer.reference_common.cache``) as the window's Reference view uses it:
both of its engines (``reference_cpu.CpuThread``, ``reference_gpu.GpuSlices``) resume a view
from it and store their samples into it."""

from __future__ import annotations


def resume_cached(renderer, report=None):
    """(cache key, spp resumed from the cache) for a renderer just (re)targeted. A damaged entry
    is set aside with one line through ``report`` and the view renders afresh."""
    from viewer.reference_common import cache

    key = cache.setup_key(renderer.setup)
    e = cache.load(key, shape=(renderer.height, renderer.width, 3), report=report)
    if e is not None:
        renderer.resume(e.sum, e.sum2, e.spp)
        return key, e.spp
    return key, 0


def store_samples(renderer, key, engine, seed=0, report=None):
    """Put a renderer's samples into the cache (when it has any and more than stored); a cache
    that cannot be written is said through ``report(line, error=True)``."""
    if renderer is None or key is None or renderer.spp < 1:
        return
    from viewer.reference_common import cache

    state = renderer.state()
    if state is not None:
        try:
            cache.store(key, cache.Entry(*state, engine, seed), report=report)
        except cache.CacheError as e:
            if report is None:
                raise
            report(str(e), error=True)
