"""The probe: a ``.brdf`` file's first compile and a 4 x 4 render of its programs, in a child
process with a time and a memory limit, before its GLSL reaches a window's context or
``brdf-viewer check``'s evaluator.

A shader that runs for minutes, or a compile that takes gigabytes, then costs a child that the
parent kills (``timeout`` seconds, ``BRDF_VIEWER_PROBE_TIMEOUT``; the child's address space is
limited to ``memory_mb``, ``BRDF_VIEWER_PROBE_MEMORY_MB``), and the file is refused in one line.
The parent only waits on the child, so it answers Ctrl-C and SIGTERM meanwhile, and the child
dies with it (Linux: the parent-death signal; otherwise the wait's cleanup kills it).

The verdict is kept per content (the GLSL block of the file, the probe's version and limits):
in the process, and for a file that passed, in ``<cache folder>/brdf_probe/`` (a refusal is
not written there: a machine busy enough to miss the limit once is no lasting verdict).
A compile error is not the probe's business: the file passes it, and the compile where the file
is used reports the error on the file's line as always. A child that cannot make a GL context
(no EGL) says nothing about the file either: it passes, and the caller's own GL reports.

Protocol: the file's text on stdin as JSON ``{"path", "text"}``; out, one JSON line each:
``{"ready": true}`` once the context exists, then ``{"ok": true}`` or ``{"ok": false, "error"}``.
"""

from __future__ import annotations

import hashlib
import json
import os
import subprocess
import sys
import threading

from viewer import ViewerError

SIZE = 4                                   # the test render: SIZE x SIZE direction pairs
TIMEOUT_ENV = "BRDF_VIEWER_PROBE_TIMEOUT"  # seconds
MEMORY_ENV = "BRDF_VIEWER_PROBE_MEMORY_MB"
OFF_ENV = "BRDF_VIEWER_PROBE"              # "0": no probe (the child itself, and nothing else)
DEFAULT_TIMEOUT = 10.0
DEFAULT_MEMORY_MB = 2048
VERSION = 1

started = 0                                # the probes' children started in this process
_VERDICTS: dict[str, str] = {}             # content key -> "" (passed) or the refusal's line
_RUNNING: set = set()                      # the probes' children now running
_LOCK = threading.Lock()
_cancels = 0                                 # cancel_all calls so far (a probe started before one is cancelled)


def timeout() -> float:
    try:
        return max(0.1, float(os.environ.get(TIMEOUT_ENV, DEFAULT_TIMEOUT)))
    except ValueError:
        return DEFAULT_TIMEOUT


def memory_mb() -> int:
    try:
        return max(64, int(os.environ.get(MEMORY_ENV, DEFAULT_MEMORY_MB)))
    except ValueError:
        return DEFAULT_MEMORY_MB


def _key(bfile, limits) -> str:
    h = hashlib.sha256(f"{VERSION} {limits}\n".encode())
    h.update(bfile.glsl_block().encode("utf-8", errors="replace"))
    return h.hexdigest()[:32]


def _cache_file(key: str):
    from viewer.base.io import cache_root

    return cache_root() / "brdf_probe" / f"{key}.ok"


def probe(bfile) -> None:
    """Refuse ``bfile`` (a ``viewer.brdf.brdffile.BrdfFile``) with a one-line ViewerError when its
    compile and 4 x 4 test render do not finish within the time limit or the memory limit, or
    when a call reaches the loop budget; pass it otherwise (a compile error included)."""
    if os.environ.get(OFF_ENV) == "0":
        return
    t, mb = timeout(), memory_mb()
    key = _key(bfile, (t, mb))
    hit = _VERDICTS.get(key)
    if hit is None and _cache_file(key).is_file():
        hit = _VERDICTS[key] = ""
    if hit is None:
        hit = _run_child(bfile, t, mb)
        if hit is None:
            return  # no verdict: the caller's own GL compiles and reports
        _VERDICTS[key] = hit
        if hit == "":
            _remember(key)
    if hit:
        raise ViewerError(hit)


def _remember(key: str) -> None:
    from viewer.base.io import atomic_write_bytes

    try:
        _cache_file(key).parent.mkdir(parents=True, exist_ok=True)
        atomic_write_bytes(_cache_file(key), b"passed\n")
    except (OSError, ViewerError):
        pass  # no cache: probed again next time


def cancel_all() -> None:
    """Kill the probes' children now running (a window closing on SIGTERM), and those of probes
    already under way whose child is not yet registered (they see the cancel when they register)."""
    global _cancels
    with _LOCK:
        _cancels += 1
        procs = list(_RUNNING)
    for p in procs:
        try:
            p.kill()
        except OSError:
            pass


