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

Protocol: one JSON object per line. In: ``{"id", "scene" (TOML text), "base_dir", "urgent"}``.
Out: ``{"working": id}`` after each kind of frame drawn for a request, then ``{"id", "ok": true,
"keys": [program keys compiled], "tables": {params JSON: exported tables}, "seconds"}`` or
``{"id", "ok": false, "error"}``.
"""

from __future__ import annotations

import collections
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


def serve(inp=sys.stdin, out=sys.stdout) -> int:
    """The child: read requests, urgent ones first, and answer each on one line."""
    from viewer.gl.context import create_offscreen_context
    from viewer.gl.renderer import Renderer
    from viewer.scene import load_scene_text

    queue: collections.deque = collections.deque()
    cond = threading.Condition()
    closed = []

    def read():
        for line in inp:
            try:
                req = json.loads(line)
            except ValueError:
                continue
            with cond:
                if req.get("urgent"):
                    queue.appendleft(req)
                else:
                    queue.append(req)
                cond.notify()
        with cond:
            closed.append(True)
            cond.notify()

    threading.Thread(target=read, name="compile-ahead-reader", daemon=True).start()
    ctx = create_offscreen_context()
    renderer = Renderer(ctx)
    echo = []  # the second renderer, made after the first request's programs are in Mesa's cache

    def echo_renderer():
        if not echo:
            echo.append(Renderer(ctx))
        return echo[0]
    print(json.dumps({"ready": True}), file=out, flush=True)
    while True:
        with cond:
            while not queue and not closed:
                cond.wait()
            if not queue:
                break
            req = queue.popleft()
        t0 = time.perf_counter()
        try:
            scene = load_scene_text(req["scene"], base_dir=req.get("base_dir"), label="<compile ahead>")
            # a line after each kind of frame: a child at work on a long request (a traced
            # scene on a loaded machine) is not taken for a silent one and replaced
            working = json.dumps({"working": req["id"]})
            answer = {"id": req["id"], "ok": True,
                      **prepare(renderer, scene, echo_renderer, lambda: print(working, file=out, flush=True))}
        except Exception as e:  # noqa: BLE001 - the window compiles it itself and reports the error
            answer = {"id": req["id"], "ok": False, "error": f"{type(e).__name__}: {str(e).splitlines()[0] if str(e) else ''}"}
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

    def request(self, scene, urgent: bool = True) -> int | None:
        """Ask for ``scene``'s programs and tables; the request's id (the earlier one for a scene
        already asked for), None when the child is not running."""
        from viewer.scene import scene_to_toml

        if not self.alive:
            return None
        text = scene_to_toml(scene, absolute_paths=True)
        base = None if scene.base_dir is None else str(scene.base_dir)
        with self._lock:
            key = f"{base}\n{text}"
            if key in self._ids:
                return self._ids[key]
            rid = self._ids[key] = self._next
            self._next += 1
        try:
            if not self._sent:  # given work after waiting idle: its silence starts now
                self._silence.heard(self._proc.pid)
            self._sent[rid] = time.monotonic()
            self._proc.stdin.write(json.dumps({"id": rid, "scene": text, "base_dir": base, "urgent": urgent}) + "\n")
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
