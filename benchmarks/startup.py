"""Start-up of the window: `python benchmarks/startup.py [--runs 5] [--state-dir DIR]` prints the
median whole-process time from launching `python -m viewer` (default scene) to its first frame
(the line the app prints when the first frame is on screen), and the app's own figure (from
App() to the first frame, i.e. without the interpreter and the imports). Under Xvfb when there
is no display. Each run gets an empty state folder, so no saved session changes what starts."""

from __future__ import annotations

import argparse
import os
import re
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from run import _xvfb  # noqa: E402  (the same private Xvfb as the other figures)

ROOT = Path(__file__).resolve().parent.parent


def one_run(env, root: Path = ROOT) -> tuple[float, float | None]:
    t0 = time.perf_counter()
    proc = subprocess.Popen([sys.executable, "-m", "viewer"], cwd=root, env=env, stdout=subprocess.DEVNULL,
                            stderr=subprocess.PIPE, text=True)
    whole, inside = None, None
    try:
        for line in proc.stderr:
            m = re.search(r"first frame after ([0-9.]+) s", line)
            if m:
                whole, inside = time.perf_counter() - t0, float(m.group(1))
                break
    finally:
        proc.terminate()
        try:
            proc.wait(timeout=30)
        except subprocess.TimeoutExpired:
            proc.kill()
    if whole is None:
        raise SystemExit("the window printed no first frame")
    return whole, inside


def main():
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--runs", type=int, default=5)
    ap.add_argument("--root", default=str(ROOT), help="the source tree to start (default: this one), "
                                                      "e.g. an older checkout to compare with")
    args = ap.parse_args()
    root = Path(args.root).resolve()
    xvfb, display = _xvfb()
    if display is None:
        print("start to first frame: skipped (no display and no Xvfb)")
        return
    wholes, insides = [], []
    try:
        for _ in range(args.runs):
            with tempfile.TemporaryDirectory() as state:
                env = dict(os.environ, DISPLAY=display, XDG_CONFIG_HOME=state,
                           BRDF_VIEWER_STATE=os.path.join(state, "state.toml"),
                           PYTHONPATH=str(root) + os.pathsep + os.environ.get("PYTHONPATH", ""))
                w, i = one_run(env, root)
            wholes.append(w)
            insides.append(i)
    finally:
        if xvfb:
            xvfb.terminate()
    print(f"start to first frame, whole process (python -m viewer, default scene): median "
          f"{statistics.median(wholes):.2f} s of {args.runs} ({', '.join(f'{x:.2f}' for x in wholes)})")
    print(f"  of which App() to first frame (after the imports): median {statistics.median(insides):.2f} s")


if __name__ == "__main__":
    main()
