"""The classroom viewer driven through the window app's own API under Xvfb: compare
views, every model with a slider move, shader hot reload with the error overlay, saving and
reopening scenes and screenshots, the lecture tour, the window state and loading meshes.

Each test runs the app in a subprocess (a private Xvfb, the ``display`` fixture of conftest.py) and prints one
JSON line of measurements that the test checks; the app is never imported into pytest itself."""

import json
import shutil
import textwrap

import numpy as np
import pytest

from gui_harness import run_py

pytestmark = pytest.mark.skipif(shutil.which("Xvfb") is None, reason="needs Xvfb (apt-get install xvfb)")


def _result(r):
    assert r.returncode == 0, r.stdout[-3000:] + r.stderr[-3000:]
    lines = [ln for ln in r.stdout.splitlines() if ln.startswith("RESULT ")]
    assert lines, r.stdout[-2000:] + r.stderr[-2000:]
    return json.loads(lines[-1][len("RESULT "):])


SCENE = textwrap.dedent("""
    [camera]
    position = [0.0, 0.4, 3.2]
    target = [0.0, 0.0, 0.0]
    fov_y = 40.0
    width = 320
    height = 240
    [environment]
    map = "studio"
    [render]
    ibl = "split_sum"
    msaa = 0
    [[lights]]
    type = "point"
    position = [2.0, 3.0, 2.0]
    intensity = [12.0, 12.0, 12.0]
    [[objects]]
    mesh = "sphere"
    material = "ball"
    [materials.ball]
    model = "lambert"
    """)


def test_every_model_and_a_slider_change_the_image(display, tmp_path):
    scene = tmp_path / "s.toml"
    scene.write_text(SCENE)
    r = run_py(f"""
        import json, numpy as np
        from viewer import brdf
        from viewer.brdf.spec import Params
        from viewer.app.main import App
        app = App({str(scene)!r}, size=(560, 300), restore_state=False)
        app.show_ui = False
        def image():
            app.session.dirty = True
            app.frame()
            return app.session.renderer.read_linear(app.session.hdr).astype(np.float64)
        out = {{}}
        prev = image()
        for name in brdf.names():
            p = brdf.get(name).params()
            app.session.scene.materials["ball"] = p
            a = image()
            switched = float(np.abs(a - prev).max())
            moved = None
            sliders = []  # (top-level param, field of a table or None)
            for prm in brdf.get(name).spec.params:
                if prm.kind in ("float", "rgb"):
                    sliders.append((prm, None))
                elif prm.kind == "table":  # e.g. the layered model's coating
                    sliders += [(prm, f) for f in prm.fields if f.kind in ("float", "rgb")]
            for prm, fld in sliders:  # the first slider that visibly acts
                s = prm if fld is None else fld
                lo, hi = s.slider_range
                cur = np.asarray(p[prm.name] if fld is None else p[prm.name][fld.name], float)
                new = lo + (hi - lo) * (0.35 if float(np.mean(cur)) > lo + 0.5 * (hi - lo) else 0.8)
                val = float(new) if s.kind == "float" else np.full(3, float(new))
                if fld is not None:
                    table = Params(p[prm.name].model, dict(p[prm.name]))
                    table[fld.name] = val
                    val = table
                app.session.scene.materials["ball"] = p.replace(**{{prm.name: val}})
                b = image()
                d = float(np.abs(b - a).max())
                if d > 1e-3:
                    moved = (prm.name, d)
                    break
            out[name] = {{"switched": switched, "moved": moved and (moved[0], moved[1]), "finite": bool(np.isfinite(a).all())}}
            prev = a
        app.close()
        print("RESULT " + json.dumps(out))
        """, display, timeout=400)
    res = _result(r)
    from viewer import brdf

    assert set(res) == set(brdf.names())
    for name, v in res.items():
        assert v["finite"], name
        assert v["moved"] is not None, f"{name}: no slider changed the image"
    # switching models changes the image (consecutive models in registry order all differ)
    # (the first, lambert, is what the scene starts with)
    assert all(v["switched"] > 1e-3 for n, v in res.items() if n != "lambert"), res


