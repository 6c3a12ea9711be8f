"""A disk cache for prefiltered environments (``viewer.gl.ibl``), keyed by content.

* Where: ``$BRDF_VIEWER_CACHE`` when set (tests point it at a temporary folder), otherwise
  ``$XDG_CACHE_HOME/brdf-viewer``, otherwise ``~/.cache/brdf-viewer``.
* Key: a BLAKE2b hash of the map's bytes, shape and dtype, the prefilter settings (as sorted
  JSON) and ``CACHE_VERSION``; bump the version whenever the prefilter's output changes for the
  same settings (a shader fix), so stale entries are never read.
* Format: one uncompressed ``.npz`` per key (float data compresses poorly and ``np.load`` of an
  uncompressed archive is fast), written atomically (temporary file in the same folder, then
  rename: ``viewer.base.io.atomic_write_bytes``), so a crash or a concurrent writer never leaves a
  half-written entry under the final name.
* Failures never break rendering: a missing, truncated or corrupt file, or one whose stored key
  or arrays do not match, reads as a miss (logged) and is rebuilt and overwritten; an unwritable
  cache folder is logged and skipped.
"""

from __future__ import annotations

import hashlib
import io
import json
import logging
import os
from pathlib import Path

import numpy as np

log = logging.getLogger(__name__)

CACHE_VERSION = 1
ENV_VAR = "BRDF_VIEWER_CACHE"


def cache_dir() -> Path:
    """The cache folder (not created here)."""
    override = os.environ.get(ENV_VAR)
    if override:
        return Path(override).expanduser()
    xdg = os.environ.get("XDG_CACHE_HOME")
    base = Path(xdg).expanduser() if xdg else Path.home() / ".cache"
    return base / "brdf-viewer"


def content_key(data: np.ndarray | None, settings: dict, kind: str = "ibl") -> str:
    """Hex key of ``data`` (any array, or None) + ``settings`` (JSON-serializable) + the version."""
    h = hashlib.blake2b(digest_size=20)
    h.update(f"{kind}:v{CACHE_VERSION}:".encode())
    h.update(json.dumps(settings, sort_keys=True, default=_jsonable).encode())
    if data is not None:
        a = np.ascontiguousarray(data)
        h.update(f"{a.dtype.str}{a.shape}".encode())
        h.update(memoryview(a).cast("B"))
    return h.hexdigest()


def _jsonable(x):
    if isinstance(x, np.ndarray):
        return x.tolist()
    if isinstance(x, np.generic):
        return x.item()
    raise TypeError(f"not JSON-serializable: {type(x).__name__}")


def path_for(key: str, kind: str = "ibl") -> Path:
    return cache_dir() / f"{kind}-{key}.npz"


def load(key: str, kind: str = "ibl", expect: dict[str, tuple] | None = None) -> dict[str, np.ndarray] | None:
    """The arrays stored under ``key``, or None on a miss. ``expect`` maps array names to shapes
    they must have; an entry with a wrong key, a missing or misshapen array, or non-finite values
    is treated as corrupt (a miss)."""
    path = path_for(key, kind)
    if not path.is_file():
        return None
    try:
        with np.load(path, allow_pickle=False) as z:
            out = {name: z[name] for name in z.files}
        stored = out.get("key")
        if stored is None or stored.shape != () or str(stored.item()) != key:
            raise ValueError("stored key does not match")
        for name, shape in (expect or {}).items():
            a = out.get(name)
            if a is None or tuple(a.shape) != tuple(shape):
                raise ValueError(f"array {name!r} missing or of the wrong shape")
            if a.dtype.kind == "f" and not np.all(np.isfinite(a)):
                raise ValueError(f"array {name!r} has non-finite values")
        return out
    except Exception as e:  # noqa: BLE001 - any unreadable entry is a miss, rebuilt by the caller
        log.warning("ignoring corrupt cache file %s (%s); it will be rebuilt", path, e)
        return None


def store(key: str, arrays: dict[str, np.ndarray], kind: str = "ibl") -> Path | None:
    """Write ``arrays`` (plus the key) atomically; returns the path, or None if it could not."""
    from viewer.base.io import atomic_write_bytes

    path = path_for(key, kind)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        buf = io.BytesIO()
        np.savez(buf, key=np.array(key), **{k: np.ascontiguousarray(v) for k, v in arrays.items()})
        return atomic_write_bytes(path, buf.getvalue())
    except Exception as e:  # noqa: BLE001 - a cache that cannot be written is only slower
        log.warning("cannot write the environment cache %s (%s)", path, e)
        return None
