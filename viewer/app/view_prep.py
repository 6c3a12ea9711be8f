"""The view's first frame of a scene, prepared over several frames: on software OpenGL the parts
a frame needs the first time (the DFG table, the environment light's textures, the materials'
tables, and above all each program's machine code, which llvmpipe generates at its first draw)
cost up to a second of the window's thread together. Where the view would draw a scene it has
not drawn yet (the session's first frame, another scene, a lecture step), ``ViewPrep`` makes
those parts one per frame instead, and the view meanwhile shows no image (never the last
scene's frame) under the label ``label`` gives: what is ready and what comes next. The parts:

* "the environment map" (a file read or a sky generated: numpy on a worker thread, the frames
  meanwhile make the other parts or wait);
* "the DFG table" (``viewer.gl.ibl.IBL.ensure_dfg``: the disk cache, else a GPU pass drawn a
  band of rows a frame);
* "the view's targets" (the HDR colour and depth targets at the view's size);
* "the environment map's mip chain" (``IBL.upload_map``: the map on the GPU and its mip chain);
* "the environment light" (``IBL.set_environment``: its prefilter, from the disk cache or made);
* "the tables of <material>" (``MaterialUniforms.prepare``: albedo tables, compensation terms),
  one material per frame;
* "the sky's program" (the background pass, drawn once into one pixel of the view's target);
* "the program of <materials>" (each forward program the frame lacks, drawn once into one
  pixel with the shadow and thickness passes it needs), one per frame;

then the frame itself, with every program drawn before. Where the compile-ahead child runs, a
program part the driver's cache does not hold yet (``viewer.app.driver_cache``) first waits
for it, asked for the scene as drawn before its other requests, until it answers: the child
draws the scene in every kind of frame the window draws, which puts the machine code of all
of them in Mesa's disk cache, and the window's first draws (this trial draw, the preview, the
tiles) read it. What is still to do is worked out from the renderer's state each
frame (``plan``), so a part another frame already made (the compile-ahead child's programs, a map
the disk cache now holds) is never made twice, and the label is the state's. The first frame of a
preparation makes nothing: it shows the placeholder at once. ``ViewPrep`` is held by
``viewer.app.view_frames.ViewFrames`` as ``frames.prep``; GL calls stay on the window's thread
(one context). No imgui, no glfw."""

from __future__ import annotations

import dataclasses

#: the FrameSource form of the view while it is prepared: no image shown
PREPARING = "preparing"
#: the seconds of parts one frame makes before it shows the placeholder (the frame goal): cheap
#: parts (a cached DFG table, targets, a material's tables) share a frame, so the view comes
#: about as soon as it did when the whole first frame was drawn at once
BUDGET_S = 0.15
#: the parts that end their frame (after cheap parts only: under an eighth of the budget): their
#: first draws make a program's code, a cost not known before (50-400 ms a program on llvmpipe,
#: even from the driver's cache; two programs in one frame made 0.6 s): a trial draw of the
#: scene's programs, the DFG table's pass, the environment map's mip chain and its prefilter
#: (cold, 0.1-0.2 s apiece; the DFG table, the view's targets and the mip chain in one frame
#: took 0.21 s of the window's thread, the mip chain and the prefilter together 0.3 s, 0.7 s
#: beside two busy processes); and the shadow atlas (every triangle from every shadowed light:
#: the gallery's took 0.28 s of its first preview frame beside two busy processes)
OWN_FRAME = ("dfg", "mips", "environment", "shadows", "program", "sky")
#: the rows of the DFG table one frame draws on a disk cache miss (of 32; its first frame links
#: the pass's program): on llvmpipe the 32x32 pass runs on one rasterizer thread, 80 ms quiet
#: for the whole table and half a second of its frame beside two busy processes
DFG_BAND_ROWS = 8
#: the one pixel of the view's target a part's trial draw covers (x, y, w, h)
PIXEL = (0, 0, 1, 1)


