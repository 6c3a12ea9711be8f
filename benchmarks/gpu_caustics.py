"""The GPU engine's photon integrator: `python benchmarks/gpu_caustics.py [--passes N] [--size S]`
(prints numbers, asserts nothing).

a. Each caustic oracle of tests/caustic_oracles.py (point light over a mirror lighting a wall;
   directional light through an absorbing glass slab onto a floor) on the GPU engine's photon
   integrator: the image mean over the pixels away from the caustic's edges against the closed
   form (exact) and against the closed form with the caustic averaged over each pass's gather
   disk (the estimator's expectation at this pass count), with the standard error from the spread
   of the per-pass means; the path integrator's error beside it.
b. The same scenes on the CPU engine's photon integrator (one process): GPU / CPU - 1 of the image
   means, with its standard error.
c. Samples (camera samples = pixels x passes) per second of photon and path on the GPU engine at
   the given size on the oracle scenes and on the lecture's glass step, after a warm-up pass; the
   photon pass's share (emission, photon tracing, grid) of a photon pass.
"""

from __future__ import annotations

import argparse
import os
import sys
import time

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "tests"))

from caustic_oracles import expected, glass_slab_scene, mirror_wall_scene  # noqa: E402

ORACLES = {"mirror_wall": (mirror_wall_scene, 8), "glass_slab": (glass_slab_scene, 1)}


def passes(r, n):
    out, prev = [], None
    for _ in range(n):
        r.step(1)
        s, _q, _spp = r.state()
        s = np.asarray(s, np.float64)
        out.append(s if prev is None else s - prev)
        prev = s
    return np.stack(out)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--passes", type=int, default=64)
    ap.add_argument("--size", type=int, default=32)
    ap.add_argument("--speed-size", type=int, default=64)
    args = ap.parse_args()
    from viewer.gl.context import create_offscreen_context
    from viewer.gpupt import GpuReferenceRenderer
    from viewer.pathtracer import ReferenceRenderer
    from viewer.reference_common import caustics
    from viewer.scene.lecture import tour_scene

    ctx = create_offscreen_context()
    n, size = args.passes, args.size
    print(f"load: {os.getloadavg()}")
    print(f"a/b. oracles at {size}x{size}, {n} passes (photons per pass {caustics.photons_per_pass(size, size)})")
    for name, (make, depth) in ORACLES.items():
        res = {}
        for integ in ("photon", "path"):
            with GpuReferenceRenderer(make(size), width=size, height=size, max_depth=depth, seed=11, ctx=ctx,
                                      integrator=integ) as g:
                res[integ] = passes(g, n)
                r1 = g.photons.r1 if g.photons is not None else r1
        with ReferenceRenderer(make(size), width=size, height=size, max_depth=depth, seed=12, workers=0,
                               integrator="photon") as c:
            cpu = passes(c, n)
        radii = [caustics.pass_radius(r1, i) for i in range(1, n + 1)]
        exact, expect, mask = expected(name, size, radii)
        for integ, imgs in res.items():
            per = imgs[:, mask].mean(axis=1)
            m, se = per.mean(0), per.std(0, ddof=1) / np.sqrt(n)
            print(f"  {name:12s} gpu {integ:6s} vs exact {100 * (m / exact[mask].mean(0) - 1)} %"
                  f"  vs kernel expectation {100 * (m / expect[mask].mean(0) - 1)} %  (se {100 * se / exact[mask].mean(0)} %)")
        g_tot, c_tot = res["photon"].sum(axis=(1, 2, 3)), cpu.sum(axis=(1, 2, 3))
        se = np.hypot(g_tot.std(ddof=1), c_tot.std(ddof=1)) / np.sqrt(n) / c_tot.mean()
        print(f"  {name:12s} gpu/cpu photon - 1 = {100 * (g_tot.mean() / c_tot.mean() - 1):+.3f} % (se {100 * se:.3f} %)")
    s = args.speed_size
    print(f"c. samples/s on the GPU engine at {s}x{s} (after a warm-up pass)")
    scenes = {"mirror_wall": (mirror_wall_scene(s), 8), "glass_slab": (glass_slab_scene(s), 8),
              "lecture_glass": (tour_scene(1), 8)}
    for name, (sc, depth) in scenes.items():
        rates = {}
        for integ in ("path", "photon"):
            with GpuReferenceRenderer(sc, width=s, height=s, max_depth=depth, seed=1, ctx=ctx, integrator=integ) as g:
                g.step(1)
                k = 8
                t0 = time.perf_counter()
                share = 0.0
                for _ in range(k):
                    g.step(1)
                    if g.photons is not None:
                        share += g.photons.build_seconds
                dt = time.perf_counter() - t0
                rates[integ] = k * s * s / dt
                extra = f", photon pass {100 * share / dt:.0f}% of the time" if g.photons is not None else ""
                print(f"  {name:14s} {integ:6s} {rates[integ]:10.0f} samples/s{extra}")
        print(f"  {name:14s} photon / path = {rates['photon'] / rates['path']:.3f}")


if __name__ == "__main__":
    main()
