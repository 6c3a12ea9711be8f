"""Compile a changed material's programs beside the window, so that a preset or model change never
stops the window's frames while the shader compiler works (on a software rasterizer a program
takes 0.1-6 s: the GLSL link and llvmpipe's code generation at the first draw).

A child process (``python -m viewer.app.compile_ahead``), at a lower priority and on its own
headless OpenGL context (EGL), draws each scene the window sends it at a tiny size in every kind
of frame the window draws (``window_frames``: the view while dragged, the raster frame whole and
in tiles over its quarter-resolution preview, a traced scene's mask and traced tiles, with the
window's own ``ProgressiveTrace``), because llvmpipe makes a program's machine code at its first
draw for the state in use (sample count, a scissor, which frame-sized texture is bound) and
keys its on-disk cache (Mesa's) by that state. It draws them twice: with a renderer whose
programs it compiles, then with a second renderer (``prepare``'s ``echo``) whose programs link
from Mesa's cache, as the window's then do: llvmpipe keys some of a program's machine code apart
for a program linked from that cache and one compiled afresh, and the window's first draw finds
its code in the cache only when the child drew a program linked as the window's is. The
window's own compile and first draw of the same program afterwards are then cache hits; and it builds the
materials' albedo tables and multiple-scattering terms, which it sends back for the window to
adopt (``MaterialTables.adopt``) instead of building them itself. A process, not a thread: a GL
call holds the interpreter lock for its whole duration.

The window keeps drawing the material as it was until the child reports the new one done
(``Session`` does the holding back), or until the child has been silent for ``LEASH_S`` seconds (``viewer.app.prefetch``)
with work outstanding: then it is replaced and the window compiles the change itself. Requests marked ``urgent`` (the material just changed) go
before the compile-ahead of the scene's presets. Without a driver cache (a driver that keeps
none, or ``MESA_SHADER_CACHE_DISABLE``) the window still compiles the program itself, after
the child's tables, and the frames of that compile are as long as before. Any failure of the child
(no EGL, a crash) turns it off with ``error`` set: the window then compiles as it always did.

The order of the child's work: the scene the window shows first (``URGENT``; of those, the
latest scene shown first, and a scene's requests in the order sent: a traced scene's untraced
copy, which lets the window draw its real materials untraced, before its traced programs),
then the next lecture step's (``AHEAD``), then the idle-time warm-up's (``IDLE``). A request
asked for again with a higher priority (the next step's scene, now shown) moves up; and a
request of lower priority than one waiting is put back after the kind of frame it is drawing
(what it drew stays in Mesa's cache), so the scene shown never waits behind the warm-up. The
child's renderers draw the environment light with the quick prefilter the window draws with
(``viewer.gl.ibl.IBL.defer``): the full prefilter is the background prefilter's work
(``viewer.app.prefetch``), and it would hold the answer back by seconds.

Protocol: one JSON object per line. In: ``{"id", "scene" (TOML text), "base_dir", "priority":
[tier, batch]}`` (tier ``URGENT``, ``AHEAD`` or ``IDLE``; a higher batch is a later scene
shown) or ``{"promote": id, "priority"}``. Out: ``{"working": id}`` after each kind of frame
drawn for a request, then ``{"id", "ok": true, "keys": [program keys compiled], "tables":
{params JSON: exported tables}, "seconds"}`` or ``{"id", "ok": false, "error"}``.
"""

from __future__ import annotations

import json
import os
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


