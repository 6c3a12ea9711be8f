"""Progressive accumulation over a persistent pool of worker processes.

Work is split into chunks (blocks of rows x a few sample indices) whose layout depends only
on the image size and the samples asked for, never on the number of workers. The random
numbers of a chunk come from the counter-based streams ``philox(seed, block, sample)``, and
the main process adds the chunks' sums in chunk order, so an image depends on the seed (and
on how many samples each ``step`` asked for), never on the workers.

Processes: ``workers`` (default ``os.cpu_count()``) processes started with the ``spawn``
method. ``fork`` would copy a process that may hold a GL context, a glfw window and driver
threads (their locks included) into the children, which is unsafe; ``spawn`` starts clean
interpreters that import only numpy, embreex and ``viewer.pathtracer`` / ``viewer.reference_common`` / ``viewer.brdf``
(no GL). As always with ``spawn``, the launching script must guard its entry point with
``if __name__ == "__main__"`` (the package's ``brdf-viewer`` script and ``python -m viewer``
need nothing: ``multiprocessing`` does not re-run a package's ``__main__``).
``workers=0`` renders in the calling process (no pool).

Threads instead (``pool="threads"``, and ``pool="auto"`` where it applies): where every bounce of
the scene runs the compiled loop (``Integrator.fused``, which releases the GIL and calls Embree
from compiled code), ``workers`` threads of this process render, each with an ``Integrator`` of
its own, taken from a queue chunk by chunk. No interpreter, numpy, numba or kernel cache is
loaded again per worker and no sums are pickled back: a command-line render of the benchmark's
scene at 1280x720 and 4 spp spent about 1 CPU s of its 5 starting two worker processes. The
estimator is the same (the same chunks, random streams and summation order), so the image is
identical whichever pool renders it. ``pool="auto"`` takes threads for such a scene and worker
processes for any other (the numpy steps hold the GIL between their array operations); the
window asks for processes always (``pool="processes"``), so that its GUI thread never waits
for the GIL behind a render.

``nice``: the worker processes lower their priority by that much as they start (the window's
reference, so that the window's frames and its rasterizer threads come first on the cores and
the reference takes the time they leave); the threads of ``pool="threads"`` run at the caller's.

A worker whose parent dies (killed
with SIGKILL or SIGTERM, so that it never shut the pool down) notices within
``PARENT_CHECK_S`` and exits (``watch_parent``); multiprocessing's resource tracker, which
waits for every holder of its pipe, ends with the last of them.

Cancellation: ``step(cancel=event)`` checks the event every few milliseconds while it waits
for chunks (each chunk takes about 0.1 s), cancels the chunks not started, and returns
False at once; the partial pass is discarded, so the accumulated image stays what the
completed steps made it.
"""

from __future__ import annotations

import concurrent.futures as cf
import multiprocessing as mp
import os
import pickle
import queue
import tempfile
import threading
import time

import numpy as np

from viewer.brdf import twin_trust
from viewer.reference_common.estimator import EstimatorOptions, mean_of, variance_of_mean
from viewer.base.heap import keep_freed_memory
from viewer.pathtracer.integrator import Integrator
from viewer.reference_common.setup import RenderSetup
from viewer.pathtracer.spawn_guard import check_entry_point_guarded

TARGET_BLOCK_PIXELS = 2048     # pixels per block of rows (fixed: defines the random streams)
TARGET_CHUNK_PATHS = 8192      # camera samples per block and chunk: the samples per chunk
WIDE_CHUNK_PATHS = 32768       # a chunk holds several blocks up to this many paths (about 0.1 s on one core)
POLL_S = 0.005

_WORKER: Integrator | None = None
_WORKER_KEY: str | None = None
_INITIAL: tuple | None = None   # (setup, key) the pool was created with


def _build(setup: RenderSetup) -> Integrator:
    """An Integrator, or a one-line ViewerError when a package it needs is missing (it travels
    from a worker to the caller of ``step`` intact; a bare ImportError in the pool's
    initializer would only break the pool, with a traceback per worker and no name)."""
    try:
        if setup.extra.get("spectral") or setup.integrator == "photon":
            from viewer.pathtracer.photons import integrator_for

            return integrator_for(setup)
        return Integrator(setup)
    except ImportError as e:
        from viewer import ViewerError
        from viewer.base.optional import explain

        raise ViewerError(explain(e, None, f"the {setup.kernel} ray kernel of the reference path tracer")) from None


