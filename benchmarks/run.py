"""Figures for the closing notes: `python benchmarks/run.py` (prints numbers, asserts nothing).

- start to first frame of the window app (under Xvfb when there is no display)
- frame time of the default scene at 1280x720 and 640x360 (the offscreen renderer, which the
  window uses too), full quality (scene MSAA) and the interactive preview (no MSAA)
- whole-process time of `brdf-viewer render` for a 512x512 PNG
- screen-space reflections: the SSR pass alone and the frame with and without SSR at 1280x720
- the plots window's albedo curve of the slowest model (varnished_gold)
"""

from __future__ import annotations

import os
import re
import shutil
import statistics
import subprocess
import sys
import tempfile
import time


def _xvfb():
    if os.environ.get("DISPLAY"):
        return None, os.environ["DISPLAY"]
    if not shutil.which("Xvfb"):
        return None, None
    r, w = os.pipe()
    proc = subprocess.Popen(["Xvfb", "-displayfd", str(w), "-screen", "0", "1600x1000x24", "-nolisten", "tcp"],
                            pass_fds=(w,), stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    os.close(w)
    with os.fdopen(r) as f:
        return proc, ":" + f.readline().strip()


def start_to_first_frame(runs=3):
    proc, display = _xvfb()
    if display is None:
        print("start to first frame: skipped (no display and no Xvfb)")
        return
    env = dict(os.environ, DISPLAY=display)
    firsts, wholes = [], []
    try:
        for _ in range(runs):
            t = time.perf_counter()
            r = subprocess.run([sys.executable, "-m", "viewer", "--frames", "1"], env=env,
                               capture_output=True, text=True, timeout=300)
            wholes.append(time.perf_counter() - t)
            m = re.search(r"first frame after ([0-9.]+) s", r.stderr)
            if m:
                firsts.append(float(m.group(1)))
    finally:
        if proc:
            proc.terminate()
    print(f"window, start to first frame (in-process, after imports): median {statistics.median(firsts):.2f} s")
    print(f"window, process start to exit after 1 frame:              median {statistics.median(wholes):.2f} s")


def frame_times(frames=5):
    from viewer.scene.camera import OrbitCamera
    from viewer.gl.context import create_offscreen_context
    from viewer.gl.renderer import Renderer
    from viewer.scene import load_scene

    ctx = create_offscreen_context()
    print(f"GL: {ctx.info['GL_RENDERER']} | {ctx.info['GL_VERSION']} | {os.cpu_count()} CPU cores")
    r = Renderer(ctx)
    scene = load_scene("default")
    cam = OrbitCamera.from_scene(scene)
    for w, h in ((1280, 720), (640, 360)):
        for label, msaa in (("full (MSAA %d)" % scene.render.msaa, None), ("preview (no MSAA)", 0)):
            r.render(scene, cam, w, h, msaa=msaa)
            ctx.finish()
            ts = []
            for _ in range(frames):
                t = time.perf_counter()
                r.render(scene, cam, w, h, msaa=msaa)
                ctx.finish()
                ts.append(time.perf_counter() - t)
            print(f"default scene {w}x{h} {label:18s}: median {1000 * statistics.median(ts):7.1f} ms/frame")
    # image-based lighting: the studio map, split sum (prefiltering once, not in the frame time)
    ibl_scene = load_scene("default", ['environment={map="studio"}'])
    for mode in ("split_sum", "fis"):
        ibl_scene.render.ibl = mode
        r.render(ibl_scene, cam, 1280, 720)
        ctx.finish()
        ts = []
        for _ in range(frames):
            t = time.perf_counter()
            r.render(ibl_scene, cam, 1280, 720)
            ctx.finish()
            ts.append(time.perf_counter() - t)
        print(f"default scene 1280x720, studio map, IBL {mode:9s}: median {1000 * statistics.median(ts):7.1f} ms/frame")
    r.release()
    ctx.release()


def model_switch():
    """Time to switch the default scene's ball to each model and show a frame at 640x360 (the
    window's preview size): first switch (compiles that model's program, builds its albedo
    table) and a repeat switch (both cached)."""
    from viewer import brdf
    from viewer.scene.camera import OrbitCamera
    from viewer.gl.context import create_offscreen_context
    from viewer.gl.renderer import Renderer
    from viewer.scene import load_scene

    ctx = create_offscreen_context()
    r = Renderer(ctx)
    scene = load_scene("default")
    cam = OrbitCamera.from_scene(scene)
    r.render(scene, cam, 640, 360, msaa=0)
    ctx.finish()
    rows = []
    for name in brdf.names():
        scene.materials["ball"] = brdf.get(name).params()
        t = time.perf_counter()
        r.render(scene, cam, 640, 360, msaa=0)
        ctx.finish()
        first = time.perf_counter() - t
        scene.materials["ball"] = brdf.get("lambert").params()
        r.render(scene, cam, 640, 360, msaa=0)
        scene.materials["ball"] = brdf.get(name).params(**{})
        r.tables.clear()
        t = time.perf_counter()
        r.render(scene, cam, 640, 360, msaa=0)
        ctx.finish()
        rows.append((name, first, time.perf_counter() - t))
    print("model switch (frame at 640x360 incl.): first time (compile) | again (program cached, table rebuilt)")
    for name, a, b in rows:
        print(f"  {name:18s} {1000 * a:7.0f} ms | {1000 * b:7.0f} ms")
    r.release()
    ctx.release()


def ssr_times(frames=5):
    """The reflective-floor scene at 1280x720 (MSAA 4): frame time with SSR on and off, and the
    SSR pass alone (resolve of its three attachments, the colour mip chain and the trace)."""
    from viewer.scene.camera import OrbitCamera
    from viewer.gl.context import create_offscreen_context
    from viewer.gl.renderer import Renderer
    from viewer.scene import load_scene

    ctx = create_offscreen_context()
    r = Renderer(ctx)
    scene = load_scene("reflective_floor")
    cam = OrbitCamera.from_scene(scene)
    w, h = 1280, 720

    def median_ms(fn):
        fn()
        ctx.finish()
        ts = []
        for _ in range(frames):
            t = time.perf_counter()
            fn()
            ctx.finish()
            ts.append(time.perf_counter() - t)
        return 1000 * statistics.median(ts)

    for on in (False, True):
        scene.render.ssr = on
        ms = median_ms(lambda: r.render(scene, cam, w, h))
        print(f"reflective_floor {w}x{h} MSAA 4, SSR {'on ' if on else 'off'}: median {ms:7.1f} ms/frame")
    ibl = r.ibl()
    ms = median_ms(lambda: r.ssr().resolve_and_trace(ibl, cam, w, h, True, scene.environment.rotation_deg))
    print(f"reflective_floor {w}x{h}, the SSR pass alone (resolve, mips, trace): median {ms:7.1f} ms")
    r.release()
    ctx.release()


def render_process(runs=3):
    with tempfile.TemporaryDirectory() as d:
        ts = []
        for i in range(runs):
            t = time.perf_counter()
            subprocess.run([sys.executable, "-m", "viewer", "render", "default", "--out", f"{d}/o{i}.png",
                            "--width", "512", "--height", "512"], check=True, capture_output=True, timeout=300)
            ts.append(time.perf_counter() - t)
    print(f"brdf-viewer render default 512x512 PNG, whole process: median {statistics.median(ts):.2f} s")


def albedo_curve_time(runs=3):
    sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
    from viewer import plots
    from viewer.brdf.presets import get_preset

    p = plots.as_params(get_preset("varnished_gold"))   # the slowest model: a layered coat over a microfacet
    ts = []
    for _ in range(runs):
        t = time.perf_counter()
        plots.albedo_curve(p)
        ts.append(time.perf_counter() - t)
    print(f"plots: albedo curve of varnished_gold (the slowest model): median {statistics.median(ts):.2f} s")


if __name__ == "__main__":
    albedo_curve_time()
    frame_times()
    ssr_times()
    model_switch()
    render_process()
    start_to_first_frame()
