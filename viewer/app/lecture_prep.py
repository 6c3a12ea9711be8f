"""*Prepare lecture*: trace every lecture step that has traced chains for one window size into the
traced-frame cache (``viewer.gl.trace_cache``), so that in class each such step opens fully
traced, whatever the window lays out at that size (lecture strip or side panel, plots docked or
not, any UI scale): each step is traced once at the window's full width (rounded down to even)
and height, and every narrower view of that height is the centre of that entry.

``brdf-viewer bake --lecture`` runs ``LecturePrep`` to the end; the window's *Prepare lecture*
runs that command in a child process (``BackgroundPrep``), so its frames never wait for a trace.
Both trace the way the window's progressive trace does (``viewer.gl.raytrace.ProgressiveTrace``,
full resolution only), so the entry is what the window would have traced live."""

from __future__ import annotations

import dataclasses
import os
import re
import subprocess
import sys
import threading
import time

#: the largest tile when nobody waits for a frame (the bake): a whole frame of 1920 x 1080
BAKE_TILE_PIXELS = 1 << 22
#: set for ``bake --lecture`` run by the window: the window's pid, whose end ends the bake too
PARENT_ENV = "BRDF_VIEWER_PREP_PARENT"


@dataclasses.dataclass
class StepResult:
    step: int          # 0-based lecture step
    seconds: float     # wall-clock time to trace it (0 when it was cached already)
    cached: bool       # the cache held it already
    stored: object     # the entry's path, or None (the cache folder could not be written)


def view_size(window_size) -> tuple[int, int]:
    """The view a window of ``window_size`` = (w, h) framebuffer pixels is prepared for: its full
    width rounded down to even (the window's views are even: see ``viewer.gl.trace_cache``) and
    its height."""
    w, h = int(window_size[0]), int(window_size[1])
    return (max(2, w - w % 2), h)


def traced_steps() -> list[int]:
    """The 0-based lecture steps whose scenes trace specular chains."""
    from viewer.gl.raytrace import chain_traces
    from viewer.scene.lecture import TOUR, tour_scene

    out = []
    for i in range(len(TOUR)):
        scene = tour_scene(i)
        if scene.render.raytrace and any(chain_traces(scene.materials[o.material])
                                         for o in scene.objects):
            out.append(i)
    return out


def prepared_text(window_size) -> str:
    """What a preparation for ``window_size`` covers, in words."""
    w, h = window_size
    vw, vh = view_size(window_size)
    return (f"a {w}x{h} window (every view {vh} pixels high up to {vw} wide: lecture strip or side panel, "
            "plots docked or not, any UI scale)")


class LecturePrep:
    """Traces ``steps`` (default: every traced step) for a window of ``window_size`` = (w, h)
    framebuffer pixels (``view_size``) with ``renderer``."""

    def __init__(self, ctx, renderer, window_size, steps=None, view_mode: int = 0):
        self.ctx = ctx
        self.renderer = renderer
        self.window_size = (int(window_size[0]), int(window_size[1]))
        if self.window_size[0] <= 0 or self.window_size[1] <= 0:
            raise ValueError(f"window size {self.window_size[0]}x{self.window_size[1]}: both must be >= 1")
        self.size = view_size(self.window_size)
        self.steps = list(traced_steps() if steps is None else steps)
        self.view_mode = int(view_mode)
        self.results: list[StepResult] = []
        self.messages: list[str] = []   # entries set aside
        self.started = time.perf_counter()
        self.elapsed_s = 0.0
        self._trace = None
        self._index = 0

    @property
    def done(self) -> bool:
        return self._index >= len(self.steps)

    @property
    def current(self) -> int | None:
        return None if self.done else self.steps[self._index]

    def progress_text(self) -> str:
        if self.done:
            return f"lecture prepared for {prepared_text(self.window_size)} in {self.elapsed_s:.1f} s"
        frac = self._trace.progress if self._trace is not None else 0.0
        w, h = self.window_size
        return (f"preparing lecture for a {w}x{h} window: step {self.current + 1} "
                f"({self._index + 1}/{len(self.steps)}) {100 * frac:.0f}%, "
                f"{time.perf_counter() - self.started:.0f} s")

    def _begin(self):
        from viewer.scene.camera import OrbitCamera
        from viewer.gl.raytrace import ProgressiveTrace
        from viewer.scene.lecture import tour_scene

        scene = tour_scene(self.current)
        self._trace = ProgressiveTrace(self.ctx)
        w, h = self.size
        self._trace.start(self.renderer, scene, OrbitCamera.from_scene(scene), w, h, self.view_mode,
                          coarse=False, cache=True, store=True, max_pixels=BAKE_TILE_PIXELS)
        if self._trace.cache_message:
            self.messages.append(self._trace.cache_message)

    def _end(self):
        t = self._trace
        self.results.append(StepResult(self.current, 0.0 if t.from_cache else t.elapsed_s, t.from_cache,
                                       t.stored))
        t.release()
        self._trace = None
        self._index += 1
        if self.done:
            self.elapsed_s = time.perf_counter() - self.started

    def step(self, budget_s: float = 0.2) -> StepResult | None:
        """About ``budget_s`` of work (a step's untraced frame, or tiles); the step's result when
        one finished, else None."""
        if self.done:
            return None
        if self._trace is None:
            self._begin()
        else:
            self._trace.step(budget_s)
        if self._trace.done:
            self._end()
            return self.results[-1]
        return None

    def run(self, on_result=None) -> list[StepResult]:
        """Everything left, in large tiles; ``on_result(result)`` after each step."""
        while not self.done:
            if self._trace is None:
                self._begin()
            self._trace.finish()
            self._end()
            if on_result is not None:
                on_result(self.results[-1])
        return self.results

    def cancel(self):
        if self._trace is not None:
            self._trace.release()
            self._trace = None
        self._index = len(self.steps)


