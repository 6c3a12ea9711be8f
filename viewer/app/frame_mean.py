"""The running mean of a still view's raster frames, each drawn with new sample sets: brute-force
IBL (``BF_FRAMES``) and the sampled environment light of ``.brdf`` file materials
(``viewer.gl.file_env.SETTLE_FRAMES``), shown while it converges, as the offscreen
``Renderer.render_arrays(frames=K)`` averages them. No imgui, no glfw."""

from __future__ import annotations

import numpy as np

BF_FRAMES = 256  # brute-force IBL: frames averaged before the view stops refining


def frames_wanted(scene) -> int:
    """The frames a still raster view of ``scene`` averages before it rests: ``BF_FRAMES`` for
    brute-force IBL, ``SETTLE_FRAMES`` where a file material's environment light is sampled,
    else 1 (a frame is the image)."""
    if scene.render.ibl == "brute_force":
        return BF_FRAMES
    from viewer.gl.file_env import settle_frames

    return settle_frames(scene)


class FrameMean:
    """The sum of the frames since the last ``reset`` and their count; ``add`` gives the mean as
    a texture of its own."""

    def __init__(self):
        self.count = 0
        self._sum = None
        self._tex = None

    @property
    def texture(self):
        return self._tex

    def reset(self) -> None:
        self.count, self._sum = 0, None

    def add(self, renderer, ctx, hdr):
        """Add the frame ``hdr`` (the renderer's resolved texture); the mean so far, uploaded."""
        from viewer.app.compare_view import upload_rgb

        img = renderer.read_linear(hdr).astype(np.float64)
        self._sum = img if self._sum is None else self._sum + img
        self.count += 1
        self._tex = upload_rgb(ctx, self._tex, self._sum / self.count)
        return self._tex

    def mean(self) -> np.ndarray | None:
        """(H, W, 3) float64 mean of the frames added (row 0 = top), None before the first."""
        return None if self._sum is None else self._sum / self.count

    def release(self) -> None:
        if self._tex is not None:
            self._tex.release()
            self._tex = None
