"""How fast a prepared traced step opens in every layout of the window it was prepared for:

    python benchmarks/prepared_open.py [--width 1920 --height 1080] [--steps 3] [--cache DIR]

Prepares the steps as ``brdf-viewer bake --lecture --width W --height H`` does (the window's
*Prepare lecture* runs that same command for its own size) into a temporary cache, then opens
each step from the cache (``ProgressiveTrace.start(cache=True)``, what the window does when a
step is shown) at the view size of every layout a W x H window has: the lecture strip or the
side panel, plots docked or not, UI scale 1, 1.5 and 2, the interface hidden. Prints the
preparation's time and, per step and layout, the view size, whether it was a hit and the
seconds until the finished view was in the texture, with the process's CPU seconds in that time
(on a loaded machine the rest is waiting for a core). ``--cache DIR``: prepare into (and open
from) DIR instead of a temporary folder, so a second run finds the steps prepared and measures
the opening alone. Asserts nothing."""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--width", type=int, default=1920)
    ap.add_argument("--height", type=int, default=1080)
    ap.add_argument("--steps", default="3", help="1-based lecture steps with traced chains")
    ap.add_argument("--cache", help="the cache folder to prepare into (default: a new temporary one)")
    args = ap.parse_args(argv)
    os.environ["BRDF_VIEWER_CACHE"] = args.cache or tempfile.mkdtemp(prefix="brdf-viewer-bench-")
    print(f"cache {os.environ['BRDF_VIEWER_CACHE']}; load average {os.getloadavg()[0]:.1f}")
    w, h = args.width, args.height
    t0 = time.perf_counter()
    r = subprocess.run([sys.executable, "-m", "viewer", "bake", "--lecture", "--width", str(w), "--height", str(h),
                        "--steps", args.steps], capture_output=True, text=True)
    print(r.stdout.strip())
    if r.returncode:
        print(r.stderr.strip())
        return r.returncode
    print(f"prepared in {time.perf_counter() - t0:.1f} s (bake --lecture, the window's Prepare lecture runs it)")

    from viewer.app.layout import view_columns, window_layout
    from viewer.gl.context import create_offscreen_context
    from viewer.gl.raytrace import ProgressiveTrace
    from viewer.gl.renderer import Renderer
    from viewer.scene.lecture import TOUR, tour_scene

    ctx = create_offscreen_context()
    renderer = Renderer(ctx)
    layouts = []
    for scale in (1.0, 1.5, 2.0):
        for lecture, plots, name in ((True, False, "strip"), (True, True, "strip + plots"),
                                     (False, False, "side panel"), (False, True, "side panel + plots")):
            v = window_layout(w, h, scale, lecture=lecture, plots=plots)["view"]
            layouts.append((f"{name}, UI {scale:g}", view_columns(v, 1.0, w)[1]))
    layouts.append(("interface hidden", view_columns(window_layout(w, h, 1.0, show_ui=False)["view"], 1.0, w)[1]))
    print(f"{'step':<28} {'layout':<26} {'view':>10} {'hit':>4} {'open s':>7} {'cpu s':>6} {'done':>5}")
    for step in [int(s) - 1 for s in args.steps.split(",")]:
        scene = tour_scene(step)
        renderer.render(scene, None, 64, 36, raytrace=False)  # programs and environment: not in the figure
        pt = ProgressiveTrace(ctx)
        for name, vw in layouts:
            t, c = time.perf_counter(), time.process_time()
            pt.start(renderer, scene, None, vw, h, cache=True)
            ctx.finish()
            dt, dc = time.perf_counter() - t, time.process_time() - c
            # "done": the trace has nothing left to draw (the view is complete, not a first pass)
            print(f"{TOUR[step].title[:28]:<28} {name:<26} {f'{vw}x{h}':>10} {'yes' if pt.from_cache else 'no':>4} "
                  f"{dt:7.3f} {dc:6.3f} {'yes' if pt.done else 'no':>5}", flush=True)
        pt.release()
    renderer.release()
    return 0


if __name__ == "__main__":
    sys.exit(main())
