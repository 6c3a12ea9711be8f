"""Shared helpers for the window tests (test_gui, test_classroom, test_window_views,
test_monte_carlo_gui, test_soak): the environment a window subprocess runs in and a runner for
a script in such a subprocess. The private X server is the ``display`` fixture (conftest.py)."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import tempfile
import textwrap

HAVE_X = shutil.which("Xvfb") is not None or bool(os.environ.get("DISPLAY"))

# How long a window subprocess may run before it counts as hung: a hang detector, not a latency
# bound. Generous, because a window that prefilters its environment maps into a cold cache on a
# loaded two-core machine took over 120 s (the bound these runs had before).
HANG_S = 900.0


def window_env(display: str) -> dict:
    """The environment for a window subprocess on ``display``: each app run starts from no saved
    window state (one run's compare view or window size must not leak into the next test);
    test_classroom checks the restoring itself."""
    env = dict(os.environ)
    env["DISPLAY"] = display
    env["BRDF_VIEWER_STATE"] = os.path.join(tempfile.mkdtemp(prefix="brdf-viewer-state-"), "state.toml")
    # no compile-ahead child beside each test window (its preset warm-up would load the two
    # cores for minutes); tests/test_compile_ahead.py runs it
    env.setdefault("BRDF_VIEWER_COMPILE_AHEAD", "0")
    # every still frame whole: a test reads the frame a change drew (tests/test_tiled_frames.py
    # tiles them)
    env.setdefault("BRDF_VIEWER_TILED_FRAMES", "0")
    # a scene's first frame drawn at once, not prepared over frames (tests/test_view_prep.py
    # prepares them)
    env.setdefault("BRDF_VIEWER_PREPARE_FRAMES", "0")
    # the plots' data in the frame that draws them (tests/test_plot_worker.py runs the worker)
    env.setdefault("BRDF_VIEWER_PLOT_WORKER", "0")
    env.pop("WAYLAND_DISPLAY", None)
    return env


def run_py(code: str, display: str, timeout: float = HANG_S):
    """Run ``code`` (dedented) in a Python subprocess on ``display``; the CompletedProcess.
    ``timeout``: at least ``HANG_S``."""
    return subprocess.run([sys.executable, "-c", textwrap.dedent(code)], env=window_env(display),
                          capture_output=True, text=True, timeout=max(timeout, HANG_S))