def test_split_view_shows_raster_left_and_reference_right(display, tmp_path):
    # The raster side shows a term view (the Fresnel term F, unlike any shading) and the
    # reference side its shaded image, so each half can be told apart from the other.
    scene = tmp_path / "s.toml"
    scene.write_text(SCENE.replace('map = "studio"', "constant = [0.3, 0.3, 0.3]").replace("split_sum", "off"))
    r = run_py(f"""
        import json, time, numpy as np
        from viewer.app.main import App
        from viewer.gl.renderer import VIEW_MODES
        from viewer.image.colour import to_srgb8
        app = App({str(scene)!r}, size=(800, 400), restore_state=False)
        app.show_ui = False
        app.session.view_mode = list(VIEW_MODES).index("N.L")
        app.session.set_image_mode("split")
        t0 = time.time()
        while (app.session.reference is None or app.session.reference.spp < 4) and time.time() - t0 < 600:
            app.frame(); time.sleep(0.02)
        for _ in range(3):
            app.frame()
        app.session.compare.settle()   # the metrics measured on the worker thread, adopted
        shot = app.capture_window().astype(float)
        raster = app.session.renderer.read_srgb(app.session.hdr).astype(float)
        ref, spp = app.session.reference.latest()
        ref8 = to_srgb8(ref).astype(float)
        h, w = raster.shape[:2]
        cut = int(round(w * app.session.compare.split))
        big_ref = np.repeat(np.repeat(ref8, 2, axis=0), 2, axis=1)[:h, :w]
        L = slice(10, cut - 10); R = slice(cut + 10, w - 10); rows = slice(40, h - 40)
        out = dict(
            left_vs_raster=float(np.abs(shot[rows, L] - raster[rows, L]).mean()),
            left_vs_ref=float(np.abs(shot[rows, L] - big_ref[rows, L]).mean()),
            right_vs_ref=float(np.abs(shot[rows, R] - big_ref[rows, R]).mean()),
            right_vs_raster=float(np.abs(shot[rows, R] - raster[rows, R]).mean()),
            spp=int(spp), metrics=app.session.compare.metrics is not None)
        # frame time with the split view and the reference running (the closing note's figure)
        ts = []
        for _ in range(5):
            t = time.perf_counter(); app.frame(); ts.append(time.perf_counter() - t)
        out["frame_ms"] = 1000 * float(np.median(ts))
        app.close()
        print("RESULT " + json.dumps(out))
        """, display, timeout=300)
    res = _result(r)
    print(res)
    assert res["spp"] >= 4
    assert res["metrics"]
    # left half: the raster image as rendered (only the divider's label and line are drawn over it)
    assert res["left_vs_raster"] < 2.0, res
    # right half: the reference (2x upsampled with bilinear filtering vs nearest here, and
    # noisy at 4+ spp): far closer to the reference than to the raster's term view
    assert res["right_vs_ref"] < 0.5 * res["right_vs_raster"], res
    assert res["left_vs_ref"] > 2 * res["left_vs_raster"], res


