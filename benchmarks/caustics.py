"""The ``photon`` integrator against ``path`` on the CPU engine:
`python benchmarks/caustics.py [--size 160x96] [--seconds 60] [--workers 2] [--png DIR]`
(prints numbers, asserts nothing; figures from one run, so their ratios hold on a loaded machine).

1. samples/s of both integrators on lecture step 3 (the glass cube under the sky's sun);
2. the glass slab scene (tests/test_caustics.py's oracle 2, seen by a camera): seconds until the
   mean of the floor under the slab is within 5% of the closed form (path: never, it is black);
3. lecture step 3 at equal time (``--seconds`` each): the raster-vs-reference block p90
   (``viewer.image.compare.agreement``) and the reference's own noise, the block p90 between two
   references of different seeds, for path and photon; ``--png`` writes the references.
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "tests"))


def run_for(make, seconds):
    """A renderer from ``make()`` stepped until ``seconds`` have passed: (mean image, spp, seconds)."""
    r = make()
    try:
        r.warm_up()
        t0 = time.perf_counter()
        per = r.samples_per_chunk()
        while time.perf_counter() - t0 < seconds:
            r.step(per)
        return r.mean(), r.spp, time.perf_counter() - t0
    finally:
        r.close()


def slab_time(integrator, workers, limit_s=300.0):
    import numpy as np

    from test_caustics import SLAB_E, slab_scene, slab_transmittance
    from viewer.pathtracer import ReferenceRenderer
    from viewer.scene import load_scene_text
    from scene_text import camera

    text = slab_scene(0.0).replace(camera([0, 3, 3], [0, 0, 0], 40.0),
                                   camera([0.0, 0.6, 0.0], [0.0, 0.0, 0.0001], 60.0, 64, 48))
    want = 0.5 / math.pi * SLAB_E * slab_transmittance(0.0)
    r = ReferenceRenderer(load_scene_text(text), width=64, height=48, max_depth=1, workers=workers,
                          integrator=integrator)
    try:
        r.warm_up()
        t0 = time.perf_counter()
        while time.perf_counter() - t0 < limit_s:
            r.step(1)
            m = r.mean()[8:40, 8:56].reshape(-1, 3).mean(0)
            err = float(np.max(np.abs(m / want - 1)))
            if err < 0.05:
                return time.perf_counter() - t0, r.spp, err
        return None, r.spp, err
    finally:
        r.close()


def main(argv=None) -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--size", default="160x96")
    ap.add_argument("--seconds", type=float, default=60.0)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--png", default=None)
    a = ap.parse_args(argv)
    w, h = (int(x) for x in a.size.split("x"))

    from viewer.scene.camera import OrbitCamera
    from viewer.image.colour import to_srgb8
    from viewer.image.compare import agreement
    from viewer.pathtracer import ReferenceRenderer
    from viewer.scene import load_scene

    scene = load_scene("lecture:3")
    cam = OrbitCamera.from_scene(scene)

    def make(integrator, seed):
        return lambda: ReferenceRenderer(scene, camera=cam, width=w, height=h, max_depth=8, seed=seed,
                                         workers=a.workers, integrator=integrator)

    print(f"lecture step 3 at {w}x{h}, {a.workers} workers")
    refs = {}
    for integ in ("path", "photon"):
        img, spp, sec = run_for(make(integ, 1), a.seconds)
        img2, spp2, _ = run_for(make(integ, 2), a.seconds)
        refs[integ] = (img, img2, spp, sec)
        print(f"  {integ:<7} {spp * w * h / sec:9.0f} samples/s ({spp} spp in {sec:.1f} s)")
    try:
        from viewer.gl.context import create_offscreen_context
        from viewer.gl.renderer import Renderer

        raster = Renderer(create_offscreen_context()).render_arrays(scene, width=w, height=h)[0]
    except Exception as e:  # noqa: BLE001 - no OpenGL: the reference figures alone
        raster = None
        print(f"  (no raster: {e})")
    for integ, (img, img2, spp, sec) in refs.items():
        noise = agreement(img2, img)["block_p90"]
        line = f"  {integ:<7} equal time {sec:.0f} s ({spp} spp): reference noise block p90 {noise:.3f}"
        if raster is not None:
            g = agreement(raster, img)
            line += f"; raster vs reference mean rel {g['mean_rel']:.3f}, block p90 {g['block_p90']:.3f}"
        print(line)
        if a.png:
            from viewer.base.io import write_png

            Path(a.png).mkdir(parents=True, exist_ok=True)
            write_png(Path(a.png) / f"step3_{integ}.png", to_srgb8(img, scene.render.exposure, scene.render.tonemap))
    print("glass slab (normal incidence), floor under the slab within 5% of the closed form:")
    for integ in ("path", "photon"):
        sec, spp, err = slab_time(integ, a.workers, limit_s=min(120.0, 4 * a.seconds))
        said = f"{sec:.1f} s ({spp} spp)" if sec is not None else f"not within {spp} spp (error {err:.0%})"
        print(f"  {integ:<7} {said}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
