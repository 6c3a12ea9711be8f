"""A ``.brdf`` file's numpy twin is Python code that came with the file: who may run it, and how.

Consent. A twin runs only when the user has trusted it: ``trust(PATH)`` (the command line's
``--trust-twin PATH``, a file or a folder; the window's question, remembered per folder in its
state file), ``$BRDF_VIEWER_TRUST_TWINS`` (paths joined by ``:``), or the program's own folder of
examples ``viewer/brdfs`` (it ships with the program). Nothing a file says grants it: not a scene
file, not a screenshot's embedded scene, not a dropped folder. The rule is applied to the twin's
real path (symlinks and ``..`` resolved): a symlink in a trusted folder that points elsewhere is
not trusted. Without consent the file works without its twin and ``untrusted`` says so in one
line (to stderr, or to the listener the window sets). The CPU reference's worker processes take
the parent's decision (``decide``), never their own.

Misbehaviour. A trusted twin is first imported and evaluated once in a short-lived child process
(``python -c`` running ``viewer.brdf.twin_child``) within ``TIME_LIMIT_S``
(``$BRDF_VIEWER_TWIN_TIME_LIMIT`` overrides it): a twin that sleeps, exits or crashes there is one
``NAME.py: ...`` line, and the program goes on. Only then is it imported in-process, and every call of its functions goes through the
wrappers here, which turn anything it raises (``SystemExit`` included: a twin's ``sys.exit`` is
its own mistake, not the user's wish) and any output of the wrong shape, ``None`` or NaN / Inf
into one ``ViewerError`` naming the twin. ``KeyboardInterrupt`` is the user's and passes through.
"""

from __future__ import annotations

import importlib.util
import json
import os
import subprocess
import sys
import traceback
from pathlib import Path

import numpy as np

from viewer import ViewerError

TRUST_ENV = "BRDF_VIEWER_TRUST_TWINS"
TIME_LIMIT_ENV = "BRDF_VIEWER_TWIN_TIME_LIMIT"
#: seconds a twin's import and its first evaluation may take in the probe's child process
TIME_LIMIT_S = 20.0
#: the program's own examples (trusted: they ship with it)
BUILT_IN = Path(__file__).resolve().parent.parent / "brdfs"
#: the line the probe's child writes its verdict after (the twin may print anything before it)
VERDICT = "brdf-viewer twin probe:"

_GRANTED: list[Path] = []            # trust(): --trust-twin and the window's answers (real paths)
_DECIDED: frozenset | None = None     # a worker process: exactly the twins its parent trusted
_LISTENER = None                      # untrusted(): None prints to stderr


def real(path) -> Path:
    """``path`` with ``~``, ``..`` and every symlink resolved."""
    return Path(os.path.realpath(os.path.expanduser(os.fspath(path))))


def twin_of(brdf_path) -> Path:
    """The numpy twin's path beside a ``.brdf`` file (whether or not it exists)."""
    return Path(brdf_path).with_suffix(".py")


def trust(path, where: str = "--trust-twin") -> Path:
    """Trust the twins in the folder ``path`` (and the folders inside it), or the twin ``path``
    names (the ``.py`` itself or its ``.brdf``); a path that does not exist is a one-line
    ViewerError. Returns what is trusted."""
    p = Path(os.path.expanduser(os.fspath(path)))
    if not p.exists():
        raise ViewerError(f"{where} {path}: no such file or folder")
    if p.is_file() and p.suffix.lower() == ".brdf":
        p = twin_of(real(p))  # the twin beside the file itself, as viewer.brdf.load finds it
    root = real(p)
    if root not in _GRANTED:
        _GRANTED.append(root)
    return root


def forget() -> None:
    """Drop every ``trust`` of this process (the environment's and the built-in folder stay)."""
    _GRANTED.clear()


def roots() -> list[Path]:
    """What is trusted now: the built-in folder, the environment's paths, ``trust``'s."""
    env = [real(s) for s in os.environ.get(TRUST_ENV, "").split(os.pathsep) if s.strip()]
    env = [real(twin_of(p)) if p.suffix.lower() == ".brdf" and p.is_file() else p for p in env]
    return [BUILT_IN, *env, *_GRANTED]


def is_trusted(twin) -> bool:
    """Whether the user has consented to running ``twin`` (by its real path)."""
    r = real(twin)
    if _DECIDED is not None:
        return str(r) in _DECIDED
    return any(r == root or (root.is_dir() and r.is_relative_to(root)) for root in roots())


def trusted_twins(brdf_paths) -> list[str]:
    """The real paths of the trusted twins beside ``brdf_paths``: the decision a worker process
    receives (``decide``)."""
    out = []
    for b in brdf_paths:
        t = twin_of(real(b))
        if t.is_file() and is_trusted(t) and str(real(t)) not in out:
            out.append(str(real(t)))
    return out


def decide(twins) -> None:
    """In a worker process: trust exactly ``twins`` (real paths, the parent's ``trusted_twins``),
    whatever this process's environment says; None: back to this process's own rule."""
    global _DECIDED
    _DECIDED = None if twins is None else frozenset(str(t) for t in twins)


