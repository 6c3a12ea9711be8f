"""Reference lifecycle: cancelling and restarting the window's reference
view over and over leaves no threads, processes, temporary files or memory behind.

Measured from /proc (no psutil): threads = /proc/self/task, processes = the worker processes
of the pools the test itself made (``worker_pids``; other tests and other xdist workers run
processes of their own), memory = resident set from /proc/self/statm.

Allowed memory drift: 16 MB between the end of the first tenth of the restarts (pool started,
caches warm) and the last restart. Every restart deep-copies the scene (the sphere alone is
0.74 MB of vertex and index data), so leaking one snapshot per restart would grow RSS by
hundreds of MB over the run; what stays below 16 MB is allocator noise (glibc keeps freed
arenas; images in flight), not growth per restart.
"""

from __future__ import annotations

import os
import signal
import sys
import tempfile
import time
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).parent))
import lifecycle  # noqa: E402

ALLOWED_DRIFT_MB = 16.0
# 300 restarts: leaking one scene snapshot (0.74 MB) per restart would grow RSS by about 220 MB,
# over ten times the allowed drift; benchmarks/hardening.py runs a storm of 1000
RESTARTS = 300


@pytest.fixture
def private_tmp(tmp_path, monkeypatch):
    """The renderer's setup files go to a folder of this test only (other processes on the
    machine may render at the same time)."""
    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path))
    return tmp_path


def test_a_restart_storm_leaves_nothing_behind(private_tmp):
    r = lifecycle.restart_storm(RESTARTS, workers=2, seed=5, max_pause_s=0.01)
    print(r.summary())
    assert not r.errors, r.errors[:3]
    assert r.final_spp >= 1                         # still renders after the storm
    assert r.workers_seen and r.after_close_workers == set(), r.after_close_workers
    assert r.after_close_tasks <= r.baseline_tasks and r.after_close_threads == r.baseline_threads
    assert r.peak_tasks <= r.baseline_tasks + 4     # one reference thread + the pool's helper threads
    assert r.after_close_setup_files == [] and not list(private_tmp.glob("brdf-viewer-setup-*"))
    assert r.drift_mb < ALLOWED_DRIFT_MB, r.summary()


def test_restarts_without_worker_processes(private_tmp):
    before = set(lifecycle.children())   # whatever earlier tests of this process left running
    r = lifecycle.restart_storm(200, workers=0, seed=6, max_pause_s=0.01)
    assert not r.errors and r.final_spp >= 1
    assert r.workers_seen == set()   # no pool, no worker process
    new = {p: c for p, c in lifecycle.children().items() if p not in before and not lifecycle.is_resource_tracker(c)}
    assert new == {}, new
    assert r.after_close_tasks <= r.baseline_tasks
    assert r.drift_mb < ALLOWED_DRIFT_MB, r.summary()


def _wait(predicate, seconds=120.0):   # a deadline for a background job, generous for a loaded machine
    t0 = time.perf_counter()
    while not predicate() and time.perf_counter() - t0 < seconds:
        time.sleep(0.01)
    return predicate()


def test_a_killed_worker_is_reported_and_the_next_restart_recovers(private_tmp):
    from viewer.app.reference_view import ReferenceView
    from viewer.scene.camera import OrbitCamera
    from viewer.scene import load_scene

    scene = load_scene("sphere")
    cam = OrbitCamera.from_scene(scene)
    rv = ReferenceView(None, scale=0.1, max_depth=2, workers=2)
    try:
        rv.update(scene, cam, (160, 120))
        assert _wait(lambda: rv.spp >= 1), rv.error
        pids = rv.worker_pids()   # started on demand: one for the one block of 16 x 12 pixels
        assert pids
        os.kill(pids[0], signal.SIGKILL)
        assert _wait(lambda: bool(rv.error)), "no error shown"
        assert "BrokenProcessPool" in rv.error
        cam.yaw += 0.1
        rv.update(scene, cam, (160, 120))
        assert _wait(lambda: rv.spp >= 1), rv.error   # a fresh pool, not the broken one
        fresh = rv.worker_pids()
        assert rv.error == "" and fresh and not set(pids) & set(fresh)
    finally:
        rv.close()
    assert _wait(lambda: not lifecycle.alive(pids + fresh)), lifecycle.alive(pids + fresh)


def test_stop_then_the_same_view_resumes(private_tmp):
    from viewer.app.reference_view import ReferenceView
    from viewer.scene.camera import OrbitCamera
    from viewer.scene import load_scene

    scene = load_scene("sphere")
    cam = OrbitCamera.from_scene(scene)
    rv = ReferenceView(None, scale=0.1, max_depth=2, workers=0)
    try:
        rv.update(scene, cam, (160, 120))
        assert _wait(lambda: rv.spp >= 1)
        assert rv.stop(timeout=120)        # idle within the timeout (generous: a loaded machine)
        rv.update(scene, cam, (160, 120))  # same scene and camera (raster -> reference in the window)
        assert _wait(lambda: rv.spp >= 1)  # used to stay stopped: the key had not changed
    finally:
        rv.close()
    assert not rv.has_thread