def test_shader_error_overlay_names_the_include_and_frames_continue(display, tmp_path):
    from viewer.gl.shaders import shader_root

    root = tmp_path / "shaders"
    shutil.copytree(shader_root(), root)
    r = run_py(f"""
        import json, os, time, numpy as np
        from viewer.gl.shaders import set_shader_root
        set_shader_root({str(root)!r})
        from viewer.app.main import App
        app = App("sphere", size=(640, 360), restore_state=False)
        for _ in range(3):
            app.frame()
        before = app.session.renderer.read_linear(app.session.hdr).copy()
        f = {str(root / "brdf" / "lambert.glsl")!r}
        text = open(f).read()
        lines = text.splitlines()
        # a syntax error on a known line of an included file
        bad_line = next(i for i, ln in enumerate(lines) if "{{" in ln) + 2
        lines.insert(bad_line - 1, "this is not glsl;")
        open(f, "w").write("\\n".join(lines) + "\\n")
        st = os.stat(f); os.utime(f, (st.st_atime, st.st_mtime + 5))
        t0 = time.perf_counter(); n0 = app.frame_count
        while not app.hot_reload.errors and time.perf_counter() - t0 < 600:   # a deadline, not a latency
            app.frame()
        seen = time.perf_counter() - t0
        errs = [(e.file, e.line) for e in app.hot_reload.errors]
        for _ in range(3):
            app.session.dirty = True; app.frame()
        shot = app.capture_window()
        after = app.session.renderer.read_linear(app.session.hdr)
        open(f, "w").write(text)
        st = os.stat(f); os.utime(f, (st.st_atime, st.st_mtime + 10))
        t0 = time.perf_counter()
        while app.hot_reload.errors and time.perf_counter() - t0 < 600:
            app.frame()
        fixed = not app.hot_reload.errors
        # the overlay: a red-bordered window in the top right of the view
        red = int(((shot[..., 0] > 180) & (shot[..., 1] < 90) & (shot[..., 2] < 90)).sum())
        out = dict(errors=errs, bad_line=bad_line, seen_s=seen, frames=app.frame_count - n0,
                   same=bool(np.array_equal(before, after)), fixed=fixed, red=red)
        app.close()
        print("RESULT " + json.dumps(out))
        """, display)
    res = _result(r)
    print(res)
    assert res["errors"], res
    assert ["brdf/lambert.glsl", res["bad_line"]] in res["errors"], res
    # reported (the errors above) after the change; its latency (polled every 0.25 s) is printed
    # by tests/test_hot_reload.py's report, not asserted
    assert res["frames"] >= 4 and res["same"], res  # the last good program keeps rendering
    assert res["red"] > 50, res
    assert res["fixed"], res


def test_save_and_reopen_scene_and_screenshot_give_the_same_image(display, tmp_path):
    r = run_py(f"""
        import json, numpy as np
        from viewer.app.main import App
        app = App("default", size=(640, 360), restore_state=False)
        app.frame()
        app.session.camera.orbit(40.0, 15.0, 360)  # the saved camera is where the user left it
        app.session.scene.materials["ball"] = app.session.scene.materials["ball"].replace(kd=np.array([0.2, 0.5, 0.7]))
        def image():
            app.session.dirty = True
            app.frame()
            return app.session.renderer.read_linear(app.session.hdr).copy()
        a = image()
        ok1 = app.session.save_scene({str(tmp_path / "saved.toml")!r})
        ok2 = app.take_screenshot({str(tmp_path / "shot.png")!r}) is not None
        ok3 = app.session.save_material("ball", {str(tmp_path / "ball.toml")!r})
        app.session.open_scene("sphere")
        b0 = image()
        ok4 = app.session.open_scene({str(tmp_path / "saved.toml")!r})
        b = image()
        ok5 = app.session.open_scene({str(tmp_path / "shot.png")!r})
        c = image()
        # a material file loaded onto another material
        app.session.open_scene("default")
        ok6 = app.session.load_material("ball", {str(tmp_path / "ball.toml")!r})
        alb = [float(x) for x in app.session.scene.materials["ball"]["kd"]]
        bad = app.session.open_scene({str(tmp_path / "missing.toml")!r})
        status = app.session.status
        still = app.session.scene.label
        app.close()
        print("RESULT " + json.dumps(dict(ok=[ok1, ok2, ok3, ok4, ok5, ok6], differs=float(np.abs(a - b0).max()),
              scene=float(np.abs(a - b).max()), shot=float(np.abs(a - c).max()), albedo=alb,
              bad=bad, status=status, still=still)))
        """, display)
    res = _result(r)
    assert all(res["ok"]), res
    assert res["differs"] > 0.01  # another scene in between: the comparison can fail
    # identical images: every value of the scene and camera round-trips exactly through TOML
    assert res["scene"] == 0.0 and res["shot"] == 0.0, res
    assert res["albedo"] == pytest.approx([0.2, 0.5, 0.7])
    assert not res["bad"] and "missing.toml" in res["status"] and "not found" in res["status"]
    assert res["still"] == "<built-in default>"


