"""The notebook widget (docs/notebook.md): ``viewer.notebook.Viewer`` without a kernel (its frames
and events called directly) against ``viewer.render`` of the same scene, the window's editor
rules and the orbit camera; and ``examples/explore.ipynb`` executed on a headless kernel."""

from __future__ import annotations

import base64
import importlib
import io
import sys
import time
from pathlib import Path

import numpy as np
import pytest

import viewer
from viewer import ViewerError

ROOT = Path(__file__).resolve().parent.parent
W, H = 160, 90

pytest.importorskip("jupyter_rfb", reason="the notebook widget needs jupyter_rfb: pip install -e '.[notebook]'")
pytest.importorskip("ipywidgets", reason="the notebook widget needs ipywidgets: pip install -e '.[notebook]'")


def srgb(linear, scene):
    from viewer.image.colour import to_srgb8

    return to_srgb8(linear, scene.render.exposure, scene.render.tonemap)


@pytest.fixture(scope="module")
def widget():
    from viewer.notebook import Viewer

    v = Viewer("default", W, H, workers=0)   # workers=0: the reference in this process's thread
    yield v
    v.close()


def test_frame_is_viewer_render(widget):
    """The widget's frame is the offscreen renderer's image of the same scene: the linear image
    bit for bit; the 8-bit frame is the GPU's sRGB encoding of it, which may round differently
    from numpy's float64 ``to_srgb8`` by one step (measured: 0 on llvmpipe)."""
    frame = widget.frame()
    assert frame.shape == (H, W, 3) and frame.dtype == np.uint8
    linear = viewer.render("default", W, H)
    assert np.array_equal(widget.view.raster()[0], linear)
    assert np.abs(frame.astype(int) - srgb(linear, widget.view.scene)).max() <= 1


def test_set_renders_the_new_value(widget):
    """``set`` is the slider's path: the alias alpha sets alpha_x and alpha_y, and the frame is
    ``viewer.render`` with the same ``--set`` assignment (parsed by the scene loader instead)."""
    before = widget.frame().copy()
    widget.set("materials.ball.alpha", 0.3)
    m = widget.view.scene.materials["ball"]
    assert m["alpha_x"] == m["alpha_y"] == 0.3
    after = widget.frame()
    want = viewer.render("default", W, H, overrides=["materials.ball.alpha=0.3"])
    assert np.array_equal(widget.view.raster()[0], want)
    assert np.abs(after.astype(int) - before).max() > 10   # the highlight changed visibly
    with pytest.raises(ViewerError, match="out of range"):
        widget.set("materials.ball.alpha", 7.0)
    assert widget.view.scene.materials["ball"]["alpha_x"] == 0.3   # the old value stays
    with pytest.raises(ViewerError, match="no parameter|has no parameter"):
        widget.set("materials.ball.shinyness", 1.0)


def test_roughness_slider_sets_alpha_squared(widget):
    """The editor's roughness slider is in r = sqrt(alpha), as the window's; moving it renders
    alpha = r^2 on both axes."""
    editor = widget.editors["ball"]
    editor.controls["roughness r"].value = 0.5
    m = widget.view.scene.materials["ball"]
    assert m["alpha_x"] == pytest.approx(0.25) and m["alpha_y"] == pytest.approx(0.25)
    widget.frame()
    want = viewer.render("default", W, H, overrides=[f"materials.ball.alpha={m['alpha_x']!r}"])
    assert np.array_equal(widget.view.raster()[0], want)


def test_editor_hides_what_the_fresnel_variant_ignores(widget):
    """A dielectric Fresnel shows ior, not eta / k; a conductor the reverse (the window's rule)."""
    editor = widget.editors["ball"]
    editor.controls["fresnel"].value = "dielectric"
    assert "ior" in editor.controls and "eta" not in editor.controls
    editor.controls["fresnel"].value = "conductor"
    assert widget.view.scene.materials["ball"]["fresnel"] == "conductor"
    assert "eta" in editor.controls and "k" in editor.controls and "ior" not in editor.controls
    assert "f0" not in editor.controls
    editor.controls["fresnel"].value = "dielectric"


def test_colour_picker_and_refused_value(widget):
    """A colour up to 1 is a picker of the stored value (#rrggbb, no sRGB conversion, as the
    window's colour edit); a value the spec refuses leaves the old one and says why."""
    editor = widget.editors["floor"]
    editor.controls["albedo"].value = "#336699"
    assert np.allclose(widget.view.scene.materials["floor"]["albedo"], [0x33 / 255, 0x66 / 255, 0x99 / 255])
    ball = widget.editors["ball"]
    ior = ball.controls["ior"]
    old = widget.view.scene.materials["ball"]["ior"]
    ball.apply("ior", float("nan"), ior, old)
    assert widget.view.scene.materials["ball"]["ior"] == old and ior.value == old
    assert "ior" in ball.message.value and "out of range" in ball.message.value