def _run_child(bfile, t: float, mb: int):
    """The verdict: "" passed, a refusal's line; None: no verdict (the child could not run)."""
    global started
    name = bfile.path.name
    with _LOCK:
        cancels = _cancels
    env = dict(os.environ, **{OFF_ENV: "0", MEMORY_ENV: str(mb)})
    try:
        proc = subprocess.Popen([sys.executable, "-m", "viewer.gl.file_probe"], stdin=subprocess.PIPE,
                                stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env)
    except OSError:
        return None
    started += 1
    with _LOCK:
        _RUNNING.add(proc)
        if _cancels != cancels:  # cancelled between this probe's start and now: no verdict either
            proc.kill()
    try:
        out, err = proc.communicate(json.dumps({"path": str(bfile.path), "text": "\n".join(bfile.lines)}),
                                    timeout=t)
    except subprocess.TimeoutExpired:
        proc.kill()
        proc.communicate()
        return (f"{name}: its GLSL did not finish a {SIZE}x{SIZE} test render within {t:g} s "
                f"(an unbounded loop?)")
    except BaseException:  # Ctrl-C, SIGTERM, anything: the child never outlives the wait
        proc.kill()
        proc.wait()
        raise
    finally:
        with _LOCK:
            _RUNNING.discard(proc)
    msgs = []
    for line in out.splitlines():
        try:
            msgs.append(json.loads(line))
        except ValueError:
            continue
    ready = any(m.get("ready") for m in msgs)
    verdict = next((m for m in msgs if "ok" in m), None)
    if verdict is not None:
        return "" if verdict["ok"] else verdict.get("error") or f"{name}: refused by the test render"
    if proc.returncode in (-9, -15):  # killed from outside (cancel_all): no verdict on the file
        raise ViewerError(f"{name}: the test render of its GLSL was stopped")
    if not ready:
        return None
    # ready, then no verdict: the child died in the compile or the render (the memory limit)
    return (f"{name}: its GLSL's compile and {SIZE}x{SIZE} test render needed more than {mb:,} MB of memory "
            f"or crashed the compiler (too large a program?)")


def _limit_memory(mb: int) -> None:
    try:
        import resource

        resource.setrlimit(resource.RLIMIT_AS, (mb << 20, mb << 20))
    except (ImportError, ValueError, OSError):
        pass


def _die_with_parent() -> None:
    """Linux: SIGKILL this process when its parent dies (no orphan keeps running a shader)."""
    if not sys.platform.startswith("linux"):
        return
    try:
        import ctypes
        import signal

        libc = ctypes.CDLL(None, use_errno=True)
        libc.prctl(1, int(signal.SIGKILL), 0, 0, 0)   # PR_SET_PDEATHSIG
        if os.getppid() == 1:                          # the parent died before the call
            os._exit(1)
    except (OSError, AttributeError):
        pass


def serve(inp=sys.stdin, out=sys.stdout) -> int:
    """The child: compile the file's programs and render SIZE x SIZE pairs through each."""
    import numpy as np

    from viewer.brdf.brdffile import parse
    from viewer.gl.context import create_offscreen_context
    from viewer.gl.file_brdf import FileBrdfError, FileEvaluator

    req = json.loads(inp.read())
    bfile = parse(req["path"], text=req["text"])
    ctx = create_offscreen_context()
    print(json.dumps({"ready": True}), file=out, flush=True)
    ev = FileEvaluator(ctx)
    n = SIZE * SIZE
    rng = np.random.default_rng(0)
    u = rng.random((n, 2))
    z = np.sqrt(1.0 - u[:, 0])
    r = np.sqrt(u[:, 0])
    wi = np.stack([r * np.cos(6.283 * u[:, 1]), r * np.sin(6.283 * u[:, 1]), z], axis=1)
    wo = wi[::-1].copy()
    try:
        ev.eval(bfile, None, wi, wo)
        if bfile.has_sampler:
            ev.sample(bfile, None, wo, u)
        ctx.finish()
        answer = {"ok": True}
    except FileBrdfError:
        answer = {"ok": True}   # the compile where the file is used reports it, on its line
    except ViewerError as e:
        answer = {"ok": False, "error": str(e)}
    print(json.dumps(answer), file=out, flush=True)
    return 0


def main() -> int:
    _die_with_parent()
    _limit_memory(memory_mb())
    try:
        return serve()
    except MemoryError:
        return 3
    except Exception as e:  # noqa: BLE001 - the parent reads the missing verdict
        print(f"{type(e).__name__}: {str(e).splitlines()[0] if str(e) else ''}", file=sys.stderr)
        return 1


if __name__ == "__main__":
    sys.exit(main())
