"""The ``photon`` integrator against ``path`` on the CPU engine:
`python benchmarks/caustics.py [--size 160x96] [--seconds 60] [--workers 2] [--png DIR]`
(prints numbers, asserts nothing; figures from one run, so their ratios hold on a loaded machine).

1. samples/s of both integrators on lecture step 3 (the glass cube under the sky's sun);
2. the glass slab scene (tests/test_caustics.py's oracle 2, seen by a camera): seconds until the
   mean of the floor under the slab is within 5% of the closed form (path: never, it is black);
3. lecture step 3 at equal time (``--seconds`` each): the raster-vs-reference block p90
   (``viewer.image.compare.agreement``) and the reference's own noise, the block p90 between two
   references of different seeds, for path and photon; ``--png`` writes the references.

`python benchmarks/caustics.py --budget [--steps 2,3,10,11,13] [--size 160x90] [--ref-passes 512]`
instead measures, per lecture step, how many passes (and seconds) the reference the prepared
lecture bakes (``bake --lecture --spp 256``: the integrator ``auto`` picks, ``photon`` on these
steps) needs before its caustics are right:

* the long-run reference: ``--ref-passes`` passes of another seed;
* the caustic region: the 8 x 8 blocks where the photon map carries at least 10% of the
  reference's light (the reference minus an image of the same passes with the gather turned off)
  and the camera sees no glass or mirror directly (there the sun's own sub-pixel image, the path
  tracer's under either integrator, gives rare samples thousands of times the rest);
* at 4, 8, ..., 256 passes: the error of the region's mean (with its standard error, from the
  spread of the passes: each pass is an independent estimate) and the median and 90th
  percentile of its blocks' relative errors (luminance), and the seconds so far; "within 5%" is
  the pass count from which on the region's mean and its median block stay within 5%; the
  reference's own standard error on the region's mean is printed beside it.

The size is smaller than the bake's (480 x 270, half the lecture camera's) to fit a run on a
busy machine: photons per pass are one per pixel either way (``photons_per_pass``), so the gather
disk holds the same photons per pixel and a pass's relative error per block is about the same;
the seconds at the bake's size are about (480 x 270) / (w x h) times these (printed too).
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


def _luminance(img):
    import numpy as np

    from viewer.brdf.sampling import LUMINANCE_REC709

    return np.asarray(img, dtype=np.float64) @ LUMINANCE_REC709


def _blocks(y, b=8):
    hh, ww = (y.shape[0] // b) * b, (y.shape[1] // b) * b
    return y[:hh, :ww].reshape(hh // b, b, ww // b, b).mean(axis=(1, 3))


def _pass_blocks(r, n, b=8):
    """(n, by, bx) the 8 x 8 block means of the luminance of each of ``n`` more passes of ``r``."""
    import numpy as np

    out = []
    prev = np.asarray(r.state()[0], dtype=np.float64)
    for _ in range(n):
        r.step(1)
        cur = np.asarray(r.state()[0], dtype=np.float64)
        out.append(_blocks(_luminance(cur - prev), b))
        prev = cur
    return np.array(out)


def _sees_delta(scene, cam, w, h, b=8):
    """(by, bx) the 8 x 8 blocks with a pixel whose camera ray first hits a surface with a delta
    lobe (glass, a mirror): there the sun's own image (a glint smaller than a pixel, found by a
    camera ray now and then, the path tracer's under either integrator) makes rare samples
    thousands of times the rest (measured: one pixel sample of 1,085 where a pass's brightest is
    0.2 on step 10), which the caustic's error would be lost in."""
    import numpy as np

    from viewer.pathtracer.integrator import surface_hits
    from viewer.pathtracer.photons import integrator_for
    from viewer.reference_common.setup import RenderSetup

    it = integrator_for(RenderSetup.from_scene(scene, cam, w, h, 8, integrator="photon"))
    rows, cols = np.divmod(np.arange(w * h), w)
    o, d = it.camera_rays(rows, cols, np.full((w * h, 2), 0.5))
    _t, prim, bu, bv = it.kernel.intersect(o, d, 0.0, np.inf)
    delta = np.zeros(w * h, dtype=bool)
    hit = prim >= 0
    mats = surface_hits(it, d[hit], prim[hit], bu[hit], bv[hit]).mat
    delta[hit] = np.array([m.lobes.has_delta for m in it.s.materials])[mats]
    return _blocks(delta.reshape(h, w).astype(np.float64), b) > 0


