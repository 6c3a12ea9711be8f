"""The window's live reference, measured in a real window:

    xvfb-run -a -s "-screen 0 1600x1000x24" python benchmarks/window_reference.py [--engines auto,cpu] [--scene default]

The built-in gallery (or the scene ``--scene`` names) in the split view (raster | reference) of a 1280x720 window: the
reference's samples per pixel after 5, 20 and 60 s, its samples/s, and the frame time while it
runs (median and 90th percentile of the frames drawn; the window's loop, ``App.tick``, sleeps
between them while only the reference changes), then the frame time while the camera orbits
(a drag simulated as the window's input handling does it: 8 pixels per frame for 10 s), once per
engine (``auto``: what the window uses, the kind of OpenGL decides; ``cpu``: the CPU engine on a background thread, as before
the GPU engine existed). Then the variance views (standard error, relative error, samples
needed) with the convergence plot: the time to compute and upload one error map, and the frame
time with the view on.

Each engine runs in its own child process with an empty reference cache (so no stored image
gives it a head start). Prints numbers, asserts nothing.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

MARKS = (5.0, 20.0, 60.0)


def child(engine: str, scene: str = "gallery") -> None:
    from viewer.app.main import App
    from viewer.image.variance import ERROR_VIEWS

    app = App(scene, size=(1280, 720), restore_state=False)
    app.frame()
    rv = app.session.reference_view()
    rv.engine_request = engine
    app.session.set_image_mode("split")
    tick = getattr(app, "tick", lambda: app.frame() or True)   # (a window without tick draws flat out)
    t0 = time.perf_counter()
    spp_at, frames = {}, []
    while len(spp_at) < len(MARKS):
        t = time.perf_counter()
        if tick():   # the window's loop: a frame, or a sleep while only the reference changes
            frames.append((t - t0, app.frame_ms))
        el = time.perf_counter() - t0
        for m in MARKS:
            if m not in spp_at and el >= m:
                spp_at[m] = rv.spp
    vw, vh = app.viewport()[2:]
    first = max((f for t, f in frames[:3]), default=0.0)
    ft = np.array([f for t, f in frames[3:]] or [np.nan])   # after the first frames (programs compile)
    # orbiting: the drag as InputKeys.handle applies it, every frame for 10 s
    drag, t2 = [], time.perf_counter()
    while time.perf_counter() - t2 < 10.0:
        app.session.camera.orbit(8.0, 0.0, vh)
        app.session.changed()
        app.keys.last_interaction = app.keys.last_event = time.perf_counter()
        if tick():
            drag.append(app.frame_ms)
    dt = np.array(drag[1:] or [np.nan])
    spp_drag = rv.spp
    # the variance views need a variance: at least 2 whole samples per pixel (5 minutes at most)
    t1 = time.perf_counter()
    while rv.latest_variance() is None and time.perf_counter() - t1 < 300:
        app.frame()
    t_var = time.perf_counter() - t0
    print(f"engine {engine!r} -> {rv.engine} ({rv.engine_reason})")
    print(f"   {scene}, split view, window 1280x720 (view {vw}x{vh}, reference {rv.scale:g} x the view's resolution)")
    print("   reference spp after " + ", ".join(f"{m:.0f} s: {spp_at[m]}" for m in MARKS)
          + f"; {rv.samples_per_second / 1e3:.0f} k samples/s")
    print(f"   frame time while the reference runs: median {np.median(ft):.0f} ms, 90th percentile "
          f"{np.percentile(ft, 90):.0f} ms ({len(ft)} frames after the first 3; the longest of those "
          f"{first:.0f} ms); {len(frames) / MARKS[-1]:.1f} frames/s drawn)")
    print(f"   frame time while orbiting: median {np.median(dt):.0f} ms, 90th percentile "
          f"{np.percentile(dt, 90):.0f} ms ({len(dt)} frames in 10 s; reference at {spp_drag} spp: it restarts when the drag pauses)")
    got = rv.latest_variance()
    print(f"   a variance (>= 2 spp) after {t_var:.0f} s" if got else "   no variance after 5 more minutes")
    # the variance views
    app.session.monte_carlo.show_convergence = True
    for view in ERROR_VIEWS:
        app.session.monte_carlo.view = view
        view_ms, frame_ms = [], []
        for _ in range(8):
            app.session.monte_carlo.invalidate()     # recompute the map every frame, as each new pass does
            t = time.perf_counter()
            app.frame()
            frame_ms.append(1000 * (time.perf_counter() - t))
            view_ms.append(app.session.monte_carlo.view_ms)
        got = rv.latest_variance()
        shape = "x".join(map(str, got[1].shape[1::-1])) if got else "?"
        print(f"   variance view {view!r} ({shape} map): compute + upload {np.median(view_ms):.1f} ms; "
              f"frame {np.median(frame_ms):.0f} ms median (convergence plot on)")
    app.glfw.set_window_should_close(app.window, True)
    app.run()


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--engines", default="auto,cpu", help="comma-separated: auto, cpu, gpu (default auto,cpu)")
    ap.add_argument("--scene", default="gallery", help="the scene (default: the built-in gallery)")
    ap.add_argument("--_child", help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args._child:
        child(args._child, args.scene)
        return
    for engine in args.engines.split(","):
        with tempfile.TemporaryDirectory() as tmp:
            env = dict(os.environ, BRDF_VIEWER_CACHE=tmp)
            r = subprocess.run([sys.executable, __file__, "--_child", engine, "--scene", args.scene], env=env, capture_output=True,
                               text=True, timeout=900)
            print(r.stdout, end="")
            if r.returncode != 0:
                print(f"   ({engine}: exit status {r.returncode}: {r.stderr.strip().splitlines()[-1:]})")


if __name__ == "__main__":
    main()
