"""What the driver's on-disk shader cache (Mesa's) holds of the viewer's forward programs, as far as
the window knows: the programs a compile-ahead child answered for (``viewer.app.compile_ahead``),
each drawn there in every kind of frame the window draws, so that the window's own first draws
of them read their machine code from that cache (milliseconds) instead of making it on the
window's thread (0.3-1 s a program on llvmpipe, over a second beside two busy processes).

The view's preparation (``viewer.app.view_prep``) asks it whether a program is held: if so, the
window makes the program itself at once; if not, it waits for the child's answer, showing the
placeholder, however long the child takes. Without this record every first frame would either
wait for the child (seconds on a warm cache, where the window's own draw costs milliseconds) or
not wait for it (a frozen second on a cold one).

The record is a JSON file in the viewer's cache folder, ``driver_programs.json``: the driver (its
renderer and version strings), the cache it is about (the path and inode of the cache's index
file: a cache removed and made anew is another, and the record starts empty again) and the
programs, each as its key and the scene's ``drawing_state``: llvmpipe makes a program's code for
the state it is drawn in, which holds more than the program (the sample count, and the kind of
texture at each of its units: the environment map's, the shadow atlas's, whose sizes differ
between scenes), so a program drawn in one scene is not held for another: the lecture's Lambert
floor under the studio map and a point light took 0.4 s of the window's thread after the same
program had been drawn under the sky with no light. It holds data only, is written atomically,
and a file that cannot be read is an empty record. Mesa's cache may still evict an entry the
record names; then the window makes that program itself, as it would have without the record.
No imgui, no glfw, no GL calls."""

from __future__ import annotations

import json
import os
from pathlib import Path

from viewer.base.io import atomic_write_bytes, cache_root

FILE = "driver_programs.json"
#: the most programs the record keeps (the latest): the presets of every model at a few switch
#: settings are a few hundred
MAX_ENTRIES = 4096
#: the largest record read (``MAX_ENTRIES`` of about 120 bytes is about 0.5 MB): a bigger file is
#: an empty record, never read into memory
MAX_BYTES = 2 ** 21


def shader_cache_index() -> Path | None:
    """The index file of the cache Mesa uses (``MESA_SHADER_CACHE_DIR``, else
    ``$XDG_CACHE_HOME/mesa_shader_cache``, else ``~/.cache/mesa_shader_cache``); None where the
    cache is off (``MESA_SHADER_CACHE_DISABLE``)."""
    if os.environ.get("MESA_SHADER_CACHE_DISABLE", "").strip().lower() in ("1", "true", "yes"):
        return None
    d = os.environ.get("MESA_SHADER_CACHE_DIR")
    if d:
        return Path(d).expanduser() / "index"
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return Path(base) / "mesa_shader_cache" / "index"


def cache_identity() -> str | None:
    """The cache the record is about: its index file's path and inode (None: none yet, or off)."""
    index = shader_cache_index()
    if index is None:
        return None
    try:
        return f"{index}#{index.stat().st_ino}"
    except OSError:
        return None


def drawing_state(scene) -> str:
    """What of ``scene`` besides a program's key decides the code llvmpipe makes for it: the sample
    count, the environment map (or a constant), the lights' kinds (the shadow atlas), whether an
    absorbing object makes the thickness pass (its texture at a unit every program reads) and
    the frame's switches."""
    from viewer.gl.program_set import absorbing

    r, env = scene.render, scene.environment
    lights = ",".join(sorted(str(light.type) for light in scene.lights))
    thick = any(absorbing(scene.materials[o.material]) for o in scene.objects)
    return (f"msaa={int(r.msaa)};env={env.map if env.map is not None else 'constant'};lights={lights};"
            f"absorbers={thick};shadows={bool(r.shadows)};ibl={r.ibl};ssr={bool(r.ssr)}")


def entry(key: str, state: str) -> str:
    """How the record names a program: its key and the ``drawing_state`` it was drawn in."""
    return f"{key}@{state}"


