"""Lecture mode and its preparation: the tour's steps (each step's scene, its title and plot,
the time from the key press to its first frame), the background prefilter of the tour's
environment maps started with it (``viewer.app.prefetch.Prefetch``), and Prepare lecture, which
traces every step into the traced-frame cache in a child process
(``viewer.app.lecture_prep.BackgroundPrep``). ``LectureControl`` is held by
``viewer.app.session.Session`` as ``session.tour``. No imgui, no glfw."""

from __future__ import annotations

import time

from viewer import ViewerError

# the plot tab each lecture step's ``plot`` names
STEP_TABS = {"polar": "Polar", "lobe": "3D lobe", "albedo": "Albedo", "fresnel": "Fresnel",
             "bouguer": "Bouguer", "spectral": "Spectral", "sampling": "Sampling"}


class LectureControl:
    """The lecture tour of ``session`` (``prefetch``: prefilter the lecture's environment maps in
    a background process when lecture mode starts)."""

    def __init__(self, session, prefetch: bool = True):
        self.session = session
        self.lecture_step = -1     # -1: lecture mode off; else the tour's step shown
        self.step_timer = None     # (step, perf_counter at the key press) until its first frame
        self.step_listeners: list = []  # called with the step lecture mode shows (None: mode off)
        self.prefetch = None       # the lecture maps' background prefilter
        self.prep = None           # Prepare lecture's job (viewer.app.lecture_prep), None when none ran
        self._prefetch_on = prefetch

    def release(self) -> None:
        """Stop the prefetch and the preparation."""
        if self.prefetch is not None:
            self.prefetch.stop()
        if self.prep is not None:
            self.prep.cancel()

    def lecture(self, step: int | None):
        """Show the lecture tour's ``step`` (0-based; None ends lecture mode). The step's scene
        replaces the current one; a step that fails to load leaves the scene as it was."""
        from viewer.scene.lecture import TOUR, tour_scene

        s = self.session
        if step is None:
            self.lecture_step = -1
            s.notify("lecture mode off")
            for listener in self.step_listeners:
                listener(None)
            return True
        step %= len(TOUR)
        t0 = time.perf_counter()
        try:
            scene = tour_scene(step)
        except ViewerError as e:
            s.notify(f"lecture step {step + 1} not loaded: {e}", error=True)
            return False
        s.files.set_scene(scene)
        self.enter_step(step)
        s.notify(f"lecture {step + 1}/{len(TOUR)}: {TOUR[step].title} (loading...)")
        self.step_timer = (step, t0)  # the true time: until the step's first full frame is drawn
        return True

    def lecture_next(self):
        from viewer.scene.lecture import TOUR

        return self.lecture((self.lecture_step + 1) % len(TOUR))

    def lecture_previous(self):
        """The step before (from lecture mode off: the last one)."""
        from viewer.scene.lecture import TOUR

        return self.lecture((max(self.lecture_step, 0) - 1) % len(TOUR))

    def lecture_back(self):
        """The key / strip's previous step (from the first: the last)."""
        from viewer.scene.lecture import TOUR

        return self.lecture((self.lecture_step - 1) % len(TOUR))

    @property
    def lecture_title(self) -> tuple[str, str]:
        """("3/15  Total internal reflection", caption) of the step shown, ("", "") when off."""
        from viewer.scene.lecture import TOUR

        if self.lecture_step < 0:
            return "", ""
        s = TOUR[self.lecture_step]
        return f"{self.lecture_step + 1}/{len(TOUR)}  {s.title}", s.caption

    def step_plot(self, step: int) -> dict:
        """What the plots show beside ``step``: its tab (or None), light from inside (the
        critical angle), the materials plotted (the step's subjects, not the floor)."""
        from viewer.scene.lecture import TOUR

        return dict(tab=STEP_TABS.get(TOUR[step].plot), inside=TOUR[step].key == "tir",
                    shown={name: name != "floor" for name in self.session.scene.materials})

    def step_shown(self):
        """The step's first frame is drawn (its preview where the view is drawn in tiles, its
        untraced view where it traces): say how long the key press took to show it, and how it
        is drawn while its programs compile beside (grey stand-ins, untraced): the status line
        shows this message over the compile's own."""
        from viewer.app.view_frames import FORM_WORDS
        from viewer.scene.lecture import TOUR

        s = self.session
        step, t0 = self.step_timer
        self.step_timer = None
        if step != self.lecture_step:
            return
        dt = time.perf_counter() - t0
        why = ""
        st = getattr(s.renderer.ibl(), "stats", {})
        if st.get("provisional"):
            why = "; the environment light is a quick prefilter until the full one is ready (in the background)"
        elif st.get("prefilter_passes"):
            why = f"; the environment map was prefiltered in {st.get('prefilter_s', 0.0):.1f} s, cached from now on"
        src = s.frame_source  # drawn while its programs compile beside: the message says so
        held = s.pending and src is not None and src.scene is s.scene and src.form in FORM_WORDS
        plain = f"lecture {step + 1}/{len(TOUR)}: {TOUR[step].title} ({dt:.2f} s{why})"
        if held:  # true of that frame alone (Session.message_true): the plain line once another is shown
            why += (f"; its first frame {FORM_WORDS[src.form].removeprefix('drawn ')} while "
                    f"{', '.join(s.pending)} compile in the background")
            s.notify(f"lecture {step + 1}/{len(TOUR)}: {TOUR[step].title} ({dt:.2f} s{why})",
                     frame=(src.scene, src.form), plain=plain)
        else:
            s.notify(plain)

    def enter_step(self, step: int):
        """Lecture mode on at ``step`` for the scene already shown."""
        from viewer.scene.lecture import TOUR

        s = self.session
        self.lecture_step = step
        if self.prefetch is None and self._prefetch_on:  # the tour's other maps, prefiltered in the background
            from viewer.app.prefetch import Prefetch

            self.prefetch = Prefetch(step)
        if TOUR[step].image:  # a step about the reference shows it
            s.set_image_mode(TOUR[step].image)
        if s.compiles.on and step + 1 < len(TOUR):  # the next step's programs, compiled ahead
            s.compiles.ask_ahead(step + 1)
        for listener in self.step_listeners:
            listener(step)

    @property
    def preparing(self) -> bool:
        """Prepare lecture is tracing the lecture's steps into the traced-frame cache (in a child
        process: the window's frames go on as usual)."""
        return self.prep is not None and not self.prep.done

    def prepare_lecture(self, size=None, steps=None) -> bool:
        """Trace every lecture step with traced chains (``steps``: only those) for the window's
        size (``size`` = (w, h) framebuffer pixels; by default ``window_px``, which the window
        sets each frame, else the view's last size) into the traced-frame cache, in a child
        process (``viewer.app.lecture_prep.BackgroundPrep``: ``bake --lecture``), so that every
        layout of a window of that size finds its steps prepared. Again while it runs: cancelled."""
        from viewer.app.lecture_prep import BackgroundPrep

        s = self.session
        if self.preparing:
            self.prep.cancel()
            s.notify("Prepare lecture cancelled")
            return False
        size = size or s.window_px or s.frames.hdr_for
        if not size or size[0] <= 0 or size[1] <= 0:
            s.notify("Prepare lecture: no view to size it by yet (draw a frame first)", error=True)
            return False
        self.prep = BackgroundPrep(size, steps)
        s.notify(self.prep.progress_text(), error=bool(self.prep.error))
        return not self.prep.error

    def prepare_step(self):
        """What the preparation's child said since the last frame, as the view's messages."""
        s = self.session
        results = self.prep.poll()
        for msg in self.prep.messages:
            s.notify(msg)
        self.prep.messages.clear()
        if self.prep.error:
            s.notify(self.prep.error, error=True)
        elif results and self.prep.done:
            traced = [r for r in self.prep.results if not r.cached]
            s.notify(f"{self.prep.progress_text()} ({len(self.prep.results)} steps, {len(traced)} traced now)")
        elif results or self.prep.done:
            s.notify(self.prep.progress_text())
