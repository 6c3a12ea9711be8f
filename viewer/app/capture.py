"""The window's captures (``App.capture``): the whole window or the 3D view as drawn, read from the
screen at the end of a frame, and screenshots (the view, no UI, as a PNG whose text chunks hold
the scene and all parameters: ``Session.take_screenshot``)."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np


class Capture:
    """The captures of ``app`` (an ``App``: its ``ctx``, ``session``, ``viewport`` and ``frame``)."""

    def __init__(self, app):
        self.app = app
        self.wanted = None   # called with the screen (H, W, 3) uint8 once the next frame is drawn

    def read_screen(self, fw, fh) -> np.ndarray:
        data = self.app.ctx.screen.read(viewport=(0, 0, fw, fh), components=3, alignment=1)
        return np.frombuffer(data, np.uint8).reshape(fh, fw, 3)[::-1].copy()

    def frame_drawn(self, fw, fh) -> None:
        """The frame's UI is rendered (not yet swapped): hand the screen to a capture waiting for it."""
        if self.wanted is not None:
            self.wanted(self.read_screen(fw, fh))
            self.wanted = None

    def capture_view(self) -> np.ndarray:
        """The 3D view as shown (compare view, heat maps, their labels and colour bars), without
        the panels, the lecture caption and the status toast: (H, W, 3) uint8, row 0 = top."""
        app = self.app
        app.view_only = True
        try:
            img = self.capture_window(redraw=False)
        finally:
            app.view_only = False
        vx, _, vw, vh = app.viewport()
        return img[img.shape[0] - vh:, vx:vx + vw].copy()

    def capture_window(self, redraw: bool = True) -> np.ndarray:
        """The whole window as shown (3D view and UI), (H, W, 3) uint8, row 0 = top. ``redraw``:
        render the raster afresh first (False: the view as it stands, e.g. a finished one, never
        restarted into tiles)."""
        out = []
        self.wanted = out.append
        if redraw:
            self.app.session.changed()
        self.app.frame(wait=False)
        return out[0] if out else None

    def take_screenshot(self, path: str | os.PathLike | None = None) -> Path | None:
        """Save the 3D view (no UI) as a PNG with the scene and parameters in its text chunks."""
        _, _, vw, vh = self.app.viewport()
        return self.app.session.take_screenshot(path, (vw, vh), self.capture_view)