def test_renderer_close_ends_its_processes(private_tmp):
    from viewer.pathtracer import ReferenceRenderer
    from viewer.scene import load_scene

    scene = load_scene("sphere", ["camera.width=16", "camera.height=12"])
    before = lifecycle.task_count()
    started = []
    for _ in range(2):
        with ReferenceRenderer(scene, max_depth=2, workers=2, pool="processes") as r:
            r.warm_up()
            r.step(1)
            r.reset(scene)
            pids = r.worker_pids()
            assert len(pids) == 2 and lifecycle.alive(pids) == set(pids)
            started += pids
        assert lifecycle.alive(pids) == set()   # close waits for its workers
    assert len(set(started)) == 4
    assert _wait(lambda: lifecycle.task_count() <= before)  # (threads of earlier tests may still be ending)
    assert not list(private_tmp.glob("brdf-viewer-setup-*"))


def test_worker_processes_take_the_niceness_asked_for(private_tmp):
    """``nice``: each worker process runs that much behind this one (the window's reference
    yields the cores to the window's frames); without it, at this process's own."""
    from viewer.pathtracer import ReferenceRenderer
    from viewer.scene import load_scene

    scene = load_scene("sphere", ["camera.width=16", "camera.height=12"])
    own = os.getpriority(os.PRIO_PROCESS, 0)
    for nice, expect in ((5, min(19, own + 5)), (0, own)):
        with ReferenceRenderer(scene, max_depth=2, workers=2, pool="processes", nice=nice) as r:
            r.warm_up()
            r.step(1)
            assert [os.getpriority(os.PRIO_PROCESS, p) for p in r.worker_pids()] == [expect, expect]


def test_the_windows_reference_renders_behind_the_window(private_tmp):
    """The window's CPU engine asks its workers for ``REFERENCE_NICE``."""
    from viewer.app.reference_cpu import REFERENCE_NICE
    from viewer.app.reference_view import ReferenceView
    from viewer.scene.camera import OrbitCamera
    from viewer.scene import load_scene

    scene = load_scene("sphere")
    rv = ReferenceView(None, scale=0.1, max_depth=2, workers=1, engine="cpu")
    try:
        rv.update(scene, OrbitCamera.from_scene(scene), (160, 120))
        assert _wait(lambda: rv.spp >= 1)
        own = os.getpriority(os.PRIO_PROCESS, 0)
        assert REFERENCE_NICE > 0 and rv.cpu.renderer.nice == REFERENCE_NICE
        assert [os.getpriority(os.PRIO_PROCESS, p) for p in rv.cpu.renderer.worker_pids()] == [min(19, own + REFERENCE_NICE)]
    finally:
        rv.close()


def test_a_failing_gpu_engine_falls_back_to_the_cpu_engine(gl_ctx, monkeypatch):
    """The GPU engine that raises (here on being made) is dropped: its error stands in the view,
    ``gpu_failed`` names it, and the next update renders with the cpu engine's thread."""
    import viewer.gpupt.engine as gpu_engine
    from viewer.app.reference_view import ReferenceView
    from viewer.scene.camera import OrbitCamera
    from viewer.scene import load_scene

    class Broken:
        def __init__(self, *args, **kwargs):
            raise RuntimeError("no program")

    monkeypatch.setattr(gpu_engine, "GpuReferenceRenderer", Broken)
    scene = load_scene("sphere")
    cam = OrbitCamera.from_scene(scene)
    rv = ReferenceView(gl_ctx, scale=0.05, max_depth=1, workers=0, engine="gpu")
    try:
        v0 = rv.version
        rv.update(scene, cam, (160, 120))
        assert rv.error.startswith("gpu reference failed (RuntimeError: no program)"), rv.error
        assert rv.gpu_failed == "RuntimeError: no program" and rv.engine == "cpu" and rv.version > v0
        assert rv.key is None and rv.active_engine is None and not rv.needs_frames and not rv.has_thread
        rv.update(scene, cam, (160, 120))   # the cpu engine from now on
        assert rv.has_thread and _wait(lambda: rv.spp >= 1) and rv.error == ""
    finally:
        rv.close()
    assert not rv.has_thread


def test_the_gpu_engine_never_keeps_the_cpu_engines_preview_mark(gl_ctx):
    """The view's first image from the GPU engine is no coarse preview, whatever the cpu engine
    showed before it (the mark would say "preview" over a full-resolution GPU image)."""
    from viewer.app.reference_view import ReferenceView
    from viewer.scene.camera import OrbitCamera
    from viewer.scene import load_scene

    scene = load_scene("sphere")
    cam = OrbitCamera.from_scene(scene)
    rv = ReferenceView(gl_ctx, scale=1.0, max_depth=1, engine="gpu", frame_budget_s=0.01)
    try:
        rv.preview = True   # as the cpu engine leaves it while its coarse first image is shown
        t0 = time.perf_counter()
        while rv.spp < 1 and time.perf_counter() - t0 < 300:
            rv.update(scene, cam, (12, 8))
        assert rv.engine == "gpu" and rv.spp >= 1 and rv.error == "", rv.error
        assert not rv.preview
    finally:
        rv.close()
