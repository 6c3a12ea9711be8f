"""Process / thread / memory accounting for the reference lifecycle test
(tests/test_reference_lifecycle.py) and benchmarks/hardening.py. Linux /proc only (no psutil)."""

from __future__ import annotations

import glob
import os
import random
import tempfile
import threading
import time
from dataclasses import dataclass, field


def task_count() -> int:
    """Threads of this process, native ones included (Embree's, OpenBLAS's)."""
    return len(os.listdir("/proc/self/task"))


def fd_count() -> int:
    return len(os.listdir("/proc/self/fd"))


def rss_bytes(pid: str | int = "self") -> int:
    with open(f"/proc/{pid}/statm") as f:
        return int(f.read().split()[1]) * os.sysconf("SC_PAGE_SIZE")


def children(parent: int | None = None, zombies: bool = True) -> dict[int, str]:
    """pid -> command line of every process whose parent is ``parent`` (default: this one);
    ``zombies=False`` leaves out the ended ones no one has reaped (they hold no memory)."""
    me = os.getpid() if parent is None else parent
    out = {}
    for d in os.listdir("/proc"):
        if not d.isdigit():
            continue
        try:
            with open(f"/proc/{d}/stat") as f:
                fields = f.read().rsplit(")", 1)[1].split()
            if int(fields[1]) != me or (not zombies and fields[0] == "Z"):
                continue
            with open(f"/proc/{d}/cmdline", "rb") as f:
                out[int(d)] = f.read().replace(b"\0", b" ").decode(errors="replace").strip()
        except (OSError, IndexError, ValueError):
            continue  # ended meanwhile
    return out


def is_resource_tracker(cmdline: str) -> bool:
    """multiprocessing's resource tracker: one helper process per interpreter, started on the
    first use of a 'spawn' pool and kept until exit (by design, not per pool)."""
    return "multiprocessing.resource_tracker" in cmdline


def worker_children() -> dict[int, str]:
    return {p: c for p, c in children().items() if not is_resource_tracker(c)}


def alive(pids) -> set[int]:
    """Those of ``pids`` that are still processes of ours (children of this process, not yet
    reaped zombies). A test counts only the processes it started itself: other tests, other
    xdist workers and other users of the machine run processes of their own."""
    me, out = os.getpid(), set()
    for pid in pids:
        try:
            with open(f"/proc/{pid}/stat") as f:
                fields = f.read().rsplit(")", 1)[1].split()
        except (OSError, IndexError):
            continue  # gone
        if fields[0] != "Z" and int(fields[1]) == me:
            out.add(int(pid))
    return out


def setup_files() -> list[str]:
    return glob.glob(os.path.join(tempfile.gettempdir(), "brdf-viewer-setup-*"))


@dataclass
class StormResult:
    restarts: int
    seconds: float
    baseline_tasks: int
    baseline_threads: list
    after_close_tasks: int
    after_close_threads: list
    after_close_workers: set       # of the pool's worker processes seen during the storm: those alive
    after_close_setup_files: list
    rss_warm: int                 # after the first tenth of the restarts
    rss_end: int                  # after the last restart, before close
    rss_samples: list = field(default_factory=list)
    peak_tasks: int = 0
    final_spp: int = 0
    errors: list = field(default_factory=list)
    workers_seen: set = field(default_factory=set)   # every worker process the view's pools started

    @property
    def drift_mb(self) -> float:
        return (self.rss_end - self.rss_warm) / 2 ** 20

    def summary(self) -> str:
        return (f"{self.restarts} restarts in {self.seconds:.1f} s; threads {self.baseline_tasks} before, "
                f"peak {self.peak_tasks}, {self.after_close_tasks} after close; worker processes after close "
                f"{len(self.after_close_workers)}; setup files left {len(self.after_close_setup_files)}; RSS "
                f"{self.rss_warm / 2 ** 20:.1f} MB after warm-up -> {self.rss_end / 2 ** 20:.1f} MB at the end "
                f"(drift {self.drift_mb:+.1f} MB, min {min(self.rss_samples) / 2 ** 20:.1f}, max "
                f"{max(self.rss_samples) / 2 ** 20:.1f}); image after the storm: {self.final_spp} spp")


def restart_storm(n: int, workers: int = 2, seed: int = 0, max_pause_s: float = 0.02,
                  scene_name: str = "sphere") -> StormResult:
    """Restart the window's reference view ``n`` times in a row (a camera change each time,
    after a random pause of 0..max_pause_s so the cancel lands in every phase: while the
    renderer resets, while chunks run, between passes), then let one job finish a pass, then
    close the view. No GL context: the view needs one only to upload its texture."""
    from viewer.app.reference_view import ReferenceView
    from viewer.scene.camera import OrbitCamera
    from viewer.scene import load_scene

    rng = random.Random(seed)
    scene = load_scene(scene_name)
    cam = OrbitCamera.from_scene(scene)
    baseline_tasks, baseline_threads = task_count(), sorted(t.name for t in threading.enumerate())
    rv = ReferenceView(None, scale=0.1, max_depth=2, workers=workers)
    samples, peak, errors = [], 0, []
    rss_warm = None
    seen: set[int] = set()
    # one finished pass first: the renderer's compiled kernels are loaded (in this process with
    # workers=0, where numba and its kernels add tens of MB once) before the memory baseline at
    # a tenth of the storm, which a storm of short pauses can otherwise reach before any render
    rv.update(scene, cam, (160, 120))
    t_warm = time.perf_counter()
    while rv.spp < 1 and not rv.error and time.perf_counter() - t_warm < 600:
        time.sleep(0.01)
    seen.update(rv.worker_pids())
    t0 = time.perf_counter()
    for i in range(n):
        cam.yaw += 1e-3
        rv.update(scene, cam, (160, 120))
        time.sleep(rng.random() * max_pause_s)
        seen.update(rv.worker_pids())
        peak = max(peak, task_count())
        if rv.error:
            errors.append(rv.error)
        if i % max(1, n // 50) == 0:
            samples.append(rss_bytes())
        if i == n // 10:
            rss_warm = rss_bytes()
    seconds = time.perf_counter() - t0
    rss_end = rss_bytes()
    samples.append(rss_end)
    t1 = time.perf_counter()
    while rv.spp < 1 and not rv.error and time.perf_counter() - t1 < 600:
        time.sleep(0.01)
    final_spp = rv.spp
    seen.update(rv.worker_pids())
    if rv.error:
        errors.append(rv.error)
    rv.close()
    deadline = time.perf_counter() + 30   # generous: a loaded machine reaps slowly
    while (alive(seen) or task_count() > baseline_tasks) and time.perf_counter() < deadline:
        time.sleep(0.02)  # processes are reaped and threads end shortly after close returns
    return StormResult(n, seconds, baseline_tasks, baseline_threads, task_count(),
                       sorted(t.name for t in threading.enumerate()), alive(seen), setup_files(),
                       rss_warm if rss_warm is not None else samples[0], rss_end, samples, peak, final_spp, errors,
                       seen)