def caustic_budget(steps, w, h, ref_passes, workers, checkpoints=(4, 8, 16, 32, 64, 128, 256)):
    """The --budget measurement (see the module docstring); prints one table per step."""
    import numpy as np

    from viewer.pathtracer import ReferenceRenderer
    from viewer.pathtracer import photons as cpu_photons
    from viewer.reference_common.caustics import choose_integrator
    from viewer.scene.camera import OrbitCamera
    from viewer.scene.lecture import tour_scene

    scale = (480 * 270) / (w * h)
    print(f"caustic budget at {w}x{h} ({workers} workers; bake --lecture renders 480x270: seconds x {scale:.1f}),"
          f" reference {ref_passes} passes", flush=True)
    for step in steps:
        scene = tour_scene(step - 1)
        cam = OrbitCamera.from_scene(scene)
        name, why = choose_integrator(scene)

        def make(seed, wk=workers):
            return ReferenceRenderer(scene, camera=cam, width=w, height=h, max_depth=8, seed=seed, workers=wk,
                                     integrator="photon")

        # the same estimator without the gather (one process: the patch reaches no worker pool)
        gather = cpu_photons.CausticMap.gather
        cpu_photons.CausticMap.gather = lambda *a_, **k_: None
        try:
            with make(12, 0) as r:
                r.step(64)
                rest = _blocks(_luminance(r.mean()))
        finally:
            cpu_photons.CausticMap.gather = gather
        t0 = time.perf_counter()
        with make(11) as r:
            ref_p = _pass_blocks(r, ref_passes)
        t_ref = time.perf_counter() - t0
        bref = ref_p.mean(axis=0)
        region = (bref > 0) & ((bref - rest) >= 0.10 * bref) & ~_sees_delta(scene, cam, w, h)
        share = float((bref - rest)[region].sum() / max(bref[region].sum(), 1e-30))
        print(f"step {step}: auto picks {name} ({why}); reference {t_ref:.0f} s; caustic region "
              f"{int(region.sum())} of {region.size} blocks, the photon map's share there {share:.0%}", flush=True)
        if not region.any():
            continue
        ref_region = ref_p[:, region].mean(axis=1)                 # per pass: the region's mean
        ref_mean = ref_region.mean()
        ref_se = ref_region.std(ddof=1) / np.sqrt(ref_passes) / ref_mean
        with make(1) as r:
            r.warm_up()
            t0 = time.perf_counter()
            run_p = []
            rows = []
            done = 0
            for n in checkpoints:
                run_p.append(_pass_blocks(r, n - done))
                done = n
                sec = time.perf_counter() - t0
                allp = np.concatenate(run_p)
                b = allp.mean(axis=0)
                reg = allp[:, region].mean(axis=1)
                err = float(reg.mean() / ref_mean - 1.0)
                se = float(reg.std(ddof=1) / np.sqrt(n) / ref_mean) if n > 1 else float("nan")
                rel = np.abs(b[region] / bref[region] - 1.0)
                rows.append((n, sec, err, se, float(np.median(rel)), float(np.percentile(rel, 90))))
        ok = [abs(e) <= 0.05 and med <= 0.05 for _n, _s, e, _se, med, _p in rows]
        first = next((k for k in range(len(rows)) if all(ok[k:])), None)
        for k, (n, sec, err, se, med, p90) in enumerate(rows):
            print(f"  {n:4d} passes {sec:7.1f} s (~{sec * scale:6.0f} s at 480x270): region mean {err:+.1%} "
                  f"(run's standard error {se:.1%}), blocks median {med:.1%}, p90 {p90:.1%}"
                  f"{'  <- within 5% from here on' if k == first else ''}", flush=True)
        said = (f"{rows[first][0]} passes, {rows[first][1]:.0f} s here, about {rows[first][1] * scale:.0f} s at 480x270"
                if first is not None else f"not within 5% for good by {checkpoints[-1]} passes")
        print(f"  step {step}: the reference's own standard error on the region's mean {ref_se:.1%}; "
              f"caustic within 5%: {said}; the bake's budget is 256 passes", flush=True)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--size", default=None, help="default 160x96; with --budget 160x90")
    ap.add_argument("--seconds", type=float, default=60.0)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--png", default=None)
    ap.add_argument("--budget", action="store_true", help="the prepared lecture's budget per glass step")
    ap.add_argument("--steps", default="2,3,10,11,13", help="with --budget: 1-based lecture steps")
    ap.add_argument("--ref-passes", type=int, default=512)
    a = ap.parse_args(argv)
    if a.budget:
        w, h = (int(x) for x in (a.size or "160x90").split("x"))
        caustic_budget([int(s) for s in a.steps.split(",")], w, h, a.ref_passes, a.workers)
        return 0
    w, h = (int(x) for x in (a.size or "160x96").split("x"))

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