#: how often a worker checks that the process that started it is still alive (seconds)
PARENT_CHECK_S = 0.5


def watch_parent(parent_pid: int, every_s: float = PARENT_CHECK_S) -> threading.Thread:
    """In a worker: a daemon thread that ends this process when ``parent_pid`` is no longer its
    parent (killed with SIGKILL or SIGTERM, it could not shut the pool down; the worker is then
    reparented and would wait on the task queue for good, with the resource tracker, whose pipe
    the workers hold, waiting with it). Polling ``os.getppid`` works on every POSIX system and
    needs no help from the parent; ``prctl(PR_SET_PDEATHSIG)`` is not used, since it fires when
    the parent's *thread* that started the worker ends (the window starts pools from its
    reference thread)."""
    def watch():
        while True:
            if os.getppid() != parent_pid:
                os._exit(0)   # nothing to save: the parent that would read the results is gone
            time.sleep(every_s)

    t = threading.Thread(target=watch, name="parent-watch", daemon=True)
    t.start()
    return t


def _init_worker(setup: RenderSetup, key: str, parent_pid: int | None = None, nice: int = 0):
    global _INITIAL
    if nice > 0:
        try:
            os.nice(nice)  # before any thread of its own starts: they inherit it
        except OSError:  # not allowed here: at the parent's priority
            pass
    keep_freed_memory()
    if parent_pid is not None:
        watch_parent(parent_pid)
    _INITIAL = (setup, key)
    try:
        it = _worker_for(key, None)  # build now, so warm_up() starts ready workers
        warm_kernels(it)
    except Exception:  # noqa: BLE001 - reported by the first chunk, which builds again
        pass


def warm_kernels(it: Integrator):
    """Load (or, the first time in an environment, compile) the integrator's compiled kernels
    now (``Integrator.warm``), so the first chunk does not wait for them."""
    before = it.bad_values
    it.warm()
    it.bad_values = before


def _worker_for(key: str, path: str | None) -> Integrator:
    """The worker's integrator for scene version ``key``, loaded from ``path`` (written once by
    ``reset``) when the worker last rendered another version: a scene change reuses the worker
    processes instead of starting new ones. ``path`` None: the pool's initial setup."""
    global _WORKER, _WORKER_KEY
    if _WORKER_KEY != key:
        if path is None and _INITIAL is not None and _INITIAL[1] == key:
            setup = _INITIAL[0]
        else:  # (a chunk of a cancelled pass may name a file already removed: it fails here)
            with open(path, "rb") as f:
                setup = pickle.load(f)
        _WORKER, _WORKER_KEY = None, None  # free the old scene before building the next
        # a worker runs the numpy twins its parent trusted, and no others (never its own decision)
        twin_trust.decide(setup.extra.get("trusted_twins", ()))
        _WORKER = _build(setup)
        _WORKER_KEY = key
    return _WORKER


def _run_chunk(key, path, blocks, samples, seed):
    it = _worker_for(key, path)
    before = it.bad_values
    sums = it.render_blocks(blocks, samples, seed)
    return sums, it.bad_values - before


def _warm(seconds, key=None, path=None):
    if key is not None:
        _worker_for(key, path)  # raises what the first chunk would (a missing package)
    time.sleep(seconds)
    return os.getpid()


def _worker_modules():
    import sys

    return sorted(sys.modules)


KERNELS = {"embree": "embreex", "numba": "numba"}  # ray kernel -> the package it needs
POOLS = ("auto", "processes", "threads")   # what renders the chunks (ReferenceRenderer's ``pool``)


def _check_kernel(kernel: str) -> None:
    """A one-line ViewerError for an unknown kernel or a missing package, here in the calling
    process (in a worker it would only break the pool, with a message that names nothing)."""
    from viewer import ViewerError
    from viewer.base.optional import require

    if kernel not in KERNELS:
        raise ViewerError(f"kernel: {kernel!r} is not a ray kernel; allowed: {', '.join(KERNELS)}")
    require(KERNELS[kernel], f"the {kernel} ray kernel of the reference path tracer (kernel={kernel!r})",
            load=False)


