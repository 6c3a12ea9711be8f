"""How the view is shown and kept: the image mode (raster, reference, the compare views), the
view mode (shaded, normals, ...), reflections, the camera's reset and fit, screenshots and the
saved state. ``ViewState`` is held by ``viewer.app.session.Session`` as ``session.view``. No
imgui, no glfw."""

from __future__ import annotations

import datetime
import hashlib
import os
import sys
from pathlib import Path

from viewer import ViewerError


def scene_digest(scene) -> str:
    """What the saved state remembers of the scene a session ended on: a digest of its text
    without the camera (an orbit, or the camera the last scene file keeps, is the same scene)."""
    from viewer.scene import scene_to_data, scene_to_toml

    data = scene_to_data(scene, absolute_paths=True)
    data.pop("camera", None)
    return hashlib.sha256(scene_to_toml(data).encode("utf-8")).hexdigest()[:32]


class ViewState:
    """The image, view and reflection modes, the camera actions, screenshots and saved state of
    ``session``."""

    def __init__(self, session):
        self.session = session
        self.screenshot_dir = Path.cwd()

    def reset_camera(self) -> None:
        s = self.session
        s.camera.reset()
        s.dirty = True

    def fit_camera(self) -> None:
        s = self.session
        s.camera.fit(*s.scene.bounds())
        s.dirty = True

    @property
    def image_mode(self) -> str:
        return self.session.compare.mode

    def set_image_mode(self, mode: str):
        """One of ``compare_view.MODES``: raster, reference, split, side by side, difference,
        relative difference. Modes without the reference stop its render (no CPU spent). The
        raster image shown stays (a mode whose raster has another size, side by side, draws it
        anew; one after the reference alone, which draws no raster, too)."""
        from viewer.app.compare_view import MODES

        s = self.session
        if mode not in MODES:
            raise ViewerError(f"image mode {mode!r}: unknown; allowed: {', '.join(MODES)}")
        was, s.compare.mode = s.compare.mode, mode
        if not s.compare.uses_reference and not s.monte_carlo.active and s.reference is not None:
            s.reference.stop(timeout=0)  # cancelled, it publishes nothing more: the frame never waits for it
        if was == "reference" or s.hdr is None:
            s.dirty = True

    def cycle_image_mode(self) -> None:
        from viewer.app.compare_view import MODES

        self.set_image_mode(MODES[(MODES.index(self.session.compare.mode) + 1) % len(MODES)])

    def set_view_mode(self, index: int) -> None:
        """One of ``viewer.gl.renderer.VIEW_MODES`` by index (shaded, normals, ...)."""
        from viewer.gl.renderer import VIEW_MODES

        s = self.session
        if not 0 <= int(index) < len(VIEW_MODES):
            s.notify(f"view {index}: unknown; allowed 0..{len(VIEW_MODES) - 1}", error=True)
            return
        s.view_mode = int(index)
        s.dirty = True

    @property
    def reflection_mode(self) -> str:
        from viewer.app.reflections import reflection_mode

        return reflection_mode(self.session.scene.render)

    def set_reflection_mode(self, mode: str, ssr_on_glossy: bool | None = None) -> bool:
        """Reflections / refraction: off, SSR or ray traced (``viewer.app.reflections``)."""
        from viewer.app.reflections import MODES, set_reflection_mode

        s = self.session
        if mode not in MODES:
            s.notify(f"reflections {mode!r}: unknown; allowed: {', '.join(MODES)}", error=True)
            return False
        if set_reflection_mode(s.scene.render, mode, ssr_on_glossy=ssr_on_glossy):
            s.dirty = True
            return True
        return False

    def take_screenshot(self, path=None, size=None, capture=None) -> Path | None:
        """Save the view as a PNG (atomic) with the scene and parameters in its text chunks.
        ``size``: the view's (w, h); the raster alone is rendered afresh at it. ``capture``: a
        function returning the view as shown ((H, W, 3) uint8), used for the compare views and
        error maps (the window's); without one they fall back to the raster."""
        from viewer.gl.renderer import VIEW_MODES
        from viewer.base.io import write_png
        from viewer.scene.screenshot import png_text

        s = self.session
        if path is None:
            stamp = datetime.datetime.now().strftime("%Y%m%d-%H%M%S")
            path = self.screenshot_dir / f"brdf-viewer-{stamp}.png"
        vw, vh = size if size is not None else (s.scene.camera.width, s.scene.camera.height)
        if vw == 0 or vh == 0:
            s.notify("screenshot skipped: the window is minimized", error=True)
            return None
        try:
            extra = {"view": list(VIEW_MODES)[s.view_mode], "image": s.compare.mode}
            if capture is None or (s.compare.mode == "raster" and not s.monte_carlo.active):
                # the raster alone, as shown when the view holds it at full quality (a traced
                # view, finished or not, is saved as it stands: nothing waits, nothing restarts);
                # otherwise rendered afresh at the view's size
                shown = s.hdr is not None and not s.dirty and s.quality in ("full", "tracing")
                if shown and tuple(s.hdr.size) == (vw, vh):
                    srgb = s.renderer.read_srgb(s.hdr, s.scene.render.exposure, s.scene.render.tonemap)
                else:
                    srgb = s.render_image(vw, vh)
                    s.dirty = True  # the renderer's target was drawn over
            else:  # what the view shows: split, side by side, heat map with its colour bar, labels
                srgb = capture()
                if s.metrics_text():
                    extra["metrics"] = s.metrics_text()
            write_png(path, srgb, png_text(s.scene, s.camera, extra))
        except (OSError, ViewerError) as e:
            s.notify(f"screenshot failed: {e}", error=True)
            return None
        s.notify(f"saved {path}")
        print(s.status, file=sys.stderr)
        return Path(path)

    def state_entries(self) -> dict:
        """The session's part of the saved state."""
        s = self.session
        return dict(compare_mode=s.compare.mode, split=s.compare.split, view_mode=s.view_mode,
                    scene_digest=scene_digest(s.scene))

    def save_state(self, window: dict | None = None, path: os.PathLike | None = None) -> bool:
        """The state for the next start (the session's entries and the window's, ``window``) and
        the scene as last_scene.toml next to it, both written atomically. A problem is reported
        on stderr and returns False: the session is never lost to a state file."""
        from viewer.app import state as state_mod
        from viewer.base.io import atomic_write_bytes
        from viewer.scene import scene_to_toml
        from viewer.scene.screenshot import scene_with_camera

        s = self.session
        st = dict(s.state)
        st.update(window or {})
        st.update(self.state_entries())
        try:
            state_mod.save_state(st, path)
            text = scene_to_toml(scene_with_camera(s.scene, s.camera))
            last = state_mod.last_scene_path() if path is None else Path(path).with_name("last_scene.toml")
            atomic_write_bytes(last, text.encode("utf-8"))
        except Exception as e:  # noqa: BLE001 - never lose the session to a state-file problem
            print(f"brdf-viewer: window state not saved: {type(e).__name__}: {e}", file=sys.stderr)
            return False
        s.state = st
        return True