def test_resize_with_pixel_ratio_and_orbit(widget):
    """A resize event renders at width x height x pixel_ratio; a left drag orbits the window's
    camera by the same amount, a wheel notch dollies one step."""
    from viewer.scene.camera import OrbitCamera

    widget.handle_event({"event_type": "resize", "width": 100, "height": 60, "pixel_ratio": 2.0})
    assert widget.frame().shape == (120, 200, 3)
    cam = widget.view.camera
    want = OrbitCamera(cam.position, cam.target, cam.fov_y)
    want.orbit(30.0, -12.0, 60)
    widget.handle_event({"event_type": "pointer_down", "x": 10.0, "y": 20.0, "button": 1, "buttons": (1,)})
    widget.handle_event({"event_type": "pointer_move", "x": 40.0, "y": 8.0, "button": 1, "buttons": (1,)})
    widget.handle_event({"event_type": "pointer_up", "x": 40.0, "y": 8.0, "button": 1, "buttons": ()})
    assert cam.yaw == pytest.approx(want.yaw) and cam.pitch == pytest.approx(want.pitch)
    d = cam.distance
    widget.handle_event({"event_type": "wheel", "dx": 0.0, "dy": -100.0, "x": 5.0, "y": 5.0})
    assert cam.distance == pytest.approx(d * 0.9)   # one notch nearer, as glfw's wheel step
    widget.handle_event({"event_type": "double_click", "x": 5.0, "y": 5.0, "button": 1})
    widget.handle_event({"event_type": "resize", "width": W, "height": H, "pixel_ratio": 1.0})
    assert widget.frame().shape == (H, W, 3)


def test_snapshot_is_a_png_of_the_frame(widget):
    from PIL import Image

    bundle = widget.snapshot()._repr_mimebundle_()
    img = np.asarray(Image.open(io.BytesIO(base64.b64decode(bundle["image/png"]))).convert("RGB"))
    assert np.array_equal(img, widget.frame())


def test_reference_converges(widget):
    """The reference toggle shows the progressive path tracer: its spp grows and its estimated
    RMSE falls (for an unbiased estimator about as 1/sqrt(spp))."""
    widget.show_reference(True)
    try:
        seen = []
        deadline = time.monotonic() + 30.0
        while time.monotonic() < deadline:
            frame = widget.frame()
            st = widget.reference_status()
            if st["rmse"] is not None and (not seen or st["spp"] > seen[-1][0]):
                seen.append((st["spp"], st["rmse"]))
            if len(seen) >= 2 and seen[-1][0] >= 4 * seen[0][0]:
                break
            time.sleep(0.1)
        assert st["engine"] == "cpu" and st["error"] == ""
        assert len(seen) >= 2, seen
        (s0, e0), (s1, e1) = seen[0], seen[-1]
        assert s1 > s0 and e1 < e0, seen
        assert frame.shape == (H, W, 3)
        widget.show_reference(True, split=True)   # raster left of the divider, reference right
        split, raster = widget.frame(), widget.view.raster()[1]
        cut = W // 2
        assert np.array_equal(split[:, :cut], raster[:, :cut])
        assert np.all(split[:, cut] == 255) and not np.array_equal(split[:, cut + 1:], raster[:, cut + 1:])
    finally:
        widget.show_reference(False)


def test_without_jupyter_rfb_one_line(monkeypatch):
    """Without the [notebook] extra, importing viewer.notebook says what to install."""
    monkeypatch.setitem(sys.modules, "jupyter_rfb", None)
    for name in [m for m in sys.modules if m.startswith("viewer.notebook")]:
        monkeypatch.delitem(sys.modules, name)
    with pytest.raises(ViewerError) as e:
        importlib.import_module("viewer.notebook")
    assert "jupyter_rfb is not installed" in str(e.value) and ".[notebook]" in str(e.value)
    assert "\n" not in str(e.value)


def test_material_by_name():
    """A preset by name and a .brdf file as the scene give those materials."""
    from viewer.notebook import load_view_scene

    sc = load_view_scene("default", material="gold")
    assert sc.materials["ball"].model == "microfacet" and sc.materials["ball"]["fresnel"] == "conductor"
    sc = load_view_scene(str(ROOT / "viewer/brdfs/cooktorrance.brdf"))
    assert viewer.brdf.is_file(sc.materials["ball"])
    with pytest.raises(ViewerError, match="not a material"):
        load_view_scene("default", material="gold", target="nothing")


