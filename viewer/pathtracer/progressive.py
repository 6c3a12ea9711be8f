"""Progressive accumulation over a persistent pool of worker processes.

Work is split into chunks (a block of rows x a few sample indices) whose layout depends only
on the image size and the samples asked for, never on the number of workers. The random
numbers of a chunk come from the counter-based streams ``philox(seed, block, sample)``, and
the main process adds the chunks' sums in chunk order, so an image depends on the seed (and
on how many samples each ``step`` asked for), never on the workers.

Processes: ``workers`` (default ``os.cpu_count()``) processes started with the ``spawn``
method. ``fork`` would copy a process that may hold a GL context, a glfw window and driver
threads (their locks included) into the children, which is unsafe; ``spawn`` starts clean
interpreters that import only numpy, embreex and ``viewer.pathtracer`` / ``viewer.brdf``
(no GL). As always with ``spawn``, the launching script must guard its entry point with
``if __name__ == "__main__"`` (the package's ``brdf-viewer`` script and ``python -m viewer``
need nothing: ``multiprocessing`` does not re-run a package's ``__main__``).
``workers=0`` renders in the calling process (no pool).

Cancellation: ``step(cancel=event)`` checks the event every few milliseconds while it waits
for chunks (each chunk takes well under 100 ms), cancels the chunks not started, and returns
False at once; the partial pass is discarded, so the accumulated image stays what the
completed steps made it.
"""

from __future__ import annotations

import concurrent.futures as cf
import math
import multiprocessing as mp
import os
import pickle
import tempfile
import threading
import time

import numpy as np

from viewer.pathtracer.integrator import Integrator, RenderSetup

TARGET_BLOCK_PIXELS = 2048     # pixels per block of rows (fixed: defines the random streams)
TARGET_CHUNK_PATHS = 8192      # camera samples per chunk (about 60 ms on one core)
POLL_S = 0.005

_WORKER: Integrator | None = None
_WORKER_KEY: str | None = None


def _init_worker(setup: RenderSetup, key: str):
    global _WORKER, _WORKER_KEY
    _WORKER, _WORKER_KEY = Integrator(setup), key


def _worker_for(key: str, path: str | None) -> Integrator:
    """The worker's integrator for scene version ``key``, loaded from ``path`` (written once by
    ``reset``) when the worker last rendered another version: a scene change reuses the worker
    processes instead of starting new ones."""
    global _WORKER, _WORKER_KEY
    if _WORKER_KEY != key:
        with open(path, "rb") as f:
            _WORKER = Integrator(pickle.load(f))
        _WORKER_KEY = key
    return _WORKER


def _run_chunk(key, path, row0, row1, samples, seed, block_id):
    it = _worker_for(key, path)
    before = it.bad_values
    s, s2 = it.render_block(row0, row1, samples, seed, block_id)
    return s, s2, it.bad_values - before


def _warm(seconds):
    time.sleep(seconds)
    return os.getpid()


def _worker_modules():
    import sys

    return sorted(sys.modules)