# every step in the real window, untraced (15-17 s): with -m slow; the default run walks every
# step forwards and backwards on the session's frames (tests/test_right_picture.py) and renders
# every scene and step finite with each switch (tests/test_classroom_fixes.py)
@pytest.mark.slow
def test_lecture_tour_visits_every_step(display):
    r = run_py("""
        import json, time, numpy as np
        from viewer.app.main import App
        from viewer.scene.lecture import TOUR
        app = App("sphere", size=(800, 450), restore_state=False)
        app.frame()
        out = []
        for i in range(len(TOUR)):
            t = time.perf_counter()
            ok = app.session.lecture(i)
            # the glass steps trace their specular chains; on software GL a traced glass ball at
            # this size takes minutes a frame, so here they render untraced (the traced steps are
            # rendered at small sizes in tests/test_reflections_choice.py)
            app.session.scene.render.raytrace = False
            app.frame()
            dt = time.perf_counter() - t
            # the importance-sampling step opens the reference view: no raster frame to read
            raster = app.session.hdr is not None
            img = app.session.renderer.read_linear(app.session.hdr) if raster else np.zeros((1, 1, 3))
            out.append(dict(ok=ok, step=app.session.lecture_step, label=app.session.scene.label, ms=1000 * dt, raster=raster,
                            finite=bool(np.isfinite(img).all()), neg=float(img.min()), std=float(img.std())))
        # stepping back and forth again (programs warm): the time a lecturer waits per key press
        again = []
        for i in [1, 2, 3, 2, 1]:
            t = time.perf_counter(); app.session.lecture(i); app.frame(); again.append(1000 * (time.perf_counter() - t))
        app.session.lecture(None)
        # a projector's UI scale: the panel widens with it and the view starts where it ends
        # (no band of clear colour between them)
        app.set_ui_scale(2.0)
        for _ in range(2):
            app.frame()
        shot = app.capture_window().astype(int)
        pw = app.panel_width
        band = shot[100:300, 370:pw - 10]          # was the gap before the panel followed the scale
        clear = (np.abs(band - [20, 20, 23]).sum(axis=-1) <= 3).mean()
        app.close()
        print("RESULT " + json.dumps(dict(steps=out, again_ms=again, pw=pw, clear=float(clear))))
        """, display, timeout=300)
    res = _result(r)
    from viewer.scene.lecture import TOUR

    print(res)
    assert res["pw"] == 720 and res["clear"] < 0.05, (res["pw"], res["clear"])
    assert len(res["steps"]) == len(TOUR)
    for i, s in enumerate(res["steps"]):
        assert s["ok"] and s["step"] == i and TOUR[i].key in s["label"], s
        if s["raster"]:
            assert s["finite"] and s["neg"] >= 0.0 and s["std"] > 1e-3, s
        else:
            assert TOUR[i].image == "reference", s


def test_window_state_is_restored(display, tmp_path):
    state = tmp_path / "state.toml"
    code = f"""
        import json, os
        os.environ["BRDF_VIEWER_STATE"] = {str(state)!r}
        from viewer.app.main import App
        app = App("sphere")
        app.frame()
        out = dict(size=list(app.glfw.get_window_size(app.window)), scale=app.ui_scale,
                   mode=app.session.compare.mode, split=app.session.compare.split, plots=app.plots.visible)
        if {{}} == {{}} and os.environ.get("STEP") == "1":
            app.glfw.set_window_size(app.window, 900, 500)
            app.set_ui_scale(1.5)
            app.session.set_image_mode("side by side")
            app.session.compare.split = 0.3
            app.plots.visible = True
            for _ in range(3):
                app.frame()
        app.close()
        print("RESULT " + json.dumps(out))
        """
    import os

    os.environ["STEP"] = "1"
    try:
        first = _result(run_py(code, display))
    finally:
        os.environ.pop("STEP")
    second = _result(run_py(code, display))
    assert first["size"] == [1280, 720] and first["mode"] == "raster"
    assert second == dict(size=[900, 500], scale=1.5, mode="side by side", split=0.3, plots=True), second
    assert (tmp_path / "last_scene.toml").exists()
    # a damaged state file is ignored (with a message), never fatal
    state.write_text("ui_scale = 'huge'\nwindow_width = -5\n[[[")
    third = run_py(code, display)
    assert third.returncode == 0 and "window state ignored" in third.stderr, third.stderr


