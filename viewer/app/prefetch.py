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

import itertools
import os
import signal
import subprocess
import sys
import threading
import time

LEASH_ENV = "BRDF_VIEWER_CHILD_LEASH"
LEASH_S = 30.0   # the longest silence of a compile-ahead child with work outstanding (a program: 0.1-6 s)
PREFETCH_LEASH_S = 120.0  # of a prefetch child (one map's prefilter on a loaded machine: tens of seconds)


#: a child still burning CPU is working, not hung: its silence is forgiven up to this many leashes
#: (a traced program compiles for tens of seconds on a loaded software-GL machine)
BUSY_LEASHES = 10


def cpu_seconds(pid) -> float | None:
    """The CPU time (user + system) process ``pid`` has used, from ``/proc`` (None where there is
    no ``/proc`` or the process is gone)."""
    try:
        with open(f"/proc/{int(pid)}/stat") as f:
            fields = f.read().rsplit(")", 1)[1].split()
        return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")
    except (OSError, ValueError, IndexError, TypeError):
        return None


class Silence:
    """How long a child has been silent, forgiving the time it spent working: ``heard(pid)``
    when it prints a line (or is given work); ``over(leash, pid)`` is True when it printed
    nothing for ``leash`` seconds and used no CPU time over the last leash (stopped, or hung
    waiting), or printed nothing for ``BUSY_LEASHES`` leashes whatever it did. Without ``/proc``
    its CPU time is unknown and silence alone counts."""

    def __init__(self, pid=None):
        self.heard(pid)

    def heard(self, pid=None):
        self.last = self.busy = time.monotonic()
        self.cpu = cpu_seconds(pid) if pid is not None else None

    def over(self, leash: float, pid) -> bool:
        now = time.monotonic()
        cpu = cpu_seconds(pid) if pid is not None else None
        if cpu is not None and self.cpu is not None and cpu > self.cpu + 0.005:
            self.busy = now  # it worked since the last look: not hung
        if cpu is not None:
            self.cpu = cpu
        return now - self.busy > leash or now - self.last > BUSY_LEASHES * leash


def leash_seconds(default: float = LEASH_S) -> float:
    """How long a child with work outstanding may stay silent before it is replaced
    (``BRDF_VIEWER_CHILD_LEASH`` seconds, else ``default``)."""
    try:
        return max(0.05, float(os.environ.get(LEASH_ENV, default)))
    except ValueError:
        return default


def tour_maps(start: int = 0) -> list:
    """The tour's distinct environments with a map, as (step index, Environment), from step
    ``start`` on (wrapping), each map and intensity once."""
    from viewer.scene.lecture import TOUR, tour_scene

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


def warm_tour_builtins(start: int = 0):
    """The tour's built-in maps (``viewer.environment.procedural``), from step ``start`` on,
    generated into the disk cache on a background thread of the window
    (``procedural.warm_builtin``): the prefetch child at its low priority may reach them after
    the class does, and the step's first frame would generate its map on the window's thread."""
    from viewer.environment import procedural

    def names():  # on the thread: listing the tour's maps loads its scenes (seconds under load)
        return list(dict.fromkeys(str(env.map) for _, env in tour_maps(start) if env.is_builtin))
    return procedural.warm_builtin(names)


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
    """``prefilter_tour`` in a child process, its progress read by a thread.

    On a leash: a child silent for ``leash`` seconds before it is done (``PREFETCH_LEASH_S``,
    ``BRDF_VIEWER_CHILD_LEASH``: stopped, hung) is killed and started again once, from the same
    step (the maps it finished are cached, so they cost a read); silent again, it is ended with
    ``error`` set, and the window prefilters the remaining maps itself as it would without it.
    ``command``: the child's command line (a stand-in in tests; without one the tour's built-in
    maps are generated on a thread of the window too: ``warm_tour_builtins``)."""

    RESTARTS = 1

    def __init__(self, start_step: int = 0, command=None, leash: float | None = None):
        self.total = 0
        self.finished = 0
        self.current = ""
        self.error = ""
        self.done = False
        self.replaced = 0
        self.seconds: list[tuple[str, float, bool]] = []  # (map, seconds, was it cached already)
        self.command = list(command or [sys.executable, "-m", "viewer.app.prefetch", str(int(start_step))])
        self.leash = leash_seconds(PREFETCH_LEASH_S) if leash is None else float(leash)
        self._proc = None
        self._silence = Silence()
        self._stopping = False
        self._start()
        if self._proc is not None:
            threading.Thread(target=self._watch, name="brdf-viewer-prefetch-leash", daemon=True).start()
        self.maps_thread = None
        if command is None:  # the tour's built-in maps, generated here beside the frames
            self.maps_thread = warm_tour_builtins(start_step)

    def _start(self) -> None:
        try:
            proc = subprocess.Popen(self.command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                                    env=dict(os.environ), cwd=os.getcwd())
        except OSError as e:
            self.error, self.done = f"cannot start ({e})", True
            return
        self._proc = proc
        self._silence = Silence(proc.pid)
        self._thread = threading.Thread(target=self._read, args=(proc,), name="brdf-viewer-prefetch", daemon=True)
        self._thread.start()

    @property
    def pid(self) -> int | None:
        return None if self._proc is None else self._proc.pid

    def _watch(self):
        while not self.done and not self._stopping:
            time.sleep(min(0.5, self.leash / 4))
            if self.done or self._stopping or not self._silence.over(self.leash, self.pid):
                continue
            old = self._proc
            self._proc = None
            try:
                old.kill()
            except OSError:
                pass
            old.wait()
            if self.replaced >= self.RESTARTS:
                self.error = f"the prefetch process did not answer within {self.leash:g} s (twice)"
                self.done = True
                return
            self.replaced += 1
            self._start()

    def progress_text(self) -> str:
        if self.error:
            return f"environment maps not prepared: {self.error}"
        if self.done:
            return f"environment maps prepared: {self.finished}/{self.total}"
        return f"preparing environment maps {self.finished}/{self.total}"

    def _read(self, proc):
        for line in proc.stdout:
            if proc is not self._proc:
                continue
            self._silence.heard(proc.pid)
            parts = line.split()
            if parts[:1] == ["total"]:
                self.total = int(parts[1])
            elif parts[:1] == ["done"] and len(parts) >= 5:
                self.finished = int(parts[1])
                self.seconds.append((parts[2], float(parts[3]), parts[4] == "cached"))
        err = proc.stderr.read()
        rc = proc.wait()
        if proc is not self._proc:
            return  # replaced (or being replaced) by the leash
        if rc not in (0, -15) and not self.error:  # -15: stopped by us (SIGTERM)
            last = [x for x in err.strip().splitlines() if x.strip()]
            self.error = last[-1] if last else f"exit status {rc}"
        self.done = True

    def stop(self, timeout: float = 10.0) -> None:
        """End the child process (a map half prefiltered is simply not cached)."""
        self._stopping = True
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


