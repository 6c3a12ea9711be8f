"""What the window costs while nobody touches it, in a real window:

    xvfb-run -a -s "-screen 0 1920x1080x24" python benchmarks/idle_window.py [W H [SCALE]]

The window opens on the default scene (1920x1080 at UI scale 1.5 unless told otherwise, a fresh
state file and viewer cache, the machine's driver shader cache) and runs its own loop
(``App.run``). Once it has settled (the session reports no pending work, ``App.settled``, or
at most ``SETTLE_MAX_S``), the window's process and its children are sampled over ``SAMPLE_S``
seconds: CPU time from /proc (user + system, live children and reaped ones) and frames drawn.
Prints the settle time, CPU % of one core (window, children, together) and frames per second.
"""

import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SETTLE_MAX_S = float(os.environ.get("IDLE_SETTLE_MAX_S", 120))
SAMPLE_S = 20.0

CHILD = r"""
import json, os, sys, threading, time
sys.path.insert(0, ROOT)
from viewer.app.main import App

TICK = os.sysconf("SC_CLK_TCK")

def cpu(pid):
    with open(f"/proc/{pid}/stat") as f:
        v = f.read().rsplit(")", 1)[1].split()
    return (int(v[11]) + int(v[12])) / TICK, (int(v[13]) + int(v[14])) / TICK  # own, reaped children

def descendants(pid):
    out = []
    for task in os.listdir(f"/proc/{pid}/task"):
        try:
            with open(f"/proc/{pid}/task/{task}/children") as f:
                kids = [int(x) for x in f.read().split()]
        except OSError:
            continue
        for k in kids:
            out += [k] + descendants(k)
    return out

def sample():
    me = os.getpid()
    own, reaped = cpu(me)
    kids = 0.0
    for k in descendants(me):
        try:
            kids += cpu(k)[0]
        except OSError:
            pass
    return own, kids + reaped

app = App("default", size=(W, H), restore_state=False)
app.set_ui_scale(SCALE)
result = {}
settled = getattr(app, "settled", None) or (lambda: False)  # a window without it: SETTLE_MAX_S

def monitor():
    t0 = time.perf_counter()
    while time.perf_counter() - t0 < SETTLE_MAX and not settled():
        time.sleep(0.25)
    result["settle_s"] = time.perf_counter() - t0
    result["settled"] = settled()
    f0, a = app.frame_count, sample()
    t1 = time.perf_counter()
    time.sleep(SAMPLE)
    f1, b = app.frame_count, sample()
    dt = time.perf_counter() - t1
    result.update(seconds=dt, frames=f1 - f0, window_cpu=(b[0] - a[0]) / dt, children_cpu=(b[1] - a[1]) / dt)
    app.request_close()
    app.glfw.post_empty_event()

threading.Thread(target=monitor, daemon=True).start()
app.run()
print("RESULT " + json.dumps(result))
"""


def main(argv):
    w, h = (int(argv[0]), int(argv[1])) if len(argv) >= 2 else (1920, 1080)
    scale = float(argv[2]) if len(argv) >= 3 else 1.5
    with tempfile.TemporaryDirectory() as cache:
        env = dict(os.environ, BRDF_VIEWER_CACHE=cache, BRDF_VIEWER_STATE=os.path.join(cache, "state.toml"))
        code = (CHILD.replace("ROOT", repr(str(ROOT))).replace("(W, H)", f"({w}, {h})")
                .replace("(SCALE)", f"({scale})").replace("SETTLE_MAX", repr(SETTLE_MAX_S))
                .replace("(SAMPLE)", f"({SAMPLE_S})"))
        r = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=600)
    line = [x for x in r.stdout.splitlines() if x.startswith("RESULT ")]
    if not line:
        raise SystemExit(r.stderr[-3000:])
    res = json.loads(line[0][len("RESULT "):])
    print(f"default scene, {w}x{h}, UI scale {scale}: settled after {res['settle_s']:.1f} s"
          + ("" if res["settled"] else " (not settled: sampled anyway)"))
    print(f"over {res['seconds']:.1f} s: window {100 * res['window_cpu']:.1f}% of a core, children "
          f"{100 * res['children_cpu']:.1f}%, together {100 * (res['window_cpu'] + res['children_cpu']):.1f}%; "
          f"{res['frames'] / res['seconds']:.2f} frames/s")


if __name__ == "__main__":
    main(sys.argv[1:])
