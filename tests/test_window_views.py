"""The window under Xvfb: screenshots of compare views save what the view shows (the split, with
its labels) and the scene; --screenshot to a folder that cannot be written fails in one line
before the window opens; lecture mode collapses the panel and docks the plots beside the view;
a key tap shorter than a frame (a presentation clicker) is never lost; the tour's maps are
prefiltered in the background; side by side shows each image whole."""

import json
import os
import shutil
import subprocess
import sys

import pytest

from gui_harness import HANG_S, run_py, window_env

pytestmark = pytest.mark.skipif(shutil.which("Xvfb") is None, reason="needs Xvfb (apt-get install xvfb)")

SCENE = """
[camera]
position = [0.0, 1.0, 3.2]
target = [0.0, 0.3, 0.0]
fov_y = 40.0
[environment]
constant = [0.4, 0.4, 0.4]
[render]
ibl = "split_sum"
msaa = 0
[[objects]]
mesh = "sphere"
material = "ball"
translate = [0.0, 0.5, 0.0]
scale = 0.5
[[objects]]
mesh = "plane"
material = "floor"
scale = 3.0
[materials.ball]
model = "lambert"
albedo = [0.8, 0.3, 0.2]
[materials.floor]
model = "lambert"
albedo = [0.5, 0.5, 0.5]
"""


def _result(r):
    assert r.returncode == 0, r.stderr[-3000:]
    line = [x for x in r.stdout.splitlines() if x.startswith("RESULT ")]
    assert line, r.stdout[-2000:] + r.stderr[-2000:]
    return json.loads(line[-1][len("RESULT "):])


def test_lecture_layout_clicker_taps_and_split_screenshot(display, tmp_path):
    """One window (its start-up is the slow part): lecture mode at UI scale 2, three key taps
    shorter than a frame, then a split view whose screenshot must equal the view."""
    shot = tmp_path / "split.png"
    r = run_py(f"""
        import ctypes, json, time, os
        import numpy as np
        from PIL import Image
        from viewer.app.main import App
        T0 = time.time(); times = dict()
        app = App("lecture:1", size=(800, 450), restore_state=False)
        app.set_ui_scale(2.0)
        for _ in range(2):
            app.frame()
        lay = app.layout()
        out = dict(step0=app.session.lecture_step, plots=app.plots.visible, tab=app.plots.tab,
                   view_w=lay["view"].w, has_strip="strip" in lay, has_panel="panel" in lay,
                   plots_x=lay["plots"].x if "plots" in lay else None, view_right=lay["view"].right,
                   prefetch_started=app.session.prefetch is not None)
        # real X key events through XTest, press and release back to back (shorter than a frame)
        x11 = ctypes.CDLL("libX11.so.6"); xtst = ctypes.CDLL("libXtst.so.6")
        x11.XOpenDisplay.restype = ctypes.c_void_p
        dpy = ctypes.c_void_p(x11.XOpenDisplay(os.environ["DISPLAY"].encode()))
        x11.XKeysymToKeycode.restype = ctypes.c_ubyte
        right = x11.XKeysymToKeycode(dpy, ctypes.c_ulong(0xff53))  # XK_Right
        import glfw
        glfw.focus_window(app.window)
        app.frame()
        for _ in range(3):  # three taps 40 ms apart while no frame runs: each must count
            xtst.XTestFakeKeyEvent(dpy, right, 1, 0); xtst.XTestFakeKeyEvent(dpy, right, 0, 0)
            x11.XFlush(dpy); time.sleep(0.04)
        t1 = time.time()  # a loaded X server may deliver them a little later: frames until all count
        while app.session.lecture_step < 3 and time.time() - t1 < 600:
            app.frame()
        app.frame()
        times["taps"] = time.time() - T0
        out["step_after_taps"] = app.session.lecture_step
        out["status"] = app.session.status
        # a split view: the screenshot is the view as drawn (divider, labels, RMSE)
        app.session.lecture(None)
        app.set_ui_scale(1.0)
        app.show_ui = False
        import glfw; glfw.set_window_size(app.window, 640, 360)
        app.session.reference_view().engine_request = "cpu"  # the GPU engine's first compile takes a minute on llvmpipe
        app.session.set_image_mode("split")
        t0 = time.time()
        while (app.session.reference is None or app.session.reference.spp < 2) and time.time() - t0 < 600:
            app.frame(); time.sleep(0.02)
        times["ref"] = time.time() - T0; out["engine"] = app.session.reference.engine
        rv = app.session.reference            # a still reference: the view does not change between frames
        rv.stop(); rv.update = lambda *a, **k: None  # (stop alone lets the next update restart it)
        for _ in range(2):             # and metrics caught up with its last pass (they refresh every 0.5 s)
            time.sleep(0.6); app.frame()
        app.TOAST_S = 0.0  # no toast over the view
        view = app.capture_view().astype(int)
        app.take_screenshot({str(shot)!r})
        png = np.asarray(Image.open({str(shot)!r}).convert("RGB")).astype(int)
        from viewer.base.io import read_png_text
        text = read_png_text({str(shot)!r})
        state = json.loads(text["brdf-viewer:state"])
        cut = int(round(png.shape[1] * app.session.compare.split))
        col = png[60:-60, cut - 1:cut + 2].min(axis=(0, 2)).max()
        # side by side: each half at the view's aspect ratio (whole, letterboxed)
        app.session.set_image_mode("side by side")
        vx, vy, vw, vh = app.viewport()
        rr = app.session.compare.raster_rect((vx, vy, vw, vh)); ref = app.session.compare.reference_rect((vx, vy, vw, vh))
        times["shot"] = time.time() - T0
        app.close()
        times["closed"] = time.time() - T0
        out["times"] = times
        out.update(shape=list(png.shape), view_shape=list(view.shape),
                   diff=float(np.abs(png - view).max()), mean=float(np.abs(png - view).mean()),
                   scene="brdf-viewer:scene" in text, image=state.get("image"), divider=int(col),
                   aspect=[rr[2] / rr[3], ref[2] / ref[3], vw / vh])
        print("RESULT " + json.dumps(out))
        """, display, timeout=300)
    res = _result(r)
    print(res)
    assert res["step0"] == 0 and res["plots"] and res["tab"] == "Polar" and res["prefetch_started"]
    assert res["has_strip"] and not res["has_panel"] and res["view_w"] >= 0.7 * 800
    assert res["plots_x"] is not None and res["plots_x"] >= res["view_right"]  # beside the view
    assert res["step_after_taps"] == 3, res  # all three taps stepped the tour
    assert "lecture 4/" in res["status"] and " s" in res["status"] and "loading" not in res["status"], res
    assert res["shape"] == res["view_shape"] == [360, 640, 3]
    assert res["diff"] == 0.0, res  # the file holds exactly the view as drawn
    assert res["scene"] and res["image"] == "split"
    assert res["divider"] >= 250, res  # the divider line is in the picture
    a_raster, a_ref, a_view = res["aspect"]
    assert abs(a_raster - a_view) < 0.02 and abs(a_ref - a_view) < 0.02, res


