"""Cancel latency of the reference renderer: `python benchmarks/cancel.py [--runs N] [--workers N]`
(prints numbers, asserts nothing).

A ``ReferenceRenderer`` (gold sphere on a grey floor, 64 x 64, a point light, a constant sky)
runs ``step(10_000)`` in a thread; once its first chunks have finished, the cancel event is
set. Printed: the seconds from ``cancel.set()`` to the return of ``step`` (median, worst),
which is bounded by the polling interval of the pool (``POLL_S``) plus the chunks in flight;
and whether the renderer was still usable (one more ``step(1)``) with the cancelled pass
discarded. The unit test (tests/test_pathtracer.py) checks only the behaviour, with a bound a
loaded machine meets: latency is measured here.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import threading
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
from scene_text import camera, environment, material, point_light, scene, sphere_on_floor  # noqa: E402

# the unit test's scene (tests/test_pathtracer.py small_scene at 64 x 64)
SCENE = scene(camera([0.0, 1.2, 3.5], [0.0, 0.4, 0.0], 45.0, 64, 64), environment(constant=[0.3, 0.35, 0.4]),
              point_light([2.0, 3.0, 2.0], [20.0, 20.0, 20.0]), sphere_on_floor(height=0.5),
              material("ball", preset="gold", alpha=0.3), material("floor", model="lambert", albedo=[0.5, 0.5, 0.5]))


def one_run(r) -> tuple[float, bool]:
    cancel, running, out = threading.Event(), threading.Event(), {}

    def work():
        out["ok"] = r.step(10_000, cancel=cancel, progress=lambda f: running.set())
        out["t"] = time.perf_counter()

    th = threading.Thread(target=work)
    th.start()
    running.wait(120)
    t0 = time.perf_counter()
    cancel.set()
    th.join()
    return out["t"] - t0, out["ok"] is False


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=5)
    ap.add_argument("--workers", type=int, default=2)
    args = ap.parse_args()

    import tempfile

    import numpy as np

    from viewer.pathtracer import ReferenceRenderer
    from viewer.pathtracer.progressive import POLL_S
    from viewer.scene import load_scene

    with tempfile.TemporaryDirectory() as d:
        path = Path(d) / "cancel.toml"
        path.write_text(SCENE)
        scene = load_scene(path)
    with ReferenceRenderer(scene, seed=0, workers=args.workers) as r:
        r.step(1)   # workers started and warm
        ref = r.mean().copy()
        lat, cancelled = [], []
        for _ in range(args.runs):
            t, c = one_run(r)
            lat.append(t)
            cancelled.append(c)
        discarded = r.spp == 1 and np.array_equal(r.mean(), ref)
        usable = r.step(1) and r.spp == 2
        pids = r.worker_pids()
    print(f"cancel latency, {args.workers} workers, 64x64, {args.runs} runs: median "
          f"{1000 * statistics.median(lat):.1f} ms, worst {1000 * max(lat):.1f} ms (pool polls every "
          f"{1000 * POLL_S:.0f} ms)")
    print(f"   cancelled every time: {all(cancelled)}; cancelled passes discarded: {discarded}; "
          f"usable after: {usable}; {len(pids)} worker processes")


if __name__ == "__main__":
    main()