def test_mesh_loading_from_the_gui_keeps_the_previous_state_on_errors(display, tmp_path):
    import trimesh

    good = tmp_path / "box.obj"
    trimesh.creation.box(extents=(2.0, 1.0, 1.0)).export(good)
    bad = tmp_path / "broken.ply"
    bad.write_bytes(b"ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nend_header\n0 0")
    r = run_py(f"""
        import json
        from viewer.app.main import App
        app = App("sphere", size=(640, 360), restore_state=False)
        app.frame()
        app.keys.on_drop(None, [{str(bad)!r}])
        s1, m1 = app.session.status, app.session.scene.objects[0].mesh
        app.frame()
        red1 = app.overlay_plan()[1]["toast_error"]  # the toast of an error notification is red
        app.keys.on_drop(None, [{str(good)!r}])
        s2, m2 = app.session.status, app.session.scene.objects[0].mesh
        app.frame()
        red2 = app.overlay_plan()[1]["toast_error"]
        app.keys.on_drop(None, [{str(tmp_path / "notes.txt")!r}])
        s3 = app.session.status
        red3 = app.overlay_plan()[1]["toast_error"]
        tri = len(app.session.scene.objects[0].mesh_data.indices)
        app.close()
        print("RESULT " + json.dumps(dict(s1=s1, m1=m1, s2=s2, m2=m2, s3=s3, tri=tri, red=[red1, red2, red3])))
        """, display)
    res = _result(r)
    assert res["m1"] == "sphere" and "mesh not loaded" in res["s1"] and "broken.ply" in res["s1"], res
    assert res["m2"].endswith("box.obj") and res["tri"] == 12, res
    assert "unknown kind" in res["s3"] and ".toml" in res["s3"], res
    assert res["red"] == [True, False, True], res  # errors red, the loaded mesh's line not


def test_fuzzed_files_into_the_running_window_keep_the_previous_state(display, tmp_path):
    """Mutated scenes, meshes and environment maps (tests/fuzz_cases.py) opened in the running
    window: each either loads or leaves the scene exactly as it was, with one line of status."""
    import fuzz_cases as fc

    rng = np.random.default_rng(11)
    texts = fc.builtin_scene_texts()
    scenes, meshes, envs = [], [], []
    kinds = [k for k in fc.SCENE_KINDS if k != "override"]  # the window opens files, no --set
    for i in range(24):
        p = tmp_path / f"scene{i}.toml"
        name = sorted(texts)[i % len(texts)]
        _, raw, _ = fc.mutate_scene(rng, texts[name], kinds[i % len(kinds)])
        p.write_bytes(raw)
        scenes.append(str(p))
    for i in range(16):
        meshes.append(str(fc.make_mesh_case(rng, tmp_path, fc.MESH_KINDS[i % len(fc.MESH_KINDS)], i)[1]))
    for i in range(13):
        envs.append(str(fc.make_env_case(rng, tmp_path, fc.ENV_KINDS[i % len(fc.ENV_KINDS)], i)[1]))
    r = run_py(f"""
        import json
        from viewer.app.main import App
        from viewer.scene import scene_to_toml
        app = App("sphere", size=(480, 300), restore_state=False)
        app.frame()
        out = dict(loaded=0, refused=0, bad=[])
        def attempt(kind, fn, path):
            before = scene_to_toml(app.session.scene)
            ok = fn(path)
            app.frame()
            after = scene_to_toml(app.session.scene)
            if ok:
                out["loaded"] += 1
            else:
                out["refused"] += 1
                if after != before or "\\n" in app.session.status or not app.session.status:
                    out["bad"].append([kind, path, app.session.status])
        for p in {scenes!r}:
            attempt("scene", app.session.open_scene, p)
            app.session.open_scene("sphere")
        for p in {meshes!r}:
            attempt("mesh", app.session.load_mesh, p)
        for p in {envs!r}:
            attempt("env", app.session.set_environment, p)
        app.close()
        print("RESULT " + json.dumps(out))
        """, display, timeout=400)
    res = _result(r)
    print(res["loaded"], "loaded,", res["refused"], "refused")
    assert res["bad"] == [], res["bad"]
    assert res["refused"] >= 20 and res["loaded"] + res["refused"] == 24 + 16 + 13
