"""The window's frame pacing (``App.pacing``): what the loop does next, from the state alone
(``loop_wait``: draw now, a warm-up step without a frame, a frame at least every ``IDLE_FRAME_S``
while something on screen changes with time, or rest until input or a wake-up), fed by
``Session.pending_work()``, and one turn of the loop (``tick``) that draws, warms up or waits on
the window system's events. On software OpenGL a frame costs about a core for 100-200 ms, which
the reference's worker processes need (gallery, split view: 31 k samples/s drawing flat out)."""

from __future__ import annotations

import time


class Pacing:
    """The loop of ``app`` (an ``App``: its ``session``, ``keys`` (the last input), ``hot_reload``,
    ``side_panel``, ``glfw``, ``frame`` and ``TOAST_S``)."""

    IDLE_FRAME_S = 0.5  # a frame at least this often while something on screen changes with time
    POLL_S = 0.5        # resting: the hot reloader and the file dialogs are polled this often
    SETTLE_S = 0.5      # frames follow without sleeping for this long after an input event
    # a new reference image alone is drawn this long after the last frame at the soonest: the
    # gallery's split view drew each pass at once, 5.6 frames/s of 72-110 ms each, half a core
    # taken from the reference's workers (see docs/performance.md)
    REFERENCE_FRAME_S = 0.3
    throttle = True     # False: ``tick`` draws flat out, as ``App.frame`` does

    def __init__(self, app):
        self.app = app
        self.frames_skipped = 0         # turns of ``tick`` that slept instead of drawing
        # (input events, time, reference version, loop_wait's kind) at the last frame
        self.drawn = (-1, -1.0, None, None)

    def loop_wait(self) -> tuple[str, float]:
        """What the loop does next, from the state alone: ("draw", 0) a frame now (the raster
        renders or refines, a compiled program is ready, input within ``SETTLE_S``, the GPU
        reference slicing the frames, models to compile here while idle: one after each frame);
        ("warm", 0) no frame, one preset sent to the compile-ahead child;
        ("frames", ``IDLE_FRAME_S``) something on screen changes with time (a toast, the CPU
        reference's passes, a compile beside the window, the lecture maps' prefilter, the hot
        reloader's note): a frame on input or a wake-up and at least this often; ("rest",
        ``POLL_S``) nothing changes: no frame until input or a wake-up."""
        app = self.app
        s = app.session
        if self.throttle and s.frames.prep.waits_on_child:
            # the view's placeholder waits for the compile-ahead child's answer, which wakes the loop
            return "frames", self.IDLE_FRAME_S
        if not self.throttle or s.dirty or s.quality != "full" or s.refining:
            return "draw", 0.0
        if s.compile_ready or (s.reference is not None and s.reference.needs_frames):
            return "draw", 0.0
        if s.compare.uses_reference and s.reference is None:  # a compare view's first frame starts it
            return "draw", 0.0
        now = time.perf_counter()
        if now - app.keys.last_event < self.SETTLE_S:
            return "draw", 0.0
        if s.warming:  # presets to send to the child take no frame; models compiled here do, as before
            return ("warm", 0.0) if s.warms_beside else ("draw", 0.0)
        m = s.last_message
        if (m is not None and m.text and now - m.time <= app.TOAST_S) or app.hot_reload.noting \
                or any(w in ("compiling", "reference", "prefetch") for w in s.pending_work()):
            return "frames", self.IDLE_FRAME_S
        return "rest", self.POLL_S

    def idle(self) -> bool:
        """The loop waits on events between frames (``loop_wait``: "frames" or "rest"): no raster
        image to render or refine, no program to compile here, no input for ``SETTLE_S``, no GPU
        reference slicing the frames, no warm-up left."""
        return self.loop_wait()[0] in ("frames", "rest")

    def settled(self) -> bool:
        """Nothing left to do at all: the loop rests and the session reports no pending work
        (``Session.pending_work``: the compile-ahead child has answered every request too)."""
        return self.loop_wait()[0] == "rest" and not self.app.session.pending_work()

    def reference_version(self):
        rv = self.app.session.reference
        return None if rv is None else rv.version

    def frame_begins(self) -> None:
        """A frame begins (its events polled): what it is drawn after, for ``wants_frame``."""
        self.drawn = (self.app.keys.input_events, time.perf_counter(), self.reference_version(),
                      self.loop_wait()[0])

    def wants_frame(self, kind: str | None = None) -> bool:
        """Something to draw since the last frame: input, a new reference image (``REFERENCE_FRAME_S``
        after the last frame at the soonest), ``IDLE_FRAME_S``
        gone by while something changes with time, the first turn of a rest (the frame that
        shows it: a toast gone), or ``idle`` no more. ``kind``: ``loop_wait``'s (asked when None)."""
        kind = kind or self.loop_wait()[0]
        events, at, version, drawn_kind = self.drawn
        if kind == "draw" or self.app.keys.input_events != events:
            return True
        if self.reference_version() != version:
            return time.perf_counter() - at >= self.REFERENCE_FRAME_S
        if kind == "frames":
            return time.perf_counter() - at >= self.IDLE_FRAME_S
        return kind == "rest" and drawn_kind != "rest"

    def tick(self) -> bool:
        """One turn of the loop (``loop_wait``): a frame (True), or a step of the warm-up, or a
        wait on the window system's events: until input, a wake-up (a reference pass, the
        compile-ahead child's answer), ``IDLE_FRAME_S`` after the last frame while something
        changes with time, or ``POLL_S`` while resting (False when no frame followed)."""
        app = self.app
        kind, wait = self.loop_wait()
        if kind == "draw":
            app.frame()
            return True
        if kind == "warm":
            app.glfw.poll_events()
            app.session.warm_one()
        elif not self.wants_frame(kind):
            if kind == "frames":
                soon = self.REFERENCE_FRAME_S if self.reference_version() != self.drawn[2] else self.IDLE_FRAME_S
                wait = self.drawn[1] + soon - time.perf_counter()
            app.glfw.wait_events_timeout(max(wait, 0.001))
            if kind == "rest":
                self.poll_resting()
        if not self.wants_frame():
            self.frames_skipped += 1
            return False
        app.frame(wait=False)
        return True

    def poll_resting(self):
        """What a frame polls, without the frame: shaders edited (hot reload), file dialogs closed."""
        app = self.app
        if app.hot_reload.poll():
            app.session.changed()
        app.side_panel.poll()