def test_screenshot_to_an_unwritable_path_fails_in_one_line(display, tmp_path):
    (tmp_path / "file.txt").write_text("x")
    for bad in (tmp_path / "no" / "such" / "folder" / "s.png", "/proc/s.png", tmp_path / "file.txt" / "s.png"):
        r = subprocess.run([sys.executable, "-m", "viewer", "--frames", "2", "--screenshot", str(bad)],
                           env=window_env(display), capture_output=True, text=True, timeout=HANG_S, cwd=tmp_path)
        assert r.returncode == 2, (r.returncode, r.stderr)
        lines = [x for x in r.stderr.splitlines() if x.strip()]
        assert len(lines) == 1 and "--screenshot" in lines[0] and "error" in lines[0], r.stderr
        assert "first frame" not in r.stderr  # refused before the window opened


@pytest.mark.slow  # a cold cache prefilters each map for several seconds on a software rasterizer
def test_tour_maps_prefiltered_in_the_background(tmp_path):
    from viewer.app.prefetch import Prefetch, tour_maps

    maps = tour_maps(0)
    assert maps and len({str(e.map) for _, e in maps}) == len(maps)
    p = Prefetch(0)
    t0 = __import__("time").time()
    while not p.done and __import__("time").time() - t0 < 300:
        __import__("time").sleep(0.2)
    assert p.done and not p.error, p.progress_text()
    assert p.finished == p.total == len(maps)
    # a second run finds every map in the disk cache
    p2 = Prefetch(0)
    while not p2.done:
        __import__("time").sleep(0.1)
    assert all(cached for _, _, cached in p2.seconds), p2.seconds


def test_leaving_the_reference_cancels_it_without_waiting_for_its_thread():
    """A mode without the reference (a lecture step, the raster view) cancels the reference's
    job and goes on: the cancelled job publishes nothing more, so the frame never waits for a
    busy reference thread (it waited up to 5 s: step 14 to 15 of the tour)."""
    import types

    from viewer.app.view_state import ViewState

    class BusyReference:
        waited = None

        def stop(self, timeout=5.0):
            self.waited = timeout
            return False   # a thread that stays busy: only a caller that waits would notice

    ref = BusyReference()
    compare = types.SimpleNamespace(mode="split", uses_reference=False)
    session = types.SimpleNamespace(compare=compare, monte_carlo=types.SimpleNamespace(active=False),
                                    reference=ref, hdr=object(), dirty=False)
    ViewState(session).set_image_mode("raster")
    assert compare.mode == "raster" and ref.waited == 0