def block_layout(width: int, height: int) -> list[tuple[int, int]]:
    rows = max(1, TARGET_BLOCK_PIXELS // max(width, 1))
    return [(r, min(r + rows, height)) for r in range(0, height, rows)]


class ReferenceRenderer:
    """Progressive reference rendering of ``scene`` (``camera``: an ``OrbitCamera`` or anything
    with position, target, up, fov_y; default ``OrbitCamera.from_scene``)."""

    def __init__(self, scene, camera=None, width=None, height=None, max_depth=8, seed=0,
                 workers=None, env_image=None, kernel: str = "embree"):
        if int(max_depth) < 1:
            raise ValueError("max_depth must be >= 1")
        self.max_depth, self.env_image, self.kernel = int(max_depth), env_image, kernel
        self.seed = int(seed)
        self.workers = (os.cpu_count() or 1) if workers is None else int(workers)
        self._local: Integrator | None = None
        self._pool: cf.ProcessPoolExecutor | None = None
        self._setup_file: str | None = None
        self._version = 0
        self._set_setup(RenderSetup.from_scene(scene, camera, width, height, self.max_depth, env_image, kernel))
        if self.workers > 0:
            self._pool = cf.ProcessPoolExecutor(max_workers=self.workers, mp_context=mp.get_context("spawn"),
                                                initializer=_init_worker, initargs=(self.setup, self._key))

    def _set_setup(self, setup: RenderSetup):
        self.setup = setup
        self.width, self.height = setup.width, setup.height
        self.blocks = block_layout(self.width, self.height)
        self.spp = 0
        self.bad_values = 0
        self._sum = np.zeros((self.height, self.width, 3))
        self._sum2 = np.zeros((self.height, self.width, 3))
        self._version += 1
        self._key = f"{os.getpid()}-{id(self)}-{self._version}"
        if self.workers == 0:
            self._local = Integrator(setup)

    def reset(self, scene, camera=None, width=None, height=None):
        """Start over on a changed scene, camera or size, keeping the worker processes."""
        self._set_setup(RenderSetup.from_scene(scene, camera, width, height, self.max_depth,
                                               self.env_image, self.kernel))
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
    def _chunks(self, s0: int, spp: int):
        block_px = max(b1 - b0 for b0, b1 in self.blocks) * self.width
        per = max(1, min(spp, TARGET_CHUNK_PATHS // max(block_px, 1)))
        out = []
        for g0 in range(s0, s0 + spp, per):
            samples = tuple(range(g0, min(g0 + per, s0 + spp)))
            for bid, (r0, r1) in enumerate(self.blocks):
                out.append((self._key, self._setup_file, r0, r1, samples, self.seed, bid))
        return out

    def step(self, spp: int = 1, cancel: threading.Event | None = None, progress=None) -> bool:
        """Add ``spp`` samples per pixel. Returns False (and adds nothing) when ``cancel`` is set
        before the pass completes. ``progress(fraction)`` is called as chunks finish."""
        spp = int(spp)
        if spp < 1:
            return True
        chunks = self._chunks(self.spp, spp)
        results = [None] * len(chunks)
        if self._pool is None:
            for i, c in enumerate(chunks):
                if cancel is not None and cancel.is_set():
                    return False
                before = self._local.bad_values
                s, s2 = self._local.render_block(*c[2:])
                results[i] = (s, s2, self._local.bad_values - before)
                if progress:
                    progress((i + 1) / len(chunks))
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
        new_sum = self._sum.copy()
        new_sum2 = self._sum2.copy()
        bad = 0
        for (_, _, r0, r1, _, _, _), (s, s2, nb) in zip(chunks, results):
            new_sum[r0:r1] += s
            new_sum2[r0:r1] += s2
            bad += nb
        self._sum, self._sum2 = new_sum, new_sum2
        self.bad_values += bad
        self.spp += spp
        return True

    # ------------------------------------------------------------------ results
    def mean(self) -> np.ndarray:
        """(H, W, 3) float32 running mean, row 0 = top."""
        if self.spp == 0:
            return np.zeros((self.height, self.width, 3), dtype=np.float32)
        return (self._sum / self.spp).astype(np.float32)

    def variance(self) -> np.ndarray:
        """(H, W, 3) variance of the mean per pixel: unbiased sample variance / n
        (inf with fewer than 2 samples)."""
        n = self.spp
        if n < 2:
            return np.full((self.height, self.width, 3), np.inf, dtype=np.float32)
        m = self._sum / n
        var = np.maximum(self._sum2 - n * m * m, 0.0) / (n - 1)
        return (var / n).astype(np.float32)

    def warm_up(self):
        """Start every worker process now (and build its ray-tracing structures), so the
        first ``step`` measures rendering only."""
        if self._pool is not None:
            futs = [self._pool.submit(_warm, 0.05) for _ in range(self.workers)]
            for f in futs:
                f.result()

    def worker_modules(self) -> list[str]:
        """The modules imported in a worker (to check that workers never import GL)."""
        if self._pool is None:
            return []
        return self._pool.submit(_worker_modules).result()

    def close(self):
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
            if self._pool is not None:
                self._pool.shutdown(wait=False, cancel_futures=True)
        except Exception:
            pass
