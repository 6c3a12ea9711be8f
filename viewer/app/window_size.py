"""The window's size, bounded before the window exists and again once its GL context does.

A size from the state file or ``--width`` / ``--height`` is fitted to the display (the primary
monitor's video mode) before the window is made, and to the context's limits
(``GL_MAX_VIEWPORT_DIMS``, ``GL_MAX_TEXTURE_SIZE``, ``GL_MAX_RENDERBUFFER_SIZE``) after: the
renderer's targets are textures and renderbuffers of the framebuffer's size, so a size past
either cannot be drawn. Without a monitor to ask, a side is at most ``NO_MONITOR_MAX``. Each
fitting that changes the size says so in one line on stderr."""

from __future__ import annotations

import sys

#: the smallest side the window keeps (the state file refuses less)
MIN_SIDE = 64
#: the largest side when no monitor tells its size
NO_MONITOR_MAX = 4096


def fit(size, bound, what: str) -> tuple[int, int]:
    """``size`` (w, h) with each side in [MIN_SIDE, bound's side] (``bound`` (w, h) or None: as
    it is); one line on stderr naming ``what`` bounded it when it changed."""
    w, h = int(size[0]), int(size[1])
    if bound is None:
        return max(w, MIN_SIDE), max(h, MIN_SIDE)
    bw, bh = max(int(bound[0]), MIN_SIDE), max(int(bound[1]), MIN_SIDE)
    out = min(max(w, MIN_SIDE), bw), min(max(h, MIN_SIDE), bh)
    if out != (w, h):
        print(f"brdf-viewer: window {w}x{h} does not fit {what} ({bw}x{bh}); opening it at {out[0]}x{out[1]}",
              file=sys.stderr)
    return out


def monitor_bound(glfw) -> tuple[tuple[int, int], str]:
    """(the largest window size, what bounds it): the primary monitor's video mode, or
    NO_MONITOR_MAX a side when glfw knows no monitor."""
    try:
        monitor = glfw.get_primary_monitor()
        mode = glfw.get_video_mode(monitor) if monitor else None
    except Exception:  # noqa: BLE001 - a platform without monitors (some remote displays)
        mode = None
    if mode is None or mode.size.width <= 0 or mode.size.height <= 0:
        return (NO_MONITOR_MAX, NO_MONITOR_MAX), "the largest window without a monitor's size"
    return (int(mode.size.width), int(mode.size.height)), "the display"


def gl_bound(info: dict) -> int:
    """The largest framebuffer side a context with ``info`` (``moderngl.Context.info``) draws."""
    sides = []
    for key in ("GL_MAX_TEXTURE_SIZE", "GL_MAX_RENDERBUFFER_SIZE", "GL_MAX_VIEWPORT_DIMS"):
        v = info.get(key)
        if v is None:
            continue
        sides.extend(int(x) for x in (v if isinstance(v, (tuple, list)) else (v,)))
    return min(sides) if sides else NO_MONITOR_MAX
