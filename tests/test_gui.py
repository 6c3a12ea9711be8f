"""The window app under a real X server (Xvfb): it starts on the default scene, renders frames,
saves a screenshot through its own action, survives resizes and a 0x0 framebuffer, and exits
cleanly on window close and on SIGTERM."""

import os
import shutil
import signal
import subprocess
import sys
import time

import numpy as np
import pytest

from gui_harness import HANG_S, run_py, window_env

pytestmark = pytest.mark.skipif(shutil.which("Xvfb") is None and not os.environ.get("DISPLAY"),
                                reason="needs Xvfb (apt-get install xvfb) or a display")


def test_starts_renders_and_screenshots(display, tmp_path):
    shot = tmp_path / "shot.png"
    r = subprocess.run([sys.executable, "-m", "viewer", "--frames", "4", "--screenshot", str(shot)],
                       env=window_env(display), capture_output=True, text=True, timeout=HANG_S, cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    assert "first frame" in r.stderr
    from PIL import Image

    img = np.asarray(Image.open(shot).convert("RGB")).astype(float)
    # the scene, not a uniform image: clear structure and the terracotta ball
    assert img.std() > 20, img.std()
    assert (img[..., 0] - img[..., 2]).max() > 80  # some clearly orange pixels
    from viewer.base.io import read_png_text
    from viewer.scene import parse_scene

    text = read_png_text(shot)
    import tomllib

    scene = parse_scene(tomllib.loads(text["brdf-viewer:scene"]), None, load_meshes=False)
    assert scene.materials["ball"].model == "microfacet"
    assert not any(p.name.endswith(".part") for p in tmp_path.iterdir())  # atomic write


def test_window_close_resize_and_zero_framebuffer(display):
    r = run_py("""
        import numpy as np
        from viewer.app.main import App
        app = App(None, size=(800, 500))
        for _ in range(3):
            app.frame()
        a = app.capture_window()
        assert a.shape[:2] == (500, 800), a.shape
        assert a.std() > 10
        app.glfw.set_window_size(app.window, 1000, 640)
        for _ in range(20):
            app.frame()
            if app.glfw.get_framebuffer_size(app.window) == (1000, 640):
                break
        b = app.capture_window()
        assert b.shape[:2] == (640, 1000), b.shape
        assert app.layout()["view"].x + app.layout()["view"].w <= 1000   # the new size, not the last frame's
        # a frame asks the window system for the sizes once (each is a round trip to the server)
        calls = []
        real_w, real_f = app.glfw.get_window_size, app.glfw.get_framebuffer_size
        app.glfw.get_window_size = lambda w: calls.append("window") or real_w(w)
        app.glfw.get_framebuffer_size = lambda w: calls.append("framebuffer") or real_f(w)
        app.session.changed()
        app.frame()
        app.glfw.get_window_size, app.glfw.get_framebuffer_size = real_w, real_f
        assert sorted(calls) == ["framebuffer", "window"], calls
        # a minimized window has a 0x0 framebuffer: frames are skipped, nothing breaks
        real = app.glfw.get_framebuffer_size
        app.glfw.get_framebuffer_size = lambda w: (0, 0)
        before = app.frame_count
        for _ in range(3):
            app.frame()
        assert app.frame_count == before
        app.glfw.get_framebuffer_size = real
        app.frame()
        app.glfw.set_window_should_close(app.window, True)
        rc = app.run()
        assert app.window is None
        print("CLOSED", rc)
    """, display)
    assert r.returncode == 0, r.stderr + r.stdout
    assert "CLOSED 0" in r.stdout


def test_sigterm_exits_cleanly(display, tmp_path):
    p = subprocess.Popen([sys.executable, "-m", "viewer"], env=window_env(display), stderr=subprocess.PIPE,
                         stdout=subprocess.PIPE, text=True, cwd=tmp_path)
    try:
        t0 = time.time()
        line = ""
        while "first frame" not in line and time.time() - t0 < 600:
            line = p.stderr.readline()
            if not line and p.poll() is not None:
                break
        assert "first frame" in line, line
        p.send_signal(signal.SIGTERM)
        rc = p.wait(120)
        err = p.stderr.read()
        assert rc == 0, err
        assert "Traceback" not in err
    finally:
        if p.poll() is None:
            p.kill()


def test_no_display_message(tmp_path):
    env = dict(os.environ)
    env.pop("DISPLAY", None)
    env.pop("WAYLAND_DISPLAY", None)
    r = subprocess.run([sys.executable, "-m", "viewer"], env=env, capture_output=True, text=True, timeout=HANG_S)
    assert r.returncode == 2
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1, r.stderr
    assert "no display" in lines[0] and "brdf-viewer render" in lines[0]


def test_reference_view_renders_in_background_and_restarts(display):
    r = run_py("""
        import time
        import numpy as np
        from viewer import brdf
        from viewer.app.main import App
        app = App("sphere", size=(520, 300))
        app.session.set_image_mode("reference")
        t0 = time.time()
        while (app.session.reference is None or app.session.reference.spp < 2) and time.time() - t0 < 600:
            app.frame()
        rv = app.session.reference
        assert rv.spp >= 2, rv.error
        img = app.capture_window()
        assert img[:, 360:].std() > 5  # the sphere is there (not a blank view)
        frames_before = app.frame_count
        for _ in range(5):   # the raster stays live: frames complete while the reference renders
            app.frame()
        assert app.frame_count == frames_before + 5
        key_before = rv.key
        app.session.scene.materials["ball"] = brdf.get("lambert").params(albedo=[0.1, 0.1, 0.1])
        app.session.dirty = True
        app.frame()
        assert rv.key != key_before and rv.spp < 2  # restarted on the change
        t0 = time.time()
        while rv.spp < 1 and time.time() - t0 < 600:
            app.frame()
        assert rv.spp >= 1
        app.glfw.set_window_should_close(app.window, True)
        app.run()
        print("REF OK")
    """, display, timeout=180)
    assert r.returncode == 0, r.stderr + r.stdout
    assert "REF OK" in r.stdout


def test_environment_switch_and_bad_file_keeps_previous(display, tmp_path):
    bad = tmp_path / "broken.hdr"
    bad.write_bytes(b"#?RADIANCE\\nFORMAT=32-bit_rle_rgbe\\n\\n-Y 4 +X 8\\n\\x02")  # truncated
    r = run_py(f"""
        import numpy as np
        from viewer.app.main import App
        app = App(None, size=(640, 360))
        app.frame()
        before = app.capture_window()
        assert app.session.set_environment("studio")
        app.frame()
        after = app.capture_window()
        assert np.abs(after.astype(float) - before).mean() > 1.0  # the image changed
        env = app.session.scene.environment
        assert not app.session.set_environment({str(bad)!r})
        assert app.session.scene.environment is env and "broken.hdr" in app.session.status
        app.keys.on_drop(app.window, [{str(tmp_path / 'photo.png')!r}])
        assert "scene not opened" in app.session.status and "photo.png" in app.session.status  # a .png opens as a scene
        app.frame()
        app.glfw.set_window_should_close(app.window, True)
        app.run()
        print("ENV OK")
    """, display)
    assert r.returncode == 0, r.stderr + r.stdout
    assert "ENV OK" in r.stdout


@pytest.mark.slow  # a window's brute-force IBL programs: ~20 s of compiles; the accumulation itself is
# tests/test_file_same_image.py's (a session offscreen), the window's frame loop every other test's here
def test_brute_force_ibl_accumulates_in_the_window(display):
    r = run_py("""
        from viewer.app.main import App
        app = App(None, ['environment={map="studio"}', 'render.ibl="brute_force"'], size=(400, 240))
        for _ in range(6):
            app.frame()
        assert app.session.bf_count >= 4, app.session.bf_count
        n = app.session.bf_count
        app.session.camera.orbit(5.0, 0.0, 240.0)
        app.session.dirty = True
        app.frame()
        assert app.session.bf_count <= 1  # a change starts the average over
        app.glfw.set_window_should_close(app.window, True)
        app.run()
        print("BF OK", n)
    """, display)
    assert r.returncode == 0, r.stderr + r.stdout
    assert "BF OK" in r.stdout