class DriverCacheRecord:
    """The record for ``driver`` (the GL renderer and version, e.g. from ``ctx.info``), read from
    ``path`` (default: the viewer's cache folder)."""

    def __init__(self, driver: str, path: Path | None = None):
        self.driver = str(driver)
        self.path = Path(path) if path is not None else cache_root() / FILE
        self.cache = cache_identity()
        self.entries: list[str] = self._read()
        self._held = set(self.entries)

    def _read(self) -> list[str]:
        if self.cache is None:
            return []
        try:
            if self.path.stat().st_size > MAX_BYTES:  # not one this viewer wrote: never read whole
                return []
            data = json.loads(self.path.read_text())
        except (OSError, ValueError):
            return []
        if not isinstance(data, dict) or data.get("driver") != self.driver or data.get("cache") != self.cache:
            return []
        out = data.get("programs")
        return [e for e in out if isinstance(e, str)][-MAX_ENTRIES:] if isinstance(out, list) else []

    def holds(self, keys, state: str) -> bool:
        """Every program of ``keys`` is in the driver's cache for ``state`` (``drawing_state``;
        as recorded)."""
        return bool(keys) and all(entry(k, state) in self._held for k in keys)

    def add(self, keys, state: str) -> None:
        """``keys`` drawn by a child in ``state`` in every kind of frame: now in the driver's
        cache. Written at once (a few kilobytes) when anything is new."""
        cache = cache_identity()
        if cache is None:  # no cache (off, or none written yet): nothing it could hold
            return
        if cache != self.cache:  # the cache was made anew: what the record said is gone
            self.cache, self.entries, self._held = cache, [], set()
        new = [entry(k, state) for k in dict.fromkeys(keys) if entry(k, state) not in self._held]
        if not new:
            return
        self.entries = (self.entries + new)[-MAX_ENTRIES:]
        self._held = set(self.entries)
        data = {"driver": self.driver, "cache": self.cache, "programs": self.entries}
        try:
            self.path.parent.mkdir(parents=True, exist_ok=True)
            atomic_write_bytes(self.path, json.dumps(data).encode())
        except OSError:
            pass  # a read-only cache folder: the record lives for this session only


class CacheWriters:
    """This process's shader-cache writers: the threads Mesa writes its on-disk cache with
    ("disk$N"), queued at the lowest priority (SCHED_BATCH, nice 19; a process without privilege
    cannot raise them). Beside two busy processes on two cores they got about 1 % of a core, and
    a program linked, or its machine code made, stayed unwritten for seconds: another process
    (or a link here) then found nothing in the cache and made it again. ``idle()`` tells when
    they are done: each asleep, its CPU time unchanged since the look before (at least
    ``QUIET_S`` earlier). Where /proc does not tell (not Linux), always idle."""

    QUIET_S = 0.02

    def __init__(self):
        self._last: dict[int, int] = {}  # writer thread id -> its CPU ticks at the last look
        self._at = 0.0

    @staticmethod
    def threads() -> list[int]:
        """The ids of this process's cache writer threads ([] where /proc does not tell)."""
        out = []
        try:
            for t in os.listdir("/proc/self/task"):
                with open(f"/proc/self/task/{t}/comm") as f:
                    if "disk$" in f.read():
                        out.append(int(t))
        except OSError:
            return []
        return out

    def idle(self) -> bool:
        """The writers have nothing left to write (see the class)."""
        import time

        now = time.monotonic()
        looks = {}
        quiet = True
        for tid in self.threads():
            try:
                with open(f"/proc/self/task/{tid}/stat") as f:
                    fields = f.read().rsplit(")", 1)[1].split()
            except OSError:
                continue  # ended
            looks[tid] = int(fields[11]) + int(fields[12])
            quiet = quiet and fields[0] in "SI" and self._last.get(tid) == looks[tid]
        if not looks:
            return True
        if now - self._at < self.QUIET_S:
            return False  # too soon after the last look to tell
        self._last, self._at = looks, now
        return quiet

    def wait(self, bound_s: float = 60.0, progress=None) -> bool:
        """Block until ``idle()`` (True) or ``bound_s`` (False); ``progress()`` every half second."""
        import time

        t0 = last = time.monotonic()
        while not self.idle():
            if time.monotonic() - t0 > bound_s:
                return False
            time.sleep(self.QUIET_S)
            if progress is not None and time.monotonic() - last > 0.5:
                progress()
                last = time.monotonic()
        return True