_PENDING = itertools.count()  # the background prefilters' files, one each


class MapPrefilter:
    """The full prefilter of the map the window's renderer drew with a quick one
    (``viewer.gl.ibl.IBL.defer``): ``prefilter_file`` in a child process. ``key`` is the map's
    cache key; ``ready`` once the disk cache holds it; ``error`` when the child failed (the window
    keeps the quick prefilter then, and says so)."""

    def __init__(self, key: str, image):
        import numpy as np

        from viewer.environment import cache
        from viewer.base.io import atomic_write_bytes

        self.key = key
        self.error = ""
        self.started = time.perf_counter()
        self._proc = None
        # its own file: a stopped job's child may still be exiting (and then removes its file)
        # when a job of the same map starts again
        self._path = cache.cache_dir() / f"pending-{key}-{os.getpid()}-{next(_PENDING)}.npy"
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

    def stop(self, timeout: float = 10.0, wait: bool = True) -> None:
        """End the child (terminated, killed after ``timeout`` s) and remove its file;
        ``wait=False``: the child is signalled and reaped on a thread of its own (the window's
        frames never wait for a child to exit: 0.5 s beside two busy processes)."""
        if not wait:
            proc = self._proc
            if proc is not None and proc.poll() is None:
                proc.terminate()
            threading.Thread(target=self.stop, args=(timeout,), name="brdf-viewer-prefilter-stop",
                             daemon=True).start()
            return
        stop_child(self._proc, timeout)
        self._cleanup()


#: the niceness of the window's background children (the prefetch, the compile-ahead child, Prepare
#: lecture's bake): on a two-core machine a child at the window's priority halves its frame rate
CHILD_NICE = 10


def behind_the_window(pid) -> None:
    """Lower the priority of the child process ``pid``, just started, to ``CHILD_NICE`` (never
    raise it): its threads (llvmpipe's rasterizer threads, made when its GL context is) inherit
    it. Where the system does not allow it, nothing happens."""
    try:
        os.setpriority(os.PRIO_PROCESS, int(pid), max(CHILD_NICE, os.getpriority(os.PRIO_PROCESS, int(pid))))
    except (OSError, AttributeError, TypeError, ValueError):
        pass


def stop_child(proc, timeout: float = 10.0) -> None:
    """Terminate a child process still running (None: none), killing it after ``timeout`` s."""
    if proc is not None and proc.poll() is None:
        proc.terminate()
        try:
            os.kill(proc.pid, signal.SIGCONT)  # a stopped child receives the SIGTERM now
        except OSError:
            pass
        try:
            proc.wait(timeout)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()


def main(argv=None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    try:
        os.nice(CHILD_NICE)  # behind the window's own frames
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
