"""The CPU engine of the window's Reference view (``viewer.app.reference_view``): one background
thread that runs the newest request on one ``ReferenceRenderer``, whose workers are processes,
so the raster view stays interactive.

Contracts (``CpuThread``): one thread for the life of the view, started by the first ``start``;
``post`` only leaves the newest request and cancels the job in progress, and a job of an older
generation publishes nothing (the newest request wins); the thread re-targets its renderer
(``reset`` keeps the worker processes), so two jobs never share one renderer; a job that fails
drops its renderer, so the next request starts a fresh pool rather than a broken one; ``close``
ends the thread, which closes the renderer and its worker processes."""

from __future__ import annotations

import threading
import time

#: the worker processes' niceness over the window's: the window's frames first (with the split
#: view of lecture step 14 rendering at the window's priority, a frame of the window's with 15 ms
#: of its own CPU took 130-180 ms, and a tile of 30 ms took 55-150 ms), the reference in the time
#: they leave, which is all of it once the view settles
REFERENCE_NICE = 10
PREVIEW_SPP = 4              # the coarse first image's samples per pixel, at a quarter of the resolution
PREVIEW_MIN_PIXELS = 64 * 64  # smaller views start with full passes at once (a pass is quick there)


class CpuThread:
    """The background thread of ``view`` (a ``ReferenceView``) and the renderer it owns. What the
    thread publishes goes into the view's image under ``view.lock`` (``view.published`` counts it
    and wakes the window). ``cond`` guards ``request``, ``generation``, ``busy`` and ``closing``."""

    def __init__(self, view):
        self.view = view
        self.thread: threading.Thread | None = None
        self.cond = threading.Condition()
        self.request = None      # (generation, scene, camera, w, h, options): the job the thread runs next
        self.generation = 0      # of the newest request; older jobs publish nothing
        self.cancel = threading.Event()
        self.busy = False        # the thread is running a job
        self.closing = False
        self.renderer = None     # owned by the background thread

    @property
    def alive(self) -> bool:
        """The thread is alive (False before the first ``start`` and after ``close``)."""
        thread = self.thread
        return thread is not None and thread.is_alive()

    def forget(self) -> None:
        """Under ``cond``: no request pending, and the job in progress cancelled (it publishes
        nothing more)."""
        self.request = None
        self.generation += 1
        self.cancel.set()

    def post(self, scene, camera, w, h, options) -> None:
        """Under ``cond``: the job to run next (the one in progress is cancelled)."""
        self.generation += 1
        self.request = (self.generation, scene, camera, int(w), int(h), options)
        self.cancel.set()

    def start(self) -> None:
        """Under ``cond``: wake the thread for the request posted, starting it the first time."""
        self.cond.notify_all()
        if self.thread is None or not self.thread.is_alive():
            self.thread = threading.Thread(target=self.loop, name="reference", daemon=True)
            self.thread.start()

    def close(self, timeout: float | None = None) -> None:
        """End the thread (it closes the renderer and its worker processes); waits for it
        (``timeout`` None: until it has ended)."""
        with self.cond:
            self.closing = True
            self.forget()
            self.cond.notify_all()
            thread = self.thread
        if thread is not None and thread is not threading.current_thread():
            thread.join(timeout)
            if not thread.is_alive():
                self.thread = None

    # ------------------------------------------------------------------ the thread
    def loop(self):
        """The thread's body: the newest request, job after job, until ``close``."""
        try:
            while True:
                with self.cond:
                    self.busy = False
                    self.cond.notify_all()
                    while self.request is None and not self.closing:
                        self.cond.wait()
                    if self.closing:
                        return
                    gen, scene, camera, w, h, options = self.request
                    self.request = None
                    self.cancel.clear()  # a later restart sets it again
                    self.busy = True
                self.job(gen, scene, camera, w, h, options)
                del scene, camera
        finally:
            self.drop_renderer()
            with self.cond:
                self.busy = False
                self.cond.notify_all()

    def current(self, gen) -> bool:
        return gen == self.generation and not self.cancel.is_set()

    def job(self, gen, scene, camera, w, h, options):
        """Render one request until cancelled: the cached image or a coarse preview first, then
        passes of the samples that fill a chunk, each published; the samples are stored."""
        from viewer import ViewerError
        from viewer.app.reference_cache import resume_cached, store_samples
        from viewer.pathtracer import ReferenceRenderer
        from viewer.image.variance import rmse_estimate

        v, cancel = self.view, self.cancel
        try:
            if self.renderer is not None:
                self.renderer.reset(scene, camera=camera, width=w, height=h, **options)  # keeps its workers
            else:
                self.renderer = ReferenceRenderer(scene, camera=camera, width=w, height=h,
                                                  max_depth=v.max_depth, workers=v.workers, pool="processes",
                                                  nice=REFERENCE_NICE, **options)   # processes: the GUI thread never waits for the GIL
            r = self.renderer
            key, have = resume_cached(r, v.notice)
            if have:
                img, var = r.mean(), r.variance()
                with v.lock:
                    if self.current(gen):
                        v.image, v.image_spp, v.image_variance = img, r.spp, var
                        v.published()
            elif w * h >= PREVIEW_MIN_PIXELS:
                # nothing cached: a coarse image first (a quarter of the resolution, PREVIEW_SPP),
                # in a twentieth of a full pass's time, so the view opens on a converging image
                # rather than an empty one; shown as a preview (0 spp, no variance: no metrics,
                # no error views), then the passes at full resolution start from nothing
                r.reset(scene, camera=camera, width=max(1, w // 4), height=max(1, h // 4), **options)
                r.step(PREVIEW_SPP, cancel)
                img = r.mean()
                with v.lock:
                    if self.current(gen):
                        v.image, v.image_spp, v.image_variance = img, 0, None
                        v.preview = True
                        v.previews += 1
                        v.published()
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
                    with v.lock:
                        if self.current(gen):
                            v.image, v.image_spp, v.image_variance = img, r.spp, var
                            v.preview = False
                            v.curve.add(r.spp, rmse_estimate(var))
                            elapsed = time.perf_counter() - v.started_at
                            v.samples_per_second = (r.spp - have) * w * h / max(elapsed, 1e-9)
                            v.published()
            finally:
                if r.spp > have:
                    store_samples(r, key, "cpu", report=v.notice)
        except ViewerError as e:
            self.fail(gen, str(e))
        except Exception as e:  # noqa: BLE001 - shown in the window; the raster view keeps running
            self.fail(gen, f"reference failed: {type(e).__name__}: {e}")

    def fail(self, gen, message):
        # The renderer may be half-reset or its pool broken (a worker killed): start afresh next time.
        self.drop_renderer()
        if gen == self.generation:
            self.view.error = message
            self.view.published()

    def drop_renderer(self):
        """Close the renderer and its worker processes (background thread only)."""
        renderer, self.renderer = self.renderer, None
        if renderer is not None:
            try:
                renderer.close()
            except Exception:  # noqa: BLE001 - closing a broken pool
                pass
