"""Prefilter the lecture tour's environment maps once, in the background, into the disk cache
(``viewer.environment.cache``), so the first visit of a step with a new map does not wait
seconds for the prefilter pass: the window's own image-based lighting then loads the levels
from the cache.

The work runs in a thread on its own headless OpenGL context (EGL), one map at a time, from the
step being shown onwards. ``finished`` / ``total`` and ``progress_text()`` say how far it is; a
map that is already cached takes only its hash and a file read. Any failure (no EGL, a map that
does not load) ends the prefetch with ``error`` set; the window works as before without it.
"""

from __future__ import annotations

import threading
import time


def tour_maps(start: int = 0) -> list:
    """The tour's distinct environments with a map, as (step index, Environment), from step
    ``start`` on (wrapping), each map and intensity once."""
    from viewer.lecture import TOUR, tour_scene

    seen, out = set(), []
    n = len(TOUR)
    for k in range(n):
        i = (start + k) % n
        env = tour_scene(i, load_meshes=False).environment
        if env.map is None:
            continue
        key = (str(env.map), float(env.intensity))
        if key not in seen:
            seen.add(key)
            out.append((i, env))
    return out


class Prefetch:
    def __init__(self, start_step: int = 0):
        self.total = 0
        self.finished = 0
        self.current = ""
        self.error = ""
        self.done = False
        self.seconds: list[tuple[str, float, bool]] = []  # (map, seconds, was it cached already)
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, args=(start_step,), name="brdf-viewer-prefetch",
                                        daemon=True)
        self._thread.start()

    def progress_text(self) -> str:
        if self.error:
            return f"environment maps not prepared: {self.error}"
        if self.done:
            return f"environment maps prepared: {self.finished}/{self.total}"
        return f"preparing environment maps {self.finished}/{self.total}" + (f" ({self.current})" if self.current else "")

    def _run(self, start_step: int):
        ctx = ibl = None
        try:
            maps = tour_maps(start_step)
            self.total = len(maps)
            from viewer.gl.context import create_offscreen_context
            from viewer.gl.ibl import IBL

            ctx = create_offscreen_context()
            ibl = IBL(ctx)
            for _, env in maps:
                if self._stop.is_set():
                    break
                self.current = str(env.map)
                t0 = time.perf_counter()
                ibl.set_environment(env.radiance_map())
                ctx.finish()
                self.seconds.append((self.current, time.perf_counter() - t0, bool(ibl.stats.get("cached"))))
                self.finished += 1
        except Exception as e:  # noqa: BLE001 - a background convenience: report, never crash the window
            self.error = f"{type(e).__name__}: {e}"
        finally:
            try:
                if ibl is not None:
                    ibl.release()
                if ctx is not None:
                    ctx.release()
            except Exception:  # noqa: BLE001 - teardown of a context that failed to start
                pass
            self.current = ""
            self.done = True

    def stop(self, timeout: float = 30.0) -> None:
        """Ask the thread to stop after the map in progress, and wait for it."""
        self._stop.set()
        self._thread.join(timeout)
