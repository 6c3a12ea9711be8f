"""Traced lecture steps, cold and prepared: `python benchmarks/lecture_trace.py [--width 1920
--height 1080] [--steps 2,3] [--no-before]` (prints numbers, asserts nothing).

For every lecture step with traced glass or mirrors, at a view of W x H pixels:

- *cold*: the window's progressive trace from an empty traced-frame cache (``ProgressiveTrace``
  stepped with the session's frame budget, as the window does on a still view): the time until
  the half-resolution pass covers the traced area, and until the trace is complete (its true
  elapsed time, the untraced first frame included);
- *before*: the same view traced the way the window did before the mask (every pixel, bands of
  rows from the top, tiles of at most 4,096 pixels, the view's MSAA in every tile, the whole
  frame's MSAA resolve per tile): emulated here with the renderer's ``region`` frames, so both
  run on the same machine in the same minute (the machine is shared: compare the ratio);
- *prepared*: the step opened again from the traced-frame cache (Prepare lecture filled it) at
  the size it was traced, and *lecture view*: opened in the view a W x H window lays out in
  lecture mode with the plots docked at UI scale 1.5 (the entry's centre columns).

Then the whole tour's preparation (``LecturePrep.run``, what Prepare lecture and
``brdf-viewer bake --lecture`` do) from an empty cache. The cache is a temporary folder; the
first frame of each step (program compiles, environment prefiltering, BVH upload) is rendered at
64 x 36 first and left out of every number.
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

OLD_STRIP_PIXELS = 4096


def before(renderer, ctx, scene, w, h, budget_s):
    """The former progressive trace's work: bands of rows from the top over the whole width
    (tiles from the left when a band is over the budget), the view's MSAA, every pixel; seconds."""
    t0 = time.perf_counter()
    renderer.render(scene, None, w, h, raytrace=False)
    ctx.finish()
    rows_done, pixels, first = 0, 2 * w, True
    while rows_done < h:
        top = h - rows_done
        rows = 2 if first else (max(4, pixels // w // 4 * 4) + top % 4 if pixels >= 4 * w else (top % 4 or 4))
        first = False
        band = min(rows, top)
        x = 0
        while x < w:
            tw = w if pixels >= band * w else max(16, pixels // band // 4 * 4)
            tw = min(tw, w - x)
            t1 = time.perf_counter()
            hdr = renderer.render(scene, None, w, h, region=(x, top - band, tw, band))
            renderer.resolved_framebuffer(hdr).read(viewport=(x, top - band, tw, band), components=4, dtype="f4")
            ctx.finish()
            dt = max(time.perf_counter() - t1, 1e-6)
            n = tw * band
            pixels = max(16, min(int(1.5 * n) + 16, int(n * budget_s / dt), OLD_STRIP_PIXELS))
            x += tw
        rows_done += band
    return time.perf_counter() - t0


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--width", type=int, default=1920)
    ap.add_argument("--height", type=int, default=1080)
    ap.add_argument("--steps", default="", help="1-based lecture steps (default: every traced step)")
    ap.add_argument("--no-before", action="store_true", help="skip the former trace (it takes minutes a step)")
    args = ap.parse_args(argv)
    os.environ["BRDF_VIEWER_CACHE"] = tempfile.mkdtemp(prefix="brdf-viewer-bench-")

    from viewer.app.layout import view_columns, window_layout
    from viewer.app.lecture_prep import LecturePrep, traced_steps
    from viewer.app.view_frames import TRACE_BUDGET_S
    from viewer.gl.context import create_offscreen_context
    from viewer.gl.raytrace import ProgressiveTrace
    from viewer.gl.renderer import Renderer
    from viewer.scene.lecture import TOUR, tour_scene

    ctx = create_offscreen_context()
    renderer = Renderer(ctx)
    w, h = args.width, args.height
    steps = [int(s) - 1 for s in args.steps.split(",") if s] or traced_steps()
    print(f"{ctx.info['GL_RENDERER']}, view {w}x{h}, frame budget {TRACE_BUDGET_S * 1000:.0f} ms, "
          f"{os.cpu_count()} CPUs, load {os.getloadavg()[0]:.1f}", flush=True)
    print(f"{'step':<40} {'masked':>7} {'coarse s':>9} {'cold s':>8} {'before s':>9} {'ratio':>6} {'prepared s':>11} "
          f"{'lecture view s':>15}")
    for i in steps:
        scene = tour_scene(i)
        renderer.render(scene, None, 64, 36)
        renderer.render(scene, None, 64, 36, raytrace=False)
        ctx.finish()
        pt = ProgressiveTrace(ctx)
        pt.start(renderer, scene, None, w, h, cache=True, store=True)
        coarse_s = None
        while not pt.done:
            pt.step(TRACE_BUDGET_S)
            if coarse_s is None and not pt.coarse:
                coarse_s = time.perf_counter() - pt.started
        cold = pt.elapsed_s
        masked = pt.mask.mean()
        pt.start(renderer, scene, None, w, h, cache=True)
        prepared = pt.elapsed_s if pt.from_cache else float("nan")
        # the lecture's own view in a window of w x h (strip, plots docked, UI 1.5): the entry's centre
        lw = view_columns(window_layout(w, h, 1.5, lecture=True, plots=True)["view"], 1.0, w)[1]
        pt.start(renderer, scene, None, lw, h, cache=True)
        lecture_view = pt.elapsed_s if pt.from_cache else float("nan")
        pt.release()
        old = float("nan") if args.no_before else before(renderer, ctx, scene, w, h, TRACE_BUDGET_S)
        label = f"{i + 1}. {TOUR[i].title}"[:40]
        print(f"{label:<40} {100 * masked:6.1f}% {coarse_s or 0.0:9.1f} {cold:8.1f} {old:9.1f} "
              f"{old / cold:6.2f} {prepared:11.2f} {lecture_view:15.2f}", flush=True)
    os.environ["BRDF_VIEWER_CACHE"] = tempfile.mkdtemp(prefix="brdf-viewer-bench-")
    prep = LecturePrep(ctx, renderer, (w, h), steps)
    prep.run()
    print(f"preparation of the tour ({len(steps)} traced steps, empty cache): {prep.elapsed_s:.1f} s")
    renderer.release()
    return 0


if __name__ == "__main__":
    sys.exit(main())
