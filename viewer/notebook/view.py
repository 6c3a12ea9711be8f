"""What the notebook widget shows, without the widget: the scene, the orbit camera, the offscreen
rasterizer at the widget's pixel size, values set as the window's sliders set them, and the
progressive reference (``viewer.app.reference_view.ReferenceView``, both engines) beside it.

``NotebookView`` needs no Jupyter: ``viewer.notebook.Viewer`` (the ``jupyter_rfb`` widget) holds
one and forwards its frames and events to it; the unit tests drive it directly."""

from __future__ import annotations

import json
import math
import os
import threading
import time
from pathlib import Path

import numpy as np

from viewer import ViewerError

MODES = ("raster", "reference", "split")
_shared = None   # (SharedContext, Renderer) of this process's widgets, made by the first
_shared_lock = threading.Lock()
MATERIAL_FILES = (".brdf", ".bparam")   # a scene argument naming one of these is a material


class SharedContext:
    """The widgets' one GL context, current on one thread at a time: ``with gl:`` makes it
    current on the calling thread for the block (waiting while another thread has it) and
    releases it after the outermost block.

    Jupyter calls a widget from more than one thread: JupyterLab 4.4 and later with ipykernel 7
    handle widget messages (a drag, a slider, the browser's frame requests) on a subshell thread
    while cells run on the main one. An EGL context still current on the thread that used it
    last draws nothing on another (Mesa reads back uninitialised memory and reports no error:
    the frames of a drag in JupyterLab were noise), so no thread keeps it between uses."""

    def __init__(self, ctx):
        self.ctx = ctx
        self.lock = threading.RLock()
        self.depth = 0   # nested blocks of the thread holding the lock

    def __enter__(self):
        self.lock.acquire()
        self.depth += 1
        self.ctx.__enter__()   # again in a nested block too: an engine choice inside may release it
        return self.ctx

    def __exit__(self, *exc):
        self.depth -= 1
        try:
            if self.depth == 0:
                self.ctx.__exit__(None, None, None)   # EGL: no context current on this thread now
        finally:
            self.lock.release()


def load_view_scene(scene="default", material=None, target=None, overrides=(), width=None, height=None):
    """The Scene a notebook view starts from: ``scene`` as ``viewer.render`` takes it (a name, a
    path as a string or any ``os.PathLike``, TOML text or a Scene); a ``.brdf`` / ``.bparam`` path
    there (string or path object) means the ``default`` scene with that material. ``material`` (a
    preset such as ``"gold"``, a model name, a ``.brdf``, ``.bparam`` or material ``.toml`` file,
    string or path object) replaces the material ``target`` (default: the scene's first)."""
    from viewer.api import load

    if isinstance(scene, os.PathLike):   # pathlib.Path or any path object: a file, never TOML text
        scene = Path(os.fsdecode(scene))
    if isinstance(material, os.PathLike):
        material = os.fsdecode(material)
    if isinstance(scene, Path) and scene.suffix.lower() in MATERIAL_FILES:
        scene = str(scene)
    if isinstance(scene, str) and "\n" not in scene and scene.lower().endswith(MATERIAL_FILES):
        if material is not None:
            raise ViewerError(f"scene: {scene!r} is a material file and material={material!r} is given too; "
                              "allowed: one of them")
        scene, material = "default", scene
    sc = load(scene, overrides, width, height)
    if material is not None:
        from viewer.scene.load import material_from_name

        names = list(sc.materials)
        if not names:
            raise ViewerError(f"{sc.label}: the scene has no material for material={material!r}")
        name = names[0] if target is None else target
        if name not in sc.materials:
            raise ViewerError(f"target: {name!r} is not a material of {sc.label}; allowed: {', '.join(names)}")
        sc.materials[name] = material_from_name(str(material))
    return sc


def toml_value(value) -> str:
    """A Python value (number, bool, string, sequence, numpy array) as TOML text for ``--set``."""
    if isinstance(value, np.ndarray):
        value = value.tolist()
    elif isinstance(value, np.generic):
        value = value.item()
    if isinstance(value, tuple):
        value = list(value)
    try:
        return json.dumps(value, allow_nan=False)
    except (TypeError, ValueError):
        raise ViewerError(f"value: {value!r} is not a scene value; allowed: a number, true/false, a string "
                          "or a list of numbers") from None


