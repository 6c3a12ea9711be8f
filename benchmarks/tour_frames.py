"""The longest frames of a classroom's tour, in a real window at 1920x1080 and UI scale 1.5:

    xvfb-run -a -s "-screen 0 1920x1080x24" python benchmarks/tour_frames.py [--quick]

The window opens on the default scene; then, one action at a time: L (lecture mode), the digit
keys 1-9 and 0 and Right through all the tour's steps, Esc, a preset change in the material
editor, a slider dragged over 12 frames, the gallery with ray tracing turned on, the compare
views (split, difference, side by side, reference, and back to the raster), every tab of the
plots window and *Prepare lecture* (the window's frames while its child traces the steps). Each
action is followed frame by frame, drawn flat out, until the view settles (nothing dirty,
compiling, tiling, tracing or computing for three frames; a compare view also waits for the
reference's first pass and, for the difference, its metrics) or a bound is reached (``SETTLE_S``
seconds, ``--quick`` a third). Prints per action the longest frame, the frames over 150 ms and
over 500 ms, the frames followed and the time until settled (``*``: the bound was reached
first), then the same frames measured in CPU time, which other processes on the machine do not
lengthen: the longest frame in the window thread's own CPU time (``time.thread_time``: the
Python work, the GL calls' driver work and llvmpipe's shader compiles and code generation, which
run on the calling thread) with its frames over 150 and 500 ms, and the process's CPU time in
the frame of longest wall time (``time.process_time``: that thread, llvmpipe's rasterizer
threads and any other thread of the window, such as the plots' worker). On a loaded machine the
wall column grows and the CPU columns stay; a frame long in wall time but short in thread CPU
waited for the rasterizer or another thread. Keys go through the window's key path
(``app.keys.taps``), the editor's actions through the session's, as the panels call them.
``--profile TEXT``: the slowest frame of each action whose label holds TEXT is profiled
(cProfile, by cumulative time); ``--profile-over MS``: every frame over MS milliseconds of wall
time is (its 12 costliest calls, and the viewer's calls by cumulative time). ``--cold``: every
cache starts empty (Mesa's shader cache, the environment maps' prefilters, the traced frames:
``XDG_CACHE_HOME`` a new folder), as on a machine where the viewer never ran; otherwise the
caches are as they are. ``--frames N``: each action's first N frames in thread CPU (ms), one line
each, to see how a scene's first frame is spread over its preparation's frames
(``viewer/app/view_prep.py``).
"""

from __future__ import annotations

import cProfile
import os
import pstats
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

SIZE = (1920, 1080)
UI_SCALE = 1.5
SETTLE_S = 30.0
GOAL_MS, LIMIT_MS = 150.0, 500.0


def busy(app) -> str:
    """What still changes the view without input ("" when nothing does)."""
    s = app.session
    for what in ("dirty", "refining", "compiling", "pending"):
        if getattr(s, what):
            return what
    if s.quality != "full":
        return s.quality
    if getattr(app.plots, "computing", False) and app.plots.visible:
        return "plots computing"
    if s.compare.uses_reference:
        rv = s.reference
        img = None if rv is None else rv.latest()
        if img is None or img[1] == 0:
            return "reference"
        if s.compare.mode.endswith("difference") and s.compare.metrics is None:
            return "metrics"
    return ""


def follow(app, bound_s: float, during=None, profile: bool = False, over_ms: float | None = None) -> dict:
    """Frames until the view settles (or ``bound_s``); ``during(i)`` runs before frame ``i``.
    ``profile``: the slowest frame's profile is printed (cProfile, by cumulative time);
    ``over_ms``: every frame over that many milliseconds is (its costliest calls)."""
    frames, cpu, proc, calm, t0 = [], [], [], 0, time.perf_counter()
    i, worst = 0, None
    while True:
        if during is not None:
            during(i)
        prof = cProfile.Profile() if profile or over_ms is not None else None
        t, c, p = time.perf_counter(), time.thread_time(), time.process_time()
        if prof is not None:
            prof.enable()
        app.frame(wait=False)
        if prof is not None:
            prof.disable()
        frames.append(1000 * (time.perf_counter() - t))
        cpu.append(1000 * (time.thread_time() - c))
        proc.append(1000 * (time.process_time() - p))
        if over_ms is not None and frames[-1] > over_ms:
            print(f"    frame {i}: {frames[-1]:.0f} ms, thread CPU {cpu[-1]:.0f} ms", flush=True)
            st = pstats.Stats(prof)
            st.sort_stats("tottime").print_stats(12)
            st.sort_stats("cumulative").print_stats(r"viewer[/\\]", 25)  # the viewer's own calls, nested
        if profile and frames[-1] >= max(frames):
            worst = prof
        i += 1
        if during is None or i >= getattr(during, "frames", 0):
            calm = 0 if busy(app) else calm + 1
        settled = calm >= 3
        over = time.perf_counter() - t0 > bound_s
        if settled or over:
            if worst is not None:
                pstats.Stats(worst).sort_stats("cumulative").print_stats(30)
            return {"frames": frames, "cpu": cpu, "proc": proc, "settled": settled,
                    "s": time.perf_counter() - t0, "busy": busy(app)}


def _for_seconds(seconds: float):
    """A ``during`` that changes nothing and keeps the frames followed for ``seconds``."""
    t0 = []

    def during(i):
        if not t0:
            t0.append(time.perf_counter())
        during.frames = i + 2 if time.perf_counter() - t0[0] < seconds else 0
    during.frames = 1
    return during