def not_run_message(brdf_path, twin) -> str:
    return (f"{Path(brdf_path).name}: its numpy twin {Path(twin).name} was not run (not trusted); "
            f"trust it with --trust-twin {twin}")


def set_listener(fn) -> None:
    """``fn(brdf_path, twin_path, message)`` hears of every twin not run (None: print the message
    to stderr); the window asks its question from it."""
    global _LISTENER
    _LISTENER = fn


def untrusted(brdf_path, twin) -> None:
    """Say that ``twin`` was not run (once per load of the file: ``viewer.brdf.load`` caches)."""
    msg = not_run_message(brdf_path, twin)
    if _LISTENER is None:
        print(f"brdf-viewer: {msg}", file=sys.stderr, flush=True)
    else:
        _LISTENER(Path(brdf_path), Path(twin), msg)


# ----------------------------------------------------------------------------- running it


def time_limit() -> float:
    text = os.environ.get(TIME_LIMIT_ENV)
    if text:
        try:
            v = float(text)
            if v > 0:
                return v
        except ValueError:
            pass
        raise ViewerError(f"{TIME_LIMIT_ENV}={text}: not a number of seconds > 0")
    return TIME_LIMIT_S


def failure(twin, what: str, e: BaseException) -> str:
    """One line for the exception ``e`` that the twin's code raised during ``what``, naming
    ``NAME.py:LINE`` where the traceback passes through the twin."""
    twin = Path(twin)
    if isinstance(e, SystemExit):
        return f"{twin.name}: the numpy twin called sys.exit({e.code!r}) {what}"
    tb = traceback.extract_tb(e.__traceback__)
    names = {str(twin), os.path.realpath(twin)}
    line = next((fr.lineno for fr in reversed(tb) if fr.filename in names), None)
    where = f"{twin.name}:{line}" if line else twin.name
    text = str(e).splitlines()[0] if str(e) else ""
    return f"{where}: the numpy twin raised {type(e).__name__}{': ' + text if text else ''} {what}"


class _OverTime(BaseException):
    """A twin's call ran past the time limit (raised by the alarm, caught in ``call``)."""


def _alarm(signum, frame):
    raise _OverTime()


def call(twin, what: str, fn, *args):
    """``fn(*args)``, with anything the twin's code raises (``SystemExit`` too) as one
    ViewerError naming it; ``KeyboardInterrupt`` is the user's and passes through. On a
    process's main thread (the commands, the reference's workers) each call is also held to
    ``time_limit()`` by an alarm, so a twin that sleeps or spins in a later call is one line too
    (elsewhere, e.g. the window's threads, only the first call in the probe's child is)."""
    import signal
    import threading

    timed = (hasattr(signal, "setitimer") and threading.current_thread() is threading.main_thread()
             and signal.getitimer(signal.ITIMER_REAL)[0] == 0.0)
    limit = time_limit()
    old = signal.signal(signal.SIGALRM, _alarm) if timed else None
    try:
        if timed:
            signal.setitimer(signal.ITIMER_REAL, limit)
        return fn(*args)
    except KeyboardInterrupt:
        raise
    except _OverTime:
        raise ViewerError(f"{Path(twin).name}: the numpy twin did not return within {limit:g} s {what} "
                          f"(the time limit; {TIME_LIMIT_ENV} sets it)") from None
    except BaseException as e:  # noqa: BLE001 - a student's file: any error is theirs, in one line
        raise ViewerError(failure(twin, what, e)) from None
    finally:
        if timed:
            signal.setitimer(signal.ITIMER_REAL, 0.0)
            signal.signal(signal.SIGALRM, old)


def import_twin(twin):
    """Execute the twin's module here (consent already given) and check its functions; one-line
    ViewerErrors as ``call``."""
    twin = Path(twin)
    name = f"brdf_twin_{abs(hash(str(real(twin))))}"
    spec = importlib.util.spec_from_file_location(name, twin)
    mod = importlib.util.module_from_spec(spec)
    try:
        spec.loader.exec_module(mod)
    except KeyboardInterrupt:
        raise
    except BaseException as e:  # noqa: BLE001 - a student's file: any error is theirs, in one line
        if isinstance(e, SystemExit):
            raise ViewerError(failure(twin, "while being imported", e)) from None
        tb = traceback.extract_tb(e.__traceback__)
        line = next((fr.lineno for fr in reversed(tb) if fr.filename == str(twin)), None)
        where = f"{twin.name}:{line}" if line else twin.name
        raise ViewerError(f"{where}: the numpy twin cannot be loaded: {type(e).__name__}: {e}") from None
    if not callable(getattr(mod, "eval", None)):
        raise ViewerError(f"{twin.name}: a numpy twin needs eval(p, wi, wo)")
    has_s, has_p = callable(getattr(mod, "sample", None)), callable(getattr(mod, "pdf", None))
    if has_s != has_p:
        raise ViewerError(f"{twin.name}: a numpy twin's sampler needs both sample(p, wo, u) and pdf(p, wi, wo)")
    return mod


