"""Classroom-viewer figures, in a real window:

    xvfb-run -a -s "-screen 0 1600x1000x24" python benchmarks/classroom.py

Prints the time to step between lecture presets (first visit, which compiles programs and
prefilters environment maps, and a second visit), and the frame time at 1280x720 with the split
view while the reference renders: idle (the raster image cached, the reference's new passes
uploaded and both halves tone mapped) and while the camera moves (a new raster frame and a
reference restart every frame)."""

import os
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
# each figure is one whole frame (a still view drawn in tiles would take several frames to be
# whole; benchmarks/preset_switch.py measures those)
os.environ.setdefault("BRDF_VIEWER_TILED_FRAMES", "0")
os.environ.setdefault("BRDF_VIEWER_PREPARE_FRAMES", "0")  # and a scene's first frame at once


def main():
    from viewer.app.main import App
    from viewer.scene.lecture import TOUR

    app = App("sphere", size=(1280, 720), restore_state=False)
    app.frame()

    def visit():
        out = []
        for i in range(len(TOUR)):
            t = time.perf_counter()
            app.session.lecture(i)
            app.frame()
            out.append(1000 * (time.perf_counter() - t))
        return out

    first, again = visit(), visit()
    print("lecture step, first visit (ms):  " + " ".join(f"{x:.0f}" for x in first))
    print("lecture step, second visit (ms): " + " ".join(f"{x:.0f}" for x in again)
          + f"   median {np.median(again):.0f}")
    app.session.lecture(None)
    app.session.open_scene("default")
    app.session.set_image_mode("split")
    t0 = time.time()
    while (app.session.reference is None or app.session.reference.spp < 4) and time.time() - t0 < 300:
        app.frame()
    idle = []
    for _ in range(20):
        t = time.perf_counter()
        app.frame()
        idle.append(1000 * (time.perf_counter() - t))
    moving = []
    for _ in range(10):
        app.session.camera.orbit(5.0, 0.0, 720.0)
        app.session.dirty = True
        t = time.perf_counter()
        app.frame()
        moving.append(1000 * (time.perf_counter() - t))
    rv = app.session.reference
    print(f"split view 1280x720 (view {app.viewport()[2]}x{app.viewport()[3]}), reference running: "
          f"idle frame {np.median(idle):.0f} ms median, raster render {app.session.render_ms:.0f} ms, "
          f"frame while orbiting {np.median(moving):.0f} ms median; reference {rv.samples_per_second / 1e3:.0f} "
          f"k samples/s at half resolution")
    app.close()


if __name__ == "__main__":
    main()
