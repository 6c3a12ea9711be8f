"""Compile a changed material's programs beside the window, so that a preset or model change never
stops the window's frames while the shader compiler works (on a software rasterizer a program
takes 0.1-6 s: the GLSL link and llvmpipe's code generation at the first draw).

A child process (``python -m viewer.app.compile_ahead [--nice N]``), on its own headless
OpenGL context (EGL), draws each scene the window sends it at a tiny size in every kind
of frame the window draws (``window_frames``: the view while dragged, the raster frame whole and
in tiles over its quarter-resolution preview, a traced scene's mask and traced tiles, with the
window's own ``ProgressiveTrace``), because llvmpipe makes a program's machine code at its first
draw for the state in use (sample count, a scissor, which frame-sized texture is bound) and
keys its on-disk cache (Mesa's) by that state. It draws them twice: with a renderer whose
programs it compiles, then with a second renderer (``prepare``'s ``echo``) whose programs link
from Mesa's cache, as the window's then do, each kind of frame on programs linked anew
(``relink_scene_programs``): llvmpipe keys the code a program's draw makes in a new state by how
its earlier code in that process came about (made there, or read from the cache, as the window's
is), and the window's first draw finds its code in the cache only when the child drew a program
whose history is the window's. The
window's own compile and first draw of the same program afterwards are then cache hits; and it builds the
materials' albedo tables and multiple-scattering terms, which it sends back for the window to
adopt (``MaterialTables.adopt``) instead of building them itself. A process, not a thread: a GL
call holds the interpreter lock for its whole duration.

The window keeps drawing the material as it was until the child reports the new one done
(``Session`` does the holding back), or until the child has been silent for ``LEASH_S`` seconds (``viewer.app.prefetch``)
with work outstanding: then it is replaced and the window compiles the change itself. Requests marked ``urgent`` (the material just changed) go
before the compile-ahead of the scene's presets. Without a driver cache (a driver that keeps
none, or ``MESA_SHADER_CACHE_DISABLE``) the window still compiles the program itself, after
the child's tables, and the frames of that compile are as long as before. A child that ends by
itself after it was ready (a crash in the driver, a kill from outside) is started again,
``RESTARTS`` times at most, with a notice; what it held is compiled by the window. Any other
failure of the child that serves the scene shown (no EGL, a child that cannot start, the last
restart ended too) turns compile-ahead off with ``error`` set: the window then compiles as it
always did; a failure of the other stops only the work ahead.

Two such children run (``CompileAhead``): one for the scene the window shows, at the window's own
priority, and one for the next lecture step and the warm-up, at niceness ``AHEAD_NICE`` above it
(started with its first request), behind the window's frames. One child at a lower priority for
all of it got a tenth of a core beside two busy processes on two cores, and the scene shown (a
traced lecture step, ~10 CPU s of llvmpipe's) stayed on its stand-ins for 30-100 s; and a
process cannot lower its niceness again, so one child cannot serve both. A request sent ahead
and then shown goes to both under one id: the first answer counts, and the other child is told
to drop it. Once nothing is outstanding both children block on their pipes.

The order of a child's work: the scene the window shows first (``URGENT``; of those, the
latest scene shown first, and a scene's requests in the order sent: a traced scene's untraced
copy, which lets the window draw its real materials untraced, before its traced programs),
then the next lecture step's (``AHEAD``), then the idle-time warm-up's (``IDLE``). A request
asked for again with a higher priority (a warm-up scene that is the next step's, a scene shown
again later) moves up its child's queue; and a
request of lower priority than one waiting is put back after the kind of frame it is drawing
(what it drew stays in Mesa's cache), so the scene shown never waits behind the warm-up (the
urgent child only ever holds the scene shown; the ahead child the next step and the warm-up). The
children's renderers draw the environment light with the quick prefilter the window draws with
(``viewer.gl.ibl.IBL.defer``): the full prefilter is the background prefilter's work
(``viewer.app.prefetch``), and it would hold the answer back by seconds.

Protocol: one JSON object per line. In: ``{"id", "scene" (TOML text), "base_dir", "priority":
[tier, batch, lead]}`` (tier ``URGENT``, ``AHEAD`` or ``IDLE``; a higher batch is a later scene
shown; lead 1: the form the view shows while it waits, before the rest of its batch),
``{"promote": id, "priority"}`` or ``{"drop": id}`` (answered by the other child: out of the
queue if it waits). Out: ``{"working": id}`` after each kind of frame
drawn for a request, then ``{"id", "ok": true, "keys": [program keys compiled], "tables":
{params JSON: exported tables}, "seconds"}`` or ``{"id", "ok": false, "error"}``.
"""

