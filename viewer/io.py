"""Writing output files atomically (temporary file in the same folder, then rename), so a kill
mid-write never leaves a partial file behind."""

from __future__ import annotations

import io
import os
import tempfile
from pathlib import Path

import numpy as np

from viewer import ViewerError


def atomic_write_bytes(path, data: bytes) -> Path:
    path = Path(path)
    folder = path.parent if str(path.parent) else Path(".")
    if not folder.is_dir():
        raise ViewerError(f"{path}: the folder {folder} does not exist")
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".part", dir=folder)
    try:
        with os.fdopen(fd, "wb") as f:
            f.write(data)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    except BaseException:
        try:
            os.unlink(tmp)
        except OSError:
            pass
        raise
    return path


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
    from PIL import Image

    with Image.open(path) as im:
        im.load()
        return dict(getattr(im, "text", {}) or {})


def check_output_path(path, suffixes: tuple[str, ...], what: str) -> Path:
    p = Path(path)
    if p.suffix.lower() not in suffixes:
        raise ViewerError(f"{what} {path}: unsupported file type {p.suffix!r}; allowed: {', '.join(suffixes)}")
    folder = p.parent if str(p.parent) else Path(".")
    if not folder.is_dir():
        raise ViewerError(f"{what} {path}: the folder {folder} does not exist")
    return p
