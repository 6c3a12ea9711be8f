"""Cost of traced specular chains: `python benchmarks/raytrace.py [--frames 3] [--quick]`
(prints numbers, asserts nothing).

Frame time of the offscreen renderer (the one the window draws with) with ``[render] raytrace``
on and off, on three scenes: a smooth glass ball under the studio map, the lecture's glass cube
turned 35 degrees (total internal reflection) and a Lambert sphere over a mirror floor. Sizes:
1280 x 720 with the scene's MSAA; the window's 3D view at full quality (a 1280 x 720 window less
its 360 px panel: 920 x 720, MSAA); and its preview while the camera moves (half that, no MSAA:
460 x 360), which is what must stay interactive. The first frame of each configuration
(shader compilation, BVH upload, IBL prefiltering) is rendered at 64 x 36 first and left out.
``--quick``: the preview size only. The preview comes first, so a cut-short run still says it.

Then the window's frames with ray tracing on (``viewer.app.session``): a preview frame while the
view moves (460 x 360, no MSAA, traced materials drawn untraced: ``render(raytrace=False)``), the
first still frame (the untraced view at full quality, 920 x 720 with MSAA; 460 x 360 with
``--quick``), the refining frames that trace a strip of rows each (``ProgressiveTrace.step`` with
the session's budget: median and longest) and the time until the traced image is complete.
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "tests"))   # scene_text: the scenes the tests render too

from scene_text import glass_ball, mirror_floor  # noqa: E402

GLASS_BALL = glass_ball()

MIRROR_FLOOR = mirror_floor()

SIZES = (("window preview 460x360, no MSAA", 460, 360, 0), ("window view 920x720, MSAA", 920, 720, None),
         ("1280x720, MSAA", 1280, 720, None))


def _scenes():
    import tomllib

    from viewer.scene.lecture import TOUR, tour_scene
    from viewer.scene import parse_scene

    return {"glass ball": parse_scene(tomllib.loads(GLASS_BALL), None),
            "TIR cube (lecture)": tour_scene([s.key for s in TOUR].index("tir")),
            "mirror floor": parse_scene(tomllib.loads(MIRROR_FLOOR), None)}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frames", type=int, default=2, help="timed frames per configuration (median)")
    ap.add_argument("--quick", action="store_true", help="the preview size only")
    args = ap.parse_args(argv)

    from viewer.scene.camera import OrbitCamera
    from viewer.gl.context import create_offscreen_context
    from viewer.gl.renderer import Renderer

    ctx = create_offscreen_context()
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    print(f"GL: {ctx.info['GL_RENDERER']} | {os.cpu_count()} CPU cores | load average {load:.1f} at start | "
          f"median of {args.frames} frames")
    r = Renderer(ctx)
    sizes = SIZES[:1] if args.quick else SIZES
    print(f"{'size':34s} {'scene':20s} {'raytrace off':>14s} {'raytrace on':>14s} {'ratio':>6s}")
    scenes = _scenes()
    try:
        for label, w, h, msaa in sizes:
            for name, scene in scenes.items():
                cam = OrbitCamera.from_scene(scene)
                scene.render.ssr = False
                med = {}
                for rt in (False, True):
                    scene.render.raytrace = rt
                    r.render(scene, cam, 64, 36, msaa=msaa)  # compile, upload, prefilter
                    ctx.finish()
                    ts = []
                    for _ in range(args.frames):
                        t = time.perf_counter()
                        r.render(scene, cam, w, h, msaa=msaa)
                        ctx.finish()
                        ts.append(time.perf_counter() - t)
                    med[rt] = statistics.median(ts)
                print(f"{label:34s} {name:20s} {1000 * med[False]:11.1f} ms {1000 * med[True]:11.1f} ms "
                      f"{med[True] / med[False]:5.1f}x", flush=True)
        window_frames(ctx, r, scenes, args.quick)
    finally:
        r.release()
    return 0


def window_frames(ctx, r, scenes, quick):
    from viewer.app.view_frames import TRACE_BUDGET_S
    from viewer.scene.camera import OrbitCamera
    from viewer.gl.raytrace import ProgressiveTrace

    w, h, msaa = (460, 360, 0) if quick else (920, 720, None)
    print(f"\nwindow, ray tracing on (still view {w}x{h}{'' if quick else ', MSAA'}; strip budget "
          f"{1000 * TRACE_BUDGET_S:.0f} ms)")
    print(f"{'scene':20s} {'preview':>10s} {'still, untraced':>16s} {'refining median':>16s} {'longest':>9s} "
          f"{'frames':>7s} {'traced after':>13s}")
    pt = ProgressiveTrace(ctx)
    try:
        for name, scene in scenes.items():
            cam = OrbitCamera.from_scene(scene)
            scene.render.ssr, scene.render.raytrace = False, True
            r.render(scene, cam, 64, 36, msaa=0, raytrace=False)
            r.render(scene, cam, 64, 36, msaa=msaa)  # compile both variants
            ctx.finish()
            t = time.perf_counter()
            r.render(scene, cam, 460, 360, msaa=0, raytrace=False)
            ctx.finish()
            preview = time.perf_counter() - t
            t0 = time.perf_counter()
            pt.start(r, scene, cam, w, h, msaa=msaa)
            ctx.finish()
            still = time.perf_counter() - t0
            ts = []
            while not pt.done:
                t = time.perf_counter()
                pt.step(TRACE_BUDGET_S)
                ts.append(time.perf_counter() - t)
            total = time.perf_counter() - t0
            med = statistics.median(ts)
            print(f"{name:20s} {1000 * preview:7.1f} ms {1000 * still:13.1f} ms {1000 * med:13.1f} ms "
                  f"{1000 * max(ts):6.0f} ms {len(ts):7d} {total:11.1f} s", flush=True)
    finally:
        pt.release()


if __name__ == "__main__":
    raise SystemExit(main())