def test_frames_from_another_thread(widget):
    """JupyterLab 4.4+ with ipykernel 7 sends the widget's messages on a subshell thread while the
    cells run on the main one: a frame drawn on another thread, after frames drawn on this one,
    is the renderer's image, and so is the next frame drawn here (an EGL context left current on
    one thread draws nothing on another: those frames were noise)."""
    import threading

    from viewer.notebook import Viewer

    v = Viewer("default", 48, 27, workers=0)
    try:
        v.frame()   # drawn on this thread
        v.set("materials.ball.alpha", 0.21)
        got = {}

        def draw():
            got["frame"] = v.get_frame().copy()
            got["linear"] = v.view.raster()[0].copy()

        t = threading.Thread(target=draw)
        t.start()
        t.join(120)
        want = viewer.render("default", 48, 27, overrides=["materials.ball.alpha=0.21"])
        assert np.array_equal(got["linear"], want)
        assert np.abs(got["frame"].astype(int) - srgb(want, v.view.scene)).max() <= 1
        v.set("materials.ball.alpha", 0.3)   # and back on this thread
        v.frame()
        want = viewer.render("default", 48, 27, overrides=["materials.ball.alpha=0.3"])
        assert np.array_equal(v.view.raster()[0], want)
    finally:
        v.close()


class PathObject:
    """An os.PathLike that is not a pathlib.Path (as a library's own path type would be)."""

    def __init__(self, path):
        self.path = str(path)

    def __fspath__(self):
        return self.path


def test_scene_as_a_path_object(tmp_path):
    """A pathlib.Path or any os.PathLike is a file: a scene .toml is read from the file (not as
    TOML text), a .brdf / .bparam path means the default scene with that material, as the same
    path given as a string does; a missing file is one line naming it."""
    from viewer.notebook import load_view_scene
    from viewer.scene import load_scene

    text = (ROOT / "viewer" / "scenes" / "default.toml").read_text(encoding="utf-8")
    scene = tmp_path / "scene.toml"
    scene.write_text(text.replace("fov_y    = 35.0", "fov_y    = 33.0", 1), encoding="utf-8")
    want = load_scene(str(scene))
    assert want.camera.fov_y == 33.0   # the file's own value, so reading it is checked
    for arg in (scene, PathObject(scene)):
        sc = load_view_scene(arg)
        assert sc.camera.fov_y == 33.0 and list(sc.materials) == list(want.materials)
    ct = ROOT / "viewer" / "brdfs" / "cooktorrance.brdf"
    for arg in (ct, PathObject(ct)):
        sc = load_view_scene(arg)
        assert viewer.brdf.is_file(sc.materials["ball"]) and sc.materials["ball"]["m"] == 0.3
    values = tmp_path / "rough.bparam"
    values.write_text(f"bparam {ct}\n\n::begin parameters\nfloat m 0.01 1 0.55\n::end parameters\n")
    assert load_view_scene(values).materials["ball"]["m"] == 0.55
    assert load_view_scene("default", material=values).materials["ball"]["m"] == 0.55
    with pytest.raises(ViewerError, match="a material file and material="):
        load_view_scene(ct, material="gold")
    with pytest.raises(ViewerError, match="not found") as e:
        load_view_scene(tmp_path / "nothing.toml")
    assert "\n" not in str(e.value) and "nothing.toml" in str(e.value)


def test_viewer_takes_a_path_object(widget):
    """``Viewer(pathlib.Path(...))`` opens the file (the shared renderer of the module's widget)."""
    from viewer.notebook import Viewer

    v = Viewer(ROOT / "viewer" / "scenes" / "default.toml", 48, 27, workers=0)
    try:
        assert v.view.scene.materials["ball"].model == "microfacet"
        want = viewer.render(ROOT / "viewer" / "scenes" / "default.toml", 48, 27)
        v.frame()
        assert np.array_equal(v.view.raster()[0], want)
    finally:
        v.close()


# slow: a kernel start and the whole notebook (47-76 s on two loaded cores); the widget's own tests
# above check the same frame, slider and reference rules in this process by default
@pytest.mark.slow
def test_explore_notebook_runs(monkeypatch):
    """examples/explore.ipynb on a headless kernel at 160x90 (its settings cell is rewritten):
    its own cells assert that the widget's frame is viewer.render's, that a slider change
    renders the new value and that the reference converges; its saved output holds a static
    image (image/png)."""
    nbformat = pytest.importorskip("nbformat", reason="nbclient's notebook format: pip install -e '.[test]'")
    nbclient = pytest.importorskip("nbclient", reason="runs the notebook: pip install -e '.[test]'")
    pytest.importorskip("ipykernel", reason="the notebook's kernel: pip install -e '.[test]'")
    nb = nbformat.read(ROOT / "examples" / "explore.ipynb", as_version=4)
    settings = [c for c in nb.cells if c.cell_type == "code" and "SIZE = " in c.source]
    assert len(settings) == 1
    settings[0].source = "SIZE = (160, 90)\nWORKERS = 0\n"
    import os

    env_path = os.pathsep.join([str(ROOT)] + [p for p in os.environ.get("PYTHONPATH", "").split(os.pathsep) if p])
    monkeypatch.setenv("PYTHONPATH", env_path)   # the kernel imports this checkout
    # a cell's time limit guards against a hang, it checks no speed: the .brdf cell draws 64 frames
    # of a file material (its sampled light settling); viewer.render of that scene at 240x135 took
    # 283-324 s on two cores at load average 21-25, and the cell timed out at the former 120 s
    client = nbclient.NotebookClient(nb, timeout=600, kernel_name="python3", resources={"metadata": {"path": str(ROOT)}})
    client.execute()
    nb = nbformat.reads(nbformat.writes(nb), as_version=4)   # the notebook as saved
    images = [o for c in nb.cells if c.cell_type == "code" for o in c.get("outputs", [])
              if "image/png" in o.get("data", {}) or "image/jpeg" in o.get("data", {})]
    assert images, "no static image in the executed notebook's outputs"


