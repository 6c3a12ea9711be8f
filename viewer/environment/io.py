"""Reading and writing environment maps: Radiance RGBE (``.hdr``) and OpenEXR (``.exr``).

Libraries (both from PyPI as binary wheels, no downloads at run time):

* OpenEXR files through ``OpenEXR``, the Academy Software Foundation's official Python
  bindings (half, float and uint channels; scanline or tiled; any compression).
* Radiance files through OpenCV (``opencv-python-headless``), whose RGBE codec is Greg Ward's
  reference reader (flat and run-length encoded scanlines). imageio was tried and rejected:
  without the FreeImage plug-in (a run-time download) it decodes .hdr to 8 bits.

The format is decided by the file's first bytes, not its name: ``#?RADIANCE`` / ``#?RGBE``
for Radiance, ``76 2f 31 01`` for OpenEXR.

What is accepted, what is refused (every refusal is a ``ViewerError``, one line naming the
file and the problem):

* missing, a folder, unreadable (permissions): refused;
* not a Radiance/OpenEXR file (e.g. a PNG renamed .hdr), truncated or corrupt data, a Radiance
  orientation other than the standard ``-Y H +X W``, an EXR with no R, G, B or Y channel:
  refused;
* size: any width >= 2 and height >= 1 is accepted (a lat-long map is normally 2:1; other
  aspect ratios are stretched onto the sphere and reported as a warning);
* NaN, infinite or negative texels (possible in EXR): set to 0, counted in
  ``EnvironmentImage.sanitized`` and reported as a warning (logging, logger
  ``viewer.environment``), so one bad texel does not make a whole map unusable;
* Radiance ``EXPOSURE=`` header lines are honoured (values are divided by their product, as
  the Radiance format defines); a grey ``Y`` EXR is expanded to RGB; alpha is dropped.

Arrays are float32 (H, W, 3), linear radiance, row 0 = top of the image = the zenith of a
lat-long map (``viewer.environment.latlong``); neither format needs a flip.
"""

from __future__ import annotations

import contextlib
import io
import logging
import os
import re
import sys
import tempfile
import threading
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from viewer import ViewerError
from viewer.base.io import atomic_write_file, one_line, path_problem
from viewer.base.optional import require

log = logging.getLogger("viewer.environment")

EXR_MAGIC = b"\x76\x2f\x31\x01"
HDR_MAGICS = (b"#?RADIANCE", b"#?RGBE")
_OTHER_MAGICS = (  # for a friendlier message when the file is something else
    (b"\x89PNG\r\n\x1a\n", "a PNG image"),
    (b"\xff\xd8\xff", "a JPEG image"),
    (b"GIF8", "a GIF image"),
    (b"II*\x00", "a TIFF image"),
    (b"MM\x00*", "a TIFF image"),
    (b"BM", "a BMP image"),
    (b"\x93NUMPY", "a numpy .npy file"),
)
SUFFIXES = (".hdr", ".exr")
MAX_TEXELS = 1 << 30  # OpenCV's own limit (CV_IO_MAX_IMAGE_PIXELS); 12 GiB as float32 RGB


@dataclass
class EnvironmentImage:
    """A decoded map: ``pixels`` float32 (H, W, 3); ``format`` "hdr" or "exr"; ``sanitized``
    the number of texels whose NaN / infinite / negative values were set to 0; ``warnings``
    one-line notes (each also logged)."""

    pixels: np.ndarray
    path: Path
    format: str
    sanitized: int = 0
    warnings: list = field(default_factory=list)


def _fail(path, problem: str):
    raise ViewerError(one_line(f"{path}: {problem}"))


def _read_head(path: Path, n: int = 4096) -> bytes:
    problem = path_problem(path)
    if problem == "file not found":
        _fail(path, problem)
    if problem is not None:
        _fail(path, f"not a file ({problem}); expected a Radiance .hdr or OpenEXR .exr image")
    try:
        with open(path, "rb") as fh:
            return fh.read(n)
    except OSError as e:
        _fail(path, f"cannot be read ({e.strerror or e})")


