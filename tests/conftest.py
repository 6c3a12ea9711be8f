import os
import tempfile

import pytest

os.environ.setdefault("PYTHONHASHSEED", "0")
# the window's state file (viewer.app.state) goes to a throwaway folder, never the user's ~/.config;
# subprocesses started by the tests inherit it
os.environ["BRDF_VIEWER_STATE"] = os.path.join(tempfile.mkdtemp(prefix="brdf-viewer-state-"), "state.toml")
# the reference cache and the engine measurements likewise (never the user's ~/.cache)
SESSION_CACHE = tempfile.mkdtemp(prefix="brdf-viewer-cache-")
os.environ["BRDF_VIEWER_CACHE"] = SESSION_CACHE
# a window or session draws a new environment map fully prefiltered, as offscreen rendering does
# (tests compare the two); tests/test_env_background.py turns the quick prefilter on
os.environ["BRDF_VIEWER_DEFER_PREFILTER"] = "0"


@pytest.fixture(autouse=True)
def _private_cache(tmp_path_factory, monkeypatch):
    """Each test gets a cache folder of its own, so that no test sees a reference or an engine
    measurement another test stored (which tests ran before in this process depends on how
    xdist shares the files out). Prefiltered environments and DFG tables (the folder's top-level
    .npz entries, keyed by content: the same bytes whoever computed them) are shared: linked in
    before the test, new ones moved to the session's folder after it, so each is computed once
    per process. A module that sets its own cache folder keeps it."""
    from pathlib import Path

    if os.environ.get("BRDF_VIEWER_CACHE") != SESSION_CACHE:
        yield
        return
    shared = Path(SESSION_CACHE)
    mine = tmp_path_factory.mktemp("cache")
    for f in shared.glob("*.npz"):
        try:
            os.link(f, mine / f.name)
        except OSError:
            pass   # a file system without hard links: computed again
    monkeypatch.setenv("BRDF_VIEWER_CACHE", str(mine))
    yield
    for f in mine.glob("*.npz"):
        if not (shared / f.name).exists():
            try:
                os.replace(f, shared / f.name)
            except OSError:
                pass


@pytest.fixture(scope="session")
def gl_ctx():
    """One headless EGL context for the whole test session."""
    from viewer.gl.context import create_offscreen_context

    ctx = create_offscreen_context()
    _SESSION_CONTEXT.append(ctx)
    yield ctx
    _SESSION_CONTEXT.clear()
    ctx.release()


_SESSION_CONTEXT = []


@pytest.hookimpl(tryfirst=True)
def pytest_runtest_setup(item):
    """In-process ``cli.main(["render", ...])`` creates, uses and releases its own EGL context,
    which leaves no context current on this thread: later draws through the session's context
    would read uninitialised memory. Make the session context current again before each test
    sets up its fixtures (module-scoped ones included)."""
    for ctx in _SESSION_CONTEXT:
        ctx.__enter__()


@pytest.fixture(scope="session")
def renderer(gl_ctx):
    from viewer.gl.renderer import Renderer

    r = Renderer(gl_ctx)
    yield r
    r.release()


@pytest.fixture(scope="module")
def display():
    """A private Xvfb server for the window tests (its number chosen by Xvfb itself), or the
    existing DISPLAY when there is no Xvfb."""
    import shutil
    import subprocess

    if shutil.which("Xvfb") is None:
        yield os.environ["DISPLAY"]
        return
    r, w = os.pipe()
    proc = subprocess.Popen(["Xvfb", "-displayfd", str(w), "-screen", "0", "1600x1000x24", "-nolisten", "tcp"],
                            pass_fds=(w,), stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    os.close(w)
    with os.fdopen(r) as f:
        num = f.readline().strip()
    yield f":{num}"
    proc.terminate()
    proc.wait(10)


@pytest.fixture
def trust_twins():
    """Trust the numpy twins of these folders or files for one test, as ``--trust-twin PATH``
    does (a twin runs only when trusted: viewer/brdf/twin_trust.py)."""
    from viewer.brdf import twin_trust

    def trust(*paths):
        for p in paths:
            twin_trust.trust(p)

    yield trust
    twin_trust.forget()


def pytest_configure(config):
    """With worker processes (``-n 2``, the default), compile the CPU reference's numba kernels
    once, here in the controller, before the workers start: on a fresh clone numba's cache is
    empty, and every test process and every reference worker process it starts would otherwise
    compile the same kernels at once (the fused bounce about 21 CPU s since its Fresnel term is a
    call of its own, 110 s before; test_pathtracer.py then takes 9 s instead of 67 s). Later runs
    load the cache (a second or two)."""
    if hasattr(config, "workerinput") or not getattr(config.option, "numprocesses", None):
        return
    try:
        from viewer import pathtracer
        from viewer.scene import load_scene
        from viewer.scene.camera import OrbitCamera
    except ImportError:  # the CPU reference's extras missing: its tests skip with the reason
        return
    scene = load_scene("default")
    r = pathtracer.ReferenceRenderer(scene, camera=OrbitCamera.from_scene(scene), width=4, height=4,
                                     max_depth=8, seed=1, workers=0)
    try:
        r.step(1)
    finally:
        r.close()
