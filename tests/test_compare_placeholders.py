"""The compare views before the reference's first pass say what is coming and show nothing
false: the split's reference side stays empty (not the raster under a reference label), the
difference views have no colour bar and say they wait for the first pass."""

import numpy as np

from viewer.app.compare_view import PENDING, PENDING_DIFFERENCE, CompareView

W, H = 64, 32


def _draw(gl_ctx, renderer, mode, ref_value=None):
    cmp = CompareView(gl_ctx)
    cmp.mode = mode
    raster = gl_ctx.texture((W, H), 4, np.full((H, W, 4), 0.5, "f4").tobytes(), dtype="f4")
    ref = None if ref_value is None else gl_ctx.texture((W, H), 4, np.full((H, W, 4), ref_value, "f4").tobytes(),
                                                         dtype="f4")
    fbo = gl_ctx.framebuffer(gl_ctx.renderbuffer((W, H)))
    fbo.use()
    fbo.clear(0.0, 0.0, 0.0, 1.0)
    cmp.draw(renderer, fbo, (0, 0, W, H), raster, ref, 0.0, "none")
    img = np.frombuffer(fbo.read(components=3), np.uint8).reshape(H, W, 3)
    for t in (raster, ref):
        if t is not None:
            t.release()
    fbo.release()
    return cmp, img


def test_split_before_the_first_pass_leaves_the_reference_side_empty(gl_ctx, renderer):
    cmp, img = _draw(gl_ctx, renderer, "split")
    left, right = img[:, : W // 2 - 1], img[:, W // 2 + 1:]
    assert left.min() > 100 and right.max() == 0, (left.min(), right.max())  # raster | nothing
    labels = [t for _, t in cmp.overlay_labels((0, 0, W, H), 0)]
    assert labels == ["raster", PENDING]
    _, img = _draw(gl_ctx, renderer, "split", ref_value=0.1)  # once there is one, both halves
    assert img[:, W // 2 + 1:].min() > 0 and abs(int(img[:, 2].mean()) - int(img[:, -2].mean())) > 30


def test_difference_before_the_first_pass_says_so_without_a_bar(gl_ctx, renderer):
    for mode in ("difference", "relative difference"):
        cmp, img = _draw(gl_ctx, renderer, mode)
        assert img.max() == 0
        assert cmp.overlay_bars((0, 0, W, H)) == []
        assert cmp.overlay_labels((0, 0, W, H), 0) == [(0, PENDING_DIFFERENCE)]
