"""The window's Reference view: the CPU path tracer renders progressively in a background
thread (its workers are processes, so the raster view stays interactive) and restarts whenever
the scene, a material, a light or the camera changes.

Lifecycle: one background thread for the life of the view, started on the first ``restart``.
``restart`` only posts the newest request (a snapshot of the scene and camera) and cancels the
job in progress; the thread picks the newest request up, re-targets its ``ReferenceRenderer``
(``reset`` keeps the worker processes) and renders until cancelled. So restarting never waits
for the thread in the GUI's frame, never runs two jobs at once on one renderer (a slow reset
of a large scene used to outlive ``stop``'s join timeout, after which a second thread shared
the renderer), and a thousand restarts leave one thread and one pool. A job that fails drops
its renderer, so the next request starts a fresh pool rather than a broken one. ``close`` ends
the thread, which closes the renderer and its worker processes.

Engines: ``engine="auto"`` (default) asks ``viewer.reference_common.select.choose_engine`` once (a
hardware GPU: gpu; software GL: the stored measurement, cpu when there is none). The GPU
engine shares the window's GL context, so it runs on the GUI thread in time slices:
``update`` renders bands of rows for ``frame_budget_s`` per frame (``step_for``) and reads the
image back at most every 0.25 s. Both engines start from the reference cache
(``viewer.reference_common.cache``) when it holds the view, and store their sums there when the view
changes or closes, so returning to a view, a lecture step or an earlier slider value shows the
stored image at once and keeps refining it.

The CPU engine renders passes of ``samples_per_chunk`` samples (4 at the window's sizes): a
1-spp pass costs nearly as much. ``version`` counts the images published (a pass, a restart,
a cached image, an error) and ``wake`` (when given) is called from the thread after each, so a
window that sleeps while nothing changes (``App.tick``) draws a new pass at once.
"""

from __future__ import annotations

import copy
import threading
import time
from typing import NamedTuple

import numpy as np


class ReferenceSnapshot(NamedTuple):
    """One published pass of the reference (``ReferenceView.snapshot``)."""
    mean: np.ndarray       # (H, W, 3) float32
    variance: np.ndarray   # variance of the mean, (H, W, 3) float32
    spp: int
    version: int           # ReferenceView.version when it was taken


def scene_key(scene, camera, size) -> str:
    """Everything the reference image depends on, as text (changes restart the render)."""
    from viewer.scene import scene_to_toml

    cam = (tuple(np.round(camera.position, 9)), tuple(np.round(camera.target, 9)), round(camera.fov_y, 9))
    return f"{scene_to_toml(scene)}|{cam}|{size}"


def _cached(renderer, report=None):
    """(cache key, spp resumed from the cache) for a renderer just (re)targeted. A damaged entry
    is set aside with one line through ``report`` and the view renders afresh."""
    from viewer.reference_common import cache

    key = cache.setup_key(renderer.setup)
    e = cache.load(key, shape=(renderer.height, renderer.width, 3), report=report)
    if e is not None:
        renderer.resume(e.sum, e.sum2, e.spp)
        return key, e.spp
    return key, 0


def _store(renderer, key, engine, seed=0, report=None):
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


PREVIEW_SPP = 4              # the coarse first image's samples per pixel, at a quarter of the resolution
PREVIEW_MIN_PIXELS = 64 * 64  # smaller views start with full passes at once (a pass is quick there)


