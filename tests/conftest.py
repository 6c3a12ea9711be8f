import os
import tempfile

import pytest

os.environ.setdefault("PYTHONHASHSEED", "0")
# the window's state file (viewer.app.state) goes to a throwaway folder, never the user's ~/.config;
# subprocesses started by the tests inherit it
os.environ["BRDF_VIEWER_STATE"] = os.path.join(tempfile.mkdtemp(prefix="brdf-viewer-state-"), "state.toml")
# the reference cache and the engine measurements likewise (never the user's ~/.cache)
os.environ["BRDF_VIEWER_CACHE"] = tempfile.mkdtemp(prefix="brdf-viewer-cache-")


@pytest.fixture(scope="session")
def gl_ctx():
    """One headless EGL context for the whole test session."""
    from viewer.gl.context import create_offscreen_context

    ctx = create_offscreen_context()
    yield ctx
    ctx.release()


@pytest.fixture(scope="session")
def renderer(gl_ctx):
    from viewer.gl.renderer import Renderer

    r = Renderer(gl_ctx)
    yield r
    r.release()