def _numbers(twin, what: str, value, n: int, width: int) -> np.ndarray:
    """``value`` as (n, width) float64 (a scalar, (n,) or (n, 1) broadcast when width is 3;
    (n, 1) flattened when width is 1), else one ViewerError naming the twin."""
    name = Path(twin).name
    if value is None:
        raise ViewerError(f"{name}: the numpy twin's {what} returned None; it must return numbers for the "
                          f"{n} direction pairs")
    try:
        a = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError) as e:
        raise ViewerError(f"{name}: the numpy twin's {what} returned {type(value).__name__}, not numbers "
                          f"({str(e).splitlines()[0] if str(e) else ''})") from None
    want = f"({n}, 3)" if width == 3 else f"({n},)"
    if width == 3 and (a.ndim == 0 or a.shape in ((n,), (n, 1))):
        a = np.broadcast_to(a.reshape(-1, 1) if a.ndim else a, (n, 3))
    elif width == 1 and a.shape in ((n, 1), ()):
        a = np.broadcast_to(a.reshape(-1), (n,))
    expect = (n, 3) if width == 3 else (n,)
    if a.shape != expect:
        raise ViewerError(f"{name}: the numpy twin's {what} returned shape {a.shape} for {n} direction pairs; "
                          f"expected {want}")
    return a


def _finite(twin, what: str, a: np.ndarray, where: np.ndarray | None = None) -> np.ndarray:
    bad = ~np.isfinite(a)
    if bad.ndim > 1:
        bad = np.any(bad, axis=1)
    if where is not None:
        bad &= where
    if np.any(bad):
        raise ViewerError(f"{Path(twin).name}: the numpy twin's {what} returned NaN or Inf for "
                          f"{int(bad.sum())} of {len(bad)} direction pairs")
    return a


def _upper(wi, wo):
    return (wi[:, 2] > 0) & (wo[:, 2] > 0)


def guarded(twin, mod):
    """(eval, sample, pdf) of the twin module ``mod``, each checked as described above; sample
    and pdf are None without a sampler. eval returns (N, 3), 0 below the horizon."""
    def ev(p, wi, wo):
        f = _numbers(twin, "eval", call(twin, "in eval", mod.eval, p, wi, wo), len(wi), 3)
        up = _upper(wi, wo)
        return np.where(up[:, None], _finite(twin, "eval", f, up), 0.0)

    if not callable(getattr(mod, "sample", None)):
        return ev, None, None

    def pdf(p, wi, wo):
        up = _upper(wi, wo)
        d = _numbers(twin, "pdf", call(twin, "in pdf", mod.pdf, p, wi, wo), len(wi), 1)
        return np.where(up, _finite(twin, "pdf", d, up), 0.0)

    def sample(p, wo, u):
        out = call(twin, "in sample", mod.sample, p, wo, u)
        if not isinstance(out, tuple) or len(out) != 3:
            raise ViewerError(f"{Path(twin).name}: the numpy twin's sample returned {type(out).__name__}; "
                              f"it must return (wi, weight, pdf)")
        n = len(wo)
        wi = _finite(twin, "sample (wi)", _numbers(twin, "sample (wi)", out[0], n, 3))
        w = _finite(twin, "sample (weight)", _numbers(twin, "sample (weight)", out[1], n, 3))
        d = _finite(twin, "sample (pdf)", _numbers(twin, "sample (pdf)", out[2], n, 1))
        return np.array(wi), np.array(w), np.array(d)

    return ev, sample, pdf


def probe(twin, brdf_path) -> None:
    """Import ``twin`` and evaluate it once (eval, and sample / pdf when it has them) in a child
    process within ``time_limit()`` seconds; what goes wrong there is one ViewerError naming it."""
    twin = Path(twin)
    limit = time_limit()
    root = str(Path(__file__).resolve().parent.parent.parent)
    code = (f"import sys; sys.path.insert(0, {root!r}); from viewer.brdf.twin_child import main; "
            "sys.exit(main(sys.argv[1:]))")
    try:
        done = subprocess.run([sys.executable, "-c", code, str(twin), str(brdf_path)], stdin=subprocess.DEVNULL,
                              capture_output=True, text=True, errors="replace", timeout=limit)
    except subprocess.TimeoutExpired:
        raise ViewerError(f"{twin.name}: the numpy twin did not finish its import and a first eval within "
                          f"{limit:g} s (the time limit; {TIME_LIMIT_ENV} sets it)") from None
    except OSError as e:
        raise ViewerError(f"{twin.name}: the numpy twin could not be tried in a child process ({e})") from None
    verdict = [ln[len(VERDICT):] for ln in done.stdout.splitlines() if ln.startswith(VERDICT)]
    if verdict:
        answer = json.loads(verdict[-1])
        if answer.get("ok"):
            return
        raise ViewerError(answer.get("error") or f"{twin.name}: the numpy twin failed")
    raise ViewerError(f"{twin.name}: the numpy twin ended its process (exit status {done.returncode}) before "
                      f"its first eval finished")
