"""The classroom session without a window (viewer.app.session.Session), driven in-process on the
test session's EGL context: every action a student or lecturer takes, its outcome in the scene
and in rendered pixels, and one clear notification for each problem (broken files, NaN)."""

import math

import numpy as np
import pytest

from viewer import ViewerError

SIZE = (48, 36)  # small: the checks are about what changes, not about detail


@pytest.fixture
def session(gl_ctx, renderer):
    from viewer.app.session import Session

    s = Session(gl_ctx, "default", renderer=renderer, prefetch=False)
    s.warm = []  # no idle compiles in tests
    yield s
    s.release()


def image(s) -> np.ndarray:
    """The raster image the session shows for a view of SIZE, linear float."""
    s.changed()
    s.render_view(SIZE)
    return s.renderer.read_linear(s.hdr).astype(np.float64)


def new_messages(s, n0):
    return s.messages[n0:]


def test_notify_keeps_info_and_error_apart(session):
    session.notify("saved it")
    assert session.status == "saved it" and not session.last_message.error
    session.notify("it broke", error=True)
    assert session.status == "it broke" and session.last_message.error
    assert [m.error for m in session.messages[-2:]] == [False, True]
    assert session.messages[-1].time >= session.messages[-2].time


def test_scene_save_and_open_round_trip(session, tmp_path):
    session.set_material_param("ball", "kd", [0.2, 0.5, 0.7])
    session.camera.orbit(40.0, 15.0, 360)
    before = image(session)
    path = tmp_path / "saved.toml"
    assert session.save_scene(path) and path.exists()
    assert not session.last_message.error and str(path) in session.status
    assert not any(p.name.endswith(".part") for p in tmp_path.iterdir())  # written atomically
    assert session.open_scene("sphere") and "sphere" in session.scene.label  # another scene shown
    assert session.open_scene(path)
    assert np.allclose(session.scene.materials["ball"]["kd"], [0.2, 0.5, 0.7])
    after = image(session)
    # the same scene and camera render the same raster (deterministic; 1e-5 covers float32
    # rounding of the camera written as decimal text)
    assert after.shape == before.shape and np.abs(after - before).max() < 1e-5


def test_material_parameter_changes_the_image_and_nan_is_refused(session):
    grey = image(session)
    assert session.set_material_param("ball", "kd", [0.05, 0.8, 0.05])
    assert np.allclose(session.scene.materials["ball"]["kd"], [0.05, 0.8, 0.05])
    green = image(session)
    diff = green - grey
    assert diff[..., 1].max() > 0.05 and diff[..., 0].min() < -0.05  # the ball turned green
    for bad in ([math.nan, 0.5, 0.5], [2.0, 0.5, 0.5], "red"):
        n0 = len(session.messages)
        assert not session.set_material_param("ball", "kd", bad)
        msgs = new_messages(session, n0)
        assert len(msgs) == 1 and msgs[0].error and "kd" in msgs[0].text, msgs
        assert np.allclose(session.scene.materials["ball"]["kd"], [0.05, 0.8, 0.05])  # the old value stays
    n0 = len(session.messages)
    assert not session.set_material_param("ball", "no_such_parameter", 1.0)
    assert len(new_messages(session, n0)) == 1 and session.last_message.error
    again = image(session)
    assert np.isfinite(again).all() and np.abs(again - green).max() < 1e-6  # still renders, unchanged


def test_float_parameter_nan_keeps_the_old_value(session):
    from viewer.app.ui import preset_params

    session.set_material("ball", preset_params("gold"))
    alpha = session.scene.materials["ball"]["alpha_x"]
    n0 = len(session.messages)
    assert not session.set_material_param("ball", "alpha_x", math.nan)
    assert len(new_messages(session, n0)) == 1 and session.last_message.error
    assert session.scene.materials["ball"]["alpha_x"] == alpha
    assert session.set_material_param("ball", "alpha_x", 0.3) and session.scene.materials["ball"]["alpha_x"] == 0.3


OBJ = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n"