def sniff_format(head: bytes) -> str | None:
    """"hdr", "exr" or None from a file's first bytes."""
    if head.startswith(EXR_MAGIC):
        return "exr"
    if any(head.startswith(m) for m in HDR_MAGICS):
        return "hdr"
    return None


def check_environment_file(path) -> str:
    """Cheap check (first bytes only) that ``path`` exists, is readable and is a Radiance or
    OpenEXR file; returns "hdr" or "exr". The full decode happens in ``read_environment``."""
    path = Path(path)
    head = _read_head(path)
    fmt = sniff_format(head)
    if fmt is None:
        what = next((name for magic, name in _OTHER_MAGICS if head.startswith(magic)), None)
        if not head:
            what = "an empty file"
        _fail(path, "not a Radiance .hdr or OpenEXR .exr image"
              + (f" (it is {what})" if what else " (no #?RADIANCE or OpenEXR signature)"))
    return fmt


def read_environment(path) -> EnvironmentImage:
    """Decode a Radiance or OpenEXR file into an ``EnvironmentImage`` (see the module notes)."""
    path = Path(path)
    fmt = check_environment_file(path)
    img = _read_hdr(path) if fmt == "hdr" else _read_exr(path)
    if img.ndim != 3 or img.shape[2] != 3:
        _fail(path, f"decoded to an array of shape {img.shape}; expected (height, width, 3)")
    h, w = img.shape[:2]
    if w < 2 or h < 1:
        _fail(path, f"image is {w} x {h} texels; a lat-long map needs width >= 2 and height >= 1")
    out = EnvironmentImage(np.ascontiguousarray(img, dtype=np.float32), path, fmt)
    if w != 2 * h:
        out.warnings.append(f"{path}: image is {w} x {h}, not 2:1; it is stretched onto the sphere as a lat-long map")
    bad = ~np.isfinite(out.pixels) | (out.pixels < 0)
    if bad.any():
        out.sanitized = int(bad.any(axis=-1).sum())
        out.pixels[bad] = 0.0
        out.warnings.append(f"{path}: {out.sanitized} texels had NaN, infinite or negative values; set to 0")
    for msg in out.warnings:
        log.warning(msg)
    return out


def load_environment(path) -> np.ndarray:
    """float32 (H, W, 3) linear radiance of a Radiance ``.hdr`` or OpenEXR ``.exr`` lat-long map
    (row 0 = zenith). Bad files raise ``ViewerError``; NaN / infinite / negative texels are set
    to 0 with a logged warning (``read_environment`` also returns the count)."""
    return read_environment(path).pixels


# ----------------------------------------------------------------------------- Radiance

_HDR_RES = re.compile(rb"^\s*([-+][XY])\s+(\d+)\s+([-+][XY])\s+(\d+)\s*$")


def _hdr_header(path: Path) -> tuple[float, tuple[int, int]]:
    """(exposure product, (height, width)) from the text header of a Radiance file."""
    with open(path, "rb") as fh:
        head = fh.read(65536)
    end = head.find(b"\n\n")
    if end < 0:
        _fail(path, "truncated or corrupt Radiance header (no blank line before the resolution)")
    exposure = 1.0
    for line in head[:end].split(b"\n")[1:]:
        if line.startswith(b"EXPOSURE="):
            try:
                exposure *= float(line.split(b"=", 1)[1])
            except ValueError:
                _fail(path, f"bad Radiance header line {line[:40].decode('latin-1')!r}")
        elif line.startswith(b"FORMAT=") and b"32-bit_rle_rgbe" not in line:
            _fail(path, f"unsupported Radiance pixel format {line[7:40].decode('latin-1')!r}; allowed: 32-bit_rle_rgbe")
    nl = head.find(b"\n", end + 2)
    res_line = head[end + 2: nl if nl >= 0 else len(head)]
    m = _HDR_RES.match(res_line)
    if nl < 0 or not m:
        _fail(path, "truncated or corrupt Radiance header (no resolution line)")
    if (m.group(1), m.group(3)) != (b"-Y", b"+X"):
        _fail(path, f"unsupported Radiance orientation {res_line.decode('latin-1').strip()!r}; "
                    "allowed: the standard '-Y height +X width'")
    if not (0.0 < exposure < float("inf")):
        log.warning(f"{path}: EXPOSURE in the Radiance header multiplies to {exposure:g}; ignored (taken as 1)")
        exposure = 1.0
    h, w = int(m.group(2)), int(m.group(4))
    if h * w > MAX_TEXELS:
        _fail(path, f"image is {w} x {h} texels; at most {MAX_TEXELS} texels (2^30) are read")
    return exposure, (h, w)


