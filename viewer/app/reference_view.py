"""The window's Reference view: the CPU path tracer renders progressively in a background
thread (its workers are processes, so the raster view stays interactive) and restarts whenever
the scene, a material, a light or the camera changes."""

from __future__ import annotations

import copy
import threading
import time

import numpy as np


def scene_key(scene, camera, size) -> str:
    """Everything the reference image depends on, as text (changes restart the render)."""
    from viewer.scene import scene_to_toml

    cam = (tuple(np.round(camera.position, 9)), tuple(np.round(camera.target, 9)), round(camera.fov_y, 9))
    return f"{scene_to_toml(scene)}|{cam}|{size}"


class ReferenceView:
    def __init__(self, ctx, scale: float = 0.5, max_depth: int = 8, workers: int | None = None):
        self.ctx = ctx
        self.scale = scale
        self.max_depth = max_depth
        self.workers = workers
        self._key = None
        self._thread = None
        self._cancel = threading.Event()
        self._lock = threading.Lock()
        self._renderer = None
        self._image = None        # latest mean, (H, W, 3) float32
        self._image_spp = 0
        self._uploaded_spp = -1
        self.texture = None
        self.error = ""
        self.samples_per_second = 0.0
        self.started_at = 0.0

    @property
    def spp(self) -> int:
        return self._image_spp

    def update(self, scene, camera, viewport_size):
        """Restart when anything the image depends on changed; called once per frame."""
        w = max(1, int(viewport_size[0] * self.scale))
        h = max(1, int(viewport_size[1] * self.scale))
        key = scene_key(scene, camera, (w, h))
        if key != self._key:
            self._key = key
            self.restart(scene, camera, w, h)

    def restart(self, scene, camera, w, h):
        self.stop()
        snapshot = copy.deepcopy(scene)  # the GUI keeps editing its own copy
        cam = copy.deepcopy(camera)
        self._cancel = threading.Event()
        self._image, self._image_spp = None, 0
        self.error = ""
        self.started_at = time.perf_counter()
        self._thread = threading.Thread(target=self._run, args=(snapshot, cam, w, h, self._cancel),
                                        name="reference", daemon=True)
        self._thread.start()

    def _run(self, scene, camera, w, h, cancel):
        from viewer import ViewerError
        from viewer.pathtracer import ReferenceRenderer

        try:
            if self._renderer is not None and hasattr(self._renderer, "reset"):
                self._renderer.reset(scene, camera=camera, width=w, height=h)  # keeps its workers
            else:
                if self._renderer is not None:
                    self._renderer.close()
                self._renderer = ReferenceRenderer(scene, camera=camera, width=w, height=h,
                                                   max_depth=self.max_depth, workers=self.workers)
            r = self._renderer
            while not cancel.is_set():
                if not r.step(1, cancel):
                    break
                img = r.mean()
                with self._lock:
                    if not cancel.is_set():
                        self._image, self._image_spp = img, r.spp
                        elapsed = time.perf_counter() - self.started_at
                        self.samples_per_second = r.spp * w * h / max(elapsed, 1e-9)
        except ViewerError as e:
            self.error = str(e)
        except Exception as e:  # noqa: BLE001 - shown in the window; the raster view keeps running
            self.error = f"reference failed: {type(e).__name__}: {e}"

    def texture_for_display(self):
        """The latest image as a float texture (None until the first pass is done)."""
        with self._lock:
            img, spp = self._image, self._image_spp
        if img is None:
            return None
        if spp != self._uploaded_spp or self.texture is None or self.texture.size != (img.shape[1], img.shape[0]):
            h, w = img.shape[:2]
            rgba = np.ones((h, w, 4), dtype="f4")
            rgba[..., :3] = img[::-1]  # row 0 = top -> GL's bottom-up rows
            if self.texture is None or self.texture.size != (w, h):
                if self.texture is not None:
                    self.texture.release()
                self.texture = self.ctx.texture((w, h), 4, dtype="f4")
            self.texture.write(rgba.tobytes())
            self._uploaded_spp = spp
        return self.texture

    def stop(self):
        self._cancel.set()
        if self._thread is not None:
            self._thread.join(timeout=5.0)
            self._thread = None

    def close(self):
        self.stop()
        if self._renderer is not None:
            self._renderer.close()
            self._renderer = None
        if self.texture is not None:
            self.texture.release()
            self.texture = None
