"""Frames while switching presets, in a real window: as the window draws them (the compile-ahead
child, frames over the budget drawn in tiles), with whole frames, and on the GUI thread:

    xvfb-run -a -s "-screen 0 1600x1000x24" python benchmarks/preset_switch.py [W H]

For each run, a fresh driver shader cache (Mesa's, in a temporary folder) and a fresh viewer
cache, so every program is compiled cold: the window opens on the default scene, then the
ball's material goes through the presets below, one change per step; each step records every
frame until the new material is drawn whole. Prints per preset the longest frame and the time
until the new material shows, and the longest frame of a still redraw of the same view (what
one frame costs on this machine without any compile), the three runs in the same process order.
"""

import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PRESETS = ("glass", "gold", "soap_bubble", "copper", "red_plastic", "frosted_glass", "car_paint")

CHILD = r"""
import json, sys, time
sys.path.insert(0, ROOT)
from viewer.app.main import App
from viewer.scene import material_from_name
w, h = W, H
app = App("default", size=(w, h), restore_state=False, compile_ahead=AHEAD)
app.session.presets_ahead = False  # this run measures cold changes, not the idle warm-up
for _ in range(3):
    app.frame(wait=False)
still = []
for _ in range(3):
    app.session.dirty = True
    while True:
        t = time.perf_counter(); app.frame(wait=False); still.append(time.perf_counter() - t)
        if app.session.quality == "full" and not app.session.dirty:
            break
out = {"still_ms": 1000 * max(still), "steps": []}
for name in PRESETS:
    t0 = time.perf_counter()
    app.session.set_material("ball", material_from_name(name))
    frames = []
    while True:
        t = time.perf_counter(); app.frame(wait=False); frames.append(time.perf_counter() - t)
        s = app.session  # shown: drawn with its own programs (none pending), whole (tiles done)
        if not (s.compiling or s.pending or s.dirty or s.quality != "full"):
            break
        time.sleep(0.01)
    out["steps"].append({"preset": name, "longest_ms": 1000 * max(frames), "frames": len(frames),
                         "shown_s": time.perf_counter() - t0})
app.session.release()
print("RESULT " + json.dumps(out))
"""


def run(ahead: bool, tiled: bool, w: int, h: int) -> dict:
    with tempfile.TemporaryDirectory() as mesa, tempfile.TemporaryDirectory() as cache:
        env = dict(os.environ, MESA_SHADER_CACHE_DIR=mesa, BRDF_VIEWER_CACHE=cache,
                   BRDF_VIEWER_STATE=os.path.join(cache, "state.toml"),
                   BRDF_VIEWER_TILED_FRAMES="1" if tiled else "0")
        code = (CHILD.replace("ROOT", repr(str(ROOT))).replace("W, H", f"{w}, {h}")
                .replace("AHEAD", repr(ahead)).replace("PRESETS", repr(PRESETS)))
        r = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=1800)
        line = [x for x in r.stdout.splitlines() if x.startswith("RESULT ")]
        if not line:
            raise SystemExit(r.stderr[-3000:])
        return json.loads(line[0][len("RESULT "):])


def main(argv):
    w, h = (int(argv[0]), int(argv[1])) if len(argv) >= 2 else (1280, 720)
    runs = {"window": (True, True), "whole frames": (True, False), "GUI thread": (False, False)}
    results = {k: run(a, t, w, h) for k, (a, t) in runs.items()}
    print(f"window {w}x{h}, cold driver cache; per preset change: longest frame (ms) / time until shown (s)")
    print(f"{'preset':<15}" + "".join(f"{k:>20}" for k in runs))
    for i, name in enumerate(PRESETS):
        cells = [results[k]["steps"][i] for k in runs]
        print(f"{name:<15}" + "".join(f"{c['longest_ms']:>11.0f} / {c['shown_s']:5.1f}" for c in cells))
    worst = {k: max(s["longest_ms"] for s in v["steps"]) for k, v in results.items()}
    print("longest frame over all changes: " + ", ".join(f"{k} {v:.0f} ms" for k, v in worst.items()))
    print("longest frame of a still redraw: " + ", ".join(f"{k} {v['still_ms']:.0f} ms" for k, v in results.items()))


if __name__ == "__main__":
    main(sys.argv[1:])