def _read_hdr(path: Path) -> np.ndarray:
    cv2 = require("cv2")

    exposure, (h, w) = _hdr_header(path)
    if w < 2 or h < 1:
        _fail(path, f"image is {w} x {h} texels; a lat-long map needs width >= 2 and height >= 1")
    log_api = getattr(getattr(cv2, "utils", None), "logging", None)
    old = log_api.getLogLevel() if log_api is not None else None
    try:
        if old is not None:  # silence OpenCV's own log line: our message replaces it
            log_api.setLogLevel(log_api.LOG_LEVEL_SILENT)
        img = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
    except cv2.error as e:  # pragma: no cover - imread reports failure by returning None
        _fail(path, f"truncated or corrupt Radiance data ({str(e).strip().splitlines()[-1]})")
    finally:
        if old is not None:
            log_api.setLogLevel(old)
    if img is None:
        _fail(path, "truncated or corrupt Radiance data (the decoder stopped before the last scanline)")
    if img.shape[:2] != (h, w):
        _fail(path, f"decoded {img.shape[1]} x {img.shape[0]} texels but the header says {w} x {h}")
    img = img[..., ::-1].astype(np.float32)  # OpenCV gives BGR
    if exposure != 1.0:
        with np.errstate(all="ignore"):  # a tiny EXPOSURE: the texels that overflow are inf,
            img = (img / exposure).astype(np.float32)  # then set to 0 and counted as bad texels
    return img


# ----------------------------------------------------------------------------- OpenEXR

_QUIET_LOCK = threading.Lock()


@contextlib.contextmanager
def _captured_output():
    """Collect what C libraries print to the process's stdout and stderr (file descriptors 1 and
    2) while the block runs, instead of letting it reach the terminal; yields a list that holds
    the text afterwards. The OpenEXR library prints its own lines for a corrupt file
    ("(EXR_ERR_BAD_CHUNK_LEADER) ...", "Warning: Exception raised reading pixel data ...") beside
    the exception it raises, and a bad file must give one message, ours. Python-level output of
    other threads during the few milliseconds of a read is captured too (and dropped)."""
    out: list[str] = []
    with _QUIET_LOCK, tempfile.TemporaryFile() as sink:
        for stream in (sys.stdout, sys.stderr):
            try:
                stream.flush()
            except (AttributeError, OSError, ValueError):
                pass
        _flush_c_stdio()  # what others wrote before goes where it belongs
        saved = []
        py_streams = (sys.stdout, sys.stderr)
        py_sink = io.StringIO()
        try:
            for fd in (1, 2):
                try:
                    saved.append((fd, os.dup(fd)))
                    os.dup2(sink.fileno(), fd)
                except OSError:  # no such descriptor (a service without stdio): nothing to hide
                    pass
            # the bindings' own warnings go through Python's print (sys.stdout), which need not
            # be file descriptor 1 (pytest's capture, an IDE console)
            sys.stdout = sys.stderr = py_sink
            yield out
        finally:
            sys.stdout, sys.stderr = py_streams
            _flush_c_stdio()  # the C library's lines sit in C stdio's buffer until flushed
            for fd, copy in saved:
                os.dup2(copy, fd)
                os.close(copy)
            sink.seek(0)
            text = py_sink.getvalue() + sink.read(1 << 16).decode("utf-8", "replace")
            out.extend(line for line in text.splitlines() if line.strip())


def _flush_c_stdio() -> None:
    """fflush(NULL): C and C++ streams buffer output written to a pipe or file."""
    try:
        import ctypes

        ctypes.CDLL(None).fflush(None)
    except (OSError, AttributeError, TypeError):  # no C library to ask (not POSIX)
        pass