def window_frames(renderer, scene, size=SIZE, progress=None) -> list[tuple]:
    """Draw ``scene`` on ``renderer`` in every kind of frame the window's view draws it
    (``viewer.app.view_frames``): while dragged (half the size, no MSAA, a traced scene
    untraced), whole, in tiles over its quarter- and half-resolution previews (the first tile
    a part of the frame, under a scissor), and for a scene traced in strips its untraced frame,
    traced mask and traced tiles (half then full resolution, no MSAA). The window's own
    ``ProgressiveTrace`` draws the tiles, so their state is the window's. Returns the kinds drawn
    [(kind, sample count asked (None: the scene's), traced chains (None: the scene's))];
    ``progress()`` is called after each (the child says it is working)."""
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

    renderer.render(scene, width=(w + 1) // 2, height=(h + 1) // 2, msaa=0, raytrace=untraced)
    did(("drag", 0, untraced))
    renderer.render(scene, width=w, height=h, raytrace=untraced)
    did(("whole", None, untraced))
    if not r.ssr and frames_wanted(scene) == 1:  # the frames the window may draw in tiles
        for scale in (4, 2):
            pt = ProgressiveTrace(renderer.ctx)
            pt.cull = False  # every object's program drawn under a scissor, wherever it lies
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
        window_frames(echo, scene, progress=progress)
        echo.ctx.finish()
    return {"keys": sorted(keys), "tables": tables}


class Preempted(Exception):
    """A request of higher priority came in while this one was drawn: put back, done later."""


def _rank(req) -> tuple:
    """The order of the queue: the highest priority, then the earliest request."""
    tier, batch = req["priority"]
    return (int(tier), int(batch), -int(req["id"]))


class WorkQueue:
    """The child's requests waiting and the one being drawn, in the order of the module's text:
    ``put`` (a request, or ``{"promote": id, "priority"}``: a higher priority for a request
    waiting or being drawn), ``take`` (the next request, blocking; None once ``close``d and
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


class CompileAhead:
    """The child process and what it has done: ``compiled`` (program keys), ``tables`` (params
    JSON -> exported tables), ``done`` (request ids answered). ``on_done`` is called from the
    reader thread after each answer (the window wakes its loop with it).

    The child is on a leash: when a request has waited ``leash`` seconds (``leash_seconds()``)
    with no word from the child (a stopped, hung or swapped-out child), ``answered`` kills it,
    answers its outstanding requests with a failure (so the window compiles them itself), starts
    a new child and passes a one-line notice to ``on_notice`` (the session's status line).
    ``command``: the child's command line (a stand-in in tests)."""

    def __init__(self, on_done=None, on_notice=None, command=None, leash: float | None = None):
        self.on_done = on_done
        self.on_notice = on_notice
        self.command = list(command or [sys.executable, "-m", "viewer.app.compile_ahead"])
        self.leash = leash_seconds() if leash is None else float(leash)
        self.compiled: set[str] = set()
        self.tables: dict[str, dict] = {}
        self.done: dict[int, dict] = {}
        self.error = ""
        self.ready = False
        self.replaced = 0               # children killed for silence
        self._lock = threading.Lock()
        self._next = 0
        self._ids: dict[str, int] = {}  # request text -> id (a scene asked for again is not redone)
        self._sent: dict[int, float] = {}  # unanswered request id -> when it was sent
        self._priority: dict[int, list] = {}  # request id -> [tier, batch] as the child knows it
        self._silence = Silence()  # the child's last word, and whether it works meanwhile
        self._proc = None
        self._start()

    def _start(self) -> None:
        try:
            proc = subprocess.Popen(self.command, stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                                    stderr=subprocess.PIPE, text=True, env=dict(os.environ), cwd=os.getcwd())
        except OSError as e:
            self.error = f"cannot start ({e})"
            return
        self._proc, self.ready = proc, False
        self._silence = Silence(proc.pid)
        threading.Thread(target=self._read, args=(proc,), name="brdf-viewer-compile-ahead", daemon=True).start()

    @property
    def pid(self) -> int | None:
        """The child's process id (None: none started)."""
        return None if self._proc is None else self._proc.pid

    @property
    def alive(self) -> bool:
        return self._proc is not None and not self.error

    def request(self, scene, urgent: bool = True, batch: int = 0, ahead: bool = False) -> int | None:
        """Ask for ``scene``'s programs and tables; the request's id (the earlier one for a scene
        already asked for), None when the child is not running. ``urgent``: the scene the window
        shows (``batch``: a higher number for a later scene shown; its requests in the order
        sent); else ``ahead``: the next lecture step's, or the idle-time warm-up's. A scene
        asked for again with a higher priority, not answered yet, moves up the child's queue."""
        from viewer.scene import scene_to_toml

        if not self.alive:
            return None
        text = scene_to_toml(scene, absolute_paths=True)
        base = None if scene.base_dir is None else str(scene.base_dir)
        priority = [URGENT if urgent else AHEAD if ahead else IDLE, int(batch) if urgent else 0]
        with self._lock:
            key = f"{base}\n{text}"
            rid = self._ids.get(key)
            if rid is not None:
                if rid in self.done or rid not in self._sent or tuple(priority) <= tuple(self._priority[rid]):
                    return rid
                self._priority[rid] = priority
                line = {"promote": rid, "priority": priority}
            else:
                rid = self._ids[key] = self._next
                self._next += 1
                self._priority[rid] = priority
                line = {"id": rid, "scene": text, "base_dir": base, "priority": priority}
        try:
            if "scene" in line:
                if not self._sent:  # given work after waiting idle: its silence starts now
                    self._silence.heard(self._proc.pid)
                self._sent[rid] = time.monotonic()
            self._proc.stdin.write(json.dumps(line) + "\n")
            self._proc.stdin.flush()
        except (OSError, ValueError) as e:
            self.error = f"stopped ({e})"
            return None
        return rid

    @property
    def outstanding(self) -> int:
        """Requests sent and not answered yet (0: the child has nothing to do and blocks on its
        pipe)."""
        with self._lock:
            return self._next - len(self.done)

    def answered(self, rid) -> bool:
        """The request ``rid`` was answered, or will not be (no child, or the child stayed silent
        past the leash and was replaced)."""
        if rid in self.done or not self.alive:
            return True
        # silent past the leash and not working (stopped, hung): replaced; a child still using
        # CPU is compiling (a traced program takes tens of seconds on a loaded machine), and
        # the window compiling it itself meanwhile would freeze its frames for as long
        if rid in self._sent and self._silence.over(self.leash, self.pid):
            self._replace()
            return True
        return False

    def _replace(self) -> None:
        """Kill the silent child (SIGKILL: a stopped one too), fail what it had, start another."""
        old = self._proc
        with self._lock:
            for rid in list(self._sent):
                self.done.setdefault(rid, {"id": rid, "ok": False, "error": f"no answer within {self.leash:g} s"})
            self._sent.clear()
        self._proc = None
        if old is not None and old.poll() is None:
            try:
                old.kill()
            except OSError:
                pass
            old.wait()
        self.replaced += 1
        self._start()
        if self.on_notice is not None:
            self.on_notice(f"the compile-ahead process did not answer within {self.leash:g} s: restarted it; "
                           f"compiling here meanwhile")

    def _read(self, proc):
        for line in proc.stdout:
            try:
                msg = json.loads(line)
            except ValueError:
                continue
            if proc is not self._proc:
                continue  # a replaced child's last words
            self._silence.heard(proc.pid)
            if msg.get("ready"):
                self.ready = True
                continue
            if "working" in msg:  # between the kinds of frame of a request: heard, nothing done yet
                continue
            with self._lock:
                if msg.get("ok"):
                    self.compiled.update(msg.get("keys", ()))
                    self.tables.update(msg.get("tables", {}))
                self.done[msg["id"]] = msg
                self._sent.pop(msg["id"], None)
            if self.on_done is not None:
                self.on_done()
        err = proc.stderr.read()
        rc = proc.wait()
        if proc is not self._proc:
            return  # replaced: the new child carries on
        if not self.error:
            last = [x for x in err.strip().splitlines() if x.strip()]
            self.error = (last[-1] if last else f"exit status {rc}") if rc not in (0, -15) else "stopped"
        if self.on_done is not None:
            self.on_done()

    def stop(self, timeout: float = 10.0) -> None:
        """End the child (a request half done is simply not answered)."""
        from viewer.app.prefetch import stop_child

        if self._proc is not None and self._proc.poll() is None:
            try:
                self._proc.stdin.close()
            except OSError:
                pass
        stop_child(self._proc, timeout)
        self.error = self.error or "stopped"


def main(argv=None) -> int:
    try:
        os.nice(10)  # behind the window's own frames
    except (OSError, AttributeError):
        pass
    try:
        return serve()
    except Exception as e:  # noqa: BLE001 - one line for the window's panel
        print(f"{type(e).__name__}: {str(e).splitlines()[0] if str(e) else ''}", file=sys.stderr)
        return 1


if __name__ == "__main__":
    sys.exit(main())
