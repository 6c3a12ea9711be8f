"""``Viewer``: the viewer in a Jupyter notebook, a ``jupyter_rfb.RemoteFrameBuffer``.

The widget asks ``get_frame`` for a frame when something changed and the browser is ready for
one; jupyter_rfb sends it as JPEG while frames follow each other (dragging, a slider) and once
more as PNG when the view has been still for 0.3 s. ``frame()`` draws the current state and
returns it (no browser needed); ``snapshot()`` is a static image for a saved notebook
(image/png in its output). ``ui`` holds the canvas, the view switch and status line, the
material editors and the BRDF plots."""

from __future__ import annotations

import asyncio
import base64
import io

import ipywidgets as W
import numpy as np
from jupyter_rfb import RemoteFrameBuffer

from viewer.notebook.controls import MaterialEditor
from viewer.notebook.view import MODES, NotebookView, load_view_scene

PLOT_SIZE = (420, 280)
PLOT_DELAY_S = 0.3   # a plot follows a slider once it rests this long (a plot takes ~0.1 s)


def png_bytes(img: np.ndarray) -> bytes:
    from PIL import Image

    buf = io.BytesIO()
    Image.fromarray(np.ascontiguousarray(img)).save(buf, format="PNG")
    return buf.getvalue()


class StaticImage:
    """A frame as a notebook output: image/png (what a saved notebook and nbconvert show) and
    the raw array as ``data``."""

    def __init__(self, data: np.ndarray):
        self.data = data

    def _repr_png_(self):
        return png_bytes(self.data)

    def _repr_mimebundle_(self, include=None, exclude=None):
        return {"image/png": base64.b64encode(png_bytes(self.data)).decode("ascii"),
                "text/plain": f"<frame {self.data.shape[1]}x{self.data.shape[0]}>"}