def test_mesh_loads_and_a_broken_mesh_is_one_error(session, tmp_path):
    before = image(session)
    target = session.mesh_target
    good, bad = tmp_path / "tetra.obj", tmp_path / "broken.ply"
    good.write_text(OBJ)
    bad.write_bytes(b"ply\nformat binary_little_endian 1.0\nelement vertex 99\n\x00\x01")
    n0 = len(session.messages)
    assert not session.load_mesh(bad)
    msgs = new_messages(session, n0)
    assert len(msgs) == 1 and msgs[0].error and "broken.ply" in msgs[0].text, msgs
    assert session.scene.objects[target].mesh != str(bad.absolute())
    assert np.abs(image(session) - before).max() < 1e-6  # the old mesh is still shown
    assert session.load_mesh(good) and not session.last_message.error
    assert len(session.scene.objects[target].mesh_data.indices) == 4
    tetra = image(session)
    assert np.isfinite(tetra).all() and np.abs(tetra - before).max() > 0.05  # a new shape in the view


def test_material_file_loads_and_a_broken_one_is_one_error(session, tmp_path):
    path = tmp_path / "ball.toml"
    session.set_material_param("ball", "kd", [0.6, 0.1, 0.1])
    assert session.save_material("ball", path)
    session.set_material_param("ball", "kd", [0.1, 0.1, 0.6])
    assert session.load_material("ball", path) and not session.last_message.error
    assert np.allclose(session.scene.materials["ball"]["kd"], [0.6, 0.1, 0.1])
    bad = tmp_path / "typo.toml"
    bad.write_text('[materials.x]\nmodel = "lambert"\nalbedo = [0.5, nan\n')
    n0 = len(session.messages)
    assert not session.load_material("ball", bad)
    msgs = new_messages(session, n0)
    assert len(msgs) == 1 and msgs[0].error and "typo.toml" in msgs[0].text, msgs
    assert np.allclose(session.scene.materials["ball"]["kd"], [0.6, 0.1, 0.1])
    assert np.isfinite(image(session)).all()