def set_material_value(material, parts: list[str], value, where: str):
    """``material`` (Params) with the value at the dotted ``parts`` below it replaced, validated
    through its model's spec as the window's editor validates a slider's value (a refused value
    raises ``ViewerError``). An alias (microfacet ``alpha``) sets every parameter it stands for
    (``alpha_x`` and ``alpha_y``), as the roughness slider does; a nested material
    (``base.alpha``), a table field (``coating.ior``) and a lobe field (``lobes.0.n``) are
    reached by their names."""
    from viewer import brdf
    from viewer.brdf.spec import validate_value

    spec = brdf.spec_of(material)
    name, rest = parts[0], parts[1:]
    if not rest and name in spec.aliases:
        targets = spec.aliases[name]
        return material.replace(**{t: validate_value(spec.param(t), value, where, brdf.lookup_spec) for t in targets})
    if name not in spec.names:
        raise ViewerError(f"{where}: {material.model} has no parameter {name!r}; allowed: "
                          + ", ".join(list(spec.names) + list(spec.aliases)))
    p = spec.param(name)
    old = material[name]
    if not rest:
        return material.replace(**{name: validate_value(p, value, where, brdf.lookup_spec)})
    if p.kind == "material":
        return material.replace(**{name: set_material_value(old, rest, value, where)})
    if p.kind in ("table", "lobes"):   # the table (or list) with the one value replaced, validated whole
        return material.replace(**{name: validate_value(p, _replaced(old, rest, value, where, name), where)})
    raise ViewerError(f"{where}: {'.'.join(parts)} names no value of {material.model} "
                      f"({name} is {'a ' + p.kind if p.kind != 'lobes' else 'a list of ' + str(len(old)) + ' lobes'})")


def _replaced(old, path, value, where, here):
    """A plain copy of the table or list ``old`` with the value at ``path`` replaced."""
    key, rest = path[0], path[1:]
    if isinstance(old, (list, tuple)):
        if not key.isdigit() or int(key) >= len(old):
            raise ViewerError(f"{where}: no item {key!r} in {here}; allowed: an index 0..{len(old) - 1}")
        out = [dict(x) if isinstance(x, dict) else x for x in old]
        idx = int(key)
    elif isinstance(old, dict):
        if key not in old:
            raise ViewerError(f"{where}: {here} has no field {key!r}; allowed: {', '.join(old)}")
        out, idx = dict(old), key
    else:
        raise ViewerError(f"{where}: {here} is a value, not a table")
    out[idx] = _replaced(out[idx], rest, value, where, f"{here}.{key}") if rest else value
    return out


