"""The window's persistent state: restored at the next start, written atomically at exit.

Where: ``$BRDF_VIEWER_STATE`` if set (a file path), else ``$XDG_CONFIG_HOME/brdf-viewer/state.toml``
(``~/.config`` when XDG_CONFIG_HOME is unset). Next to it, ``last_scene.toml`` holds the last
session's scene in the scene-file format (the window's "Reopen last session" loads it).

The state is a small TOML table; anything unreadable, of the wrong type or out of range is
ignored key by key (with one line on stderr), so a damaged state file never stops the viewer.
A state file that is not a regular file of at most ``MAX_BYTES`` (a FIFO, a link to a device, a
huge file) is ignored whole, in one line, without being read.
"""

from __future__ import annotations

import os
import stat
import sys
import tomllib
from pathlib import Path

from viewer.base.input_bounds import toml_problem

#: the window's size when neither the command line nor the last session gives one
DEFAULT_WINDOW = (1280, 720)

# key -> (type, lo, hi) for numbers, (type, choices) for strings; anything else is dropped
SCHEMA = {
    "window_width": (int, 64, 16384),
    "window_height": (int, 64, 16384),
    "window_x": (int, -32768, 32768),
    "window_y": (int, -32768, 32768),
    # the framebuffer the last session drew into (full screen, or twice the window on a HiDPI
    # screen): what `bake --lecture` with no size prepares, as the window's Prepare lecture does
    "framebuffer_width": (int, 1, 16384),   # as --width: a state file cannot ask bake for more
    "framebuffer_height": (int, 1, 16384),
    "ui_scale": (float, 0.5, 4.0),
    "show_ui": (bool,),
    "compare_mode": (str, None),
    "split": (float, 0.0, 1.0),
    "view_mode": (int, 0, 64),
    "plots_visible": (bool,),
    "trusted_twin_folders": (list,),  # folders whose numpy twins the user let run (app/twin_question.py)
    "scene_digest": (str, None),  # the scene the session ended on (Session.scene_digest)
}


def state_path() -> Path:
    env = os.environ.get("BRDF_VIEWER_STATE")
    if env:
        return Path(env).expanduser()
    base = os.environ.get("XDG_CONFIG_HOME") or os.path.join(os.path.expanduser("~"), ".config")
    return Path(base) / "brdf-viewer" / "state.toml"


def last_scene_path() -> Path:
    return state_path().with_name("last_scene.toml")


#: the most bytes a state file may hold (a written one is about 300)
MAX_BYTES = 16 * 1024


def read_small_file(path: Path, limit: int = MAX_BYTES) -> bytes:
    """The bytes of ``path`` when it is a regular file of at most ``limit`` bytes; else OSError
    saying what it is. Checked with stat before it is opened (a FIFO, a device such as
    /dev/zero, a symbolic link to one, a huge file are never read), opened without blocking and
    read to ``limit`` + 1 bytes at most (it may grow between the stat and the read)."""
    st = os.stat(path)
    if not stat.S_ISREG(st.st_mode):
        raise OSError(f"not a regular file ({_kind(st.st_mode)})")
    if st.st_size > limit:
        raise OSError(f"{st.st_size} bytes; a state file holds at most {limit}")
    fd = os.open(path, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_NOCTTY", 0))
    try:
        if not stat.S_ISREG(os.fstat(fd).st_mode):  # replaced between the stat and the open
            raise OSError("not a regular file")
        data = os.read(fd, limit + 1)
    finally:
        os.close(fd)
    if len(data) > limit:
        raise OSError(f"over {limit} bytes; a state file holds at most {limit}")
    return data


def _kind(mode: int) -> str:
    for test, name in ((stat.S_ISFIFO, "a FIFO"), (stat.S_ISCHR, "a character device"),
                       (stat.S_ISBLK, "a block device"), (stat.S_ISSOCK, "a socket"), (stat.S_ISDIR, "a folder")):
        if test(mode):
            return name
    return "not a file"


def load_state(path: Path | None = None) -> dict:
    path = state_path() if path is None else Path(path)
    if not os.path.lexists(path):
        return {}
    try:
        text = read_small_file(path).decode("utf-8")
        problem = toml_problem(text)
        if problem:
            raise OSError(problem)
        raw = tomllib.loads(text)
    except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError, RecursionError) as e:
        why = e.strerror if isinstance(e, OSError) and e.strerror else str(e)
        print(f"brdf-viewer: {path}: window state ignored ({why})", file=sys.stderr)
        return {}
    out = {}
    for k, v in raw.items():
        spec = SCHEMA.get(k)
        if spec is None:
            continue
        t = spec[0]
        if t is float and isinstance(v, int) and not isinstance(v, bool):
            v = float(v)
        if not isinstance(v, t) or (t is int and isinstance(v, bool)):
            print(f"brdf-viewer: {path}: {k}: ignored (expected {t.__name__})", file=sys.stderr)
            continue
        if t is list and not all(isinstance(x, str) for x in v):
            print(f"brdf-viewer: {path}: {k}: ignored (expected a list of strings)", file=sys.stderr)
            continue
        if t in (int, float) and not (spec[1] <= v <= spec[2]):
            print(f"brdf-viewer: {path}: {k}: ignored (out of range {spec[1]}..{spec[2]})", file=sys.stderr)
            continue
        out[k] = v
    return out


def save_state(state: dict, path: Path | None = None) -> None:
    import tomli_w

    from viewer.base.io import atomic_write_bytes

    path = state_path() if path is None else Path(path)
    clean = {k: v for k, v in state.items() if k in SCHEMA and v is not None}
    path.parent.mkdir(parents=True, exist_ok=True)
    atomic_write_bytes(path, tomli_w.dumps(clean).encode("utf-8"))
