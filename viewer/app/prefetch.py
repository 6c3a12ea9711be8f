"""Prefilter the lecture tour's environment maps once, in the background, into the disk cache
(``viewer.environment.cache``), so the first visit of a step with a new map does not wait
seconds for the prefilter pass: the window's own image-based lighting then loads the levels
from the cache.

The work runs in a child process (``python -m viewer.app.prefetch START``) at a lower priority,
on its own headless OpenGL context (EGL), one map at a time from the step being shown onwards.
A process, not a thread: a GL call holds the interpreter lock for its whole duration (seconds
for a prefilter draw on a software rasterizer), which would freeze the window. The child prints
one line per map; ``finished`` / ``total`` and ``progress_text()`` follow them. A map already
cached takes only its hash and a file read. Any failure (no EGL, a map that does not load) ends
the prefetch with ``error`` set; the window works as before without it.
"""

from __future__ import annotations

import os
import subprocess
import sys
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


def prefilter_tour(start: int = 0, out=sys.stdout) -> int:
    """Prefilter every map of the tour into the disk cache; one line per map on ``out``:
    ``total N`` first, then ``done K MAP SECONDS cached|prefiltered``."""
    maps = tour_maps(start)
    print(f"total {len(maps)}", file=out, flush=True)
    from viewer.gl.context import create_offscreen_context
    from viewer.gl.ibl import IBL

    ctx = create_offscreen_context()
    ibl = IBL(ctx)
    try:
        for k, (_, env) in enumerate(maps):
            t0 = time.perf_counter()
            ibl.set_environment(env.radiance_map())
            ctx.finish()
            how = "cached" if ibl.stats.get("cached") else "prefiltered"
            print(f"done {k + 1} {env.map} {time.perf_counter() - t0:.2f} {how}", file=out, flush=True)
    finally:
        ibl.release()
        ctx.release()
    return 0


class Prefetch:
    """``prefilter_tour`` in a child process, its progress read by a thread."""

    def __init__(self, start_step: int = 0):
        self.total = 0
        self.finished = 0
        self.current = ""
        self.error = ""
        self.done = False
        self.seconds: list[tuple[str, float, bool]] = []  # (map, seconds, was it cached already)
        self._proc = None
        try:
            self._proc = subprocess.Popen([sys.executable, "-m", "viewer.app.prefetch", str(int(start_step))],
                                          stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                                          env=dict(os.environ), cwd=os.getcwd())
        except OSError as e:
            self.error, self.done = f"cannot start ({e})", True
            return
        self._thread = threading.Thread(target=self._read, name="brdf-viewer-prefetch", daemon=True)
        self._thread.start()

    def progress_text(self) -> str:
        if self.error:
            return f"environment maps not prepared: {self.error}"
        if self.done:
            return f"environment maps prepared: {self.finished}/{self.total}"
        return f"preparing environment maps {self.finished}/{self.total}"

    def _read(self):
        proc = self._proc
        for line in proc.stdout:
            parts = line.split()
            if parts[:1] == ["total"]:
                self.total = int(parts[1])
            elif parts[:1] == ["done"] and len(parts) >= 5:
                self.finished = int(parts[1])
                self.seconds.append((parts[2], float(parts[3]), parts[4] == "cached"))
        err = proc.stderr.read()
        rc = proc.wait()
        if rc not in (0, -15) and not self.error:  # -15: stopped by us (SIGTERM)
            last = [x for x in err.strip().splitlines() if x.strip()]
            self.error = last[-1] if last else f"exit status {rc}"
        self.done = True

    def stop(self, timeout: float = 10.0) -> None:
        """End the child process (a map half prefiltered is simply not cached)."""
        stop_child(self._proc, timeout)


def prefilter_file(path, out=sys.stdout) -> int:
    """Prefilter one map, a float32 ``.npy`` (H, W, 3) as the window's renderer holds it, into the
    disk cache under the key the window's renderer computes for it; ``done SECONDS`` on ``out``."""
    import numpy as np

    from viewer.gl.context import create_offscreen_context
    from viewer.gl.ibl import IBL

    img = np.load(path, allow_pickle=False)
    ctx = create_offscreen_context()
    ibl = IBL(ctx)
    try:
        t0 = time.perf_counter()
        ibl.set_environment(img)
        ctx.finish()
        print(f"done {time.perf_counter() - t0:.2f}", file=out, flush=True)
    finally:
        ibl.release()
        ctx.release()
    return 0


class MapPrefilter:
    """The full prefilter of the map the window's renderer drew with a quick one
    (``viewer.gl.ibl.IBL.defer``): ``prefilter_file`` in a child process. ``key`` is the map's
    cache key; ``ready`` once the disk cache holds it; ``error`` when the child failed (the window
    keeps the quick prefilter then, and says so)."""

    def __init__(self, key: str, image):
        import numpy as np

        from viewer.environment import cache
        from viewer.io import atomic_write_bytes

        self.key = key
        self.error = ""
        self.started = time.perf_counter()
        self._proc = None
        self._path = cache.cache_dir() / f"pending-{key}.npy"
        try:
            self._path.parent.mkdir(parents=True, exist_ok=True)
            import io

            buf = io.BytesIO()
            np.save(buf, np.ascontiguousarray(image, np.float32))
            atomic_write_bytes(self._path, buf.getvalue())
            self._proc = subprocess.Popen([sys.executable, "-m", "viewer.app.prefetch", "--map", str(self._path)],
                                          stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
                                          env=dict(os.environ), cwd=os.getcwd())
        except OSError as e:
            self.error = f"the environment map cannot be prefiltered in the background ({e})"

    @property
    def ready(self) -> bool:
        from viewer.environment import cache

        return cache.path_for(self.key).is_file()

    @property
    def finished(self) -> bool:
        """The child has ended (ready, or failed: ``error``)."""
        if self._proc is None:
            return True
        rc = self._proc.poll()
        if rc is None:
            return False
        if rc != 0 and not self.error:
            err = [x for x in (self._proc.stderr.read() or "").strip().splitlines() if x.strip()]
            self.error = f"the background prefilter failed: {err[-1] if err else f'exit status {rc}'}"
        self._cleanup()
        return True

    def _cleanup(self):
        try:
            self._path.unlink()
        except OSError:
            pass

    def stop(self, timeout: float = 10.0) -> None:
        stop_child(self._proc, timeout)
        self._cleanup()


def stop_child(proc, timeout: float = 10.0) -> None:
    """Terminate a child process still running (None: none), killing it after ``timeout`` s."""
    if proc is not None and proc.poll() is None:
        proc.terminate()
        try:
            proc.wait(timeout)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()


def main(argv=None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    try:
        os.nice(10)  # behind the window's own frames
    except (OSError, AttributeError):
        pass
    try:
        if argv[:1] == ["--map"]:
            return prefilter_file(argv[1])
        return prefilter_tour(int(argv[0]) if argv else 0)
    except Exception as e:  # noqa: BLE001 - one line for the window's panel
        print(f"{type(e).__name__}: {str(e).splitlines()[0] if str(e) else ''}", file=sys.stderr)
        return 1


if __name__ == "__main__":
    sys.exit(main())
