"""Soak test of the window app: N frames of random student actions, under a real X server.

    xvfb-run -a -s "-screen 0 1600x1000x24" python benchmarks/soak.py --frames 10000

Actions, drawn at random (seeded) between frames: model switches, slider moves with typed values
(NaN, +-Inf, negative, huge, the range's ends, ordinary values) going through the GUI's own
validation, exposure typed as NaN / Inf, window resizes (including a 0x0 framebuffer, as when
minimized), environment switches (including a file that does not exist), compare-view changes,
camera moves while the reference renders (each one restarts it), lecture steps, the plots window
and the UI scale. After every frame: glGetError must be GL_NO_ERROR and the image finite.

Printed: frames, actions per kind, failures, resident memory, Python's allocated blocks and
objects (to tell Python-side growth from the GL driver's) and the count of live GL objects
(textures, buffers, framebuffers, renderbuffers, programs, shaders, vertex arrays, queried with
glIs* over the names in use) at frame 1,000 and at the end. ``--json`` prints one JSON line.
"""

from __future__ import annotations

import argparse
import ctypes
import json
import math
import os
import random
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

TYPED = [math.nan, math.inf, -math.inf, -1.0, -1e30, 1e30, 0.0, 1e-30]
ACTIONS = ("model", "slider", "exposure", "resize", "minimize", "environment", "compare", "camera",
           "lecture", "plots", "ui_scale", "view_mode")


def rss_mb() -> float:
    with open("/proc/self/statm") as f:
        pages = int(f.read().split()[1])
    return pages * os.sysconf("SC_PAGE_SIZE") / 2 ** 20


class GLObjects:
    """Live GL object names per kind, by glIs* over 1..max_name (names are small integers,
    handed out lowest-free-first by Mesa, so a leak shows as a growing count)."""

    KINDS = ("Texture", "Buffer", "Framebuffer", "Renderbuffer", "Program", "Shader", "VertexArray", "Query")

    def __init__(self, glfw, max_name: int = 8192):
        proto = ctypes.CFUNCTYPE(ctypes.c_ubyte, ctypes.c_uint)
        self.fns = {}
        for k in self.KINDS:
            addr = glfw.get_proc_address(f"glIs{k}")
            if addr:
                self.fns[k] = proto(addr)
        self.max_name = max_name

    def count(self) -> dict:
        return {k: sum(1 for n in range(1, self.max_name) if fn(n)) for k, fn in self.fns.items()}


def soak(frames: int, seed: int = 0, size=(640, 400), report_at: int = 1000, log=print) -> dict:
    import numpy as np

    from viewer import ViewerError, brdf
    from viewer.app import ui
    from viewer.app.compare_view import MODES
    from viewer.app.main import App
    from viewer.brdf.spec import validate_value
    from viewer.gl.renderer import VIEW_MODES
    from viewer.scene.lecture import TOUR

    rng = random.Random(seed)
    app = App("default", size=size, restore_state=False)
    glo = GLObjects(app.glfw)
    counts = {a: 0 for a in ACTIONS}
    failures: list[str] = []
    snapshots = {}
    rss_series = []  # (frame, MB) every 1,000 frames: a leak climbs steadily, allocator noise does not
    t0 = time.perf_counter()

    def act(kind):
        s = app.session.scene
        counts[kind] += 1
        if kind == "model":
            name = rng.choice(list(s.materials))
            s.materials[name] = brdf.get(rng.choice(brdf.names())).params()
            app.session.dirty = True
        elif kind == "slider":
            name = rng.choice(list(s.materials))
            p = s.materials[name]
            prms = [q for q in brdf.get(p.model).spec.params if q.kind in ("float", "rgb", "choice")]
            if not prms:
                return
            q = rng.choice(prms)
            if q.kind == "choice":
                v = rng.choice(list(q.choices))
            else:
                lo, hi = q.slider_range
                x = rng.choice(TYPED + [lo, hi, rng.uniform(lo, hi), rng.uniform(lo, hi)])
                v = x if q.kind == "float" else [x, rng.uniform(lo, hi), x]
            try:  # what the panel does with a typed value (viewer.app.ui.material_editor)
                v = validate_value(q, v, f"{p.model}.{q.name}", brdf.lookup_spec)
            except ViewerError:
                return
            s.materials[name] = p.replace(**{q.name: v})
            app.session.dirty = True
        elif kind == "exposure":
            s.render.exposure = ui.finite_or(rng.choice(TYPED + [rng.uniform(-5, 5)]), s.render.exposure)
            s.render.exposure = float(np.clip(s.render.exposure, -10, 10))
        elif kind == "resize":
            app.glfw.set_window_size(app.window, rng.randint(1, 900), rng.randint(1, 600))
        elif kind == "minimize":  # a 0x0 framebuffer for a few frames
            real = app.glfw.get_framebuffer_size
            app.glfw.get_framebuffer_size = lambda w: (0, 0)
            for _ in range(3):
                app.frame()
            app.glfw.get_framebuffer_size = real
        elif kind == "environment":
            app.session.set_environment(rng.choice([None, "sky", "studio", "/nonexistent/map.hdr"]))
        elif kind == "compare":
            app.session.set_image_mode(rng.choice(MODES))
        elif kind == "camera":
            app.session.camera.orbit(rng.uniform(-50, 50), rng.uniform(-30, 30), 400)
            app.session.dirty = True
        elif kind == "lecture":
            app.session.lecture(rng.randrange(len(TOUR)) if rng.random() < 0.8 else None)
        elif kind == "plots":
            app.plots.visible = not app.plots.visible
        elif kind == "ui_scale":
            app.set_ui_scale(rng.choice([0.5, 1.0, 1.5, 3.0, math.nan]))
        elif kind == "view_mode":
            app.session.view_mode = rng.randrange(len(VIEW_MODES))
            app.session.dirty = True

    weights = {"model": 3, "slider": 8, "exposure": 1, "resize": 1, "minimize": 0.3, "environment": 0.5,
               "compare": 1, "camera": 2, "lecture": 0.5, "plots": 0.5, "ui_scale": 0.3, "view_mode": 1}
    kinds, w = zip(*weights.items())
    try:
        for i in range(1, frames + 1):
            if rng.random() < 0.35:
                act(rng.choices(kinds, w)[0])
            try:
                app.frame()
            except Exception as e:  # noqa: BLE001 - a soak failure to report, not to hide
                failures.append(f"frame {i}: {type(e).__name__}: {e}")
                if len(failures) > 20:
                    break
            err = app.ctx.error
            if err != "GL_NO_ERROR":
                failures.append(f"frame {i}: {err}")
            if app.session.hdr is not None and i % 50 == 0 and app.session.view_mode == 0:
                img = app.session.renderer.read_linear(app.session.hdr)
                if not np.isfinite(img).all() or img.min() < 0:
                    failures.append(f"frame {i}: non-finite or negative pixels "
                                    f"(model(s) {sorted({m.model for m in app.session.scene.materials.values()})})")
            if i % 1000 == 0:
                rss_series.append((i, round(rss_mb(), 1)))
            if i in (report_at, frames):
                app.session.set_image_mode("raster")  # the reference's images are not GL objects; settle it
                app.frame()
                import gc

                gc.collect()
                snapshots[i] = {"rss_mb": round(rss_mb(), 1), "gl": glo.count(),
                                "python_blocks": sys.getallocatedblocks(), "python_objects": len(gc.get_objects()),
                                "elapsed_s": round(time.perf_counter() - t0, 1)}
                log(f"frame {i}: {snapshots[i]}")
    finally:
        app.close()
    drift_check(snapshots, report_at, frames, failures)
    return {"frames": frames, "seed": seed, "actions": counts, "failures": failures, "snapshots": snapshots,
            "rss_series": rss_series}