@dataclasses.dataclass(frozen=True)
class Part:
    """One part of the frame still to make: its ``name`` (as the label says it) and ``kind``
    ("map", "dfg", "targets", "mips", "environment", "shadows", "tables", "sky" or "program"); ``materials``: for
    tables or a program, the materials of the scene they are for."""
    name: str
    kind: str
    materials: tuple = ()


def _same(a, b) -> bool:
    """Two materials' parameters are the same values (``==`` on parameters holding arrays, such as
    two glasses' absorption colours, has no single truth value)."""
    return a is b or (type(a) is type(b) and a.to_plain() == b.to_plain())


class ViewPrep:
    """The preparation of ``session``'s view (``on``: the window's; off, every frame is drawn
    whole at once, as offscreen)."""

    def __init__(self, session, on: bool = False):
        self.session = session
        self.on = on
        self.budget_s = BUDGET_S   # 0: one part per frame
        self.scene = None     # the session's scene being prepared (None: none)
        self.done: list[str] = []  # the parts made for it, in order
        self.started = False  # its placeholder frame was shown
        self.drawn = None     # (scene as drawn, raytrace, size) of the last step: what the label plans
        self.waiting = None   # (part, request id): a program the compile-ahead child makes
        self.kept = None      # what the view shows meanwhile, where it keeps its image (words), else None
        self._maps: dict = {}  # id(environment) -> (environment, thread, [error]): its map's read
        # the programs (and "background", the sky's) drawn by this view, each in the drawing
        # states drawn (``viewer.app.driver_cache.entry``)
        self.made: set[str] = set()

    @property
    def active(self) -> bool:
        """The view shows the placeholder while the parts of its first frame are made."""
        return self.scene is not None

    def plan(self, drawn, raytrace=None, size=None) -> list[Part]:
        """The parts a frame of ``drawn`` (the scene as the view would draw it: the session's,
        or its grey stand-ins) at ``size`` (w, h) still lacks, in the order they are made (the
        environment map's read first: it runs beside the others)."""
        from viewer.app.driver_cache import drawing_state, entry
        from viewer.gl.ibl import holds as ibl_holds
        from viewer.gl.program_set import frame_switches

        r = self.session.renderer
        ibl = r.ibl()
        env = drawn.environment
        ssr_on, env_on = frame_switches(drawn, raytrace)[:2]
        out = []
        read = self._map_read(env)
        if env.map is not None and read is not True:
            out.append(Part("the environment map", "map"))
        if ibl.dfg_tex is None:
            job = ibl.dfg_job  # made a band of rows a frame
            out.append(Part("the DFG table" if job is None else f"the DFG table ({job.row} of {job.size} rows drawn)",
                            "dfg"))
        if size is not None and not ssr_on and not r.output.holds(size[0], size[1], drawn.render.msaa):
            out.append(Part("the view's targets", "targets"))
        env_map = env.radiance_map() if env.map is not None and read is True else None
        constant = None if env_map is not None else self._env_constant(drawn)
        if (env.map is not None and read is not True) or not ibl_holds(ibl, env_map, constant):
            # the map's mip chain a part of its own, the prefilter another: cold, each is mostly
            # llvmpipe making its program's code (0.15-0.2 s apiece); in one frame, 0.3 s of the
            # window's thread and 0.7 s beside two busy processes
            if read is True and not ibl.map_uploaded(env_map, constant):
                out.append(Part("the environment map's mip chain", "mips"))
            out.append(Part("the environment light", "environment"))
        if not r.shadows_ready(drawn):  # before the trial draws, each of which would draw it
            out.append(Part("the shadow maps", "shadows"))
        for name in dict.fromkeys(o.material for o in drawn.objects):
            one = dataclasses.replace(drawn, objects=[o for o in drawn.objects if o.material == name])
            if not r.material_uniforms.prepared(one, env_tables=ssr_on or env_on) \
                    and not any(p.kind == "tables" and _same(drawn.materials[p.materials[0]], drawn.materials[name])
                                for p in out):  # grey stand-ins share theirs
                out.append(Part(f"the tables of {name}", "tables", (name,)))
        # a program linked for another scene is made again where this scene's drawing state is
        # new to it: llvmpipe makes its code per state (``viewer.app.driver_cache``)
        state = drawing_state(drawn)
        if env.map is not None and not ssr_on and ("background" not in r.programs
                                                   or entry("background", state) not in self.made):
            out.append(Part("the sky's program", "sky"))
        keys = r.forward_keys(drawn, raytrace=raytrace)
        by_key: dict[str, list[str]] = {}
        for name, key in keys.items():
            if key not in r.programs or entry(key, state) not in self.made:
                by_key.setdefault(key, []).append(name)
        for names in by_key.values():
            out.append(Part(f"the program of {', '.join(names)}", "program", tuple(names)))
        return out

    @staticmethod
    def _env_constant(scene):
        import numpy as np

        env = scene.environment
        return np.zeros(3) if env.constant is None else np.asarray(env.constant, float) * env.intensity

    def needed(self, frame_source, drawn=None, raytrace=None) -> bool:
        """Whether the view's next frame is one a preparation may stand for: the session's scene
        is not the one the view shows (its first frame, another scene), or it is being prepared,
        or ``drawn`` (the form of the scene the view draws next: untraced after its grey
        stand-ins, a material edited) has a program this view never drew in its drawing state
        (``unmade``; the view then keeps its image while the parts are made)."""
        if not self.on:
            return False
        return (self.scene is not None or frame_source is None or frame_source.scene is not self.session.scene
                or (drawn is not None and self.unmade(drawn, raytrace)))

    def unmade(self, drawn, raytrace=None) -> bool:
        """A program of ``drawn`` (drawn with ``raytrace``) this view has not drawn in ``drawn``'s
        drawing state: its first draw would make (or read from the driver's cache, which on
        llvmpipe still builds the program's code: 50-400 ms a program) its code on this thread."""
        from viewer.app.driver_cache import drawing_state, entry

        state = drawing_state(drawn)
        keys = self.session.renderer.forward_keys(drawn, raytrace=raytrace)
        return any(entry(k, state) not in self.made for k in keys.values())

    def step(self, drawn, size, view_mode: int = 0, raytrace=None) -> bool:
        """One frame of the preparation of ``drawn`` at ``size`` (w, h): the placeholder first,
        then parts until one passes ``budget_s`` (at least one per frame). True: the view shows the placeholder this frame (a part was
        made, or none yet); False: nothing is left, the frame itself is drawn now."""
        s = self.session
        if self.scene is not s.scene:  # a new preparation (or another scene meanwhile)
            self.scene, self.done, self.started, self.waiting = s.scene, [], False, None
        self.drawn = (drawn, raytrace, size)
        todo = self.plan(drawn, raytrace, size)
        env = drawn.environment
        if env.map is not None and "the environment map" not in self.done and not any(p.kind == "map" for p in todo) \
                and id(env) in self._maps:  # read beside since the last frame: a part made
            self.done.append("the environment map")
        if todo and todo[0].kind == "map":
            self._read_map(drawn.environment)  # on a worker thread: the other parts meanwhile
            if not self.started or len(todo) == 1 or todo[1].kind in ("mips", "environment"):
                self.started = True
                return True   # waits for the map (the placeholder)
            todo = todo[1:]
        if not todo:
            self._made_all(drawn, raytrace)
            self.finish()
            return False
        if not self.started:  # the first frame: the placeholder alone, at once
            self.started = True
            return True
        import time

        t0, made = time.perf_counter(), 0
        while True:
            part = todo[0]
            if part.kind in OWN_FRAME and made and time.perf_counter() - t0 > self.budget_s / 8:
                return True  # after cheap parts only (a target, a material's tables: milliseconds)
            if part.kind in ("program", "sky") and self._beside(drawn, part, raytrace):
                return True  # the compile-ahead child makes it: the placeholder meanwhile
            if self._make(part, drawn, size, view_mode, raytrace) is False:
                return True  # a share of the part made (a band of the DFG table's rows): the rest next frame
            self._made(part, drawn, raytrace)
            self.done.append(part.name)
            made += 1
            if part.kind in OWN_FRAME or time.perf_counter() - t0 >= self.budget_s:
                return True
            todo = self.plan(drawn, raytrace, size)
            if not todo or any(p.kind == "map" for p in todo):
                return True   # the frame itself (or the map's wait) from the next frame on

    def _beside(self, drawn, part: Part, raytrace) -> bool:
        """Whether to wait for the compile-ahead child, asked for ``drawn`` before its other
        requests, to make ``part``'s program (or the sky's): until it answers, unless the driver's cache holds
        the program already (``CompileControl.in_driver_cache``: then the window's link and
        first draw read it, milliseconds) or there is no child. A child that stops or stays
        silent past its leash counts as answered (``CompileAhead.answered``): the part is then
        made here. Waiting no longer than a fixed time was tried: on a cold cache beside two
        busy processes the child rarely answered within it, and the window then made the code
        itself, 0.8-1.5 s frames."""
        s = self.session
        ca = s.compiles.child
        if ca is None or not ca.alive:
            return False
        keys = s.renderer.forward_keys(drawn, raytrace=raytrace)
        # the sky's program: held where the scene's programs are (the child drew it with them)
        if s.compiles.in_driver_cache([keys[n] for n in part.materials or keys], drawn):
            return False
        if self.waiting is None or self.waiting[0] != part.name:
            # a traced scene drawn untraced: its untraced copy, the request the view's held-back
            # frames ask for first too (the traced programs would take many times longer)
            untraced = raytrace is False and s.renderer.traces(drawn)
            rid = s.compiles.ask_beside(s.compiles.untraced_copy(drawn) if untraced else drawn)
            if rid is None:
                return False
            self.waiting = (part.name, rid)
        return not ca.answered(self.waiting[1])

    @property
    def waits_on_child(self) -> bool:
        """The placeholder stays until the compile-ahead child answers (``_beside``): the window's
        loop need not draw it again before then (its frames would take the CPU the child
        needs); the child's answer wakes the loop."""
        if self.scene is None or self.waiting is None:
            return False
        ca = self.session.compiles.child
        return ca is not None and not ca.answered(self.waiting[1])

    def _map_read(self, env):
        """True: ``env``'s map was read (or it has none); None: not asked yet; False: being
        read. A read that failed raises its error here (the frame then reports it)."""
        if env.map is None:
            return True
        job = self._maps.get(id(env))
        if job is None or job[0] is not env:
            return None
        if job[1].is_alive():
            return False
        if job[2]:
            raise job[2][0]
        return True

    def _read_map(self, env) -> None:
        """Read (or generate) ``env``'s map on a worker thread: ``radiance_map`` decodes it once
        and caches it on the environment, where the frames then find it."""
        import threading

        if self._map_read(env) is not None:
            return
        errors: list = []

        def read():
            try:
                env.radiance_map()
            except Exception as e:  # noqa: BLE001 - given to the window's thread, which reports it
                errors.append(e)

        t = threading.Thread(target=read, name="brdf-viewer-map-read", daemon=True)
        self._maps = {k: v for k, v in self._maps.items() if v[1].is_alive()}  # only those running
        self._maps[id(env)] = (env, t, errors)
        t.start()

    def _made(self, part: Part, drawn, raytrace) -> None:
        """``part``'s program (or the sky's) drawn in ``drawn``'s drawing state."""
        from viewer.app.driver_cache import drawing_state, entry

        if part.kind in ("program", "sky"):
            keys = self.session.renderer.forward_keys(drawn, raytrace=raytrace)
            state = drawing_state(drawn)
            self.made.update(entry(k, state) for k in ([keys[n] for n in part.materials] or ["background"]))

    def _made_all(self, drawn, raytrace) -> None:
        """Every program of ``drawn`` (and the sky's) is drawn in its drawing state from now on
        (its frame is drawn next)."""
        from viewer.app.driver_cache import drawing_state, entry

        state = drawing_state(drawn)
        keys = self.session.renderer.forward_keys(drawn, raytrace=raytrace)
        self.made.update(entry(k, state) for k in [*keys.values(), "background"])

    def trace_part(self, scene, size, view_mode) -> bool:
        """Before a traced view's tiles: each program a traced tile of ``scene`` draws (the traced
        chains' and the other materials'), drawn once into one pixel in the tiles' state (no
        MSAA, the traced frame's passes and textures) at ``size`` (the pass the tiles are at),
        one a frame. llvmpipe makes a program's code per drawing state, and a tile that met four
        programs new to that state took 0.7-1 s of the window's thread (the gallery traced,
        empty caches). True when this frame drew one; False once each is drawn."""
        from viewer.app.driver_cache import drawing_state, entry

        r = self.session.renderer
        tiles = dataclasses.replace(scene, render=dataclasses.replace(scene.render, msaa=0))
        state = drawing_state(tiles) + ";traced tiles"
        by_key: dict[str, list[str]] = {}
        for name, key in r.forward_keys(scene, raytrace=None).items():
            if entry(key, state) not in self.made:
                by_key.setdefault(key, []).append(name)
        if not by_key:
            return False
        key, names = next(iter(by_key.items()))
        r.render(scene, self.session.camera, size[0], size[1], view_mode, msaa=0, raytrace=None, region=PIXEL,
                 cull=False, only=tuple(names))
        self.made.add(entry(key, state))
        return True

    def finish(self) -> None:
        """The frame itself is drawn now (or the scene went): no preparation."""
        self.scene, self.done, self.started, self.drawn, self.waiting = None, [], False, None, None
        self.kept = None

    def _make(self, part: Part, drawn, size, view_mode, raytrace) -> bool | None:
        """Make ``part`` (False: only a share of it this frame, the rest in the next ones)."""
        r = self.session.renderer
        if part.kind == "dfg":
            return r.ibl().ensure_dfg(rows=DFG_BAND_ROWS)
        if part.kind == "targets":
            r.output.ensure(size[0], size[1], drawn.render.msaa)
        elif part.kind in ("mips", "environment"):
            env = drawn.environment
            env_map = env.radiance_map() if env.map is not None else None
            constant = None if env_map is not None else self._env_constant(drawn)
            if part.kind == "mips":
                r.ibl().upload_map(env_map, constant=constant)
            else:
                r.ibl().set_environment(env_map, constant=constant)
        elif part.kind == "shadows":
            r.draw_shadows(drawn)
        elif part.kind == "tables":
            from viewer.gl.program_set import frame_switches

            ssr_on, env_on = frame_switches(drawn, raytrace)[:2]
            one = dataclasses.replace(drawn, objects=[o for o in drawn.objects if o.material in part.materials])
            r.material_uniforms.prepare(one, env_tables=ssr_on or env_on)
        else:  # a trial draw into one pixel: the program is linked and its machine code made
            # the whole scene (its objects decide switches every program has, such as glass
            # shadows), with only the part's objects drawn, wherever they lie
            r.render(drawn, self.session.camera, size[0], size[1], view_mode, raytrace=raytrace, region=PIXEL,
                     cull=False, only=() if part.kind == "sky" else part.materials)

    def label(self) -> str:
        """What the view says while it is prepared: the parts ready and the one that comes next
        (planned from the state now, so it is true of the frame shown)."""
        if self.scene is None or self.drawn is None:
            return ""
        try:
            todo = self.plan(*self.drawn)
        except Exception:  # noqa: BLE001 - a map that failed: the next frame reports it
            todo = []
        n = len(self.done) + len(todo)
        nxt = f"; next: {todo[0].name}" if todo else "; the view comes next"
        if todo and self.waiting is not None and self.waiting[0] == todo[0].name:
            nxt += " (waiting for the background compile)"
        text = f"preparing the view: {len(self.done)} of {n} parts ready{nxt}"
        return text if self.kept is None else f"{self.kept}; {text}"