def test_environment_switch_and_a_broken_map_is_one_error(session, tmp_path):
    session.scene.render.ibl = "off"  # the map as background only: no prefilter pass (seconds on software GL)
    assert session.set_environment(None) and session.scene.environment.map is None
    session.scene.environment.constant = np.array([0.0, 0.0, 0.0])
    dark = image(session)
    assert session.set_environment("studio") and session.scene.environment.map == "studio"
    assert not session.last_message.error and "studio" in session.status
    lit = image(session)
    assert dark[0].max() == 0 and lit[0].min() > 1e-3  # the map shows behind the scene (the top row)
    bad = tmp_path / "broken.hdr"
    bad.write_bytes(b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y 4 +X 4\n\x02\x02")
    n0 = len(session.messages)
    assert not session.set_environment(str(bad))
    msgs = new_messages(session, n0)
    assert len(msgs) == 1 and msgs[0].error and "broken.hdr" in msgs[0].text, msgs
    assert session.scene.environment.map == "studio"
    assert np.abs(image(session) - lit).max() < 1e-6  # still renders the last map


def test_dropped_files_go_by_kind(session, tmp_path):
    good = tmp_path / "tetra.obj"
    good.write_text(OBJ)
    n0 = len(session.messages)
    session.open_files([str(good), str(tmp_path / "notes.txt")])
    msgs = new_messages(session, n0)
    assert [m.error for m in msgs] == [False, True] and "notes.txt" in msgs[1].text
    assert session.scene.objects[session.mesh_target].mesh == str(good.absolute())


def test_a_dropped_folder_of_brdf_files_joins_the_picker(session, tmp_path):
    from pathlib import Path

    from viewer.app.ui import FILE_PREFIX, library_files, preset_params

    folder = Path(__file__).parent / "brdfs"
    n0 = len(session.messages)
    session.open_files([str(folder), str(tmp_path)])  # tmp_path holds no .brdf file
    msgs = new_messages(session, n0)
    assert [m.error for m in msgs] == [False, True], [m.text for m in msgs]
    assert "no .brdf files" in msgs[1].text
    entries = [e for e in library_files() if e.startswith(FILE_PREFIX + str(folder.resolve()))]
    assert {Path(e[len(FILE_PREFIX):]).name for e in entries} >= {"lambert_twin.brdf", "every_declaration.brdf"}
    lam = next(e for e in entries if e.endswith("lambert_twin.brdf"))
    assert preset_params(lam).model == "custom"


def test_lecture_steps_forward_and_back(session):
    from viewer.scene.lecture import TOUR

    seen = []
    session.step_listeners.append(seen.append)
    assert session.lecture(0) and session.lecture_step == 0
    first = session.scene
    assert session.lecture_title[0].startswith(f"1/{len(TOUR)}")
    assert session.lecture_next() and session.lecture_step == 1
    second = session.scene
    assert second is not first and second.label != first.label
    assert session.lecture_back() and session.lecture_step == 0 and session.scene.label == first.label
    assert session.lecture_back() and session.lecture_step == len(TOUR) - 1  # wraps to the last
    assert session.lecture(None) and session.lecture_step == -1 and session.lecture_title == ("", "")
    assert seen == [0, 1, 0, len(TOUR) - 1, None]
    assert not any(m.error for m in session.messages)


def test_compare_and_reflection_modes(session):
    from viewer.app.compare_view import MODES

    session.set_image_mode("split")
    assert session.image_mode == "split" and session.compare.uses_reference
    session.cycle_image_mode()
    assert session.image_mode == MODES[(MODES.index("split") + 1) % len(MODES)]
    with pytest.raises(ViewerError):
        session.set_image_mode("sideways")
    session.set_image_mode("reference")
    session.hdr, session.dirty = None, True
    session.render_view(SIZE)
    assert session.hdr is None and not session.dirty  # no raster is rendered for the reference alone
    session.set_image_mode("raster")
    assert session.set_reflection_mode("ray traced") and session.scene.render.raytrace
    assert session.reflection_mode == "ray traced"
    assert session.set_reflection_mode("off") and not session.scene.render.raytrace
    n0 = len(session.messages)
    assert not session.set_reflection_mode("mirror-ish")
    assert len(new_messages(session, n0)) == 1 and session.last_message.error


def test_screenshot_is_a_png_of_the_view_size(session, tmp_path):
    from PIL import Image

    from viewer.base.io import read_png_text

    path = tmp_path / "shot.png"
    assert session.take_screenshot(path, size=(64, 40)) == path
    img = Image.open(path)
    assert img.size == (64, 40) and img.mode == "RGB"
    assert np.asarray(img).std() > 5  # the scene, not a blank image
    assert "microfacet" in read_png_text(path)["brdf-viewer:scene"]
    assert not any(p.name.endswith(".part") for p in tmp_path.iterdir())
    n0 = len(session.messages)
    assert session.take_screenshot(tmp_path / "no" / "such" / "folder.png", size=(64, 40)) is None
    assert len(new_messages(session, n0)) == 1 and session.last_message.error


def test_state_round_trip(gl_ctx, renderer, session, tmp_path):
    from viewer.app import state as state_mod
    from viewer.app.session import Session

    session.set_image_mode("side by side")
    session.compare.split = 0.3
    session.set_view_mode(1)
    session.set_material_param("ball", "kd", [0.3, 0.6, 0.9])
    path = tmp_path / "state.toml"
    assert session.save_state({"ui_scale": 1.5, "show_ui": False}, path)
    st = state_mod.load_state(path)
    assert st["compare_mode"] == "side by side" and st["split"] == 0.3 and st["view_mode"] == 1
    assert st["ui_scale"] == 1.5 and st["show_ui"] is False
    # the scene the session ended on opens in its compare and term views
    again = Session(gl_ctx, str(path.with_name("last_scene.toml")), renderer=renderer, state=st, prefetch=False)
    try:
        assert again.image_mode == "side by side" and again.compare.split == 0.3 and again.view_mode == 1
        assert np.allclose(again.scene.materials["ball"]["kd"], [0.3, 0.6, 0.9])
    finally:
        again.release()
    other = Session(gl_ctx, "default", renderer=renderer, state=st, prefetch=False)  # not that scene
    try:
        assert other.image_mode == "raster" and other.view_mode == 0 and not other.same_scene
        assert other.open_scene(path.with_name("last_scene.toml"))  # the last session's scene
        assert np.allclose(other.scene.materials["ball"]["kd"], [0.3, 0.6, 0.9])
    finally:
        other.release()


def test_brute_force_accumulation_restarts_on_a_change(session):
    session.scene.render.ibl = "brute_force"
    session.changed()
    for _ in range(3):
        session.render_view(SIZE)
    assert session.bf_count == 3 and session.refining
    session.set_material_param("ball", "kd", [0.7, 0.7, 0.2])
    session.render_view(SIZE)
    assert session.bf_count == 1  # a change starts the average over


def test_the_session_imports_no_window_library():
    """Neither imgui nor glfw, not even inside a function (an AST check of the session's modules),
    and importing it loads neither (the session runs where no window can open)."""
    import ast
    import subprocess
    import sys
    from pathlib import Path

    app = Path(__file__).resolve().parents[1] / "viewer" / "app"
    for f in ("session.py", "file_actions.py"):
        for node in ast.walk(ast.parse((app / f).read_text("utf-8"))):
            names = [a.name for a in node.names] if isinstance(node, ast.Import) else \
                [node.module or ""] if isinstance(node, ast.ImportFrom) else []
            assert not any(n.split(".")[0] in ("imgui_bundle", "glfw") for n in names), (f, names)
    code = ("import sys, viewer.app.session; "
            "print(sorted(m for m in ('imgui_bundle', 'glfw') if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300,
                         cwd=app.parents[1])
    assert out.returncode == 0 and out.stdout.strip() == "[]", (out.stdout, out.stderr[-2000:])


def test_traced_chains_refine_when_still_and_not_while_interacting(session, monkeypatch, tmp_path):
    # With ray tracing on, a preview frame (the view moving) draws mirrors and glass untraced:
    # the renderer is asked for raytrace=False. Once still the untraced view comes first, then
    # strips of traced rows, frame after frame (``refining``) until the image equals one traced
    # render bit for bit; a move cancels the trace and the next still view starts over.
    import viewer.app.view_frames as smod
    from viewer.scene.lecture import TOUR

    monkeypatch.setenv("BRDF_VIEWER_CACHE", str(tmp_path))  # an empty traced-frame cache
    assert session.lecture([s.key for s in TOUR].index("tir"))
    assert session.renderer.traces(session.scene)
    asked = []
    real = session.renderer.render
    monkeypatch.setattr(session.renderer, "render", lambda *a, **k: asked.append(k.get("raytrace")) or real(*a, **k))
    monkeypatch.setattr(smod, "TRACE_BUDGET_S", 1e-9)  # one row per frame after the first strip
    session.changed()
    session.render_view(SIZE, interacting=True)
    assert asked == [False] and session.quality == "preview" and not session.refining
    asked.clear()
    session.render_view(SIZE)
    assert asked == [False] and session.tracing and session.refining and "ray tracing: 0%" in session.trace_status
    assert "half resolution first" in session.trace_status
    untraced = session.renderer.read_linear(session.hdr).copy()
    frames = 0
    while session.refining:
        session.render_view(SIZE)
        frames += 1
        assert frames < 100
    assert frames > 5 and session.quality == "full" and session.trace_status == ""
    assert None in asked and "ray traced in" in session.last_message.text
    done = session.renderer.read_linear(session.hdr).copy()
    # traced (no MSAA) where a chain starts, the untraced view elsewhere
    one_shot = session.renderer.read_linear(real(session.scene, session.camera, *SIZE, session.view_mode, msaa=0))
    mask = session.renderer.traced_mask(session.scene, session.camera, *SIZE)[::-1]
    assert np.array_equal(done, np.where(mask[..., None], one_shot, untraced))
    assert not np.array_equal(done, untraced)
    asked.clear()
    session.render_view(SIZE)  # nothing changed: nothing rendered
    assert asked == []
    session.camera.orbit(5.0, 0.0, SIZE[1])  # the window marks a moved camera so
    session.changed()
    session.render_view(SIZE, interacting=True)
    assert asked == [False] and not session.refining


def test_s_cycles_the_reference_strategy(session):
    """The S key's action: MIS -> BSDF alone -> light alone -> MIS, each said in one line."""
    seen = []
    for _ in range(3):
        n0 = len(session.messages)
        seen.append(session.cycle_strategy())
        assert session.reference.options["strategy"] == seen[-1]
        assert any("strategy" in m.text for m in new_messages(session, n0))
    assert seen == ["bsdf", "light", "mis"]