def main(argv):
    quick = "--quick" in argv
    wanted = argv[argv.index("--profile") + 1] if "--profile" in argv else None
    over_ms = float(argv[argv.index("--profile-over") + 1]) if "--profile-over" in argv else None
    first_n = int(argv[argv.index("--frames") + 1]) if "--frames" in argv else 0
    bound = SETTLE_S / 3 if quick else SETTLE_S
    if "--cold" in argv:  # before anything reads a cache: Mesa's, the viewer's
        import tempfile

        os.environ["XDG_CACHE_HOME"] = tempfile.mkdtemp(prefix="tour-frames-cache-")
        os.environ.pop("MESA_SHADER_CACHE_DIR", None)
        os.environ.pop("BRDF_VIEWER_CACHE", None)
    from viewer.app.main import App
    from viewer.app.plots_panel import TABS
    from viewer.scene.lecture import TOUR
    from viewer.scene import material_from_name

    app = App("default", size=SIZE, restore_state=False)
    app.set_ui_scale(UI_SCALE)
    rows = []

    def act(label, fn=None, during=None):
        if fn is not None:
            fn()
        r = follow(app, bound, during, profile=wanted is not None and wanted in label, over_ms=over_ms)
        r["label"] = label
        rows.append(r)
        f, c = r["frames"], r["cpu"]
        at = f.index(max(f))
        print(f"  {label:<34} {max(f):7.0f} ms  {sum(x > GOAL_MS for x in f):3d} {sum(x > LIMIT_MS for x in f):3d}"
              f"  {len(f):4d} {r['s']:6.1f} s{'' if r['settled'] else '*':1}"
              f" | {max(c):6.0f} ms {sum(x > GOAL_MS for x in c):3d} {sum(x > LIMIT_MS for x in c):3d}"
              f" {r['proc'][at]:7.0f} ms{'' if r['settled'] else '  (' + r['busy'] + ')'}", flush=True)
        if first_n:
            print(f"    first frames, thread CPU ms: {' '.join(f'{x:.0f}' for x in c[:first_n])}", flush=True)

    def key(k):
        return lambda: app.keys.taps.append(k)

    print(f"window {SIZE[0]}x{SIZE[1]}, UI scale {UI_SCALE}, settle bound {bound:.0f} s")
    print(f"  {'':<34} {'wall time':-^37} | {'thread CPU':-^18} {'process':>10}")
    print(f"  {'action':<34} {'longest':>10} >{GOAL_MS:.0f} >{LIMIT_MS:.0f} frames settled "
          f"| {'longest':>9} >{GOAL_MS:.0f} >{LIMIT_MS:.0f} {'(longest)':>10}")
    act("open default")
    act("L (lecture step 1)", key("l"))
    for i in range(1, len(TOUR)):
        k = str((i + 1) % 10) if i < 10 else "right"
        act(f"{k} (step {i + 1}: {TOUR[i].title[:18]})", key(k))
    act("Esc (lecture off)", key("escape"))
    act("default scene", lambda: app.session.open_scene("default"))
    s = app.session
    ball = next(o.material for o in s.scene.objects if o.mesh != "plane")
    act("preset gold (material picker)", lambda: s.set_material(ball, material_from_name("gold")))

    def drag(i):
        app.keys.last_interaction = time.perf_counter()  # what the window sets while a slider is held
        s.set_material_param(ball, "roughness", 0.2 + 0.05 * i)
    drag.frames = 12
    act("roughness slider drag", during=drag)
    act("gallery", lambda: s.open_scene("gallery"))
    act("gallery: ray traced", lambda: s.set_reflection_mode("ray traced"))
    for mode in ("split", "difference", "side by side", "reference", "raster"):
        act(f"compare: {mode}", lambda m=mode: s.set_image_mode(m))
    app.plots.visible = True
    s.changed()
    for tab in TABS:
        act(f"plots tab: {tab}", lambda t=tab: app.plots.select_tab(t))
    # Prepare lecture: the window's frames while its child traces the steps (for the bound,
    # then cancelled; the traced frames it stored stay in the cache: last, so no step above
    # opens from them)
    s.set_image_mode("raster")
    act("Prepare lecture (frames meanwhile)", lambda: s.prepare_lecture(),
        during=_for_seconds(bound))
    if s.preparing:
        s.prepare_lecture()  # again while it runs: cancelled
    # the compile-ahead children through the walk: a child that ended leaves the window to
    # compile the programs itself, and the frames above are then not the design's
    ca = s.compiles.child
    ahead = "off" if ca is None else (f"the shown scene's child {'running' if ca.alive else 'ended: ' + ca.error}, "
                                      f"{ca.replaced} replaced for silence, "
                                      f"{len(ca.ended)} ended by themselves"
                                      + (f" ({'; '.join(ca.ended)})" if ca.ended else ""))
    app.close()
    for what, col in (("wall time", "frames"), ("the window thread's CPU time", "cpu")):
        worst = max(max(r[col]) for r in rows)
        n150 = sum(sum(x > GOAL_MS for x in r[col]) for r in rows)
        n500 = sum(sum(x > LIMIT_MS for x in r[col]) for r in rows)
        print(f"in {what}: longest frame over all actions {worst:.0f} ms; frames over {GOAL_MS:.0f} ms: "
              f"{n150}, over {LIMIT_MS:.0f} ms: {n500}")
    print(f"compile-ahead: {ahead}")
    print(f"load average {os.getloadavg()[0]:.1f}")


if __name__ == "__main__":
    main(sys.argv[1:])
