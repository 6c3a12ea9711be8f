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

from test_gui import _env, _run_py, display  # noqa: F401 - the fixture is used by name

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


def test_split_screenshot_equals_the_view_and_side_by_side_fits(display, tmp_path):  # noqa: F811
    scene = tmp_path / "s.toml"
    scene.write_text(SCENE)
    shot = tmp_path / "split.png"
    r = _run_py(f"""
        import json, time, numpy as np
        from PIL import Image
        from viewer.app.main import App
        app = App({str(scene)!r}, size=(640, 360), restore_state=False)
        app.show_ui = False
        app.set_image_mode("split")
        t0 = time.time()
        while (app._reference is None or app._reference.spp < 2) and time.time() - t0 < 120:
            app.frame(); time.sleep(0.02)
        app._reference.stop()          # a still reference: the view does not change between frames
        for _ in range(3):             # and metrics caught up with its last pass (they refresh every 0.5 s)
            time.sleep(0.6); app.frame()
        app.status = ""; app.TOAST_S = 0.0
        view = app.capture_view().astype(int)
        whole = app.capture_window().astype(int)
        app.take_screenshot({str(shot)!r})
        png = np.asarray(Image.open({str(shot)!r}).convert("RGB")).astype(int)
        from viewer.io import read_png_text
        text = read_png_text({str(shot)!r})
        state = json.loads(text["brdf-viewer:state"])
        # the split shows the divider: a white column at the split position
        cut = int(round(png.shape[1] * app.compare.split))
        col = png[60:-60, cut - 1:cut + 2].min(axis=(0, 2)).max()
        # side by side: each half at the view's aspect ratio (whole, letterboxed)
        app.set_image_mode("side by side")
        vx, vy, vw, vh = app.viewport()
        rr = app.compare.raster_rect((vx, vy, vw, vh)); ref = app.compare.reference_rect((vx, vy, vw, vh))
        app.close()
        print("RESULT " + json.dumps(dict(shape=list(png.shape), view_shape=list(view.shape),
              diff=float(np.abs(png - view).max()), mean=float(np.abs(png - view).mean()),
              where=np.argwhere(np.abs(png - view).max(axis=-1) > 0)[:20].tolist(),
              whole_diff=float(np.abs(whole[-view.shape[0]:, -view.shape[1]:] - view).mean()),
              scene="brdf-viewer:scene" in text, image=state.get("image"), divider=int(col),
              aspect=[rr[2] / rr[3], ref[2] / ref[3], vw / vh])))
        """, display, timeout=300)
    res = _result(r)
    assert res["shape"] == res["view_shape"] == [360, 640, 3]
    # the file holds exactly the view as drawn (same pixels: the same frame composition)
    assert res["diff"] == 0.0, {k: v for k, v in res.items() if k in ("where", "mean", "diff")}
    assert res["scene"] and res["image"] == "split"
    assert res["divider"] >= 250, res  # the divider line is in the picture
    a_raster, a_ref, a_view = res["aspect"]
    assert abs(a_raster - a_view) < 0.02 and abs(a_ref - a_view) < 0.02, res


def test_screenshot_to_an_unwritable_path_fails_in_one_line(display, tmp_path):  # noqa: F811
    (tmp_path / "file.txt").write_text("x")
    for bad in (tmp_path / "no" / "such" / "folder" / "s.png", "/proc/s.png", tmp_path / "file.txt" / "s.png"):
        r = subprocess.run([sys.executable, "-m", "viewer", "--frames", "2", "--screenshot", str(bad)],
                           env=_env(display), capture_output=True, text=True, timeout=120, cwd=tmp_path)
        assert r.returncode == 2, (r.returncode, r.stderr)
        lines = [x for x in r.stderr.splitlines() if x.strip()]
        assert len(lines) == 1 and "--screenshot" in lines[0] and "error" in lines[0], r.stderr
        assert "first frame" not in r.stderr  # refused before the window opened


def test_lecture_window_layout_and_clicker_taps(display):  # noqa: F811
    r = _run_py("""
        import ctypes, json, time, os
        import numpy as np
        from viewer.app.main import App
        app = App("lecture:1", size=(1280, 720), restore_state=False)
        app.set_ui_scale(2.0)
        for _ in range(2):
            app.frame()
        lay = app.layout()
        out = dict(step0=app.lecture_step, plots=app.plots.visible, tab=app.plots.tab,
                   view_w=lay["view"].w, has_strip="strip" in lay, has_panel="panel" in lay,
                   plots_x=lay["plots"].x if "plots" in lay else None, view_right=lay["view"].right)
        # real X key events through XTest: press and release back to back (shorter than a frame)
        x11 = ctypes.CDLL("libX11.so.6"); xtst = ctypes.CDLL("libXtst.so.6")
        x11.XOpenDisplay.restype = ctypes.c_void_p
        dpy = ctypes.c_void_p(x11.XOpenDisplay(os.environ["DISPLAY"].encode()))
        x11.XKeysymToKeycode.restype = ctypes.c_ubyte
        right = x11.XKeysymToKeycode(dpy, ctypes.c_ulong(0xff53))  # XK_Right
        import glfw
        glfw.focus_window(app.window)
        for _ in range(3):
            app.frame()
        for _ in range(3):  # three taps while no frame runs: each must count
            xtst.XTestFakeKeyEvent(dpy, right, 1, 0); xtst.XTestFakeKeyEvent(dpy, right, 0, 0)
        x11.XFlush(dpy)
        time.sleep(0.3)
        for _ in range(4):
            app.frame()
        out["step_after_taps"] = app.lecture_step
        t0 = time.time()
        while app._prefetch is not None and not app._prefetch.done and time.time() - t0 < 200:
            app.frame(); time.sleep(0.1)
        out["prefetch"] = app._prefetch.progress_text()
        out["prefetch_error"] = app._prefetch.error
        out["status"] = app.status
        app.close()
        print("RESULT " + json.dumps(out))
        """, display, timeout=400)
    res = _result(r)
    print(res)
    assert res["step0"] == 0 and res["plots"] and res["tab"] == "Polar"
    assert res["has_strip"] and not res["has_panel"] and res["view_w"] >= 0.7 * 1280
    assert res["plots_x"] is not None and res["plots_x"] >= res["view_right"]  # beside the view
    assert res["step_after_taps"] == 3, res  # all three taps stepped the tour
    assert not res["prefetch_error"] and "prepared" in res["prefetch"], res
    assert "lecture 4/" in res["status"] and " s" in res["status"] and "loading" not in res["status"], res
