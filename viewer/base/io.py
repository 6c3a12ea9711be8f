"""Writing output files atomically (temporary file in the same folder, fsync, then rename), so a
kill mid-write never leaves a partial file behind; and small helpers for one-line messages about
files."""

from __future__ import annotations

import errno
import functools
import io
import os
import re
import stat
import tempfile
from pathlib import Path

import numpy as np

from viewer import OutputError, ViewerError


def one_line(text: str) -> str:
    """``text`` with every line break and control character written as an escape, so a message
    that quotes a file name, key or value stays one line (``str.splitlines`` splits on more than
    \\n: \\r, \\v, \\f, \\x1c-\\x1e, \\x85, \\u2028, \\u2029)."""
    if text.isprintable():
        return text
    return "".join(c if c.isprintable() else repr(c)[1:-1] for c in text)


def expand_user(path) -> Path:
    """``Path(path).expanduser()``, or the path unchanged where ``~user`` names nobody."""
    p = Path(path)
    try:
        return p.expanduser()
    except RuntimeError:
        return p


def path_problem(path) -> str | None:
    """None when ``path`` is a regular file; else what is wrong with it, phrased for a message
    ("file not found", "is a folder, not a file", "the name is too long", ...). Never raises:
    ``Path.exists`` raises for a name that is too long and ``os.stat`` for a NUL character."""
    return stat_file(path)[1]


def stat_file(path) -> tuple[os.stat_result | None, str | None]:
    """``(os.stat(path), None)`` for a regular file; else ``(None, problem)`` as ``path_problem``."""
    try:
        st = os.stat(path)
    except ValueError:
        return None, "the name contains a NUL character"
    except OSError as e:
        if e.errno in (errno.ENOENT, errno.ENOTDIR):
            return None, "file not found"
        if e.errno == errno.ELOOP:
            return None, "file not found (a loop of symbolic links)"
        if e.errno == errno.ENAMETOOLONG:
            return None, "the name is too long"
        return None, f"cannot be examined ({e.strerror or e})"
    if stat.S_ISDIR(st.st_mode):
        return None, "is a folder, not a file"
    if not stat.S_ISREG(st.st_mode):
        return None, "is not a regular file (a device, pipe or socket)"
    return st, None


def one_line_errors(fn):
    """Decorator: a ViewerError raised inside ``fn`` (by deeper code: the BRDF registry, mesh and
    map loading) leaves with its message on one line (``one_line``): it may quote a file name,
    key or value."""
    @functools.wraps(fn)
    def wrapper(*args, **kwargs):
        try:
            return fn(*args, **kwargs)
        except ViewerError as e:
            text = one_line(str(e))
            if text == str(e):
                raise
            raise type(e)(text) from None
    return wrapper


#: the most radiance (W / (m^2 sr)) a cached image's pixel may hold: a stored reference or traced
#: frame above it is taken for garbage (finite nonsense such as 3e38 everywhere) and set aside.
#: The brightest pixel of any built-in scene or lecture step is below 100; the sharpest highlight
#: the models allow (GGX at alpha 1e-4, D up to 3e7 /sr) under a light of I / r^2 = 10 is ~1e8.
MAX_CACHED_RADIANCE = 1e9