def test_set_reaches_tables_nested_materials_and_lobes():
    """``set``'s paths below a material: a table field, a table in a table, a nested material's
    parameter and a lobe's field, each validated by the spec (no GL needed)."""
    from viewer import brdf
    from viewer.notebook.view import set_material_value

    coat = brdf.get("layered").params()
    out = set_material_value(coat, ["coating", "thin_film", "thickness_nm"], 250.0, "t")
    assert out["coating"]["thin_film"]["thickness_nm"] == 250.0
    assert coat["coating"]["thin_film"]["thickness_nm"] != 250.0   # the old Params is not edited
    base = coat["base"].model
    name = next(p.name for p in brdf.get(base).spec.params if p.kind == "rgb")
    out = set_material_value(out, ["base", name], 0.25, "t")
    assert np.array_equal(out["base"][name], [0.25] * 3)
    with pytest.raises(ViewerError, match="out of range"):
        set_material_value(coat, ["coating", "ior"], -1.0, "t")
    with pytest.raises(ViewerError, match="no field"):
        set_material_value(coat, ["coating", "nope"], 1.0, "t")
    laf = brdf.get("lafortune").params()
    field = laf["lobes"][0]
    key = next(k for k in field if isinstance(field[k], float))
    out = set_material_value(laf, ["lobes", "0", key], 2.0, "t")
    assert out["lobes"][0][key] == 2.0
    with pytest.raises(ViewerError, match="no item"):
        set_material_value(laf, ["lobes", "9", key], 2.0, "t")


def test_gpu_engine_runs_in_the_frames():
    """The GPU engine renders a time slice per frame on the widgets' shared context: while it
    runs the widget asks for the next frame itself (``needs_frames``), and its spp grows frame by
    frame (48x27, software GL: about 3 s)."""
    from viewer.notebook import Viewer

    v = Viewer("default", 48, 27, engine="gpu", workers=0)
    try:
        v.show_reference(True)
        spp = []
        for _ in range(400):
            v.get_frame()
            spp.append(v.reference_status()["spp"])
            if spp[-1] >= 8:
                break
        st = v.reference_status()
        assert st["engine"] == "gpu" and st["error"] == "", st
        assert v.view.needs_frames and spp[-1] >= 8 and spp == sorted(spp)
    finally:
        v.close()


def test_a_drag_defers_the_reference(widget):
    """While the pointer drags the camera the reference waits and the raster view stands in (as
    in the window); releasing it asks for a frame, which starts the reference on the still view."""
    widget.show_reference(True)
    try:
        assert not widget.handle_event({"event_type": "pointer_down", "x": 5.0, "y": 5.0, "button": 1})
        widget.view.handle_event({"event_type": "pointer_move", "x": 25.0, "y": 5.0, "button": 1})
        frame = widget.frame()
        assert widget.view.reference.key is None   # paused, nothing restarted
        assert np.array_equal(frame, widget.view.raster()[1])
        assert widget.view.handle_event({"event_type": "pointer_up", "x": 25.0, "y": 5.0, "button": 1})
        widget.frame()
        assert widget.view.reference.key is not None
    finally:
        widget.show_reference(False)
        widget.view.camera.reset()
        widget.view.changed()


def test_docs_show_the_notebooks_first_cells():
    """docs/notebook.md quotes the first four code cells of examples/explore.ipynb as they are."""
    import json

    nb = json.loads((ROOT / "examples" / "explore.ipynb").read_text(encoding="utf-8"))
    doc = (ROOT / "docs" / "notebook.md").read_text(encoding="utf-8")
    cells = ["".join(c["source"]) for c in nb["cells"] if c["cell_type"] == "code"][:4]
    assert len(cells) == 4
    for source in cells:
        assert f"```python\n{source}\n```" in doc, source.splitlines()[0]
