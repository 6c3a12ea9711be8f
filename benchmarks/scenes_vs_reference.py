"""Raster against reference on every built-in scene and lecture step:
`python benchmarks/scenes_vs_reference.py [--size 160x96] [--spp 128] [--only lecture:13 ...]
[--png DIR]` (prints numbers, asserts nothing).

The raster is what the window shows once the view is still (a traced frame where the scene
says ``raytrace = true``, the scene's MSAA and SSR), the reference the CPU engine's at ``--spp``
samples per pixel, max depth 8 (the window's). Per scene: the image means, ``mean rel`` and
``block p90`` of ``viewer.image.compare.agreement`` and the seconds each renderer took. ``--png``
writes raster | reference side by side per scene (sRGB, the scene's exposure)."""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

SCENES = ("default", "sphere", "cornell", "gallery", "reflective_floor", "cornell_glossy", "soap_bubble")


def main(argv=None) -> int:
    from viewer.scene.lecture import TOUR

    ap = argparse.ArgumentParser()
    ap.add_argument("--size", default="160x96")
    ap.add_argument("--spp", type=int, default=128)
    ap.add_argument("--only", nargs="*", default=None)
    ap.add_argument("--png", default=None)
    a = ap.parse_args(argv)
    w, h = (int(x) for x in a.size.split("x"))
    names = a.only or list(SCENES) + [f"lecture:{i + 1}" for i in range(len(TOUR))]

    import numpy as np

    from viewer.scene.camera import OrbitCamera
    from viewer.image.colour import to_srgb8
    from viewer.image.compare import agreement
    from viewer.gl.context import create_offscreen_context
    from viewer.gl.renderer import Renderer
    from viewer.pathtracer import ReferenceRenderer
    from viewer.scene import load_scene

    renderer = Renderer(create_offscreen_context())
    print(f"{'scene':<16} {'raster':>8} {'ref':>8} {'mean rel':>9} {'block p90':>9} {'t raster':>8} {'t ref':>7}")
    for name in names:
        scene = load_scene(name)
        t0 = time.perf_counter()
        raster = renderer.render_arrays(scene, width=w, height=h)[0]
        t1 = time.perf_counter()
        cam = OrbitCamera.from_scene(scene)
        ref = ReferenceRenderer(scene, camera=cam, width=w, height=h, max_depth=8, seed=1)
        try:
            ref.step(a.spp)
            mean = ref.mean()
        finally:
            ref.close()
        t2 = time.perf_counter()
        g = agreement(raster, mean)
        print(f"{name:<16} {raster.mean():8.4f} {mean.mean():8.4f} {g['mean_rel']:9.3f} {g['block_p90']:9.3f} "
              f"{t1 - t0:8.2f} {t2 - t1:7.1f}", flush=True)
        if a.png:
            from PIL import Image

            out = Path(a.png)
            out.mkdir(parents=True, exist_ok=True)
            e, tm = scene.render.exposure, scene.render.tonemap
            pair = np.concatenate([to_srgb8(raster, e, tm), to_srgb8(mean, e, tm)], axis=1)
            Image.fromarray(pair).save(out / f"{name.replace(':', '_')}.png")
    renderer.release()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
