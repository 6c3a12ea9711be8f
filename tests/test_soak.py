"""A short soak of the window app (benchmarks/soak.py, 200 frames of random actions including
typed NaN / Inf / huge slider values, resizes, a 0x0 framebuffer, environment and compare-view
switches and reference restarts): no exception, no GL error, no NaN / Inf / negative pixel.
The 10,000-frame run with memory and GL-object figures is the benchmark itself (200 frames are
too few for a drift check: the first frames compile programs and fill caches)."""

import json
import subprocess
import sys
from pathlib import Path

import pytest

from gui_harness import HANG_S, window_env

ROOT = Path(__file__).resolve().parents[1]


# a soak: 200 frames of a real window (about 18 s); with -m slow, as benchmarks/soak.py runs longer ones
@pytest.mark.slow
@pytest.mark.skipif(not __import__("shutil").which("Xvfb"), reason="needs Xvfb")
def test_short_soak_has_no_failures(display):
    r = subprocess.run([sys.executable, str(ROOT / "benchmarks" / "soak.py"), "--frames", "200",
                        "--report-at", "200", "--seed", "7", "--json"],
                       env=window_env(display), capture_output=True, text=True, timeout=HANG_S)
    assert r.returncode in (0, 1), r.stderr[-3000:]
    res = json.loads(r.stdout.strip().splitlines()[-1])
    assert res["failures"] == [], res["failures"]
    acted = {k for k, n in res["actions"].items() if n}
    assert {"model", "slider", "camera", "compare"} <= acted, res["actions"]
    assert sum(res["actions"].values()) > 40
