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

``ReferenceView`` holds the image shown, its key, the engine choice and this interface; each
engine is a part of its own that it holds and passes itself to: ``cpu``
(``viewer.app.reference_cpu.CpuThread``: the background thread and its renderer) and ``gpu``
(``viewer.app.reference_gpu.GpuSlices``: the GUI thread's time slices); both resume from and
store into the cache through ``viewer.app.reference_cache``.
"""

from __future__ import annotations

import copy
import threading
import time
from typing import NamedTuple

import numpy as np

from viewer.app.reference_cpu import CpuThread
from viewer.app.reference_gpu import GpuSlices


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


class ReferenceView:
    """The reference image of the window's view: the engine that renders it (``cpu`` or ``gpu``),
    restarted whenever its key changes (``update``, once per frame). The engines write the image
    (``image``, ``image_spp``, ``image_variance``, ``preview``, ``curve``) under ``lock``; the
    GUI reads it through ``latest``, ``snapshot`` and ``texture_for_display``."""

    def __init__(self, ctx, scale: float = 0.5, max_depth: int = 8, workers: int | None = None,
                 engine: str = "auto", frame_budget_s: float = 0.02, wake=None):
        self.ctx = ctx            # texture_for_display and the GPU engine use it
        self.wake = wake          # called (from any thread) when a new image is published
        self.version = 0          # of the image shown: +1 per pass, restart, cached image, error
        self.engine_request = engine
        self.engine = None        # "cpu" | "gpu" once chosen (first update)
        self.engine_reason = ""
        self.engine_note = ""     # why the scene shown takes another engine than ``engine`` (or none)
        self.gpu_failed = ""      # the gpu engine's failure, once it failed (the cpu engine from then on)
        self._engine_key = None   # (key, engine) of the last choice
        self.frame_budget_s = frame_budget_s
        self.gpu = GpuSlices(self)   # the GPU engine's renderer, on the GUI thread
        self.cpu = CpuThread(self)   # the CPU engine's background thread and its renderer
        self.scale = scale
        self.max_depth = max_depth
        self.workers = workers
        self._key = None
        # the image shown, written by the engines under ``lock``: the latest mean, (H, W, 3)
        # float32, its samples per pixel and the variance of the mean, (H, W, 3) float32
        self.lock = threading.Lock()
        self.image = None
        self.image_spp = 0
        self.image_variance = None
        self._uploaded_spp = -1
        self.texture = None
        self.error = ""
        self.samples_per_second = 0.0
        self.started_at = 0.0
        self.preview = False      # the image shown is the coarse first one (quarter resolution)
        self.previews = 0         # coarse first images shown so far
        # the estimator (ReferenceRenderer's options); a change restarts the render
        # integrator "auto": path tracing, or with a caustic photon map where the scene has smooth
        # surfaces under small lights (caustics.choose_integrator), as on the command line
        self.options = {"strategy": "mis", "mis_heuristic": "power", "russian_roulette": True, "integrator": "auto"}
        self.curve = None         # ConvergenceCurve of the current render (RMSE estimate per pass)
        self._notices: list[tuple[str, bool]] = []   # (line, error): cache repairs, failures (take_notices)
        self._said: set[str] = set()

    def notice(self, text: str, error: bool = False) -> None:
        """Queue one line for the window (any thread): a damaged cache entry set aside and
        rendered afresh, or (``error``) a cache that cannot be written; each distinct line once."""
        with self.lock:
            if text not in self._said:
                self._said.add(text)
                self._notices.append((text, bool(error)))
        self.published()

    def take_notices(self) -> list[tuple[str, bool]]:
        """The lines queued since the last call (the session shows each as a notification)."""
        with self.lock:
            out, self._notices = self._notices, []
        return out

    @property
    def spp(self) -> int:
        return self.image_spp

    @property
    def key(self):
        """Everything the current image depends on, as text (None while stopped or paused);
        a change of scene, camera, size or estimator option gives another key."""
        return self._key

    @property
    def busy(self) -> bool:
        """The background thread is running a CPU job."""
        return self.cpu.busy

    @property
    def has_thread(self) -> bool:
        """The background thread is alive (False before the first restart and after close)."""
        return self.cpu.alive

    @property
    def active_engine(self):
        """The engine holding a renderer now: "gpu", "cpu", or None."""
        if self.gpu.renderer is not None:
            return "gpu"
        return "cpu" if self.cpu.renderer is not None else None

    @property
    def setup(self):
        """The ``RenderSetup`` of the renderer the view holds (its scene, camera, estimator
        options), or None before the first job."""
        renderer = self.gpu.renderer if self.gpu.renderer is not None else self.cpu.renderer
        return None if renderer is None else renderer.setup

    @property
    def estimator_label(self) -> str:
        """The integrator of the reference shown, in words ("path tracing", "path tracing + caustic
        photon map"; empty before the first job)."""
        from viewer.reference_common.caustics import INTEGRATOR_LABELS

        setup = self.setup
        return "" if setup is None else INTEGRATOR_LABELS.get(setup.integrator, setup.integrator)

    def samples_per_chunk(self):
        """Samples per pixel of one pass of the CPU engine (None when it holds no renderer)."""
        renderer = self.cpu.renderer
        return None if renderer is None else renderer.samples_per_chunk()

    def worker_pids(self) -> list[int]:
        """Process ids of the CPU engine's worker processes (none without a pool)."""
        renderer = self.cpu.renderer
        return [] if renderer is None else renderer.worker_pids()

    @property
    def needs_frames(self) -> bool:
        """The GPU engine renders in the GUI's frames: the window must not sleep."""
        return self.gpu.renderer is not None

    def published(self):
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
            self.cpu.cancel.set()   # a cpu job stops (its samples are stored)
            fresh, self._key = key != self._key, key
            if not self.gpu.update(fresh, scene, camera, w, h):   # the gpu engine failed: the cpu one
                self.engine, self._key, self._engine_key = "cpu", None, None
            return
        self.gpu.drop()
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
        if self._key is None and self.image is None:
            return
        with self.cpu.cond:
            self.cpu.forget()
            self._key = None
            self.clear_image()
            self.samples_per_second = 0.0

    def clear_image(self):
        """No image shown (none, 0 spp, not a preview) and a new convergence curve."""
        from viewer.image.variance import ConvergenceCurve

        with self.lock:
            self.image, self.image_spp, self.image_variance = None, 0, None
            self.preview = False
            self.curve = ConvergenceCurve(self.options["strategy"])
            self.version += 1

    def _choose_engine(self):
        if self.ctx is None:    # no GL context to share: the CPU engine
            self.engine, self.engine_reason = "cpu", "no OpenGL context"
            return
        try:
            from viewer.reference_common.select import choose_engine

            self.engine, self.engine_reason = choose_engine(self.engine_request, ctx=self.ctx)
        except Exception as e:  # noqa: BLE001 - the CPU engine always works
            self.engine, self.engine_reason = "cpu", f"gpu engine unavailable: {e}"

    def restart(self, scene, camera, w, h):
        """Render ``scene`` seen by ``camera`` at w x h from now on (the current job is
        cancelled; returns at once)."""
        snapshot = copy.deepcopy(scene)  # the GUI keeps editing its own copy
        cam = copy.deepcopy(camera)
        cpu = self.cpu
        with cpu.cond:
            if cpu.closing:
                return
            cpu.post(snapshot, cam, w, h, dict(self.options))
            self.clear_image()
            self.error = ""
            self.samples_per_second = 0.0
            self.started_at = time.perf_counter()
            cpu.start()

    # ------------------------------------------------------------------ GUI side
    def latest(self):
        """(image (H, W, 3) float32, spp) of the newest pass, or None before the first."""
        with self.lock:
            if self.image is None:
                return None
            return self.image, self.image_spp

    def snapshot(self):
        """The newest pass as one ``ReferenceSnapshot`` (mean, variance of the mean, spp,
        version), or None before the first. Its arrays are never written again (each pass
        publishes new ones), so everything computed from one snapshot agrees with itself while
        the background job keeps adding passes: take one and hand it to every consumer."""
        with self.lock:
            if self.image is None or self.image_variance is None:
                return None
            return ReferenceSnapshot(self.image, self.image_variance, self.image_spp, self.version)

    def latest_variance(self):
        """(mean, variance of the mean, spp) of the newest pass, or None before the first."""
        s = self.snapshot()
        return None if s is None else (s.mean, s.variance, s.spp)

    def texture_for_display(self):
        """The latest image as a float texture (None until the first pass is done)."""
        with self.lock:
            img, spp = self.image, self.image_spp
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
        cpu = self.cpu
        with cpu.cond:
            cpu.forget()
            self._key = None
            if self.gpu.renderer is not None:
                self.gpu.store()
            return cpu.cond.wait_for(lambda: not cpu.busy, timeout=timeout)

    def close(self, timeout: float | None = None, keep_programs: bool = False):
        """End the background thread (it closes the renderer and its worker processes) and
        release the texture. Waits for the thread (``timeout`` None: until it has ended).
        ``keep_programs`` keeps the GPU engine's compiled programs cached on the context
        for other views sharing it (the notebook's widgets)."""
        self.cpu.close(timeout)
        self.gpu.drop()
        if self.engine == "gpu" and not keep_programs:
            from viewer.gpupt.engine import release_programs

            release_programs(self.ctx)
        if self.texture is not None:
            self.texture.release()
            self.texture = None