def _exr_library_problem(lines: list[str], path: Path) -> str | None:
    """The most informative line the OpenEXR library printed, without the file name."""
    for line in lines:
        text = line.replace(str(path), "").split(" - ", 1)[-1] if "Exception raised reading" in line \
            else line.replace(str(path), "")
        text = " ".join(text.split()).lstrip(":; ")
        if text:
            return text[:200]
    return None


def _read_exr(path: Path) -> np.ndarray:
    OpenEXR = require("OpenEXR")

    error = None
    with _captured_output() as printed:
        try:
            # The header first: the bindings allocate the data window before reading a texel,
            # so a corrupt 100000 x 100000 window would ask for 37 GiB.
            with OpenEXR.File(str(path), header_only=True) as f:
                (x0, y0), (x1, y1) = (np.asarray(v, dtype=np.int64) for v in f.header()["dataWindow"])
            w, h = int(x1 - x0 + 1), int(y1 - y0 + 1)
            if w < 1 or h < 1 or w * h > MAX_TEXELS:
                _fail(path, f"OpenEXR data window is {w} x {h} texels; allowed: 1 to {MAX_TEXELS} texels (2^30)")
            with OpenEXR.File(str(path), separate_channels=True) as f:
                ch = {name: np.asarray(c.pixels) for name, c in f.channels().items()}
        except ViewerError:
            raise
        except Exception as e:  # the bindings raise RuntimeError / ValueError with a C message
            error = e
    detail = _exr_library_problem(printed, path)
    if error is not None:
        text = str(error).strip().splitlines()[-1].replace(str(path), "the file") if str(error).strip() \
            else type(error).__name__
        _fail(path, f"truncated or corrupt OpenEXR data ({detail or text})")
    if any("Exception raised reading pixel data" in line for line in printed):
        # the bindings report a failed pixel read by printing, and return what they have
        _fail(path, f"truncated or corrupt OpenEXR data ({detail})")
    # Channel names may carry a layer prefix ("diffuse.R"); take the unprefixed ones first.
    def pick(name):
        if name in ch:
            return ch[name]
        for k in sorted(ch):
            if k.rsplit(".", 1)[-1] == name:
                return ch[k]
        return None

    r, g, b = pick("R"), pick("G"), pick("B")
    if r is not None and g is not None and b is not None:
        img = np.stack([r, g, b], axis=-1)
    else:
        y = pick("Y")
        if y is None:
            _fail(path, "OpenEXR file has no R, G, B or Y channels (it has: "
                  + (", ".join(sorted(ch)) or "none") + ")")
        img = np.repeat(y[..., None], 3, axis=-1)
    if img.ndim != 3:
        _fail(path, f"OpenEXR channels have shape {img.shape[:-1]}; expected (height, width)")
    return img.astype(np.float32)


# ----------------------------------------------------------------------------- writing

def save_environment(path, array) -> None:
    """Write float (H, W, 3) linear radiance to ``path`` (.hdr: Radiance RGBE, run-length
    encoded; .exr: OpenEXR, 32-bit float RGB, ZIP compression). The file appears atomically
    (written beside it under a temporary name, fsynced, then renamed: ``viewer.base.io.atomic_write_file``),
    so a failure or a kill leaves no partial file. RGBE cannot store negative values: they are written as 0."""
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in SUFFIXES:
        _fail(path, f"unknown environment-map file type {path.suffix!r}; allowed: .hdr, .exr")
    a = np.asarray(array, dtype=np.float32)
    if a.ndim != 3 or a.shape[2] != 3 or a.shape[0] < 1 or a.shape[1] < 1:
        _fail(path, f"cannot write an array of shape {a.shape}; expected (height, width, 3)")
    def write(tmp: Path):
        if suffix == ".hdr":
            cv2 = require("cv2")
            bgr = np.ascontiguousarray(np.maximum(a, 0.0)[..., ::-1])
            if not cv2.imwrite(str(tmp), bgr):
                _fail(path, "OpenCV could not write the Radiance file")
        else:
            OpenEXR = require("OpenEXR")
            header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}
            with OpenEXR.File(header, {"RGB": np.ascontiguousarray(a)}) as f:
                f.write(str(tmp))

    try:
        atomic_write_file(path, write, suffix=suffix)
    except OSError as e:
        _fail(path, f"cannot be written ({e.strerror or e})")
