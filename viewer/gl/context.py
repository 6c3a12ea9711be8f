"""OpenGL contexts: headless EGL (tests, ``render``, ``compare``) or a glfw window (the app).

Both give a moderngl context of at least OpenGL 4.1 core; the renderer does not know which."""

from __future__ import annotations

import os

from viewer import ViewerError

GL_REQUIRED = 410


class GLUnavailable(ViewerError):
    """No usable OpenGL 4.1 context (missing driver, no display, too old a version)."""


def create_offscreen_context():
    """A surfaceless EGL context (Mesa llvmpipe on machines without a GPU)."""
    import moderngl

    try:
        ctx = moderngl.create_standalone_context(backend="egl", require=GL_REQUIRED)
    except Exception as e:  # noqa: BLE001 - glcontext raises plain Exceptions
        raise GLUnavailable(
            "cannot create a headless OpenGL 4.1 context through EGL "
            f"({str(e).splitlines()[0] if str(e) else type(e).__name__}); install Mesa's EGL "
            "(Debian/Ubuntu: apt-get install libegl1 libgl1-mesa-dri) or a GPU driver with EGL"
        ) from None
    return ctx


def release_gl(*objects) -> None:
    """Release moderngl objects (None skipped). A framebuffer that is the bound one is unbound
    first, the default framebuffer bound instead: moderngl binds its last bound framebuffer again
    after making another, and a deleted name there is GL_INVALID_OPERATION (every change of the
    frame's size or sample count raised it)."""
    import moderngl

    for o in objects:
        if o is None:
            continue
        if isinstance(o, moderngl.Framebuffer) and o.ctx.fbo is o:
            ctx = o.ctx
            (ctx.screen if ctx.screen is not None else ctx.detect_framebuffer(0)).use()
        o.release()


def have_display() -> bool:
    return bool(os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")) or os.name == "nt" or \
        __import__("sys").platform == "darwin"