class ReferenceView:
    def __init__(self, ctx, scale: float = 0.5, max_depth: int = 8, workers: int | None = None,
                 engine: str = "auto", frame_budget_s: float = 0.02, wake=None):
        self.ctx = ctx
        self.wake = wake          # called (from any thread) when a new image is published
        self.version = 0          # of the image shown: +1 per pass, restart, cached image, error            # texture_for_display and the GPU engine use it
        self.engine_request = engine
        self.engine = None        # "cpu" | "gpu" once chosen (first update)
        self.engine_reason = ""
        self.engine_note = ""     # why the scene shown takes another engine than ``engine`` (or none)
        self.gpu_failed = ""      # the gpu engine's failure, once it failed (the cpu engine from then on)
        self._engine_key = None   # (key, engine) of the last choice
        self.frame_budget_s = frame_budget_s
        self._gpu = None          # GpuReferenceRenderer on the GUI thread (engine "gpu")
        self._gpu_key = None      # its cache key
        self._gpu_read_at = 0.0
        self._gpu_samples = 0
        self.scale = scale
        self.max_depth = max_depth
        self.workers = workers
        self._key = None
        self._thread: threading.Thread | None = None
        self._cond = threading.Condition()
        self._request = None      # (generation, scene, camera, w, h): the job the thread runs next
        self._generation = 0      # of the newest request; older jobs publish nothing
        self._cancel = threading.Event()
        self._busy = False        # the thread is running a job
        self._closing = False
        self._lock = threading.Lock()
        self._renderer = None     # owned by the background thread
        self._image = None        # latest mean, (H, W, 3) float32
        self._image_spp = 0
        self._uploaded_spp = -1
        self.texture = None
        self.error = ""
        self.samples_per_second = 0.0
        self.started_at = 0.0
        self.preview = False      # the image shown is the coarse first one (quarter resolution)
        self.previews = 0         # coarse first images shown so far
        # the estimator (ReferenceRenderer's options); a change restarts the render
        self.options = {"strategy": "mis", "mis_heuristic": "power", "russian_roulette": True}
        self._variance = None     # latest variance of the mean, (H, W, 3) float32
        self.curve = None         # ConvergenceCurve of the current render (RMSE estimate per pass)
        self._notices: list[tuple[str, bool]] = []   # (line, error): cache repairs, failures (take_notices)
        self._said: set[str] = set()

    def notice(self, text: str, error: bool = False) -> None:
        """Queue one line for the window (any thread): a damaged cache entry set aside and
        rendered afresh, or (``error``) a cache that cannot be written; each distinct line once."""
        with self._lock:
            if text not in self._said:
                self._said.add(text)
                self._notices.append((text, bool(error)))
        self._published()

    def take_notices(self) -> list[tuple[str, bool]]:
        """The lines queued since the last call (the session shows each as a notification)."""
        with self._lock:
            out, self._notices = self._notices, []
        return out

    @property
    def spp(self) -> int:
        return self._image_spp

    @property
    def key(self):
        """Everything the current image depends on, as text (None while stopped or paused);
        a change of scene, camera, size or estimator option gives another key."""
        return self._key

    @property
    def busy(self) -> bool:
        """The background thread is running a CPU job."""
        return self._busy

    @property
    def has_thread(self) -> bool:
        """The background thread is alive (False before the first restart and after close)."""
        thread = self._thread
        return thread is not None and thread.is_alive()

    @property
    def active_engine(self):
        """The engine holding a renderer now: "gpu", "cpu", or None."""
        if self._gpu is not None:
            return "gpu"
        return "cpu" if self._renderer is not None else None

    @property
    def setup(self):
        """The ``RenderSetup`` of the renderer the view holds (its scene, camera, estimator
        options), or None before the first job."""
        renderer = self._gpu if self._gpu is not None else self._renderer
        return None if renderer is None else renderer.setup

    def samples_per_chunk(self):
        """Samples per pixel of one pass of the CPU engine (None when it holds no renderer)."""
        renderer = self._renderer
        return None if renderer is None else renderer.samples_per_chunk()

    def worker_pids(self) -> list[int]:
        """Process ids of the CPU engine's worker processes (none without a pool)."""
        renderer = self._renderer
        return [] if renderer is None else renderer.worker_pids()

    @property
    def needs_frames(self) -> bool:
        """The GPU engine renders in the GUI's frames: the window must not sleep."""
        return self._gpu is not None

    def _published(self):
        """A new image (or error) to show: count it and wake the window."""
        self.version += 1
        if self.wake is not None:
            try:
                self.wake()
            except Exception:  # noqa: BLE001 - a window already gone
                pass

    def update(self, scene, camera, viewport_size, defer: bool = False):
        """Restart when anything the image depends on changed; called once per frame.
        ``defer`` (the user is dragging the camera or a slider): a change cancels the CPU
        engine's job and clears its image, and the restart waits for a frame without ``defer``;
        a restart per dragged frame would never finish a pass and keeps both cores from the
        window (gallery: 463 ms frames while orbiting)."""
        w = max(1, int(viewport_size[0] * self.scale))
        h = max(1, int(viewport_size[1] * self.scale))
        key = f"{scene_key(scene, camera, (w, h))}|{sorted(self.options.items())}"
        if self.engine is None:
            self._choose_engine()
        engine = self.engine_for(scene, key)
        if engine == "gpu":
            self._cancel.set()   # a cpu job stops (its samples are stored)
            self._gpu_update(key, scene, camera, w, h)
            return
        self._drop_gpu()
        if engine is None:   # neither engine renders it: the reason stands in the view
            if key != self._key:
                self.pause()
                self._key = key
                self.error = self.engine_note
                self.version += 1
            return
        if key != self._key:
            if defer:
                self.pause()
                return
            self._key = key
            self.restart(scene, camera, w, h)

    def engine_for(self, scene, key=None):
        """The engine that renders ``scene`` ("cpu", "gpu", or None: neither can), decided once per
        key. What only the cpu engine renders (viewer/reference_common/refusals.py) takes it; under ``auto``,
        a ``.brdf`` file material without a numpy twin the cpu engine may run takes the gpu engine
        (``select.without_twin``), as on the command line. ``engine_note`` says why, or is empty.
        ``key``: the view's key, which the choice is kept under (None: chosen afresh)."""
        if self.engine is None:
            self._choose_engine()
        if key is not None and self._engine_key is not None and self._engine_key[0] == key:
            return self._engine_key[1]
        engine, note = self.engine, ""
        if engine == "gpu":
            from viewer.reference_common.refusals import cpu_only

            limit = cpu_only(scene)
            if limit is not None:
                engine, note = "cpu", limit.reason
        elif self.engine_request == "auto" and self.ctx is not None:
            from viewer.reference_common.select import without_twin

            why = without_twin(scene)
            if why is not None and self.gpu_failed:
                engine = None
                note = (f"no reference: the cpu engine has no numpy twin to run and the gpu engine "
                        f"failed ({self.gpu_failed})")
            elif why is not None:
                engine, note = "gpu", "a .brdf file without a numpy twin: the gpu engine runs its GLSL"
        self._engine_key = (key, engine)
        self.engine_note = note
        return engine

    def pause(self):
        """Cancel the job in progress and show no image until the next restart (returns at once)."""
        if self._key is None and self._image is None:
            return
        from viewer.variance import ConvergenceCurve

        with self._cond:
            self._request = None
            self._generation += 1
            self._cancel.set()
            self._key = None
            with self._lock:
                self._image, self._image_spp, self._variance = None, 0, None
                self.preview = False
                self.curve = ConvergenceCurve(self.options["strategy"])
                self.version += 1
            self.samples_per_second = 0.0

    def _choose_engine(self):
        if self.ctx is None:    # no GL context to share: the CPU engine
            self.engine, self.engine_reason = "cpu", "no OpenGL context"
            return
        try:
            from viewer.reference_common.select import choose_engine

            self.engine, self.engine_reason = choose_engine(self.engine_request, ctx=self.ctx)
        except Exception as e:  # noqa: BLE001 - the CPU engine always works
            self.engine, self.engine_reason = "cpu", f"gpu engine unavailable: {e}"

    # ------------------------------------------------------------------ GPU engine (GUI thread)
    def _gpu_update(self, key, scene, camera, w, h):
        now = time.perf_counter()
        try:
            if key != self._key:
                self._key = key
                _store(self._gpu, self._gpu_key, "gpu", report=self.notice)
                if self._gpu is None:
                    from viewer.gpupt.engine import GpuReferenceRenderer

                    # spectral=None: wavelengths where a material is dispersive, as the cpu engine
                    self._gpu = GpuReferenceRenderer(scene, camera, w, h, max_depth=self.max_depth, ctx=self.ctx,
                                                     spectral=None, **self.options)
                else:
                    self._gpu.reset(scene, camera, w, h, **self.options)
                self._gpu_key, have = _cached(self._gpu, self.notice)
                from viewer.variance import ConvergenceCurve

                with self._lock:
                    self._image = self._gpu.mean() if have else None
                    self._variance = self._gpu.variance() if have else None
                    self._image_spp = have
                    self.curve = ConvergenceCurve(self.options["strategy"])
                    self.version += 1
                self.error = ""
                self.started_at = now
                self.samples_per_second = 0.0
                self._gpu_samples = 0
                self._gpu_read_at = 0.0
            self._gpu_samples += self._gpu.step_for(self.frame_budget_s)
            if self.ctx.screen is not None:   # leave the window's framebuffer bound, as the frame expects
                self.ctx.screen.use()
            elapsed = time.perf_counter() - self.started_at
            self.samples_per_second = self._gpu_samples / max(elapsed, 1e-9)
            if self._gpu.spp != self._image_spp and (now - self._gpu_read_at > 0.25 or self._image is None):
                from viewer.variance import rmse_estimate

                img, var = self._gpu.mean(), self._gpu.variance()
                with self._lock:
                    self._image, self._image_spp, self._variance = img, self._gpu.spp, var
                    self.curve.add(self._gpu.spp, rmse_estimate(var))
                    self.version += 1
                self._gpu_read_at = now
        except Exception as e:  # noqa: BLE001 - shown in the window; fall back to the CPU engine
            self.error = f"gpu reference failed ({type(e).__name__}: {e}); using the cpu engine"
            self.gpu_failed = f"{type(e).__name__}: {e}"
            self.version += 1
            self._drop_gpu(store=False)
            self.engine, self._key, self._engine_key = "cpu", None, None

    def _drop_gpu(self, store=True):
        gpu, self._gpu = self._gpu, None
        if gpu is not None:
            if store:
                try:
                    _store(gpu, self._gpu_key, "gpu", report=self.notice)
                except Exception:  # noqa: BLE001 - a cache that cannot be written
                    pass
            gpu.close()
        self._gpu_key = None

    def restart(self, scene, camera, w, h):
        """Render ``scene`` seen by ``camera`` at w x h from now on (the current job is
        cancelled; returns at once)."""
        snapshot = copy.deepcopy(scene)  # the GUI keeps editing its own copy
        cam = copy.deepcopy(camera)
        from viewer.variance import ConvergenceCurve

        with self._cond:
            if self._closing:
                return
            self._generation += 1
            self._request = (self._generation, snapshot, cam, int(w), int(h), dict(self.options))
            self._cancel.set()
            with self._lock:
                self._image, self._image_spp, self._variance = None, 0, None
                self.preview = False
                self.curve = ConvergenceCurve(self.options["strategy"])
                self.version += 1
            self.error = ""
            self.samples_per_second = 0.0
            self.started_at = time.perf_counter()
            self._cond.notify_all()
            if self._thread is None or not self._thread.is_alive():
                self._thread = threading.Thread(target=self._loop, name="reference", daemon=True)
                self._thread.start()

    # ------------------------------------------------------------------ background thread
    def _loop(self):
        try:
            while True:
                with self._cond:
                    self._busy = False
                    self._cond.notify_all()
                    while self._request is None and not self._closing:
                        self._cond.wait()
                    if self._closing:
                        return
                    gen, scene, camera, w, h, options = self._request
                    self._request = None
                    self._cancel.clear()  # a later restart sets it again
                    self._busy = True
                self._job(gen, scene, camera, w, h, options)
                del scene, camera
        finally:
            self._drop_renderer()
            with self._cond:
                self._busy = False
                self._cond.notify_all()

    def _current(self, gen) -> bool:
        return gen == self._generation and not self._cancel.is_set()

    def _job(self, gen, scene, camera, w, h, options):
        from viewer import ViewerError
        from viewer.pathtracer import ReferenceRenderer
        from viewer.variance import rmse_estimate

        cancel = self._cancel
        try:
            if self._renderer is not None:
                self._renderer.reset(scene, camera=camera, width=w, height=h, **options)  # keeps its workers
            else:
                self._renderer = ReferenceRenderer(scene, camera=camera, width=w, height=h,
                                                   max_depth=self.max_depth, workers=self.workers, **options)
            r = self._renderer
            key, have = _cached(r, self.notice)
            if have:
                img, var = r.mean(), r.variance()
                with self._lock:
                    if self._current(gen):
                        self._image, self._image_spp, self._variance = img, r.spp, var
                        self._published()
            elif w * h >= PREVIEW_MIN_PIXELS:
                # nothing cached: a coarse image first (a quarter of the resolution, PREVIEW_SPP),
                # in a twentieth of a full pass's time, so the view opens on a converging image
                # rather than an empty one; shown as a preview (0 spp, no variance: no metrics,
                # no error views), then the passes at full resolution start from nothing
                r.reset(scene, camera=camera, width=max(1, w // 4), height=max(1, h // 4), **options)
                r.step(PREVIEW_SPP, cancel)
                img = r.mean()
                with self._lock:
                    if self._current(gen):
                        self._image, self._image_spp, self._variance = img, 0, None
                        self.preview = True
                        self.previews += 1
                        self._published()
                r.reset(scene, camera=camera, width=w, height=h, **options)
                if cancel.is_set():
                    return
            # passes of the samples that fill a chunk: a pass of 1 spp runs chunks of a quarter of
            # the paths at nearly the same cost (gallery, 460 x 360: 66 k against 259 k samples/s)
            per_pass = r.samples_per_chunk()
            try:
                while not cancel.is_set():
                    if not r.step(per_pass, cancel):
                        break
                    img, var = r.mean(), r.variance()
                    with self._lock:
                        if self._current(gen):
                            self._image, self._image_spp, self._variance = img, r.spp, var
                            self.preview = False
                            self.curve.add(r.spp, rmse_estimate(var))
                            elapsed = time.perf_counter() - self.started_at
                            self.samples_per_second = (r.spp - have) * w * h / max(elapsed, 1e-9)
                            self._published()
            finally:
                if r.spp > have:
                    _store(r, key, "cpu", report=self.notice)
        except ViewerError as e:
            self._fail(gen, str(e))
        except Exception as e:  # noqa: BLE001 - shown in the window; the raster view keeps running
            self._fail(gen, f"reference failed: {type(e).__name__}: {e}")

    def _fail(self, gen, message):
        # The renderer may be half-reset or its pool broken (a worker killed): start afresh next time.
        self._drop_renderer()
        if gen == self._generation:
            self.error = message
            self._published()

    def _drop_renderer(self):
        """Close the renderer and its worker processes (background thread only)."""
        renderer, self._renderer = self._renderer, None
        if renderer is not None:
            try:
                renderer.close()
            except Exception:  # noqa: BLE001 - closing a broken pool
                pass

    # ------------------------------------------------------------------ GUI side
    def latest(self):
        """(image (H, W, 3) float32, spp) of the newest pass, or None before the first."""
        with self._lock:
            if self._image is None:
                return None
            return self._image, self._image_spp

    def snapshot(self):
        """The newest pass as one ``ReferenceSnapshot`` (mean, variance of the mean, spp,
        version), or None before the first. Its arrays are never written again (each pass
        publishes new ones), so everything computed from one snapshot agrees with itself while
        the background job keeps adding passes: take one and hand it to every consumer."""
        with self._lock:
            if self._image is None or self._variance is None:
                return None
            return ReferenceSnapshot(self._image, self._variance, self._image_spp, self.version)

    def latest_variance(self):
        """(mean, variance of the mean, spp) of the newest pass, or None before the first."""
        s = self.snapshot()
        return None if s is None else (s.mean, s.variance, s.spp)

    def texture_for_display(self):
        """The latest image as a float texture (None until the first pass is done)."""
        with self._lock:
            img, spp = self._image, self._image_spp
        if img is None:
            return None
        if spp != self._uploaded_spp or self.texture is None or self.texture.size != (img.shape[1], img.shape[0]):
            from viewer.app.compare_view import upload_rgb

            self.texture = upload_rgb(self.ctx, self.texture, img)
            self._uploaded_spp = spp
        return self.texture

    def stop(self, timeout: float = 5.0) -> bool:
        """Cancel the job in progress and forget any pending request (the workers go idle; the
        next ``update`` with a changed key starts again). Waits up to ``timeout`` seconds for
        the thread to go idle; True when it did."""
        with self._cond:
            self._request = None
            self._generation += 1
            self._cancel.set()
            self._key = None
            if self._gpu is not None:
                _store(self._gpu, self._gpu_key, "gpu", report=self.notice)
            return self._cond.wait_for(lambda: not self._busy, timeout=timeout)

    def close(self, timeout: float | None = None, keep_programs: bool = False):
        """End the background thread (it closes the renderer and its worker processes) and
        release the texture. Waits for the thread (``timeout`` None: until it has ended).
        ``keep_programs`` keeps the GPU engine's compiled programs cached on the context
        for other views sharing it (the notebook's widgets)."""
        with self._cond:
            self._closing = True
            self._request = None
            self._generation += 1
            self._cancel.set()
            self._cond.notify_all()
            thread = self._thread
        if thread is not None and thread is not threading.current_thread():
            thread.join(timeout)
            if not thread.is_alive():
                self._thread = None
        self._drop_gpu()
        if self.engine == "gpu" and not keep_programs:
            from viewer.gpupt.engine import release_programs

            release_programs(self.ctx)
        if self.texture is not None:
            self.texture.release()
            self.texture = None