# Allowed drift between the report frame (1,000) and the end:
# - resident memory: 64 MB. Python's own heap is reported separately and stays within 1%; the
#   rest is the GL driver, which keeps the machine code of every program variant it compiled
#   (llvmpipe: a few MB each), and the allocator's arenas, which do not shrink.
# - GL programs and shaders: the forward program is compiled per material model and variant
#   (SSR, IBL mode, environment kind) on first use and cached, so their count grows until every
#   combination the actions reached was compiled (bounded: 10 models x a few variants), never by
#   repetition; the check allows that growth only.
# - vertex arrays: one per (program, mesh) and one per full-screen program, released with either,
#   so at every snapshot VAOs <= programs x (meshes + 1), meshes = buffers / 2 (vertex + index).
# - textures, buffers, framebuffers, renderbuffers: +4 (render targets are made per size and
#   feature, e.g. SSR's when a lecture step turns it on; a leak grows without bound).
RSS_DRIFT_MB = 64.0
OBJECT_SLACK = 4
BOUNDED = ("Program", "Shader", "VertexArray")


def drift_check(snapshots, report_at, frames, failures):
    if report_at not in snapshots or frames not in snapshots or report_at == frames:
        return
    a, b = snapshots[report_at], snapshots[frames]
    if b["rss_mb"] - a["rss_mb"] > RSS_DRIFT_MB:
        failures.append(f"resident memory grew {b['rss_mb'] - a['rss_mb']:.1f} MB (allowed {RSS_DRIFT_MB})")
    for k, n in b["gl"].items():
        if k not in BOUNDED and n > a["gl"].get(k, 0) + OBJECT_SLACK:
            failures.append(f"live GL {k} objects grew {a['gl'].get(k, 0)} -> {n} (allowed +{OBJECT_SLACK})")
    for frame, snap in snapshots.items():
        gl = snap["gl"]
        bound = gl.get("Program", 0) * (gl.get("Buffer", 0) // 2 + 1)
        if gl.get("VertexArray", 0) > bound:
            failures.append(f"frame {frame}: {gl['VertexArray']} vertex arrays > programs x (meshes + 1) = {bound}")


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--frames", type=int, default=10000)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--report-at", type=int, default=1000)
    ap.add_argument("--json", action="store_true")
    a = ap.parse_args()
    res = soak(a.frames, a.seed, report_at=min(a.report_at, a.frames),
               log=(lambda *x: print(*x, file=sys.stderr)) if a.json else print)
    if a.json:
        print(json.dumps(res))
    else:
        print(f"{res['frames']} frames, actions: {res['actions']}")
        print("resident memory every 1,000 frames (MB): " + " ".join(f"{mb:.0f}" for _, mb in res["rss_series"]))
        print(f"failures: {len(res['failures'])}")
        for f in res["failures"][:20]:
            print("  " + f)
    return 1 if res["failures"] else 0


if __name__ == "__main__":
    sys.exit(main())