def cache_root() -> Path:
    """The folder of every on-disk cache (references, traced frames, environment maps):
    ``$BRDF_VIEWER_CACHE``, else ``$XDG_CACHE_HOME/brdf-viewer``, else ``~/.cache/brdf-viewer``."""
    env = os.environ.get("BRDF_VIEWER_CACHE")
    if env:
        return Path(env).expanduser()
    return Path(os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")) / "brdf-viewer"


def atomic_write_bytes(path, data: bytes) -> Path:
    """Write ``data`` to ``path`` atomically: ``path`` is at every moment absent, its old
    content or the complete new content, never a part (see ``atomic_write_file``)."""

    def write(tmp: Path):
        with open(tmp, "r+b") as f:
            f.write(data)

    return atomic_write_file(path, write)


def atomic_write_file(path, write, suffix: str = "") -> Path:
    """Create ``path`` through ``write(tmp)``, which writes the whole file at ``tmp``.

    ``tmp`` is a new empty file in the same folder, named ``.NAME.PID.XXXXXXXX.part`` + ``suffix``
    (a library that picks its format by the file name gets ``suffix``, e.g. ".hdr"). When
    ``write`` returns, the file is flushed to disk (fsync), given the permissions a plain
    ``open(path, "w")`` would give it (an existing file keeps its mode; ``mkstemp`` alone would
    leave 0600), renamed over ``path`` with ``os.replace`` (atomic within a file system), and the
    folder is fsynced so that the rename survives a power cut. On any error the temporary file
    is removed and ``path`` is untouched. A writer killed mid-write cannot remove its temporary
    file; the next write to the same name removes those whose process no longer exists."""
    path = Path(path)
    folder = path.parent if str(path.parent) else Path(".")
    if not folder.is_dir():
        raise ViewerError(one_line(f"{path}: the folder {folder} does not exist"))
    prefix = f".{path.name}."
    _remove_orphans(folder, prefix)
    try:
        fd, tmp = tempfile.mkstemp(prefix=f"{prefix}{os.getpid()}.", suffix=".part" + suffix, dir=folder)
    except OSError as e:
        raise write_error(path, e) from None
    os.close(fd)
    try:
        write(Path(tmp))
        fd = os.open(tmp, os.O_RDONLY)
        try:
            os.fsync(fd)
        finally:
            os.close(fd)
        os.chmod(tmp, _mode_for(path))
        os.replace(tmp, path)
    except BaseException as e:
        try:
            os.unlink(tmp)
        except OSError:
            pass
        if isinstance(e, OSError) and not isinstance(e, ViewerError):
            raise write_error(path, e) from None
        raise
    _fsync_folder(folder)
    return path


def write_error(path, e: OSError) -> OutputError:
    """One line naming ``path`` and why it could not be written (``OutputError``, exit 1 in the
    CLI; an ``OSError`` with ``e``'s errno for code that handles write failures)."""
    err = OutputError(one_line(f"{path}: cannot be written ({e.strerror or e})"))
    err.errno = e.errno
    return err


def _mode_for(path: Path) -> int:
    try:
        return stat.S_IMODE(os.stat(path).st_mode)
    except OSError:
        return 0o666 & ~_umask()


def _umask() -> int:
    try:  # Linux >= 4.7 shows it without changing it
        with open("/proc/self/status") as f:
            for line in f:
                if line.startswith("Umask:"):
                    return int(line.split()[1], 8)
    except (OSError, ValueError, IndexError):
        pass
    mask = os.umask(0o022)  # elsewhere: read by setting (briefly, process-wide) and restoring
    os.umask(mask)
    return mask


def _fsync_folder(folder: Path) -> None:
    try:
        fd = os.open(folder, os.O_RDONLY)
    except OSError:  # Windows cannot open a folder; nothing to do there
        return
    try:
        os.fsync(fd)
    except OSError:
        pass
    finally:
        os.close(fd)


def _remove_orphans(folder: Path, prefix: str) -> None:
    """Remove ``prefix + PID.*.part*`` files in ``folder`` left by writers that were killed."""
    remove_orphan_parts(folder, prefix)


_PART = re.compile(r"^\.(?P<name>.+)\.(?P<pid>\d+)\.[A-Za-z0-9_]{8}\.part")


def remove_orphan_parts(folder, prefix: str = ".") -> list[str]:
    """Remove the temporary files (``.NAME.PID.XXXXXXXX.part*``, see ``atomic_write_file``) in
    ``folder`` whose writer is gone: its process ``PID`` no longer exists, or it is a later
    process that took the number (it started after the file was last written). Returns the
    names removed. Another process's file (alive, or another user's) is left alone."""
    try:
        entries = [e for e in os.scandir(folder) if e.name.startswith(prefix) and ".part" in e.name]
    except OSError:
        return []
    removed = []
    for e in entries:
        m = _PART.match(e.name)
        if m is None or int(m["pid"]) == os.getpid():
            continue
        try:
            written = e.stat(follow_symlinks=False).st_mtime
        except OSError:
            continue
        if not _writer_gone(int(m["pid"]), written):
            continue
        try:
            os.unlink(e.path)
            removed.append(e.name)
        except OSError:
            pass
    return removed


def _writer_gone(pid: int, written: float) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return True
    except (PermissionError, OSError, OverflowError):
        return False    # alive under another user (or not a pid at all): not ours to judge
    started = process_start_time(pid)
    return started is not None and started > written + 1.0   # the number was reused since


def process_start_time(pid: int) -> float | None:
    """When process ``pid`` started (seconds since the epoch), from /proc; None elsewhere."""
    try:
        with open(f"/proc/{pid}/stat") as f:
            fields = f.read().rsplit(")", 1)[1].split()
        with open("/proc/stat") as f:
            btime = next(int(line.split()[1]) for line in f if line.startswith("btime"))
        return btime + int(fields[19]) / os.sysconf("SC_CLK_TCK")
    except (OSError, ValueError, IndexError, StopIteration):
        return None


def png_bytes(srgb: np.ndarray, text: dict[str, str] | None = None) -> bytes:
    from PIL import Image, PngImagePlugin

    info = PngImagePlugin.PngInfo()
    for k, v in (text or {}).items():
        info.add_itxt(k, v)  # iTXt: UTF-8, so any scene text survives
    buf = io.BytesIO()
    Image.fromarray(np.ascontiguousarray(srgb, dtype=np.uint8)).save(buf, format="PNG", pnginfo=info)
    return buf.getvalue()


def write_png(path, srgb: np.ndarray, text: dict[str, str] | None = None) -> Path:
    """sRGB uint8 (H, W, 3) image, row 0 = top; ``text`` goes into PNG text chunks."""
    return atomic_write_bytes(path, png_bytes(srgb, text))


def write_npy(path, linear: np.ndarray) -> Path:
    buf = io.BytesIO()
    np.save(buf, np.ascontiguousarray(linear, dtype=np.float32))
    return atomic_write_bytes(path, buf.getvalue())


def read_png_text(path) -> dict[str, str]:
    """The text chunks of a PNG; a chunk that inflates past ``input_bounds.MAX_PNG_TEXT`` is a
    ValueError naming the bound (Pillow stops inflating there: no memory is spent on the rest)."""
    from PIL import Image, PngImagePlugin

    from viewer.base.input_bounds import MAX_PNG_TEXT

    PngImagePlugin.MAX_TEXT_CHUNK = MAX_PNG_TEXT       # Pillow's own bounds, set to ours
    PngImagePlugin.MAX_TEXT_MEMORY = 2 * MAX_PNG_TEXT
    try:
        with Image.open(path) as im:
            im.load()
            return dict(getattr(im, "text", {}) or {})
    except ValueError as e:
        if "MAX_TEXT" in str(e):
            raise ValueError(f"a text chunk larger than {MAX_PNG_TEXT} bytes") from None
        raise


def check_output_path(path, suffixes: tuple[str, ...], what: str) -> Path:
    p = Path(path)
    if p.suffix.lower() not in suffixes:
        raise ViewerError(f"{what} {path}: unsupported file type {p.suffix!r}; allowed: {', '.join(suffixes)}")
    folder = p.parent if str(p.parent) else Path(".")
    if not folder.is_dir():
        raise ViewerError(f"{what} {path}: the folder {folder} does not exist")
    return p
