"""Cost of glass shadows and traced environment occlusion: `python benchmarks/glass_shadow.py
[--frames 3] [--width 1280 --height 720]` (prints numbers, asserts nothing).

Glass shadows (viewer/gl/shadow.py): a scene of a glass ball, an absorbing glass slab and an
opaque ball on a floor under a point light, against the same scene with glass shadows switched
off for the run (``glass_shadows`` of ``program_set`` and ``frame_passes``: the glass is then
drawn into the depth atlas and casts an opaque shadow, as before there were glass shadows): the
frame when nothing moves (the atlases are kept: the cost is the GLASS_SHADOW variant's extra taps)
and the frame after the light moved (both atlases drawn again: six cube faces).

Environment occlusion (the ENV_OCCLUSION variant of traced frames): the traced frame of the
Lambert sphere over a mirror floor and of lecture step 10 (absorbing glass balls on a floor under
the sky) with occlusion against the same frame without it (``program_set.env_occluded`` switched
off for the run), and the untraced frame for scale. The first frame of each configuration
(shader compilation, BVH upload, IBL prefiltering) is rendered at 64 x 36 first, then one at the
timed size (its targets), both left out.
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

from scene_text import camera, environment, material, mirror_floor, obj, point_light, render, scene  # noqa: E402


def glass_scene(glass: bool) -> str:
    g = dict(model="dielectric", ior=1.5) if glass else dict(model="lambert", albedo=[0.8, 0.8, 0.8])
    slab = dict(g, sigma_a=[0.5, 2.0, 4.0]) if glass else g
    return scene(camera([0.0, 1.6, 4.0], [0.0, 0.4, 0.0], 40.0, 1280, 720, up=[0.0, 1.0, 0.0]),
                 environment(constant=[0.1, 0.1, 0.12]), render(ibl="split_sum", shadows=True),
                 point_light([-1.5, 4.0, 2.0], [40.0, 40.0, 40.0]),
                 obj("plane", "floor", scale=4.0),
                 obj("sphere", "ball", scale=0.4, translate=[-0.8, 0.4, 0.0]),
                 obj("cube", "slab", scale=[0.5, 0.05, 0.5], translate=[0.6, 0.8, 0.0]),
                 obj("sphere", "opaque", scale=0.3, translate=[0.2, 0.3, 0.9]),
                 material("floor", model="lambert", albedo=[0.6, 0.6, 0.6]),
                 material("ball", **g), material("slab", **slab),
                 material("opaque", model="lambert", albedo=[0.7, 0.3, 0.2]))


def _time(r, sc, cam, w, h, frames, before=None) -> float:
    r.render(sc, cam, 64, 36)   # compile, upload, prefilter
    r.render(sc, cam, w, h)     # the targets of this size (the first frame at a size costs seconds)
    r.ctx.finish()
    out = []
    for _ in range(frames):
        if before is not None:
            before()
        t = time.perf_counter()
        r.render(sc, cam, w, h)
        r.ctx.finish()
        out.append(time.perf_counter() - t)
    return statistics.median(out)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frames", type=int, default=3, help="timed frames per configuration (median)")
    ap.add_argument("--width", type=int, default=1280)
    ap.add_argument("--height", type=int, default=720)
    args = ap.parse_args(argv)

    import tomllib

    from viewer.gl import frame_passes, program_set, shadow
    from viewer.gl.context import create_offscreen_context
    from viewer.gl.renderer import Renderer
    from viewer.scene import parse_scene
    from viewer.scene.camera import OrbitCamera
    from viewer.scene.lecture import TOUR, tour_scene

    ctx = create_offscreen_context()
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    print(f"GL: {ctx.info['GL_RENDERER']} | {os.cpu_count()} CPU cores | load average {load:.1f} at start | "
          f"median of {args.frames} frames at {args.width} x {args.height}")
    r = Renderer(ctx)
    w, h = args.width, args.height
    try:
        print("glass shadows (a glass ball and an absorbing slab; peer: the same scene with glass casting "
              "opaque shadows, as before glass shadows)")
        sc = parse_scene(tomllib.loads(glass_scene(True)), None)
        cam = OrbitCamera.from_scene(sc)
        light = sc.lights[0]

        def nudge():
            light.position = [light.position[0], light.position[1], light.position[2] + 1e-3]

        for moving in (False, True):
            t = {}
            for glass in (False, True):
                switch = (lambda s: False) if not glass else shadow.glass_shadows
                program_set.glass_shadows = frame_passes.glass_shadows = switch
                try:
                    t[glass] = _time(r, sc, cam, w, h, args.frames, nudge if moving else None)
                finally:
                    program_set.glass_shadows = frame_passes.glass_shadows = shadow.glass_shadows
            what = "light moving (atlases redrawn)" if moving else "still (atlases kept)"
            print(f"  {what:32s} opaque glass {1e3 * t[False]:8.1f} ms   glass shadows {1e3 * t[True]:8.1f} ms   "
                  f"ratio {t[True] / t[False]:.2f}")
        print("environment occlusion in traced frames (peer: traced without occlusion)")
        keep = program_set.env_occluded
        scenes = {"mirror floor": parse_scene(tomllib.loads(mirror_floor(w, h, ssr=False)), None),
                  "lecture 10 (absorbing glass)": tour_scene([s.key for s in TOUR].index("absorbing_glass"))}
        for name, sc in scenes.items():
            cam = OrbitCamera.from_scene(sc)
            sc.render.raytrace = False
            t_off = _time(r, sc, cam, w, h, args.frames)
            sc.render.raytrace = True
            program_set.env_occluded = lambda *a: False
            try:
                t_plain = _time(r, sc, cam, w, h, args.frames)
            finally:
                program_set.env_occluded = keep
            t_occ = _time(r, sc, cam, w, h, args.frames)
            print(f"  {name:30s} untraced {1e3 * t_off:8.1f} ms   traced {1e3 * t_plain:8.1f} ms   "
                  f"traced + occlusion {1e3 * t_occ:8.1f} ms   occlusion / traced {t_occ / t_plain:.2f}")
    finally:
        r.release()
    return 0


if __name__ == "__main__":
    sys.exit(main())