#: a line of ``bake --lecture`` about one step: "lecture step N: traced ..." / "... already prepared"
_STEP_LINE = re.compile(r"^lecture step (\d+): (traced .* in ([0-9.]+) s|.*already prepared)")


class BackgroundPrep:
    """*Prepare lecture* in a child process: ``brdf-viewer bake --lecture --width W --height H``
    for the window's framebuffer size, on its own EGL context at a lower priority
    (``viewer.app.prefetch.behind_the_window``), so the window's frames never wait for it. The same interface as ``LecturePrep`` for the window: ``done``, ``results`` (one
    ``StepResult`` per finished step, ``stored`` the line's path), ``messages`` (lines to show),
    ``progress_text``, ``cancel``; ``error`` holds the child's one-line error when it failed.
    ``poll`` takes in what the child printed since (the window calls it each frame)."""

    def __init__(self, window_size, steps=None, command=None):
        self.window_size = (int(window_size[0]), int(window_size[1]))
        self.size = view_size(self.window_size)
        self.steps = list(traced_steps() if steps is None else steps)
        self.results: list[StepResult] = []
        self.messages: list[str] = []
        self.error = ""
        self.started = time.perf_counter()
        self.elapsed_s = 0.0
        self._lines: list[str] = []
        self._lock = threading.Lock()
        self._finished = False
        self._cancelled = False
        w, h = self.window_size
        cmd = list(command) if command is not None else [sys.executable, "-m", "viewer", "bake", "--lecture"]
        cmd += ["--width", str(w), "--height", str(h), "--steps", ",".join(str(i + 1) for i in self.steps)]
        try:
            env = dict(os.environ, **{PARENT_ENV: str(os.getpid())})  # it ends when the window dies
            self._proc = subprocess.Popen(cmd, stdin=subprocess.DEVNULL, stdout=subprocess.PIPE,
                                          stderr=subprocess.STDOUT, text=True, bufsize=1, env=env)
            from viewer.app.prefetch import behind_the_window

            behind_the_window(self._proc.pid)  # the window's frames first, as its other children
        except OSError as e:
            self._proc = None
            self.error = f"Prepare lecture could not start ({e})"
            self._finished = True
            return
        threading.Thread(target=self._read, name="brdf-viewer-prepare-lecture", daemon=True).start()

    def _read(self):
        for line in self._proc.stdout:
            with self._lock:
                self._lines.append(line.rstrip("\n"))
        rc = self._proc.wait()
        with self._lock:
            self._lines.append(f"\0exit {rc}")

    def poll(self) -> list[StepResult]:
        """Take in the child's new lines; the steps finished since the last call."""
        with self._lock:
            lines, self._lines = self._lines, []
        new = []
        for line in lines:
            if line.startswith("\0exit "):
                rc = int(line.split()[1])
                self._finished = True
                self.elapsed_s = time.perf_counter() - self.started
                if rc != 0 and not self._cancelled and not self.error:
                    self.error = "Prepare lecture stopped: " + (self._last_said or f"exit status {rc}")
                continue
            m = _STEP_LINE.match(line)
            if m:
                cached = m.group(3) is None
                stored = line.rsplit(" -> ", 1)[1] if " -> " in line else None
                r = StepResult(int(m.group(1)) - 1, 0.0 if cached else float(m.group(3)), cached, stored)
                self.results.append(r)
                new.append(r)
            elif line.strip():
                self._last_said = line.replace("brdf-viewer: error: ", "")
                if not line.startswith("lecture prepared"):
                    self.messages.append(self._last_said)
        return new

    _last_said = ""

    @property
    def done(self) -> bool:
        return self._finished

    @property
    def child_pid(self) -> int | None:
        return None if self._proc is None else self._proc.pid

    @property
    def running(self) -> bool:
        """The child process is still running."""
        return self._proc is not None and self._proc.poll() is None

    @property
    def current(self) -> int | None:
        if self.done:
            return None
        n = len(self.results)
        return self.steps[n] if n < len(self.steps) else None

    def progress_text(self) -> str:
        if self.error:
            return self.error
        if self.done:
            return f"lecture prepared for {prepared_text(self.window_size)} in {self.elapsed_s:.1f} s"
        w, h = self.window_size
        n = len(self.results)
        step = f"step {self.current + 1} ({n + 1}/{len(self.steps)})" if self.current is not None else "finishing"
        return (f"preparing lecture for a {w}x{h} window in the background: {step}, "
                f"{time.perf_counter() - self.started:.0f} s")

    def wait(self, timeout: float | None = None) -> bool:
        """Wait for the child to end and its last line to be read (``poll`` then takes in
        everything); True when it did."""
        if self._proc is None:
            return True
        try:
            self._proc.wait(timeout)
        except subprocess.TimeoutExpired:
            return False
        deadline = time.perf_counter() + 5.0
        while time.perf_counter() < deadline:  # the reader's last line
            with self._lock:
                if any(x.startswith("\0exit ") for x in self._lines):
                    break
            time.sleep(0.01)
        return True

    def cancel(self):
        from viewer.app.prefetch import stop_child

        self._cancelled = True
        stop_child(self._proc, 5.0)
        self._finished = True