from __future__ import annotations

import json
import os
import queue
import subprocess
import sys
import threading
import time

from viewer.app.prefetch import Silence, leash_seconds

#: the child's frames: small, and no side (nor its half or quarter, the drag's and the preview's)
#: a power of two, as a window's view's rarely is: llvmpipe's code for a program that samples a
#: frame-sized texture (absorbers' thickness, SSR) depends on whether its sides are
SIZE = (72, 52)
URGENT, AHEAD, IDLE = 2, 1, 0  # a request's tier: the scene shown, the next lecture step, the warm-up
TILE_ROWS = 4  # the first raster tile's rows: a part of the frame, drawn under a scissor as the window's


def params_key(params) -> str:
    """The key tables travel under: the parameter values (``MaterialTables``' own key)."""
    return json.dumps(params.to_plain(), sort_keys=True)


def window_frames(renderer, scene, size=SIZE, progress=None, before_each=None) -> list[tuple]:
    """Draw ``scene`` on ``renderer`` in every kind of frame the window's view draws it
    (``viewer.app.view_frames``): while dragged (half the size, no MSAA, a traced scene
    untraced), whole, in tiles over its quarter- and half-resolution previews (the first tile
    a part of the frame, under a scissor), and for a scene traced in strips its untraced frame,
    traced mask and traced tiles (half then full resolution, no MSAA). The window's own
    ``ProgressiveTrace`` draws the tiles, so their state is the window's. Returns the kinds drawn
    [(kind, sample count asked (None: the scene's), traced chains (None: the scene's))];
    ``progress()`` is called after each (the child says it is working), ``before_each()``
    before each (and once after the last)."""
    from viewer.app.frame_mean import frames_wanted
    from viewer.gl.raytrace import ProgressiveTrace

    w, h = size
    r = scene.render
    progressive = renderer.traces(scene) and not r.ssr and r.ibl != "brute_force"
    untraced = False if progressive else None
    done = []

    def did(kind):
        done.append(kind)
        if progress is not None:
            progress()
        if before_each is not None:
            before_each()

    if before_each is not None:
        before_each()

    renderer.render(scene, width=(w + 1) // 2, height=(h + 1) // 2, msaa=0, raytrace=untraced)
    did(("drag", 0, untraced))
    renderer.render(scene, width=w, height=h, raytrace=untraced)
    did(("whole", None, untraced))
    if not r.ssr and frames_wanted(scene) == 1:  # the frames the window may draw in tiles
        for scale in (4, 2):
            pt = ProgressiveTrace(renderer.ctx)
            pt.cull = False  # every object's program drawn under a scissor, wherever it lies
            # the window's view is prepared before it tiles (``ViewPrep``), so its quarter-
            # resolution preview is drawn without MSAA (``msaa_made``): drawn with it here, that
            # preview's code was made on the window's thread (0.4-1 s a program, cold)
            pt.msaa_made = True
            try:
                pt.start(renderer, scene, None, w, h, traced=False, rows=TILE_ROWS, max_pixels=w * h,
                         preview_scale=scale)
                pt.step(0.0)  # one tile: the top rows
                pt.finish()
            finally:
                pt.release()
            did((f"tiles over a 1/{scale} preview", None, False))
    if progressive:
        pt = ProgressiveTrace(renderer.ctx)
        pt.cull = False
        try:
            pt.start(renderer, scene, None, w, h, rows=TILE_ROWS)
            pt.step(0.0)
            pt.finish()
        finally:
            pt.release()
        did(("traced tiles", 0, None))
    return done


def prepare(renderer, scene, echo=None, progress=None) -> dict:
    """Draw ``scene`` as the window does (``window_frames``) on ``renderer`` and export the
    albedo tables of its materials: the child's work for one request. ``echo``: a second
    renderer (or a function that makes it once ``renderer`` has drawn), whose programs link from
    Mesa's cache as the window's do, draws the same frames with the tables adopted as the window
    adopts them (see the module's text). ``progress``: see ``window_frames``."""
    window_frames(renderer, scene, progress=progress)
    keys = set(renderer.forward_keys(scene).values())
    keys |= set(renderer.forward_keys(scene, raytrace=False).values())
    renderer.ctx.finish()
    used = dict.fromkeys(o.material for o in scene.objects)
    tables = {params_key(scene.materials[n]): renderer.tables.export(scene.materials[n]) for n in used}
    if echo is not None:
        echo = echo() if callable(echo) else echo
        for n in used:
            echo.tables.adopt(scene.materials[n], tables[params_key(scene.materials[n])])
        window_frames(echo, scene, progress=progress, before_each=lambda: relink_scene_programs(echo, scene))
        echo.ctx.finish()
    return {"keys": sorted(keys), "tables": tables}


def relink_scene_programs(renderer, scene) -> list[str]:
    """Link again, from Mesa's cache, the programs of ``renderer`` that a frame of ``scene``
    draws (its forward programs, traced and untraced, and the passes'); the keys relinked. On
    llvmpipe (Mesa 22.3) the code a program's draw makes in a new state is keyed by what the
    program's earlier draws in this process made: a program whose code for one state was made
    (not read from the cache) gets another key for its next state than one whose earlier code
    was all read from the cache, as the window's is once the child made it. So the echo
    draws each kind of frame on programs linked anew: a window process that then drew the
    gallery in every kind of frame made no new code (it made 6 programs' code for the traced
    tiles again, 2.2 s of its thread, while the echo drew every kind on the same programs)."""
    renderer.ctx.finish()
    forward = set(renderer.forward_keys(scene).values()) | set(renderer.forward_keys(scene, raytrace=False).values())
    keys = [k for k in renderer.program_keys() if not k.startswith("forward:") or k in forward]
    return renderer.relink_programs(keys)


class Preempted(Exception):
    """A request of higher priority came in while this one was drawn: put back, done later."""


def _rank(req) -> tuple:
    """The order of the queue: the highest priority (tier, batch, then a request the view waits
    for before the rest of its batch), then the earliest request."""
    tier, batch, *lead = req["priority"]
    return (int(tier), int(batch), int(lead[0]) if lead else 0, -int(req["id"]))


class WorkQueue:
    """The child's requests waiting and the one being drawn, in the order of the module's text:
    ``put`` (a request, ``{"promote": id, "priority"}``: a higher priority for a request
    waiting or being drawn, or ``{"drop": id}``: a request waiting taken out), ``take`` (the next request, blocking; None once ``close``d and
    empty), ``check`` (raises ``Preempted`` when a request waiting outranks the one drawn),
    ``put_back`` (the one drawn, preempted), ``finished``."""

    def __init__(self):
        self._waiting: list = []
        self._current = None
        self._closed = False
        self._cond = threading.Condition()

    def put(self, req: dict) -> None:
        with self._cond:
            if "promote" in req:
                for r in self._waiting + ([self._current] if self._current else []):
                    if r["id"] == req["promote"] and _rank({**r, "priority": req["priority"]}) > _rank(r):
                        r["priority"] = req["priority"]
            elif "drop" in req:  # answered by the other child: not drawn here (one being drawn finishes)
                self._waiting = [r for r in self._waiting if r["id"] != req["drop"]]
            elif {"id", "scene", "priority"} <= set(req):
                self._waiting.append(req)
            self._cond.notify()

    def close(self) -> None:
        with self._cond:
            self._closed = True
            self._cond.notify()

    def take(self) -> dict | None:
        with self._cond:
            while not self._waiting and not self._closed:
                self._cond.wait()
            if not self._waiting:
                return None
            self._current = max(self._waiting, key=_rank)
            self._waiting.remove(self._current)
            return self._current

    def check(self) -> None:
        with self._cond:
            if self._current is not None and self._waiting and \
                    max(_rank(r) for r in self._waiting) > _rank(self._current):
                raise Preempted()

    def put_back(self) -> None:
        with self._cond:
            if self._current is not None:
                self._waiting.append(self._current)
            self._current = None

    def finished(self) -> None:
        with self._cond:
            self._current = None


def child_renderer(ctx):
    """A renderer of the child's: its environment light drawn with the quick prefilter the
    window draws a map with until the disk cache holds the full one (``IBL.defer``), so that the
    child compiles what the window will draw and never spends seconds on a full prefilter."""
    from viewer.gl.renderer import Renderer

    r = Renderer(ctx)
    r.ibl().defer = True
    return r


def serve(inp=sys.stdin, out=sys.stdout) -> int:
    """The child: read requests, the most urgent first (see the module's text), and answer each
    on one line."""
    from viewer.gl.context import create_offscreen_context
    from viewer.scene import load_scene_text

    work = WorkQueue()

    def read():
        for line in inp:
            try:
                work.put(json.loads(line))
            except (ValueError, KeyError, TypeError):
                continue
        work.close()

    threading.Thread(target=read, name="compile-ahead-reader", daemon=True).start()
    ctx = create_offscreen_context()

    from viewer.app.driver_cache import CacheWriters

    writers = CacheWriters()
    renderer = child_renderer(ctx)
    echo = []  # the second renderer, made after the first request's programs are in Mesa's cache

    def echo_renderer():
        if not echo:
            echo.append(child_renderer(ctx))
        return echo[0]
    print(json.dumps({"ready": True}), file=out, flush=True)
    while (req := work.take()) is not None:
        t0 = time.perf_counter()
        # a line after each kind of frame: a child at work on a long request (a traced scene
        # on a loaded machine) is not taken for a silent one and replaced; and the point where
        # a request of higher priority takes its turn
        working = json.dumps({"working": req["id"]})

        def progress():
            print(working, file=out, flush=True)
            work.check()
        try:
            scene = load_scene_text(req["scene"], base_dir=req.get("base_dir"), label="<compile ahead>")
            answer = {"id": req["id"], "ok": True, **prepare(renderer, scene, echo_renderer, progress)}
            # answered once what it made is in the driver's cache, not queued for it (a lowest-
            # priority thread's work: seconds behind on a loaded machine); heard meanwhile
            writers.wait(progress=lambda: print(working, file=out, flush=True))
        except Preempted:
            work.put_back()
            continue
        except Exception as e:  # noqa: BLE001 - the window compiles it itself and reports the error
            answer = {"id": req["id"], "ok": False, "error": f"{type(e).__name__}: {str(e).splitlines()[0] if str(e) else ''}"}
        work.finished()
        answer["seconds"] = round(time.perf_counter() - t0, 3)
        print(json.dumps(answer), file=out, flush=True)
    for e in echo:
        e.release()
    renderer.release()
    ctx.release()
    return 0


#: the children's niceness, added to the window's: the scene shown at the window's own priority
#: (at nice 10 beside two busy processes on two cores a child got a tenth of a core, and a traced
#: step's ~10 CPU s took 30-100 s), the next step's and the warm-up's behind the window's frames
URGENT_NICE, AHEAD_NICE = 0, 10
#: how many times a child that ended by itself after it was ready is started again, per child
RESTARTS = 3


class _Child:
    """One of ``CompileAhead``'s processes: ``nice`` (its niceness over the window's), the
    requests sent to it and not answered (``sent``: id -> when; ``priority``: id -> [tier,
    batch] as it knows them), its silence (the leash), its error once it ended."""

    def __init__(self, role: str, nice: int):
        self.role, self.nice = role, nice
        self.proc = None
        self.ready = False
        self.error = ""
        self.replaced = 0
        self.ended: list[str] = []  # why each of its processes that ended after it was ready ended
        self.sent: dict[int, float] = {}
        self.priority: dict[int, list] = {}
        self.silence = Silence()
        self.outbox = None  # the lines for its process, written by a thread of their own

    @property
    def pid(self) -> int | None:
        return None if self.proc is None else self.proc.pid

    def write(self, line: dict) -> None:
        """Queue ``line`` for the child's process; never waits. A child reads its input on a
        thread of its own, which cannot run while its main thread is in a GL call (the
        interpreter lock is held through it: seconds for a traced program's code at a low
        priority on a loaded machine), so its pipe fills: the gallery's forty presets' scene
        texts are 160 KB, the pipe holds 64 KB, and a write from the window's thread then
        waited seconds (a 5.4 s frame, with no CPU used in it)."""
        if self.outbox is None:
            raise OSError("not running")
        self.outbox.put(json.dumps(line) + "\n")

    @staticmethod
    def pump(proc, outbox) -> None:
        """The writer thread of one process: its queued lines in order, until the ``None`` that
        ``close`` queues (then its input is closed) or the process is gone."""
        while (text := outbox.get()) is not None:
            try:
                proc.stdin.write(text)
                proc.stdin.flush()
            except (OSError, ValueError):
                return  # it ended: its reader thread sees that and says why
        try:
            proc.stdin.close()
        except (OSError, ValueError):
            pass

    def close(self) -> None:
        """Close the process's input once the lines queued before are written (it then ends)."""
        if self.outbox is not None:
            self.outbox.put(None)


class CompileAhead:
    """The child processes and what they have done: ``compiled`` (program keys), ``tables``
    (params JSON -> exported tables), ``done`` (request ids answered, each with its first
    answer). ``on_done`` is called from a reader thread after each first answer (the window wakes
    its loop with it).

    Two children: the urgent one (the scene the window shows) at the window's own priority,
    started at once, and the ahead one (the next lecture step, the warm-up) at niceness
    ``AHEAD_NICE`` above it, started with the first such request. A process cannot lower its
    niceness again without privilege, so one child cannot serve both. A request sent ahead and
    then asked for as urgent (the next step, now shown) goes to the urgent child too, under the
    same id: the first answer counts, the other child is told to drop it (``{"drop": id}``: gone
    from its queue, or answered all the same if it was being drawn, an answer that changes
    nothing but what ``compiled`` and ``tables`` already hold). ``pid``, ``ready``, ``error``
    and ``alive`` are the urgent child's (``alive``: urgent requests can be served);
    ``ahead_pid`` the other's.

    Each child is on its own leash: when a request has waited ``leash`` seconds
    (``leash_seconds()``) with no word from the child holding it (a stopped, hung or swapped-out
    child), ``answered`` kills that child, answers the requests only it held with a failure (so
    the window compiles them itself), starts another in its place and passes a one-line notice to
    ``on_notice`` (the session's status line); the other child goes on. ``command``: the
    children's command line, to which ``--nice N`` is added (a stand-in in tests)."""

    def __init__(self, on_done=None, on_notice=None, command=None, leash: float | None = None):
        self.on_done = on_done
        self.on_notice = on_notice
        self.command = list(command or [sys.executable, "-m", "viewer.app.compile_ahead"])
        self.leash = leash_seconds() if leash is None else float(leash)
        self.compiled: set[str] = set()
        self.tables: dict[str, dict] = {}
        self.done: dict[int, dict] = {}
        self.states: dict[int, str] = {}  # request id -> its scene's drawing_state (viewer.app.driver_cache)
        self._lock = threading.Lock()
        self._next = 0
        self._ids: dict[str, int] = {}  # request text -> id (a scene asked for again is not redone)
        self._urgent = _Child("urgent", URGENT_NICE)
        self._ahead: _Child | None = None  # started with the first request of the next step or the warm-up
        self._stopping = False
        self._start(self._urgent)

    def _start(self, child: _Child) -> None:
        try:
            proc = subprocess.Popen(self.command + ["--nice", str(child.nice)], stdin=subprocess.PIPE,
                                    stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                                    env=dict(os.environ), cwd=os.getcwd())
        except OSError as e:
            child.error = f"cannot start ({e})"
            return
        child.proc, child.ready = proc, False
        child.silence = Silence(proc.pid)
        child.outbox = queue.SimpleQueue()
        threading.Thread(target=self._read, args=(child, proc, child.outbox),
                         name=f"brdf-viewer-compile-ahead-{child.role}", daemon=True).start()
        threading.Thread(target=_Child.pump, args=(proc, child.outbox),
                         name=f"brdf-viewer-compile-ahead-{child.role}-input", daemon=True).start()

    def _children(self) -> list[_Child]:
        return [c for c in (self._urgent, self._ahead) if c is not None]

    @property
    def pid(self) -> int | None:
        """The urgent child's process id (None: none started)."""
        return self._urgent.pid

    @property
    def ahead_pid(self) -> int | None:
        """The ahead child's process id (None: not started yet, or it could not start)."""
        return None if self._ahead is None else self._ahead.pid

    @property
    def ready(self) -> bool:
        """The urgent child has made its context and waits for work."""
        return self._urgent.ready

    @property
    def error(self) -> str:
        """Why the urgent child does not run ("" while it does)."""
        return self._urgent.error

    @property
    def replaced(self) -> int:
        """Children killed for silence, both kinds together."""
        return sum(c.replaced for c in self._children())

    @property
    def ended(self) -> list[str]:
        """Why each child process that ended by itself after it was ready ended (the urgent
        child's first), whether or not it was started again."""
        return [w for c in self._children() for w in c.ended]

    @property
    def alive(self) -> bool:
        """Urgent requests can be served (the ahead child's failure only stops the ahead work)."""
        return self._urgent.proc is not None and not self._urgent.error

    def request(self, scene, urgent: bool = True, batch: int = 0, ahead: bool = False,
                lead: bool = False, text: str | None = None) -> int | None:
        """Ask for ``scene``'s programs and tables; the request's id (the earlier one for a scene
        already asked for), None when the child it goes to is not running. ``urgent``: the scene
        the window shows (``batch``: a higher number for a later scene shown; its requests in the
        order sent, except that one marked ``lead``, the form the view shows while it waits for
        it, goes first), for the urgent child; else ``ahead``: the next lecture step's, or the
        idle-time warm-up's, for the ahead child. A scene asked for again with a higher priority,
        not answered yet, moves up its child's queue; one sent ahead and now urgent goes to the
        urgent child as well. ``text``: ``scene``'s text (``scene_to_toml`` with absolute paths),
        where the caller has it already."""
        from viewer.app.driver_cache import drawing_state
        from viewer.scene import scene_to_toml

        if not self.alive:
            return None
        if text is None:
            text = scene_to_toml(scene, absolute_paths=True)
        base = None if scene.base_dir is None else str(scene.base_dir)
        priority = [URGENT if urgent else AHEAD if ahead else IDLE, int(batch) if urgent else 0,
                    int(bool(lead and urgent))]
        with self._lock:
            key = f"{base}\n{text}"
            rid = self._ids.get(key)
            if rid is not None and rid in self.done:
                return rid
            child = self._urgent if urgent else self._ahead
            if rid is not None and child is not None and rid in child.sent:
                if tuple(priority) <= tuple(child.priority[rid]):
                    return rid
                child.priority[rid] = priority
                line = {"promote": rid, "priority": priority}
            elif rid is not None and not urgent:
                return rid  # the urgent child has it: a higher tier already
            else:
                if child is None:  # the first request of the next step or the warm-up
                    child = self._ahead = _Child("ahead", AHEAD_NICE)
                    self._start(child)
                if child.error:
                    return None
                if rid is None:
                    rid = self._ids[key] = self._next
                    self._next += 1
                if not child.sent:  # given work after waiting idle: its silence starts now
                    child.silence.heard(child.pid)
                child.sent[rid] = time.monotonic()
                child.priority[rid] = priority
                self.states[rid] = drawing_state(scene)
                line = {"id": rid, "scene": text, "base_dir": base, "priority": priority}
        try:
            child.write(line)
        except OSError as e:
            # its process ended: the reader thread that saw it end starts another or says why
            # it stays down; this request is made by the window
            with self._lock:
                if "id" in line and child.sent.pop(rid, None) is not None:
                    child.priority.pop(rid, None)
                    if not any(rid in c.sent for c in self._children()):
                        self.done.setdefault(rid, {"id": rid, "ok": False, "error": f"stopped ({e})"})
            return None
        return rid

    @property
    def outstanding(self) -> int:
        """Requests sent and not answered yet (0: both children have nothing to do and block on
        their pipes)."""
        with self._lock:
            return self._next - len(self.done)

    def answered(self, rid) -> bool:
        """The request ``rid`` was answered, or will not be (no urgent child, or every child
        holding it stayed silent past the leash and was replaced)."""
        if rid in self.done or not self.alive:
            return True
        # silent past the leash and not working (stopped, hung): replaced; a child still using
        # CPU is compiling (a traced program takes tens of seconds on a loaded machine), and
        # the window compiling it itself meanwhile would freeze its frames for as long
        for child in self._children():
            if rid in child.sent and child.silence.over(self.leash, child.pid):
                self._replace(child)
        return rid in self.done or not self.alive

    def _fail(self, child: _Child, why: str) -> None:
        """Answer the requests ``child`` held with a failure, but for those the other child
        holds too (it may still answer them)."""
        with self._lock:
            others = [c for c in self._children() if c is not child]
            for rid in list(child.sent):
                if not any(rid in c.sent for c in others):
                    self.done.setdefault(rid, {"id": rid, "ok": False, "error": why})
            child.sent.clear()
            child.priority.clear()

    def _replace(self, child: _Child) -> None:
        """Kill the silent ``child`` (SIGKILL: a stopped one too), fail what only it had, start
        another in its place."""
        old = child.proc
        self._fail(child, f"no answer within {self.leash:g} s")
        child.proc = None
        if old is not None and old.poll() is None:
            try:
                old.kill()
            except OSError:
                pass
            old.wait()
        child.replaced += 1
        self._start(child)
        if self.on_notice is not None:
            which = "" if child is self._urgent else " (the next step's and the warm-up's)"
            self.on_notice(f"the compile-ahead process{which} did not answer within {self.leash:g} s: "
                           f"restarted it; compiling here meanwhile")

    def _read(self, child: _Child, proc, outbox):
        try:
            self._read_lines(child, proc)
        finally:
            outbox.put(None)  # its writer thread ends too

    def _read_lines(self, child: _Child, proc):
        for line in proc.stdout:
            try:
                msg = json.loads(line)
            except ValueError:
                continue
            if proc is not child.proc:
                continue  # a replaced child's last words
            child.silence.heard(proc.pid)
            if msg.get("ready"):
                child.ready = True
                continue
            if "working" in msg or "id" not in msg:  # between the kinds of frame of a request: heard
                continue
            rid = msg["id"]
            with self._lock:
                if msg.get("ok"):  # a duplicate's programs and tables are the same: merged all the same
                    self.compiled.update(msg.get("keys", ()))
                    self.tables.update(msg.get("tables", {}))
                first = rid not in self.done
                if first:
                    self.done[rid] = msg
                child.sent.pop(rid, None)
                child.priority.pop(rid, None)
                others = [c for c in self._children() if c is not child and rid in c.sent]
                for c in others:  # answered: the other child need not draw it
                    c.sent.pop(rid, None)
                    c.priority.pop(rid, None)
            for c in others:
                try:
                    c.write({"drop": rid})
                except (OSError, ValueError, AttributeError):
                    pass  # it ended or is being replaced: nothing to drop
            if first and self.on_done is not None:
                self.on_done()
        err = proc.stderr.read()
        rc = proc.wait()
        if proc is not child.proc:
            return  # replaced: the new child carries on
        last = [x for x in err.strip().splitlines() if x.strip()]
        why = (last[-1] if last else f"exit status {rc}") if rc not in (0, -15) else "stopped"
        with self._lock:
            child.outbox = None  # a request from now on fails at once, not queued for the dead
            # a child that was serving and ended by itself (a crash in the driver, a kill from
            # outside) is started again, RESTARTS times at most: the window would otherwise make
            # every later program itself, frames of seconds; one that never got ready (no
            # context) would fail alike again, and one told to stop is not started again
            again = child.ready and not self._stopping and why != "stopped" and len(child.ended) < RESTARTS
            if child.ready and why != "stopped":
                child.ended.append(why)
        if not child.error and not again:
            child.error = why
        self._fail(child, why)  # what it held is compiled by the window, or by the other child
        if again:
            self._start(child)
            if self.on_notice is not None:
                which = "" if child is self._urgent else " (the next step's and the warm-up's)"
                self.on_notice(f"the compile-ahead process{which} ended ({why}): restarted it")
        if self.on_done is not None:
            self.on_done()

    def stop(self, timeout: float = 10.0) -> None:
        """End both children (a request half done is simply not answered)."""
        from viewer.app.prefetch import stop_child

        with self._lock:
            self._stopping = True
        children = self._children()
        for c in children:
            if c.proc is not None and c.proc.poll() is None:
                c.close()
        for c in children:
            stop_child(c.proc, timeout)
            c.error = c.error or "stopped"


def niceness(argv) -> int:
    """The niceness the child's command line asks for (``--nice N``, added to the window's;
    ``AHEAD_NICE`` when not said). ValueError, with one line to show, for anything else."""
    args = list(argv)
    if not args:
        return AHEAD_NICE
    if len(args) == 2 and args[0] == "--nice":
        try:
            n = int(args[1])
        except ValueError:
            n = -1
        if 0 <= n <= 19:
            return n
        raise ValueError(f"--nice takes a whole number from 0 to 19, not {args[1]!r}")
    raise ValueError(f"usage: python -m viewer.app.compile_ahead [--nice N] (got {' '.join(args)!r})")


def main(argv=None) -> int:
    try:
        nice = niceness(sys.argv[1:] if argv is None else argv)
    except ValueError as e:
        print(e, file=sys.stderr)
        return 2
    if nice:
        try:
            os.nice(nice)  # behind the window's own frames (the next step's, the warm-up's)
        except (OSError, AttributeError):
            pass
    try:
        return serve()
    except Exception as e:  # noqa: BLE001 - one line for the window's panel
        print(f"{type(e).__name__}: {str(e).splitlines()[0] if str(e) else ''}", file=sys.stderr)
        return 1


if __name__ == "__main__":
    sys.exit(main())