class Viewer(RemoteFrameBuffer):
    """The viewer as a notebook widget.

    ``scene``: what ``viewer.render`` takes (a built-in name such as ``"default"``, a ``.toml``
    path as a string or any ``os.PathLike`` such as ``pathlib.Path``, TOML text, a Scene), or a
    ``.brdf`` / ``.bparam`` file, string or path object (the default scene with that material). ``material``: a preset (``"gold"``), a model name or a material file for the
    material ``target`` (default: the scene's first). ``overrides``: ``--set`` assignments.
    ``width`` x ``height``: the widget's size in CSS pixels (the framebuffer follows the
    browser's size and pixel ratio). ``engine`` / ``workers``: the reference's (``viewer.reference``)."""

    def __init__(self, scene="default", width: int = 480, height: int = 270, *, material=None, target=None,
                 overrides=(), engine: str = "auto", workers=None, max_depth: int = 8, **kwargs):
        sc = load_view_scene(scene, material, target, overrides)
        view = NotebookView(sc, width, height, engine=engine, workers=workers, max_depth=max_depth)
        super().__init__(css_width=f"{int(width)}px", css_height=f"{int(height)}px", **kwargs)
        self.view = view
        try:
            self._loop = asyncio.get_running_loop()   # the kernel's: the reference's thread wakes it
        except RuntimeError:
            self._loop = None
        view.wake = self._wake
        self.status = W.HTML("")
        self.mode = W.ToggleButtons(options=list(MODES), value="raster", description="view",
                                    tooltip="raster: the rasterizer; reference: the progressive path tracer; "
                                            "split: raster left of the divider, reference right")
        self.mode.observe(lambda ch: self._set_mode(ch["new"]), names="value")
        self.editors = {name: MaterialEditor(lambda n=name: self.view.scene.materials[n], self._set_from_editor,
                                             f"materials.{name}.", lambda n=name: self._material_changed(n))
                        for name in sc.materials}
        self._plot_timers = {}
        self.plots = {}   # material -> (kind picker, image, box)
        for name in sc.materials:
            self._plot_widgets(name)
        self.tabs = W.Tab(children=[W.VBox([self.editors[n].box, self.plots[n][2]]) for n in sc.materials])
        self._titles()
        self.ui = W.VBox([self, W.HBox([self.mode, self.status]), self.tabs])
        self._update_status()

    # ------------------------------------------------------------------ the binding interface
    def set(self, key: str, value):
        """Set ``key`` (``"materials.ball.alpha"``, ``"render.exposure"``, ``"lights.0.intensity"``)
        to ``value`` as the slider does (validated; a refused value raises ``ViewerError``)."""
        self.view.set(key, value)
        parts = key.split(".")
        if parts[0] == "materials" and len(parts) > 1 and parts[1] in self.editors:
            self.editors[parts[1]].rebuild()
            self._material_changed(parts[1], redraw=False)
        self.request_draw()

    def frame(self) -> np.ndarray:
        """The current view drawn now, (H, W, 3) uint8 at the framebuffer size."""
        out = self.view.frame()
        self._update_status()
        return out

    def show_reference(self, on=True, split: bool = False):
        """Switch to the progressive reference (``split``: beside the raster view) or back."""
        mode = ("split" if split else "reference") if on else "raster"
        if self.mode.value != mode:
            self.mode.value = mode   # its observer switches the view
        else:
            self._set_mode(mode)

    def reference_status(self) -> dict:
        return self.view.reference_status()

    def snapshot(self, pixel_ratio=None):
        """The current view as a static image output (image/png)."""
        return StaticImage(self.frame())

    # ------------------------------------------------------------------ jupyter_rfb
    def get_frame(self):
        out = self.frame()
        if self.view.needs_frames:   # the GPU engine renders in the frames: ask for the next
            self.request_draw()
        return out

    def handle_event(self, event):
        if self.view.handle_event(event):
            self.request_draw()

    def close(self, *args, **kwargs):
        """End the reference (its thread and workers), release the GL objects, close the widget."""
        try:
            self.view.close()
        except ImportError:   # called from __del__ while the interpreter shuts down: nothing to free
            pass
        super().close(*args, **kwargs)

    # ------------------------------------------------------------------ helpers
    def _wake(self):
        if self._loop is not None and not self._loop.is_closed():
            self._loop.call_soon_threadsafe(self.request_draw)

    def _set_mode(self, mode):
        self.view.show_reference(mode != "raster", split=mode == "split")
        self._update_status()
        self.request_draw()

    def _set_from_editor(self, key, value):
        self.view.set(key, value)

    def _update_status(self):
        v = self.view
        text = f"raster {v.pixels[0]}x{v.pixels[1]}, {v.render_ms:.0f} ms"
        if v.mode != "raster":
            st = v.reference_status()
            err = "" if st["rmse"] is None else f", rmse est. {st['rmse']:.4f}"
            text += f" &nbsp; reference: {st['engine'] or '...'} engine, {st['spp']} spp{err}"
            if st["error"]:
                text += f" <span style='color:#c33'>{st['error']}</span>"
        self.status.value = text

    def _titles(self):
        self.tabs.titles = tuple(f"{n} ({m.model})" for n, m in self.view.scene.materials.items())

    def _material_changed(self, name, redraw=True):
        self._titles()   # a preset or model switch changes the model
        if redraw:
            self.request_draw()
        try:   # this thread's loop: JupyterLab's slider changes come on a subshell thread, with a loop of its own
            loop = asyncio.get_running_loop()
        except RuntimeError:
            loop = None
        if loop is None:
            self._replot(name)
            return
        old = self._plot_timers.pop(name, None)
        if old is not None:
            old.cancel()
        self._plot_timers[name] = loop.call_later(PLOT_DELAY_S, self._replot, name)

    def _plot_widgets(self, name):
        from viewer.plots import applicable_kinds

        kinds = list(applicable_kinds(self.view.scene.materials[name]))
        pick = W.Dropdown(options=kinds, value="polar" if "polar" in kinds else kinds[0], description="plot")
        image = W.Image(format="png", width=PLOT_SIZE[0], height=PLOT_SIZE[1])
        pick.observe(lambda ch: self._replot(name), names="value")
        self.plots[name] = (pick, image, W.VBox([pick, image]))
        self._replot(name)

    def _replot(self, name):
        from viewer import ViewerError
        from viewer.plots import applicable_kinds, figure, render_figure

        pick, image, _ = self.plots[name]
        p = self.view.scene.materials[name]
        kinds = list(applicable_kinds(p))
        if list(pick.options) != kinds:
            pick.options = kinds
        if pick.value not in kinds:
            pick.value = kinds[0]
        try:
            fig = figure(p, pick.value, name=name, samples=20_000)
            image.value = png_bytes(render_figure(fig, *PLOT_SIZE, ss=2))
        except ViewerError as e:
            image.value = b""
            pick.description = f"plot ({e})"[:60]
