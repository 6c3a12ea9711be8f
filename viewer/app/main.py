"""The interactive viewer: a glfw window (OpenGL 4.1 core, forward-compatible) with imgui-bundle's
native glfw + opengl3 backends, the same Renderer as the offscreen path, and an orbit camera.

Controls: left drag orbit, right or middle drag pan, wheel dolly, double-click or R reset,
F12 screenshot (PNG whose text chunks hold the scene and all parameters)."""

from __future__ import annotations

import ctypes
import datetime
import os
import signal
import sys
import time
from pathlib import Path

import numpy as np

from viewer import ViewerError
from viewer.gl.context import GL_REQUIRED, GLUnavailable

PANEL_WIDTH = 360


class App:
    def __init__(self, scene_ref=None, overrides=(), size=(1280, 720), title="brdf-viewer"):
        import glfw
        import moderngl
        from imgui_bundle import imgui, implot

        from viewer.camera import OrbitCamera
        from viewer.gl.renderer import Renderer
        from viewer.scene import load_scene

        self.t_start = time.perf_counter()
        self.scene = load_scene(scene_ref, overrides)  # bad input: ViewerError before any window
        if not glfw.init():
            raise GLUnavailable("cannot initialise glfw (no display?); headless commands: "
                                "brdf-viewer render SCENE --out img.png")
        glfw.window_hint(glfw.CONTEXT_VERSION_MAJOR, GL_REQUIRED // 100)
        glfw.window_hint(glfw.CONTEXT_VERSION_MINOR, (GL_REQUIRED % 100) // 10)
        glfw.window_hint(glfw.OPENGL_PROFILE, glfw.OPENGL_CORE_PROFILE)
        glfw.window_hint(glfw.OPENGL_FORWARD_COMPAT, True)
        self.window = glfw.create_window(int(size[0]), int(size[1]), title, None, None)
        if not self.window:
            glfw.terminate()
            raise GLUnavailable("cannot create an OpenGL 4.1 core window: this viewer needs OpenGL 4.1 "
                                "(update the graphics driver); headless: brdf-viewer render SCENE --out img.png")
        glfw.make_context_current(self.window)
        glfw.swap_interval(1)
        self.glfw = glfw
        self.ctx = moderngl.create_context(require=GL_REQUIRED)
        self.imgui = imgui
        imgui.create_context()
        implot.create_context()
        io = imgui.get_io()
        io.set_ini_filename("")  # no imgui.ini in the user's working folder
        addr = ctypes.cast(self.window, ctypes.c_void_p).value
        imgui.backends.glfw_init_for_opengl(addr, True)
        imgui.backends.opengl3_init("#version 410")
        glfw.set_drop_callback(self.window, self._on_drop)  # imgui installs no drop callback
        self.renderer = Renderer(self.ctx)
        self.camera = OrbitCamera.from_scene(self.scene)
        self.view_mode = 0
        self.status = ""
        self.dirty = True
        self.hdr = None
        self.frame_count = 0
        self.frame_ms = 0.0
        self.render_ms = 0.0
        self.first_frame_s = None
        self._closing = False
        self._last_interaction = -1.0
        self._quality = "full"
        self._hdr_for = None
        from viewer import brdf

        self._warm = list(brdf.names())
        self.screenshot_dir = Path.cwd()

    # ------------------------------------------------------------------ lifecycle
    def request_close(self, *_):
        self._closing = True
        try:
            self.glfw.set_window_should_close(self.window, True)
        except Exception:  # noqa: BLE001 - during teardown the window may be gone
            pass

    def should_close(self) -> bool:
        return self._closing or bool(self.glfw.window_should_close(self.window))

    def run(self, frames: int = 0, screenshot: str | None = None) -> int:
        old = signal.signal(signal.SIGTERM, self.request_close)
        try:
            while not self.should_close():
                self.frame()
                if frames and self.frame_count >= frames:
                    if screenshot:
                        self.take_screenshot(screenshot)
                    break
        finally:
            signal.signal(signal.SIGTERM, old)
            self.close()
        return 0

    def close(self):
        if self.window is None:
            return
        imgui = self.imgui
        if self._reference is not None:
            self._reference.close()
        if self._bf_tex is not None:
            self._bf_tex.release()
        self.renderer.release()
        imgui.backends.opengl3_shutdown()
        imgui.backends.glfw_shutdown()
        from imgui_bundle import implot

        implot.destroy_context()
        imgui.destroy_context()
        self.ctx.release()
        self.glfw.destroy_window(self.window)
        self.glfw.terminate()
        self.window = None

    # ------------------------------------------------------------------ frame
    def viewport(self):
        fw, fh = self.glfw.get_framebuffer_size(self.window)
        ww, _ = self.glfw.get_window_size(self.window)
        scale = fw / ww if ww else 1.0
        panel = int(PANEL_WIDTH * scale) if self.show_ui else 0
        return panel, 0, max(fw - panel, 0), fh

    show_ui = True

    def frame(self):
        glfw, imgui = self.glfw, self.imgui
        t0 = time.perf_counter()
        if self.dirty or self._quality != "full" or (self.scene.render.ibl == "brute_force" and self._bf_count < 256):
            glfw.poll_events()
        else:
            glfw.wait_events_timeout(0.05)
        fw, fh = glfw.get_framebuffer_size(self.window)
        if fw == 0 or fh == 0:  # minimized: nothing to draw into
            time.sleep(0.02)
            return
        imgui.backends.opengl3_new_frame()
        imgui.backends.glfw_new_frame()
        imgui.new_frame()
        self._handle_input()
        if self.show_ui:
            self._panel()
        vx, vy, vw, vh = self.viewport()
        if vw > 0 and vh > 0:
            now = time.perf_counter()
            interacting = now - self._last_interaction < 0.3
            # While the user drags, render at half resolution without MSAA (software GL is slow);
            # a full-quality frame follows as soon as the interaction pauses.
            scale = 0.5 if interacting else 1.0
            rw, rh = max(1, int(vw * scale)), max(1, int(vh * scale))
            want_full = not interacting and self._quality != "full"
            progressive = self.scene.render.ibl == "brute_force" and not interacting and self._bf_count < 256
            if self.dirty or want_full or self.hdr is None or self._hdr_for != (vw, vh) or progressive:
                t1 = time.perf_counter()
                restart = self.dirty or want_full or self.hdr is None or self._hdr_for != (vw, vh)
                if restart:
                    self._bf_count, self._bf_sum = 0, None
                self.hdr = self.renderer.render(self.scene, self.camera, rw, rh, self.view_mode,
                                                msaa=0 if interacting else None, frame_index=self._bf_count)
                if self.scene.render.ibl == "brute_force" and not interacting:
                    self.hdr = self._accumulate(self.hdr)
                self.ctx.finish()
                self.render_ms = 1000 * (time.perf_counter() - t1)
                self._hdr_for = (vw, vh)
                self._quality = "preview" if interacting else "full"
                self.dirty = False
        shown = self.hdr
        if self.image_mode == "reference" and vw > 0 and vh > 0:
            self.reference_view().update(self.scene, self.camera, (vw, vh))
            ref = self.reference_view().texture_for_display()
            if ref is not None:
                shown = ref
        screen = self.ctx.screen
        screen.use()
        screen.viewport = (0, 0, fw, fh)
        self.ctx.clear(0.08, 0.08, 0.09)
        if shown is not None and vw > 0 and vh > 0:
            r = self.scene.render
            self.renderer.tonemap_to(screen, shown, r.exposure, r.tonemap, viewport=(vx, vy, vw, vh))
        screen.viewport = (0, 0, fw, fh)
        imgui.render()
        imgui.backends.opengl3_render_draw_data(imgui.get_draw_data())
        if self._capture_next is not None:
            self._capture_next(self._read_screen(fw, fh))
            self._capture_next = None
        glfw.swap_buffers(self.window)
        if not self.dirty and self._warm:
            self._warm_one()
        self.frame_count += 1
        if self.first_frame_s is None:
            self.first_frame_s = time.perf_counter() - self.t_start
            print(f"brdf-viewer: first frame after {self.first_frame_s:.2f} s", file=sys.stderr, flush=True)
        self.frame_ms = 1000 * (time.perf_counter() - t0)

    def _handle_input(self):
        imgui = self.imgui
        io = imgui.get_io()
        if imgui.is_any_item_active():  # a slider being dragged counts as interaction
            self._last_interaction = time.perf_counter()
        vx, vy, vw, vh = self.viewport()
        if not io.want_capture_mouse:
            d = io.mouse_delta
            if imgui.is_mouse_double_clicked(imgui.MouseButton_.left):
                self.camera.reset()
                self.dirty = True
            elif imgui.is_mouse_dragging(imgui.MouseButton_.left):
                self.camera.orbit(d.x, d.y, vh)
                self.dirty = True
                self._last_interaction = time.perf_counter()
            elif imgui.is_mouse_dragging(imgui.MouseButton_.right) or imgui.is_mouse_dragging(imgui.MouseButton_.middle):
                self.camera.pan(d.x, d.y, vh)
                self.dirty = True
                self._last_interaction = time.perf_counter()
            if io.mouse_wheel != 0.0:
                self.camera.dolly(io.mouse_wheel)
                self.dirty = True
                self._last_interaction = time.perf_counter()
        if not io.want_capture_keyboard:
            if imgui.is_key_pressed(imgui.Key.r, False):
                self.camera.reset()
                self.dirty = True
            if imgui.is_key_pressed(imgui.Key.f12, False):
                self.take_screenshot()

    # ------------------------------------------------------------------ panel
    def _panel(self):
        from viewer.app import ui
        from viewer.gl.renderer import TONEMAPS, VIEW_MODES

        imgui = self.imgui
        _, fh = self.glfw.get_window_size(self.window)
        imgui.set_next_window_pos(imgui.ImVec2(0, 0))
        imgui.set_next_window_size(imgui.ImVec2(PANEL_WIDTH, fh))
        flags = imgui.WindowFlags_.no_move | imgui.WindowFlags_.no_resize | imgui.WindowFlags_.no_collapse
        imgui.begin("brdf-viewer", None, flags)
        s = self.scene
        if imgui.collapsing_header("Scene", imgui.TreeNodeFlags_.default_open):
            imgui.text(f"file: {s.label}")
            tris = sum(len(o.mesh_data.indices) for o in s.objects)
            imgui.text(f"{len(s.objects)} objects, {tris:,} triangles, {len(s.lights)} lights")
            imgui.text(f"render {self.render_ms:.1f} ms, frame {self.frame_ms:.1f} ms")
            imgui.text_wrapped(f"GL: {self.ctx.info['GL_RENDERER']}")
            if imgui.button("Reset camera (R)"):
                self.camera.reset()
                self.dirty = True
            imgui.same_line()
            if imgui.button("Fit scene"):
                self.camera.fit(*s.bounds())
                self.dirty = True
        if imgui.collapsing_header("Display", imgui.TreeNodeFlags_.default_open):
            modes_img = ["raster", "reference"]
            ch, i = imgui.combo("image", modes_img.index(self.image_mode), modes_img)
            if ch:
                self.set_image_mode(modes_img[i])
            if self.image_mode == "reference" and self._reference is not None:
                rv = self._reference
                imgui.text(f"reference: {rv.spp} spp, {rv.samples_per_second / 1e3:.1f} k samples/s")
                if rv.error:
                    imgui.text_wrapped(rv.error)
            r = s.render
            ch, v = imgui.slider_float("exposure (EV)", float(r.exposure), -10.0, 10.0)
            if ch:
                r.exposure = ui.finite_or(v, r.exposure)
            names = list(TONEMAPS)
            ch, i = imgui.combo("tone map", names.index(r.tonemap) if r.tonemap in names else 0, names)
            if ch:
                r.tonemap = names[i]
            modes = list(VIEW_MODES)
            ch, i = imgui.combo("view", self.view_mode, modes)
            if ch:
                self.view_mode = i
                self.dirty = True
            ch, v = imgui.checkbox("shadows", bool(r.shadows))
            if ch:
                r.shadows = v
                self.dirty = True
        if imgui.collapsing_header("Environment", imgui.TreeNodeFlags_.default_open):
            self._environment_panel()
            if s.render.ibl == "brute_force":
                imgui.text(f"brute force: {self._bf_count} frames x 16 samples per pixel")
        if imgui.collapsing_header("Lights", imgui.TreeNodeFlags_.default_open):
            for i, light in enumerate(s.lights):
                imgui.push_id(f"light{i}")
                imgui.text(f"{i}: {light.type}")
                if light.type == "point":
                    ch, v = imgui.drag_float3("position", [float(x) for x in light.position], 0.02)
                    if ch and all(np.isfinite(v)):
                        light.position = np.array(v, float)
                        self.dirty = True
                    ch, v = imgui.drag_float3("intensity W/sr", [float(x) for x in light.intensity], 0.1, 0.0, 1e6)
                    if ch and all(np.isfinite(v)) and min(v) >= 0:
                        light.intensity = np.array(v, float)
                        self.dirty = True
                else:
                    ch, v = imgui.drag_float3("direction", [float(x) for x in light.direction], 0.01)
                    if ch and all(np.isfinite(v)) and np.linalg.norm(v) > 1e-6:
                        light.direction = np.array(v, float) / np.linalg.norm(v)
                        self.dirty = True
                    ch, v = imgui.drag_float3("irradiance W/m2", [float(x) for x in light.irradiance], 0.05, 0.0, 1e6)
                    if ch and all(np.isfinite(v)) and min(v) >= 0:
                        light.irradiance = np.array(v, float)
                        self.dirty = True
                imgui.pop_id()
        if imgui.collapsing_header("Materials", imgui.TreeNodeFlags_.default_open):
            for i, name in enumerate(list(s.materials)):
                imgui.push_id(f"mat_{name}")
                if i == 0:  # the first material starts open
                    imgui.set_next_item_open(True, imgui.Cond_.once)
                if imgui.tree_node(f"{name} ({s.materials[name].model})"):
                    ch, new = ui.material_editor(s.materials[name], f"{name}.")
                    if ch:
                        s.materials[name] = new
                        self.dirty = True
                    imgui.tree_pop()
                imgui.pop_id()
        imgui.separator()
        if imgui.button("Screenshot (F12)"):
            self.take_screenshot()
        if ui.last_error:
            self.status, ui.last_error = ui.last_error, ""
        if self.status:
            imgui.text_wrapped(self.status)
        imgui.end()

    _capture_next = None
    _warm = None
    image_mode = "raster"  # or "reference"
    _reference = None

    def reference_view(self):
        if self._reference is None:
            from viewer.app.reference_view import ReferenceView

            self._reference = ReferenceView(self.ctx)
        return self._reference

    def set_image_mode(self, mode: str):
        assert mode in ("raster", "reference"), mode
        self.image_mode = mode
        if mode == "raster" and self._reference is not None:
            self._reference.stop()
        self.dirty = True

    def _warm_one(self):
        """Compile one model's forward program while idle, so switching models later does not
        wait for the shader compiler (software GL compiles take 0.1-0.5 s each)."""
        from viewer import brdf

        name = self._warm.pop(0)
        try:
            self.renderer.forward_program(brdf.get(name).params())
        except ViewerError as e:
            self.status = str(e)

    def _read_screen(self, fw, fh) -> np.ndarray:
        data = self.ctx.screen.read(viewport=(0, 0, fw, fh), components=3, alignment=1)
        return np.frombuffer(data, np.uint8).reshape(fh, fw, 3)[::-1].copy()

    def capture_window(self) -> np.ndarray:
        """The whole window as shown (3D view and UI), (H, W, 3) uint8, row 0 = top."""
        out = []
        self._capture_next = out.append
        self.dirty = True
        self.frame()
        return out[0] if out else None

    _env_path_text = ""
    _bf_count = 0
    _bf_sum = None
    _bf_tex = None

    def _accumulate(self, hdr):
        """Brute-force IBL: the running mean of frames with new sample sets (as the offscreen
        ``render_arrays(frames=K)``), shown while it converges."""
        img = self.renderer.read_linear(hdr).astype(np.float64)
        self._bf_sum = img if self._bf_sum is None else self._bf_sum + img
        self._bf_count += 1
        mean = (self._bf_sum / self._bf_count).astype("f4")
        h, w = mean.shape[:2]
        rgba = np.ones((h, w, 4), "f4")
        rgba[..., :3] = mean[::-1]
        if self._bf_tex is None or self._bf_tex.size != (w, h):
            if self._bf_tex is not None:
                self._bf_tex.release()
            self._bf_tex = self.ctx.texture((w, h), 4, dtype="f4")
        self._bf_tex.write(rgba.tobytes())
        return self._bf_tex
    _env_dialog = None

    def _environment_panel(self):
        from viewer.environment.procedural import builtin_names
        from viewer.gl.renderer import IBL_MODES

        imgui = self.imgui
        env = self.scene.environment
        current = "constant" if env.map is None else (env.map if env.is_builtin else "file")
        choices = ["constant"] + list(builtin_names()) + (["file"] if current == "file" else [])
        ch, i = imgui.combo("map", choices.index(current), choices)
        if ch and choices[i] != current:
            self.set_environment(None if choices[i] == "constant" else choices[i])
        if env.map is not None and not env.is_builtin:
            imgui.text_wrapped(f"file: {env.map}")
        ch, self._env_path_text = imgui.input_text("##envpath", self._env_path_text)
        imgui.same_line()
        if imgui.button("Load .hdr/.exr"):
            self.set_environment(self._env_path_text.strip())
        if imgui.button("Browse..."):
            try:  # the desktop's own dialog (zenity / kdialog on Linux), polled, never blocking
                from imgui_bundle import portable_file_dialogs as pfd

                self._env_dialog = pfd.open_file("Environment map (.hdr, .exr)", str(Path.cwd()),
                                                 ["HDR environment maps", "*.hdr *.exr", "All files", "*"])
            except Exception as e:  # noqa: BLE001 - no dialog backend: say so, keep going
                self.status = f"no file dialog available ({e}); type a path or drop a file"
        if self._env_dialog is not None and self._env_dialog.ready(0):
            picked = self._env_dialog.result()
            self._env_dialog = None
            if picked:
                self.set_environment(picked[0])
        imgui.same_line()
        imgui.text_disabled("(or drop a file on the window)")
        if env.map is None:
            c = [float(x) for x in (env.constant if env.constant is not None else np.zeros(3))]
            ch, v = imgui.color_edit3("radiance", c, imgui.ColorEditFlags_.float | imgui.ColorEditFlags_.hdr)
            if ch and all(np.isfinite(v)) and min(v) >= 0:
                env.constant = np.array(v, float)
                self.dirty = True
        ch, v = imgui.slider_float("intensity", float(env.intensity), 0.001, 100.0, "%.3g",
                                   imgui.SliderFlags_.logarithmic)
        if ch and np.isfinite(v) and v >= 0:
            env.intensity = float(v)
            self.dirty = True
        ch, v = imgui.slider_float("rotation (deg)", float(env.rotation_deg), -180.0, 180.0)
        if ch and np.isfinite(v):
            env.rotation_deg = float(v)
            self.dirty = True
        modes = list(IBL_MODES)
        r = self.scene.render
        ch, i = imgui.combo("IBL", modes.index(r.ibl) if r.ibl in modes else 1, modes)
        if ch:
            r.ibl = modes[i]
            self.dirty = True
        ch, v = imgui.checkbox("multiple-scattering compensation", bool(r.ms_compensation))
        if ch:
            r.ms_compensation = v
            self.dirty = True

    def set_environment(self, ref) -> bool:
        """Switch the environment to a built-in map name, a .hdr/.exr path or None (constant).
        A file that does not load leaves the previous environment and shows why."""
        import dataclasses
        from pathlib import Path as _P

        env = self.scene.environment
        new = dataclasses.replace(env)
        new.__dict__.pop("_map_cache", None)
        if ref is None:
            new.map = None
            if new.constant is None:
                new.constant = np.array([0.1, 0.1, 0.1])
        else:
            from viewer.environment.procedural import builtin_names

            new.map = ref if ref in builtin_names() else _P(ref).expanduser()
            new.constant = None
            try:
                new.radiance_map()
            except ViewerError as e:
                self.status = f"environment not changed: {e}"
                return False
            except Exception as e:  # noqa: BLE001 - any decoder failure keeps the old map
                self.status = f"environment not changed: {ref}: {type(e).__name__}: {e}"
                return False
        self.scene.environment = new
        self.status = f"environment: {ref or 'constant'}"
        self.dirty = True
        return True

    def _on_drop(self, window, paths):
        for p in paths:
            if p.lower().endswith((".hdr", ".exr")):
                self.set_environment(p)
            else:
                self.status = f"dropped {p}: not an environment map; allowed: .hdr, .exr"

    # ------------------------------------------------------------------ actions
    def take_screenshot(self, path: str | os.PathLike | None = None) -> Path | None:
        """Save the 3D view (no UI) as a PNG with the scene and parameters in its text chunks."""
        from viewer.gl.renderer import VIEW_MODES
        from viewer.io import write_png
        from viewer.screenshot import png_text

        if path is None:
            stamp = datetime.datetime.now().strftime("%Y%m%d-%H%M%S")
            path = self.screenshot_dir / f"brdf-viewer-{stamp}.png"
        _, _, vw, vh = self.viewport()
        if vw == 0 or vh == 0:
            self.status = "screenshot skipped: the window is minimized"
            return None
        try:
            hdr = self.renderer.render(self.scene, self.camera, vw, vh, self.view_mode)
            srgb = self.renderer.read_srgb(hdr, self.scene.render.exposure, self.scene.render.tonemap)
            view = list(VIEW_MODES)[self.view_mode]
            write_png(path, srgb, png_text(self.scene, self.camera, {"view": view}))
        except (OSError, ViewerError) as e:
            self.status = f"screenshot failed: {e}"
            return None
        self.dirty = True
        self.status = f"saved {path}"
        print(self.status, file=sys.stderr)
        return Path(path)


def run_app(scene_ref=None, overrides=(), size=(1280, 720), frames=0, screenshot=None) -> int:
    app = App(scene_ref, overrides, size)
    return app.run(frames=frames, screenshot=screenshot)
