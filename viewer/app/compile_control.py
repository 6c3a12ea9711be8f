"""Programs compiled beside the window: a changed material's programs compile in the
compile-ahead child (``viewer.app.compile_ahead``) while the view draws it as it was
(``held_back``: the materials as last drawn, the view kept, the scene untraced, or grey
stand-ins for another scene), and the idle-time warm-up (the picker's presets sent to the child,
or without it the models compiled on this thread one per idle frame). ``CompileControl`` is held
by ``viewer.app.session.Session`` as ``session.compiles``. No imgui, no glfw."""

from __future__ import annotations

import dataclasses

from viewer import ViewerError

KEEP_IMAGE = object()  # held_back: keep the view shown as it is (the same scene, seen the same way)
UNTRACED = object()    # held_back: the scene itself, untraced, while its traced programs compile beside
#: a stand-in material's albedo: a new scene whose programs compile beside is drawn with grey
#: Lambert stand-ins for the materials not ready (its own objects, never the last scene's frame)
STAND_IN_ALBEDO = 0.5
#: the seconds of a frame spent linking programs again from the driver's cache (a link from the
#: cache takes 2-30 ms; see ``CompileControl._relink_some``)
RELINK_S = 0.04


class CompileControl:
    """What compiles beside ``session``'s window and what is drawn meanwhile (``on``: with the
    compile-ahead child; the scene's presets compile ahead while idle)."""

    def __init__(self, session, on: bool = False):
        from viewer import brdf
        from viewer.app.driver_cache import CacheWriters

        self.session = session
        self.on = on
        self.child = None          # the CompileAhead child, started on first need
        self.pending: list[str] = []  # materials drawn as they were while their programs compile
        self.awaiting = None       # the compile-ahead request the view waits for
        self.noted = None          # (request, form of the frame drawn) the last note said
        self._flat = None          # (scene, its untraced copy) asked for first (untraced_copy)
        self._texts = {}           # (id(scene), session's edits) -> (scene, its text): scene_text
        self.awaiting_flat = None  # that request, while the view shows stand-ins
        self.presets_ahead = True  # with the child: the picker's presets compile ahead while idle
        # models whose programs compile while idle on this thread (with the compile-ahead child
        # the picker's presets compile there instead, and this list stays empty)
        self.warm = [] if on else list(brdf.names())
        self._ahead_sent = False   # the presets still to send to the child (False: not begun)
        self._batch = (None, 0)    # (the scene and materials last asked for, their batch number)
        self._next = None          # (the next lecture step, its stand-in scene), asked for ahead
        self._record = None        # what the driver's cache holds (DriverCacheRecord), read on first use
        self._recorded = 0         # the children's answers put in the record so far
        self._relinked: set[str] = set()  # programs linked again from the driver's cache (_relink_some)
        self._writers = CacheWriters()  # this window's cache writes: relinked only once they are done

    def poll(self) -> None:
        """The request the view waits for answered: the view is drawn again, with the material
        as it now is."""
        if self.awaiting is not None and self.child.answered(self.awaiting):
            self.awaiting = None
            self.session.dirty = True
        if self.awaiting_flat is not None and self.child.answered(self.awaiting_flat):
            self.awaiting_flat = None  # the untraced programs: drawn untraced from now on
            self.session.dirty = True
        if self.child is not None and len(getattr(self.child, "done", ())) > self._recorded:
            self._record_answers()
        if self._recorded:
            self._relink_some()

    def _relink_some(self) -> None:
        """Link again, from the driver's cache, the programs this window linked once only (its
        fixed passes at start, a program made here before any child had made it), up to
        ``RELINK_S`` of them a frame. A program that made machine code here keys its code for a
        new state apart from one whose code was all read from the driver's cache, as the
        compile-ahead child's echo draws it (``ProgramCache.relink``): drawn in a new state, only
        the relinked one reads the child's code (a lecture step's program took 0.3-0.4 s of this
        thread otherwise). Once the child has answered a request, and while this window's own
        cache writes are done (``CacheWriters``: a program whose entry is not written yet would
        be compiled afresh again)."""
        import time

        r = self.session.renderer
        todo = [k for k in r.program_keys() if k not in self._relinked]
        if not todo or not self._writers.idle():  # nothing new (every frame after): no /proc read
            return
        t0 = time.perf_counter()
        for key in todo:
            r.relink_programs([key])
            self._relinked.add(key)
            if time.perf_counter() - t0 >= RELINK_S:
                return  # at least one a frame

    def record(self):
        """What the driver's cache holds of the programs (``viewer.app.driver_cache``), for this
        window's driver."""
        if self._record is None:
            from viewer.app.driver_cache import DriverCacheRecord

            info = self.session.renderer.ctx.info
            self._record = DriverCacheRecord(f"{info.get('GL_RENDERER', '')}|{info.get('GL_VERSION', '')}")
        return self._record

    def _record_answers(self) -> None:
        """The programs of the children's answers since the last call, each drawn there in every
        kind of frame the window draws: in the driver's cache now."""
        ca = self.child
        answers = list(ca.done.items())
        self._recorded = len(answers)
        states = getattr(ca, "states", {})
        for rid, msg in answers:
            if msg.get("ok") and rid in states:
                self.record().add(msg.get("keys", ()), states[rid])

    def in_driver_cache(self, keys, scene) -> bool:
        """The programs ``keys`` drawn in ``scene`` are in the driver's cache (a child drew them
        in a scene of the same ``drawing_state``, in every kind of frame the window draws, this
        session or an earlier one)."""
        from viewer.app.driver_cache import drawing_state

        return self.record().holds(keys, drawing_state(scene))

    @property
    def compiling(self) -> bool:
        """A changed material's programs are compiling beside the window (``pending`` names
        the materials drawn as they were meanwhile)."""
        return self.awaiting is not None and not self.child.answered(self.awaiting)

    @property
    def compile_ready(self) -> bool:
        """The programs the view waits for are ready (or a traced scene's untraced ones, while it
        shows stand-ins): the next frame draws the material as it is."""
        return ((self.awaiting is not None and self.child.answered(self.awaiting))
                or (self.awaiting_flat is not None and self.child.answered(self.awaiting_flat)))

    def worker(self):
        """The compile-ahead child (started on first use), None when it cannot run."""
        if self.child is None:
            from viewer.app.compile_ahead import CompileAhead

            s = self.session
            self.child = CompileAhead(on_done=lambda: s.wake and s.wake(), on_notice=s.notify)
        return self.child if self.child.alive else None

    def nothing_awaited(self) -> None:
        """The view waits for no program (drawn with its own, or shown from a prepared frame):
        no "compiling" read-out, and no redraw when the child answers."""
        self.pending, self.awaiting, self.awaiting_flat = [], None, None

    def held_back(self, rt_now, rt_held, stale: bool):
        """What to draw while programs compile beside the window: None (the scene, now: nothing
        to compile, or no child to compile it), a copy of the scene with the changed materials
        as they were last drawn (their programs are ready), KEEP_IMAGE (the same scene seen the
        same way: the view shown stays), UNTRACED (the scene without its traced chains, whose
        programs are ready) or, for another scene than the one drawn, the scene with the
        materials not ready as grey stand-ins: never another scene's frame or materials.
        ``rt_now`` / ``rt_held``: the traced-chain switch of the frame and of a held one."""
        from viewer.app.compile_ahead import params_key

        from viewer.gl.program_set import frame_switches

        s = self.session
        keys = s.renderer.forward_keys(s.scene, raytrace=rt_now)
        progs = s.renderer.programs
        tables = s.renderer.tables
        ssr_on, env_on = frame_switches(s.scene, rt_now)[:2]
        ms_scene = bool(s.scene.render.ms_compensation)

        def needs_tables(p):  # as MaterialUniforms.prepare builds them: for IBL, SSR and compensation
            return ssr_on or env_on or ms_scene or bool(p.get("multiple_scattering", False))

        missing = [n for n, k in keys.items() if k not in progs
                   or (needs_tables(s.scene.materials[n]) and not tables.ready(s.scene.materials[n]))]
        if not missing:  # drawn with its own programs: nothing is awaited for this scene
            self.nothing_awaited()
            return None
        ca = self.worker()
        traced = rt_held is False and s.renderer.traces(s.scene)
        # a traced scene: its untraced programs first (a fraction of the traced ones' compile),
        # so it is drawn untraced in seconds rather than with stand-ins until the traced are ready
        # this scene's requests go before those of the scenes shown before it (``batch``)
        batch = self._batch_for(s.scene)
        flat = self.untraced_copy(s.scene) if traced else None
        rid_flat = None if ca is None or not traced else ca.request(flat, urgent=True, batch=batch,
                                                                     text=self.scene_text(flat))
        if ca is not None and self._next is not None and self._next[0] == s.lecture_step + 1:
            # the next step's stand-ins (one cheap program) before this step's traced programs
            # (tens of seconds on a loaded machine): the step after opens without a compile here
            ca.request(self._next[1], urgent=True, batch=batch, text=self.scene_text(self._next[1]))
        rid = None if ca is None else ca.request(s.scene, urgent=True, batch=batch, text=self.scene_text(s.scene))
        done_beside = ca is not None and all(
            (keys[n] in progs or keys[n] in ca.compiled) and params_key(s.scene.materials[n]) in ca.tables
            for n in missing)
        if rid is None or ca.answered(rid) or done_beside:
            # compiled beside (the driver's cache has the programs; the tables come along), or
            # it failed there: compile here, which reports the error as always
            for n in missing:
                data = ca.tables.get(params_key(s.scene.materials[n])) if ca is not None else None
                if data is not None:
                    tables.adopt(s.scene.materials[n], data)
            self.pending = []
            return None
        drawn_scene, drawn = s.frames.drawn_materials or (None, {})
        # the same scene with materials edited (another scene, e.g. a lecture step, is never
        # mixed with what was drawn before: it is drawn itself, untraced or with stand-ins)
        before = {n: drawn.get(n) for n in missing} if drawn_scene is s.scene else {}
        out, how = None, "drawn as before until ready"
        if before and all(p is not None for p in before.values()):
            held = dataclasses.replace(s.scene, materials={**s.scene.materials, **before})
            if all(k in progs for k in s.renderer.forward_keys(held, raytrace=rt_held).values()):
                out = held
        if out is None and not stale and drawn_scene is s.scene:
            out = KEEP_IMAGE  # the same scene seen the same way: the view shown stays
        if out is None and traced:
            untraced = s.renderer.forward_keys(s.scene, raytrace=False)
            beside = rid_flat is not None and ca.answered(rid_flat) and getattr(ca, "done", {}).get(rid_flat, {}).get("ok")
            if beside:  # compiled beside: the driver's cache has them, the tables come along
                for n in untraced:
                    data = ca.tables.get(params_key(s.scene.materials[n]))
                    if data is not None and not tables.ready(s.scene.materials[n]):
                        tables.adopt(s.scene.materials[n], data)
            if beside or all(untraced[n] in progs and (not needs_tables(s.scene.materials[n])
                                                       or tables.ready(s.scene.materials[n])) for n in untraced):
                out, how = UNTRACED, "drawn untraced until ready"
        if out is None:  # another scene: its own objects, the materials not ready as stand-ins
            out, how = self.stand_in(missing), "drawn with grey stand-ins until ready"
            self.awaiting_flat = rid_flat
        # the frame the note is about (Session.message_true): the form drawn, or the one kept
        if out is UNTRACED:
            form = "untraced"
        elif out is KEEP_IMAGE:
            form = getattr(s.frame_source, "form", "own")
        else:
            form = "stand-in" if getattr(out, "stand_in", False) else "held"
        if self.awaiting != rid or self.noted != (rid, form):  # a new request, or drawn another way now
            s.notify(f"compiling {', '.join(missing)} in the background: {how}", frame=(s.scene, form))
            self.noted = (rid, form)
        self.awaiting = rid
        self.pending = missing
        return out

    def ask_beside(self, scene):
        """Ask the compile-ahead child for ``scene``'s programs with the session's scene's
        urgency, before the rest of its requests (the view waits for them: ``scene`` is the form
        it shows meanwhile); the same request as before for the same scene. Its id, or None
        without a child."""
        ca = self.child
        if ca is None or not ca.alive:
            return None
        return ca.request(scene, urgent=True, batch=self._batch_for(self.session.scene), lead=True,
                          text=self.scene_text(scene))

    def _batch_for(self, scene) -> int:
        """The compile-ahead batch of ``scene`` as it is now: a new one (higher) for another
        scene or other materials than the last asked for."""
        key = (id(scene), tuple(map(id, scene.materials.values())))
        if key != self._batch[0]:
            self._batch = (key, self._batch[1] + 1)
        return self._batch[1]

    def scene_text(self, scene) -> str:
        """``scene``'s text for the compile-ahead child, written once per scene object and state
        (the session's ``edits``): ``held_back`` asks for the shown scene's programs every frame
        while they compile, and writing the gallery's text takes 15-20 ms."""
        from viewer.scene import scene_to_toml

        key = (id(scene), self.session.edits)
        hit = self._texts.get(key)
        if hit is None or hit[0] is not scene:
            hit = (scene, scene_to_toml(scene, absolute_paths=True))
            self._texts = {k: v for k, v in list(self._texts.items())[-7:] if k[1] == key[1]}
            self._texts[key] = hit
        return hit[1]

    def untraced_copy(self, scene):
        """``scene`` with its traced chains off (the same copy while the scene is the same)."""
        if self._flat is None or self._flat[0] is not scene:
            self._flat = (scene, dataclasses.replace(scene, render=dataclasses.replace(scene.render, raytrace=False)))
        return self._flat[1]

    def stand_in(self, missing, scene=None):
        """The scene (``scene``, else the session's) with ``missing`` materials as grey Lambert
        stand-ins (``STAND_IN_ALBEDO``): its own objects, drawn with the cheapest program there
        is (compiled beside ahead of the scene when it is the next lecture step's, else here:
        a fraction of what the missing ones cost) while theirs compile beside."""
        from viewer import brdf

        scene = self.session.scene if scene is None else scene
        grey = brdf.get("lambert").params(albedo=[STAND_IN_ALBEDO] * 3)
        out = dataclasses.replace(scene, materials={**scene.materials, **{n: grey for n in missing}})
        out.stand_in = True  # FrameSource.form "stand-in"
        return out

    def _missing(self, scene) -> list[str]:
        """The materials of ``scene`` whose programs the window's renderer has not built."""
        progs = self.session.renderer.programs
        return [n for n, k in self.session.renderer.forward_keys(scene).items() if k not in progs]

    @property
    def warming(self) -> bool:
        """Idle-time warm-up still to do on this thread: models to compile (no compile-ahead
        child), or presets still to send to the child (one per ``warm_one``)."""
        if self.on:
            if not self.presets_ahead or self._ahead_sent == []:
                return False
            return self.child is None or self.child.alive
        return bool(self.warm)

    @property
    def warms_beside(self) -> bool:
        """The idle-time warm-up goes to the compile-ahead child (a preset's scene sent per step,
        no frame needed), not compiled on this thread."""
        return self.on

    def warm_one(self) -> None:
        """Compile one model's forward program while idle, so switching models later does not
        wait for the shader compiler (software GL compiles take 0.1-0.5 s each). With the
        compile-ahead child: ask it once for the scene's presets on its first material instead,
        and nothing compiles here. Only once the view is finished: never in a frame that still
        prepares, tiles or refines it (one preset's scene text for the child takes 20-30 ms for
        the gallery; a model compiled here, far more)."""
        from viewer import brdf

        s = self.session
        if s.dirty or s.quality != "full" or s.refining:
            return
        if self.on:
            if self.presets_ahead:
                self._warm_presets_ahead()
            return
        if not self.warm:
            return
        name = self.warm.pop(0)
        try:
            s.renderer.forward_program(brdf.get(name).params())
        except ViewerError as e:
            s.notify(str(e), error=True)

    def ask_ahead(self, step: int) -> None:
        """Lecture ``step``'s programs, compiled beside before it is shown, in the order it needs
        them: the grey stand-ins of the materials this window has no programs for (its first
        frame, drawn at once), its untraced programs (a traced step), its own."""
        from viewer.scene.lecture import tour_scene

        self._next = None
        ca = self.worker()
        if ca is not None:
            try:
                scene = tour_scene(step)
            except ViewerError:
                return  # the step reports its own problem when it opens
            missing = self._missing(scene)  # as held_back finds them when the step is shown
            if missing:
                self._next = (step, self.stand_in(missing, scene))
                ca.request(self._next[1], urgent=False, ahead=True)
            if self.session.renderer.traces(scene):  # its untraced programs first, as when it is shown
                flat = dataclasses.replace(scene, render=dataclasses.replace(scene.render, raytrace=False))
                ca.request(flat, urgent=False, ahead=True)
            ca.request(scene, urgent=False, ahead=True)

    def _warm_presets_ahead(self) -> None:
        """The presets the material picker offers, each on the scene's first non-plane object,
        sent to the compile-ahead child behind any urgent request, one per idle frame (writing
        a scene's text takes milliseconds)."""
        from viewer.brdf.presets import PRESETS
        from viewer.scene import material_from_name

        s = self.session
        if self._ahead_sent is False:
            self._ahead_sent = sorted(PRESETS)
        if not self._ahead_sent:
            return
        preset = self._ahead_sent.pop(0)
        ca = self.worker()
        objs = [o for o in s.scene.objects if o.mesh != "plane"] or s.scene.objects
        if ca is None or not objs:
            self._ahead_sent = []
            return
        try:
            params = material_from_name(preset)
        except ViewerError:
            return
        name = objs[0].material
        ca.request(dataclasses.replace(s.scene, materials={**s.scene.materials, name: params}), urgent=False)