def block_layout(width: int, height: int) -> list[tuple[int, int]]:
    rows = max(1, TARGET_BLOCK_PIXELS // max(width, 1))
    return [(r, min(r + rows, height)) for r in range(0, height, rows)]


class ReferenceRenderer:
    """Progressive reference rendering of ``scene`` (``camera``: an ``OrbitCamera`` or anything
    with position, target, up, fov_y; default ``OrbitCamera.from_scene``). ``strategy`` says how
    the environment is reached ("mis" default, "bsdf", "light"), ``mis_heuristic`` weights MIS
    ("power" default, "balance"), ``russian_roulette`` turns roulette on (default) or off: the
    ``options`` (``EstimatorOptions``). The interface is ``viewer.reference_common.estimator.ReferenceEngine``."""

    engine = "cpu"

    def __init__(self, scene, camera=None, width=None, height=None, max_depth=8, seed=0,
                 workers=None, env_image=None, kernel: str = "embree", spectral: bool | None = None,
                 strategy: str = "mis", mis_heuristic: str = "power", russian_roulette: bool = True,
                 integrator: str = "path", pool: str = "auto", nice: int = 0):
        if pool not in POOLS:
            raise ValueError(f"pool: {pool!r}; allowed: {', '.join(POOLS)}")
        if int(max_depth) < 1:
            raise ValueError("max_depth must be >= 1")
        _check_kernel(kernel)
        self.options = EstimatorOptions(strategy, mis_heuristic, russian_roulette, integrator)
        self.max_depth, self.env_image, self.kernel = int(max_depth), env_image, kernel
        self.seed = int(seed)
        self.spectral = spectral    # trace wavelengths; None: when a material is dispersive
        self.workers = (os.cpu_count() or 1) if workers is None else int(workers)
        self.pool = pool            # "processes", "threads" or "auto" (asked); self.pool_kind: in use
        self.nice = max(0, int(nice))  # the worker processes' niceness over this process's
        self.pool_kind = "none"
        self._local: Integrator | None = None
        self._pool: cf.ProcessPoolExecutor | None = None
        self._threads: cf.ThreadPoolExecutor | None = None
        self._free: queue.SimpleQueue | None = None   # the threads' integrators of this version
        self._setup_file: str | None = None
        self._version = 0
        self._set_setup(self._make_setup(scene, camera, width, height))
        self._choose_pool()

    def _choose_pool(self, first: Integrator | None = None):
        """Start the pool this scene renders on (``pool``; see the module docstring): worker
        processes (kept over a reset that keeps the kind), or threads with an integrator each."""
        if self.workers == 0:
            return
        kind = self.pool
        if kind == "auto":
            kind = "processes"
            if not (self.setup.extra.get("spectral") or self.setup.integrator == "photon"):
                first = _build(self.setup)
                if first.fused is not None:
                    kind = "threads"
        if kind == "threads":
            self._start_threads(first)
        else:
            self._stop_threads()
            if self._pool is None:
                check_entry_point_guarded()  # one line instead of multiprocessing's 20 in every worker
                self._pool = cf.ProcessPoolExecutor(max_workers=self.workers, mp_context=mp.get_context("spawn"),
                                                    initializer=_init_worker,
                                                    initargs=(self.setup, self._key, os.getpid(), self.nice))
        self.pool_kind = kind

    def _start_threads(self, first: Integrator | None):
        """``workers`` integrators of the current setup in a queue, the first one ``first``
        where given, and the thread pool (a process pool of an earlier scene is shut down)."""
        if self._pool is not None:
            self._pool.shutdown(wait=True, cancel_futures=True)
            self._pool = None
            self._drop_setup_file()
        keep_freed_memory()   # this process renders: its chunks reuse their freed arrays (heap.py)
        its = [first if first is not None else _build(self.setup)]
        its += [_build(self.setup) for _ in range(self.workers - 1)]
        warm_kernels(its[0])   # loads the compiled kernels once for every thread
        self._free = queue.SimpleQueue()
        for it in its:
            self._free.put(it)
        if self._threads is None:
            self._threads = cf.ThreadPoolExecutor(max_workers=self.workers, thread_name_prefix="reference")

    def _stop_threads(self):
        if self._threads is not None:
            self._threads.shutdown(wait=True, cancel_futures=True)
            self._threads = None
        self._free = None

    def _thread_chunk(self, free, blocks, samples, seed):
        """One chunk on an integrator of ``free`` (the queue of the version the chunk was made
        for), which goes back to the queue after it."""
        it = free.get()
        try:
            before = it.bad_values
            sums = it.render_blocks(blocks, samples, seed)
            return sums, it.bad_values - before
        finally:
            free.put(it)

    def _spectral_setup(self, scene, setup: RenderSetup) -> RenderSetup:
        from viewer.scene.materials import scene_is_dispersive

        on = scene_is_dispersive(scene) if self.spectral is None else bool(self.spectral)
        setup.extra["spectral"] = on
        self.is_spectral = on
        return setup

    def _set_setup(self, setup: RenderSetup):
        self.setup = setup
        # "path" or "photon" (an "auto" option resolved for this scene) and why
        self.integrator, self.integrator_reason = setup.integrator, setup.integrator_reason
        self.width, self.height = setup.width, setup.height
        self.blocks = block_layout(self.width, self.height)
        self.spp = 0
        self.bad_values = 0
        self._sum = np.zeros((self.height, self.width, 3))
        self._sum2 = np.zeros((self.height, self.width, 3))
        self._version += 1
        self._key = f"{os.getpid()}-{id(self)}-{self._version}"
        if self.workers == 0:
            keep_freed_memory()
            self._local = None
            self._local = _build(setup)

    def _make_setup(self, scene, camera, width, height) -> RenderSetup:
        setup = self._spectral_setup(scene, RenderSetup.from_scene(
            scene, camera, width, height, self.max_depth, self.env_image, self.kernel, **self.options.as_kwargs()))
        setup.extra["seed"] = self.seed   # the photon integrator's passes draw their photons from it
        return setup

    def reset(self, scene, camera=None, width=None, height=None, *, strategy=None, mis_heuristic=None,
              russian_roulette=None, integrator=None):
        """Start over on a changed scene, camera or size, keeping the worker processes; the
        estimator's options change where given (None: as before)."""
        self.options = self.options.updated(strategy, mis_heuristic, russian_roulette, integrator)
        self._set_setup(self._make_setup(scene, camera, width, height))
        if self.pool_kind == "threads" or self.pool == "auto":
            self._choose_pool()   # new integrators for the threads, or the kind this scene needs
        if self._pool is not None:
            fd, path = tempfile.mkstemp(prefix="brdf-viewer-setup-", suffix=".pickle")
            with os.fdopen(fd, "wb") as f:
                pickle.dump(self.setup, f, protocol=pickle.HIGHEST_PROTOCOL)
            self._drop_setup_file()
            self._setup_file = path

    def _drop_setup_file(self):
        if self._setup_file is not None:
            try:
                os.unlink(self._setup_file)
            except OSError:
                pass
            self._setup_file = None

    # ------------------------------------------------------------------ work
    def samples_per_chunk(self) -> int:
        """The samples per pixel that fill a chunk (``TARGET_CHUNK_PATHS`` camera samples): a
        ``step`` of fewer samples runs chunks of fewer paths, whose fixed cost per chunk then
        dominates (gallery at 460 x 360, 2 workers: step(1) 2.5 s, step(4) 2.6 s)."""
        block_px = max(b1 - b0 for b0, b1 in self.blocks) * self.width
        return max(1, TARGET_CHUNK_PATHS // max(block_px, 1))

    def _chunks(self, s0: int, spp: int):
        """(key, setup file, blocks, samples, seed) per chunk: the samples in groups of
        ``samples_per_chunk`` (as many as fill ``TARGET_CHUNK_PATHS`` per block), and per group
        consecutive blocks ``(row0, row1, block_id)`` up to ``WIDE_CHUNK_PATHS`` paths. Each
        pixel's sums are added in the order of its sample groups, as with one block a chunk."""
        block_px = max(b1 - b0 for b0, b1 in self.blocks) * self.width
        per = max(1, min(spp, TARGET_CHUNK_PATHS // max(block_px, 1)))
        nb = max(1, WIDE_CHUNK_PATHS // max(per * block_px, 1))
        blocks = [(r0, r1, bid) for bid, (r0, r1) in enumerate(self.blocks)]
        out = []
        for g0 in range(s0, s0 + spp, per):
            samples = tuple(range(g0, min(g0 + per, s0 + spp)))
            for i in range(0, len(blocks), nb):
                out.append((self._key, self._setup_file, tuple(blocks[i:i + nb]), samples, self.seed))
        return out

    def step(self, spp: int = 1, cancel: threading.Event | None = None, progress=None) -> bool:
        """Add ``spp`` samples per pixel. Returns False (and adds nothing) when ``cancel`` is set
        before the pass completes. ``progress(fraction)`` is called as chunks finish."""
        spp = int(spp)
        if spp < 1:
            return True
        chunks = self._chunks(self.spp, spp)
        results = [None] * len(chunks)
        if self._pool is None and self._threads is None:
            for i, c in enumerate(chunks):
                if cancel is not None and cancel.is_set():
                    return False
                before = self._local.bad_values
                sums = self._local.render_blocks(*c[2:])
                results[i] = (sums, self._local.bad_values - before)
                if progress:
                    progress((i + 1) / len(chunks))
        else:
            if self._threads is not None:
                free = self._free
                futs = {self._threads.submit(self._thread_chunk, free, *c[2:]): i for i, c in enumerate(chunks)}
            else:
                futs = {self._pool.submit(_run_chunk, *c): i for i, c in enumerate(chunks)}
            pending = set(futs)
            done_n = 0
            while pending:
                if cancel is not None and cancel.is_set():
                    for f in pending:
                        f.cancel()
                    return False
                done, pending = cf.wait(pending, timeout=POLL_S, return_when=cf.FIRST_COMPLETED)
                for f in done:
                    results[futs[f]] = f.result()
                    done_n += 1
                if done and progress:
                    progress(done_n / len(chunks))
            if cancel is not None and cancel.is_set():
                return False
        # added in place (a copy of a 1280x720 image's two sums cost more CPU than a chunk): the
        # pass is complete here, and the sums are read only by the thread that calls ``step``
        new_sum, new_sum2 = self._sum, self._sum2
        bad = 0
        for (_, _, blocks, _, _), (sums, nb) in zip(chunks, results):
            for (r0, r1, _), (s, s2) in zip(blocks, sums):
                broken = ~np.isfinite(s)
                if broken.any():  # a path whose float64 throughput overflowed would poison the pixel for good
                    bad += int(np.count_nonzero(broken))
                    s, s2 = np.where(broken, 0.0, s), np.where(broken, 0.0, s2)
                new_sum[r0:r1] += s
                new_sum2[r0:r1] += s2
            bad += nb
        self.bad_values += bad
        self.spp += spp
        return True

    # ------------------------------------------------------------------ state (the reference cache)
    def state(self):
        """(sum (H, W, 3), sum of squares (H, W, 3), spp) of the samples so far (float64 copies)."""
        return self._sum.copy(), self._sum2.copy(), self.spp

    def resume(self, total, total2, spp: int):
        """Continue from stored sums of ``spp`` samples per pixel (``viewer.reference_common.cache``):
        the next ``step`` draws sample indices from ``spp`` on."""
        total = np.asarray(total, np.float64)
        if total.shape != self._sum.shape:
            raise ValueError(f"resume: sums of shape {total.shape}, the image is {self._sum.shape}")
        self._sum, self._sum2 = total.copy(), np.asarray(total2, np.float64).copy()
        self.spp = int(spp)

    # ------------------------------------------------------------------ results
    def mean(self) -> np.ndarray:
        """(H, W, 3) float32 running mean, row 0 = top (``estimator.mean_of``)."""
        return mean_of(self._sum, self.spp)

    def variance(self) -> np.ndarray:
        """(H, W, 3) variance of the mean per pixel (``estimator.variance_of_mean``)."""
        return variance_of_mean(self._sum, self._sum2, self.spp)

    def warm_up(self):
        """Start every worker process now (and build its ray-tracing structures), so the
        first ``step`` measures rendering only."""
        if self._pool is not None:
            futs = [self._pool.submit(_warm, 0.05, self._key, self._setup_file) for _ in range(self.workers)]
            for f in futs:
                f.result()

    def worker_modules(self) -> list[str]:
        """The modules imported in a worker (to check that workers never import GL)."""
        if self._pool is None:
            return []
        return self._pool.submit(_worker_modules).result()

    def worker_pids(self) -> list[int]:
        """The process ids of the worker processes started so far (none with ``workers=0``),
        so that a caller (a test) can watch exactly these and no other process."""
        pool = self._pool
        if pool is None:
            return []
        # the standard library keeps a pool's processes only in this attribute (pid -> Process)
        return sorted(pool._processes or {})

    def close(self):
        self._stop_threads()
        if self._pool is not None:
            self._pool.shutdown(wait=True, cancel_futures=True)
            self._pool = None
        self._drop_setup_file()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    def __del__(self):
        try:
            if self._threads is not None:
                self._threads.shutdown(wait=False, cancel_futures=True)
            if self._pool is not None:
                self._pool.shutdown(wait=False, cancel_futures=True)
        except Exception:
            pass