class NotebookView:
    """The scene, camera, rasterizer and reference of one notebook widget; ``frame`` draws."""

    def __init__(self, scene, width: int = 480, height: int = 270, engine: str = "auto",
                 workers: int | None = None, max_depth: int = 8):
        from viewer.scene.camera import OrbitCamera
        from viewer.gl.context import create_offscreen_context
        from viewer.gl.renderer import Renderer
        from viewer.reference_common.select import ENGINES

        if engine not in ENGINES:
            raise ViewerError(f"engine: {engine!r} is not a reference engine; allowed: {', '.join(ENGINES)}")
        for key, v in (("width", width), ("height", height)):
            if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or not 16 <= v <= 8192:
                raise ViewerError(f"{key}: {v!r} is out of range; allowed: an integer 16..8192")
        self.scene = scene
        self.camera = OrbitCamera.from_scene(scene)
        self.size = (int(width), int(height))   # logical (CSS) pixels
        self.pixel_ratio = 1.0
        global _shared
        with _shared_lock:
            if _shared is None:   # one context and renderer for every widget: programs compile once
                gl = SharedContext(create_offscreen_context())
                with gl:
                    _shared = (gl, Renderer(gl.ctx))
        self.gl, self.renderer = _shared
        self.ctx = self.gl.ctx
        self.engine_request = engine
        self.workers = workers
        self.max_depth = max_depth
        self.mode = "raster"
        self.split = 0.5
        self.reference = None       # ReferenceView, made when first shown
        self.wake = None            # called from any thread when the reference has a new image
        self.version = 0            # +1 per change of what the raster image shows
        self.last = None            # the last frame, (H, W, 3) uint8
        self.render_ms = 0.0        # of the last raster frame
        self._raster = None         # (key, linear, srgb) of the last raster frame
        self._drag = None           # (button, x, y, moved) while a pointer button is held

    # ------------------------------------------------------------------ size and camera
    @property
    def pixels(self) -> tuple[int, int]:
        """The framebuffer size: the logical size times the pixel ratio."""
        w, h = self.size
        return max(1, round(w * self.pixel_ratio)), max(1, round(h * self.pixel_ratio))

    def resize(self, width, height, pixel_ratio=1.0):
        w, h, r = float(width), float(height), float(pixel_ratio or 1.0)
        if not (math.isfinite(w) and math.isfinite(h) and math.isfinite(r)) or w < 1 or h < 1 or r <= 0:
            return False
        new = (int(round(w)), int(round(h)))
        if new == self.size and r == self.pixel_ratio:
            return False
        self.size, self.pixel_ratio = new, r
        self.changed()
        return True

    def changed(self):
        self.version += 1

    def handle_event(self, event: dict) -> bool:
        """A ``jupyter_rfb`` event: ``resize``, pointer drags (left: orbit, right / middle: pan,
        as in the window), ``double_click`` (the camera's start), ``wheel`` (dolly). True when the
        view changed (the widget then asks for a frame)."""
        kind = event.get("event_type") or event.get("type")
        if kind == "resize":
            return self.resize(event.get("width", 0), event.get("height", 0), event.get("pixel_ratio", 1.0))
        x, y = float(event.get("x", 0.0)), float(event.get("y", 0.0))
        if kind == "pointer_down":
            self._drag = (int(event.get("button", 1)), x, y, False)
            return False
        if kind == "pointer_up":
            moved = self._drag is not None and self._drag[3]
            self._drag = None
            return moved and self.mode != "raster"   # the reference starts on the view now still
        if kind == "pointer_move" and self._drag is not None:
            button, x0, y0, _ = self._drag
            self._drag = (button, x, y, True)
            dx, dy = x - x0, y - y0
            if dx == 0 and dy == 0:
                return False
            if button == 1:
                self.camera.orbit(dx, dy, self.size[1])
            else:
                self.camera.pan(dx, dy, self.size[1])
            self.changed()
            return True
        if kind == "double_click":
            self.camera.reset()
            self.changed()
            return True
        if kind == "wheel":
            dy = float(event.get("dy", 0.0))
            if dy == 0 or not math.isfinite(dy):
                return False
            # a browser's wheel notch is about 100 (pixels) down for away; glfw's is 1 up for near
            self.camera.dolly(max(-5.0, min(5.0, -dy / 100.0)))
            self.changed()
            return True
        return False

    # ------------------------------------------------------------------ values
    def set(self, key: str, value):
        """Set ``key`` (a ``--set`` path: ``materials.ball.alpha``, ``lights.0.intensity``,
        ``render.exposure``) to ``value``. A material parameter is validated through its model's
        spec as the window's slider is (a refused value raises ``ViewerError`` and the old one
        stays); ``materials.NAME.preset`` / ``.model`` start the material afresh; anything else
        is applied as ``--set`` is."""
        from viewer.api import load
        from viewer.brdf.spec import Params
        from viewer.scene.overrides import dotted_key

        if not isinstance(key, str) or not key:
            raise ViewerError(f"key: {key!r} is not a dotted path; allowed: e.g. materials.ball.alpha")
        parts = dotted_key(key).split(".")
        where = f"set {key}"
        if parts[0] == "materials" and len(parts) == 2 and isinstance(value, Params):   # a whole material
            if parts[1] not in self.scene.materials:
                raise ViewerError(f"{where}: no material {parts[1]!r}; allowed: {', '.join(self.scene.materials)}")
            return self.set_material(parts[1], value)
        if parts[0] == "materials" and len(parts) >= 3 and parts[2] not in ("model", "preset"):
            name = parts[1]
            if name not in self.scene.materials:
                raise ViewerError(f"{where}: no material {name!r}; allowed: {', '.join(self.scene.materials)}")
            self.scene.materials[name] = set_material_value(self.scene.materials[name], parts[2:], value, where)
        else:
            self.scene = load(self.scene, [f"{key}={toml_value(value)}"])
        self.changed()

    def set_material(self, name: str, params):
        """Replace material ``name`` with validated ``params`` (a preset picked, say)."""
        self.scene.materials[name] = params
        self.changed()

    # ------------------------------------------------------------------ frames
    def raster(self):
        """(linear float32, sRGB uint8) of the raster view at the framebuffer size (kept until
        something changes)."""
        key = (self.version, self.pixels)
        if self._raster is None or self._raster[0] != key:
            w, h = self.pixels
            with self.gl:   # current on this thread for the draw and its read-back
                t = time.perf_counter()
                linear, srgb = self.renderer.render_arrays(self.scene, self.camera, w, h)
                self.render_ms = 1000.0 * (time.perf_counter() - t)
            self._raster = (key, linear, srgb)
        return self._raster[1], self._raster[2]

    def reference_image(self):
        """The reference's newest image as sRGB uint8 at the framebuffer size (None before its
        first pass); advances the GPU engine by one time slice."""
        from viewer.image.colour import to_srgb8

        w, h = self.pixels
        with self.gl:   # the engine choice and the GPU engine's time slice draw on it
            ref = self._reference()
            self.ctx.__enter__()   # again: a reference engine choice may have released it
            # at the logical size: a high-density display (pixel ratio 2) would cost four times the
            # samples for the same picture; the image is scaled up to the framebuffer (nearest pixel)
            # while a pointer drags the camera the job waits (the raster view stands in), as in the
            # window: a restart per dragged frame would never finish a pass
            ref.update(self.scene, self.camera, self.size, defer=self._drag is not None)
            got = ref.latest()
        if got is None:
            return None
        img = got[0]
        if img.shape[:2] != (h, w):   # the logical size, or the coarse first image (a quarter): scaled up
            ys = np.minimum((np.arange(h) * img.shape[0]) // h, img.shape[0] - 1)
            xs = np.minimum((np.arange(w) * img.shape[1]) // w, img.shape[1] - 1)
            img = img[ys][:, xs]
        return to_srgb8(img, self.scene.render.exposure, self.scene.render.tonemap)

    def frame(self) -> np.ndarray:
        """Draw the current mode and return it as (H, W, 3) uint8 (from any thread: one at a
        time, ``SharedContext``)."""
        with self.gl:
            return self._frame()

    def _frame(self) -> np.ndarray:
        _, srgb = self.raster() if self.mode != "reference" else (None, None)
        out = srgb
        if self.mode != "raster":
            ref = self.reference_image()
            if ref is None:   # nothing yet: the raster view stands in
                ref = self.raster()[1] if srgb is None else srgb
            if self.mode == "reference":
                out = ref
            else:
                out = srgb.copy()
                cut = int(round(self.split * out.shape[1]))
                out[:, cut:] = ref[:, cut:]
                if 0 < cut < out.shape[1]:
                    out[:, cut] = 255   # the divider
        self.last = out
        return out

    def show_reference(self, on=True, split: bool = False):
        """``on`` True: the progressive reference (``split``: raster left, reference right of the
        divider at ``self.split``); False: the raster view (the reference's job stops)."""
        self.mode = ("split" if split else "reference") if on else "raster"
        if not on and self.reference is not None:
            with self.gl:   # the GPU engine keeps its samples (a read-back) when it stops
                self.reference.stop(timeout=0.0)
        self.changed()

    def _reference(self):
        if self.reference is None:
            from viewer.app.reference_view import ReferenceView

            self.reference = ReferenceView(self.ctx, scale=1.0, max_depth=self.max_depth, workers=self.workers,
                                           engine=self.engine_request, wake=self._woken)
        return self.reference

    def _woken(self):
        if self.wake is not None:
            self.wake()

    def reference_status(self) -> dict:
        """The reference's state: ``engine`` ("cpu" / "gpu" once chosen), ``spp``, ``rmse`` (the
        estimated RMSE of its mean from the pixels' variances; None before a full pass),
        ``samples_per_second``, ``error`` and ``note`` (why this engine)."""
        from viewer.image.variance import rmse_estimate

        ref = self.reference
        if ref is None:
            return {"engine": None, "spp": 0, "rmse": None, "samples_per_second": 0.0, "error": "", "note": ""}
        snap = ref.snapshot()
        return {"engine": ref.active_engine or ref.engine, "spp": ref.spp,
                "rmse": None if snap is None else rmse_estimate(snap.variance),
                "samples_per_second": ref.samples_per_second, "error": ref.error,
                "note": ref.engine_note or ref.engine_reason}

    @property
    def needs_frames(self) -> bool:
        """The GPU engine renders in the frames: the widget asks for the next one itself."""
        return self.mode != "raster" and self.reference is not None and self.reference.needs_frames

    def close(self):
        """End the reference (its thread and workers) and release its GL objects; the shared
        renderer stays for the other widgets (as ``viewer.render`` keeps its own)."""
        if self.reference is not None:
            with self.gl:
                self.reference.close(timeout=5.0, keep_programs=True)   # other widgets share the context
            self.reference = None
