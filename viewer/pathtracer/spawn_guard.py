"""Why a ``spawn``ed worker pool fails from an unguarded script, said in one line.

``multiprocessing``'s ``spawn`` start method runs the main script again in every worker (as
``__mp_main__``) so that its functions can be unpickled there. A script that starts the
reference at module level, outside ``if __name__ == "__main__":``, would start it again in each
worker; ``multiprocessing`` stops that with a 20-line RuntimeError inside the workers and the
pool breaks. ``check_entry_point_guarded`` finds that case before any worker starts: it looks
for the main script's module-level frame on the calling stack and, when the statement running
there is not inside an ``if`` that tests ``__name__``, raises one ``ViewerError`` naming the fix.

A main module without a file (a Jupyter notebook, the REPL, ``python -c``) is never re-run by
``spawn``, so it needs no guard; neither do ``brdf-viewer`` and ``python -m viewer``.
"""

from __future__ import annotations

import ast
import sys
from functools import lru_cache

from viewer import ViewerError

FIX = ('a script that starts the reference renderer (viewer.reference, ReferenceRenderer) must run '
       'it under `if __name__ == "__main__":` (its worker processes are spawned and re-import the '
       'script), or pass workers=0 to render in this process')


@lru_cache(maxsize=8)
def _guarded_lines(filename: str, mtime: float) -> tuple[tuple[int, int], ...] | None:
    """Line ranges of the module-level ``if ... __name__ ...:`` blocks of ``filename``; None
    when the file cannot be read or parsed (then nothing is claimed)."""
    try:
        with open(filename, "rb") as f:
            tree = ast.parse(f.read(), filename)
    except (OSError, SyntaxError, ValueError):
        return None
    out = []
    for node in tree.body:
        if isinstance(node, ast.If) and any(isinstance(n, ast.Name) and n.id == "__name__"
                                            for n in ast.walk(node.test)):
            out.append((node.lineno, node.end_lineno or node.lineno))
    return tuple(out)


def check_entry_point_guarded() -> None:
    """Raise ``ViewerError`` when the caller is the main script's unguarded module-level code."""
    main = sys.modules.get("__main__")
    filename = getattr(main, "__file__", None)
    if main is None or not filename:
        return  # notebook, REPL, python -c: spawn does not re-run anything
    spec_name = getattr(getattr(main, "__spec__", None), "name", None) or ""
    if spec_name == "__main__" or spec_name.endswith(".__main__"):
        return  # python -m package: spawn skips a package's __main__ (multiprocessing.spawn)
    frame = sys._getframe(1)
    while frame is not None:
        if frame.f_globals is main.__dict__ and frame.f_code.co_name == "<module>":
            break
        frame = frame.f_back
    if frame is None:
        return  # called from a function, a thread or a callback: the module body has finished
    import os

    try:
        mtime = os.stat(filename).st_mtime
    except OSError:  # e.g. ``python - < script.py``: the workers would fail to re-import "<stdin>"
        raise ViewerError(f"the main program {filename} is not a file the worker processes can re-import; "
                          "run it from a script file (under `if __name__ == \"__main__\":`), or pass "
                          "workers=0 to render in this process") from None
    ranges = _guarded_lines(os.path.abspath(filename), mtime)
    if ranges is None:
        return
    line = frame.f_lineno
    if not any(a <= line <= b for a, b in ranges):
        raise ViewerError(f"{os.path.basename(filename)}, line {line}: {FIX}")
