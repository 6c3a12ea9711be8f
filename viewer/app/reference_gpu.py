"""The GPU engine of the window's Reference view (``viewer.app.reference_view``): it shares the
window's GL context, so it runs on the GUI thread in time slices, one per frame (``update``):
bands of rows for the view's ``frame_budget_s`` (``step_for``), the image read back at most every
``READ_S``. Its samples go into the reference cache when the view changes or closes."""

from __future__ import annotations

import time

from viewer.reference_common.select import engine_options

READ_S = 0.25   # the GPU engine's image is read back at most this often


class GpuSlices:
    """The ``GpuReferenceRenderer`` of ``view`` (a ``ReferenceView``) on the GUI thread, and its
    cache key. What it renders goes into the view's image under ``view.lock``."""

    def __init__(self, view):
        self.view = view
        self.renderer = None     # GpuReferenceRenderer (engine "gpu")
        self.cache_key = None    # its cache key
        self.read_at = 0.0       # when its image was last read back
        self.samples = 0         # samples per pixel rendered since the view's key changed

    def update(self, fresh: bool, scene, camera, w, h) -> bool:
        """This frame's slice; ``fresh``: the view's key changed, the renderer is re-targeted (and
        resumed from the cache). False: the engine failed; the view's ``error`` says so and the
        renderer is gone (the caller falls back to the cpu engine)."""
        from viewer.image.variance import ConvergenceCurve, rmse_estimate

        v = self.view
        now = time.perf_counter()
        try:
            if fresh:
                self.store()
                if self.renderer is None:
                    from viewer.gpupt.engine import GpuReferenceRenderer

                    # spectral=None: wavelengths where a material is dispersive, as the cpu engine
                    self.renderer = GpuReferenceRenderer(scene, camera, w, h, max_depth=v.max_depth, ctx=v.ctx,
                                                         spectral=None, **engine_options(GpuReferenceRenderer, v.options))
                else:
                    self.renderer.reset(scene, camera, w, h, **engine_options(self.renderer.reset, v.options))
                from viewer.app.reference_cache import resume_cached

                self.cache_key, have = resume_cached(self.renderer, v.notice)
                with v.lock:
                    v.image = self.renderer.mean() if have else None
                    v.image_variance = self.renderer.variance() if have else None
                    v.image_spp = have
                    v.preview = False   # never the cpu engine's coarse first image
                    v.curve = ConvergenceCurve(v.options["strategy"])
                    v.version += 1
                v.error = ""
                v.started_at = now
                v.samples_per_second = 0.0
                self.samples = 0
                self.read_at = 0.0
            g = self.renderer
            self.samples += g.step_for(v.frame_budget_s)
            if v.ctx.screen is not None:   # leave the window's framebuffer bound, as the frame expects
                v.ctx.screen.use()
            elapsed = time.perf_counter() - v.started_at
            v.samples_per_second = self.samples / max(elapsed, 1e-9)
            if g.spp != v.image_spp and (now - self.read_at > READ_S or v.image is None):
                img, var = g.mean(), g.variance()
                with v.lock:
                    v.image, v.image_spp, v.image_variance = img, g.spp, var
                    v.curve.add(g.spp, rmse_estimate(var))
                    v.version += 1
                self.read_at = now
            return True
        except Exception as e:  # noqa: BLE001 - shown in the window; fall back to the CPU engine
            v.error = f"gpu reference failed ({type(e).__name__}: {e}); using the cpu engine"
            v.gpu_failed = f"{type(e).__name__}: {e}"
            v.version += 1
            self.drop(store=False)
            return False

    def store(self) -> None:
        """The renderer's samples into the reference cache (a cache that cannot be written is a
        notice of the view's)."""
        from viewer.app.reference_cache import store_samples

        store_samples(self.renderer, self.cache_key, "gpu", report=self.view.notice)

    def drop(self, store: bool = True) -> None:
        """Close the renderer (its samples stored first when ``store``)."""
        gpu, self.renderer = self.renderer, None
        if gpu is not None:
            if store:
                from viewer.app.reference_cache import store_samples

                try:
                    store_samples(gpu, self.cache_key, "gpu", report=self.view.notice)
                except Exception:  # noqa: BLE001 - a cache that cannot be written
                    pass
            gpu.close()
        self.cache_key = None
