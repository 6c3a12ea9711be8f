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

import logging
import os
import re
import tempfile
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from viewer import ViewerError

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
    raise ViewerError(f"{path}: {problem}")


def _read_head(path: Path, n: int = 4096) -> bytes:
    if not path.exists():
        _fail(path, "file not found")
    if not path.is_file():
        _fail(path, "not a file (a folder?); expected a Radiance .hdr or OpenEXR .exr image")
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
    if not exposure > 0:
        exposure = 1.0
    return exposure, (int(m.group(2)), int(m.group(4)))


def _read_hdr(path: Path) -> np.ndarray:
    import cv2

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
        img /= np.float32(exposure)
    return img


# ----------------------------------------------------------------------------- OpenEXR

def _read_exr(path: Path) -> np.ndarray:
    import OpenEXR

    try:
        with OpenEXR.File(str(path), separate_channels=True) as f:
            ch = {name: np.asarray(c.pixels) for name, c in f.channels().items()}
    except Exception as e:  # the bindings raise RuntimeError / ValueError with a C message
        text = str(e).strip().splitlines()[-1] if str(e).strip() else type(e).__name__
        _fail(path, f"truncated or corrupt OpenEXR data ({text})")
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
    (written beside it under a temporary name, then renamed), so a failure leaves no partial
    file. RGBE cannot store negative values: they are written as 0."""
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in SUFFIXES:
        _fail(path, f"unknown environment-map file type {path.suffix!r}; allowed: .hdr, .exr")
    a = np.asarray(array, dtype=np.float32)
    if a.ndim != 3 or a.shape[2] != 3 or a.shape[0] < 1 or a.shape[1] < 1:
        _fail(path, f"cannot write an array of shape {a.shape}; expected (height, width, 3)")
    folder = path.parent if str(path.parent) else Path(".")
    fd, tmp = tempfile.mkstemp(prefix=f".{path.stem}.", suffix=suffix, dir=folder)
    os.close(fd)
    try:
        if suffix == ".hdr":
            import cv2

            bgr = np.ascontiguousarray(np.maximum(a, 0.0)[..., ::-1])
            if not cv2.imwrite(tmp, bgr):
                _fail(path, "OpenCV could not write the Radiance file")
        else:
            import OpenEXR

            header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}
            with OpenEXR.File(header, {"RGB": np.ascontiguousarray(a)}) as f:
                f.write(tmp)
        os.replace(tmp, path)
    except OSError as e:
        _fail(path, f"cannot be written ({e.strerror or e})")
    finally:
        if os.path.exists(tmp):
            os.unlink(tmp)
