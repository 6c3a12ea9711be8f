"""References ready in advance: an on-disk cache of finished reference passes.

An entry is keyed by the SHA-256 of everything that changes the image (``setup_key``): the
estimator version, the world-space triangles, vertex normals and tangents, every material's
parameters, the lights, the environment (its radiance and rotation), the camera, the
resolution and ``max_depth``. Both engines estimate the same image, so the engine and the seed
are not part of the key; an entry records them and its running sums, so a renderer resumes
from it and keeps refining (new samples continue at sample index ``spp``: independent of the
stored ones for the same engine and seed, and for the other engine by construction).

Files: ``<cache folder>/references/<key>.npz`` (float32 sums of radiance and of its squares,
the sample count, engine, seed), written atomically (``viewer.base.io``). A damaged entry (truncated,
corrupt, wrong shapes, nonsense values) is set aside as ``<key>.npz.damaged`` with one line and
rendered afresh; a folder that cannot be written is reported (``CacheError``), never ignored.
Opening the folder (``open_folder``) removes the ``.part`` files of writers that were killed. The folder: ``$BRDF_VIEWER_CACHE``, else
``$XDG_CACHE_HOME/brdf-viewer``, else ``~/.cache/brdf-viewer``.
"""

from __future__ import annotations

import hashlib
import io
import os
import sys
import tempfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from viewer import OutputError, ViewerError
from viewer.base.io import MAX_CACHED_RADIANCE, cache_root  # noqa: F401  (cache_root: the folder's one definition; re-exported)
from viewer.scene.validation import short

#: bump when the estimator changes what it converges to (or its noise), so old entries are unused;
#: 2: the layered walk's coat scatters multiply, measured tables are read at their bins' centres,
#: tabulated metals keep RGB above 1 (gold's red) and films on them use the metal's own table
ESTIMATOR_VERSION = "2"


def cache_folder() -> Path:
    return cache_root() / "references"


def setup_key(setup) -> str:
    """The content hash of a ``RenderSetup`` (hex)."""
    h = hashlib.sha256()

    def add(tag, a):
        h.update(tag.encode())
        if isinstance(a, np.ndarray):
            a = np.ascontiguousarray(a)
            h.update(str((a.dtype.str, a.shape)).encode())
            h.update(a.tobytes())
        else:
            h.update(repr(a).encode())

    add("version", ESTIMATOR_VERSION)
    g = setup.geometry
    add("tri", np.asarray(g.triangles, np.float64))
    add("nrm", np.asarray(g.normals, np.float64))
    add("tan", np.asarray(g.tangents, np.float64))
    add("mat", np.asarray(g.material_index, np.int64))
    for m in setup.materials:
        add("material", (m.name, m.model_name, repr(m.params.to_plain()) if hasattr(m.params, "to_plain")
                         else repr(m.params)))
    # numbers as Python floats: the repr of a numpy scalar or array follows numpy's global print
    # options, which an imported library may change (legacy="1.13" writes 2. for np.float64(2.0))
    def floats(a):
        return tuple(float(x) for x in np.round(np.asarray(a, float), 12).ravel())

    for kind, a, v in setup.lights:
        add("light", (kind, floats(a), floats(v)))
    env = setup.env
    add("env", (floats(env.constant), float(env.rotation_deg), float(env.intensity)))
    if env.image is not None:
        add("envmap", np.asarray(env.image, np.float32))
    add("camera", tuple(round(float(x), 12) for x in (*setup.cam_pos, *setup.cam_forward, *setup.cam_right,
                                                       *setup.cam_up, setup.tan_half_y)))
    add("size", (setup.width, setup.height, setup.max_depth))
    # the estimator: its mean is the same for every option, its variance (sum2) is not
    add("estimator", (setup.strategy, setup.mis_heuristic, bool(setup.russian_roulette),
                      bool(setup.extra.get("spectral", False))))
    # the integrator: "photon" estimates caustic paths another way (its passes' photon maps); "path"
    # adds nothing, so the entries stored before there was a choice stay valid
    if getattr(setup, "integrator", "path") != "path":
        add("integrator", setup.integrator)
    return h.hexdigest()


@dataclass
class Entry:
    sum: np.ndarray          # (H, W, 3) float64
    sum2: np.ndarray         # (H, W, 3) float64
    spp: int
    engine: str
    seed: int

    def mean(self) -> np.ndarray:
        return (self.sum / max(self.spp, 1)).astype(np.float32)


_OPENED: set[str] = set()


def path_for(key: str, folder: Path | None = None) -> Path:
    return open_folder(folder) / f"{key}.npz"


def open_folder(folder: Path | None = None) -> Path:
    """The cache folder; the first time a process opens it, the ``.part`` files of writers that
    were killed mid-write (up to the size of an entry each) are removed (``viewer.base.io``)."""
    folder = folder or cache_folder()
    if str(folder) not in _OPENED:
        _OPENED.add(str(folder))
        from viewer.base.io import remove_orphan_parts

        remove_orphan_parts(folder)
    return folder


#: the most samples per pixel an entry may claim: far beyond any bake (2^32 spp at 1 spp/ms is 50
#: days), far below where the int64 count or a float32 sum would stop meaning anything
MAX_SPP = 2 ** 32
ENGINES = ("cpu", "gpu")


class CacheError(OutputError):
    """An entry that could not be written (an unwritable or full cache folder): one line."""


def say(message: str) -> None:
    """The default way the cache reports an entry it set aside: one line on stderr."""
    print(f"brdf-viewer: {message}", file=sys.stderr, flush=True)


def entry_problem(e: Entry, shape: tuple | None = None) -> str | None:
    """What makes ``e`` unusable (wrong shapes, a sample count out of range, NaN, Inf or negative
    sums, a mean radiance no scene makes), or None. Sums of radiance are >= 0 (the renderers
    replace NaN, Inf and negative values by 0 before adding) and their mean is at most
    ``MAX_CACHED_RADIANCE`` (finite garbage such as 3e38 everywhere is not an image); a sum of
    squares may overflow float32 to +inf (its variance then reads as unknown), never NaN or < 0."""
    if e.sum.ndim != 3 or e.sum.shape[2] != 3:
        return f"sums of shape {e.sum.shape}, not (H, W, 3)"
    if e.sum2.shape != e.sum.shape:
        return f"sums of squares of shape {e.sum2.shape}, sums of shape {e.sum.shape}"
    if shape is not None and tuple(e.sum.shape) != tuple(shape):
        return f"sums of shape {e.sum.shape}, the image is {tuple(shape)}"
    if not 1 <= e.spp <= MAX_SPP:
        return f"{short(str(e.spp))} samples per pixel; allowed: 1 to 2^32"
    if e.engine not in ENGINES:
        return f"engine {short(e.engine)!r}; allowed: {', '.join(ENGINES)}"
    if not np.all(np.isfinite(e.sum)):
        return "NaN or Inf in the sums"
    if np.any(e.sum < 0):
        return "negative sums"
    top = float(e.sum.max(initial=0.0)) / e.spp
    if top > MAX_CACHED_RADIANCE:
        return f"a mean radiance of {top:.3g}; plausible: at most {MAX_CACHED_RADIANCE:.0e}"
    if np.any(np.isnan(e.sum2)) or np.any(e.sum2 < 0):
        return "NaN or negative sums of squares"
    return None


def set_aside(path: Path, why: str, report=None) -> None:
    """Move a damaged entry out of the way (``NAME.damaged``, or delete it when it cannot be
    renamed) and say so in one line, so the caller renders afresh and the next store writes a
    good entry."""
    target = path.with_name(path.name + ".damaged")
    try:
        os.replace(path, target)
        done = "set aside as .damaged"
    except OSError:
        try:
            path.unlink()
            done = "removed"
        except OSError as e:
            done = f"left in place ({e.strerror or e})"
    (report or say)(f"reference cache: {path}: damaged ({why}); {done}, rendering afresh")


def load(key: str, folder: Path | None = None, shape: tuple | None = None, report=None) -> Entry | None:
    """The entry stored under ``key``, or None. A damaged entry (a truncated or corrupt file,
    wrong shapes, or ``shape`` = (H, W, 3) not matched, nonsense values: see ``entry_problem``)
    is set aside (``set_aside``) with one line through ``report`` (default: stderr) and None is
    returned, so the caller renders afresh. An entry that cannot be read (permissions) is None."""
    p = path_for(key, folder)
    try:
        with open(p, "rb") as f:
            data = f.read()
    except OSError:
        return None
    if not data.startswith(b"PK\x03\x04"):   # np.load would guess another format (a pickle) and say so
        set_aside(p, "not an .npz file", report)
        return None
    try:
        with np.load(io.BytesIO(data), allow_pickle=False) as z:
            kinds = {k: z[k].dtype for k in ("sum", "sum2")}
            e = Entry(np.asarray(z["sum"], np.float64), np.asarray(z["sum2"], np.float64),
                      int(z["spp"]), str(z["engine"]), int(z["seed"]))
    except Exception as ex:  # noqa: BLE001 - BadZipFile, zlib.error, ValueError, KeyError, EOFError, ...
        set_aside(p, short(f"{type(ex).__name__}: {ex}".splitlines()[0], 80), report)
        return None
    bad_kind = [f"{k} of dtype {d}" for k, d in kinds.items() if d.kind != "f"]
    why = ("sums stored as " + ", ".join(bad_kind) + ", not floats") if bad_kind else entry_problem(e, shape)
    if why is not None:
        set_aside(p, why, report)
        return None
    return e


def check_writable(folder: Path | None = None) -> Path:
    """Create the cache folder and write a probe file there; ``CacheError`` (one line) when
    either fails, so ``bake`` says so before it renders anything."""
    folder = folder or cache_folder()
    try:
        folder.mkdir(parents=True, exist_ok=True)
        fd, probe = tempfile.mkstemp(prefix=".probe.", suffix=".part", dir=folder)
        os.close(fd)
        os.unlink(probe)
    except OSError as e:
        raise CacheError(f"reference cache {folder}: cannot be written ({e.strerror or e}); "
                         "set BRDF_VIEWER_CACHE to a writable folder") from None
    return folder


def store(key: str, entry: Entry, folder: Path | None = None, report=None) -> bool:
    """Write ``entry`` unless the stored one already has as many samples; True when written,
    False when the stored entry is kept. A folder that cannot be written (unwritable, full)
    raises ``CacheError`` (one line naming the file and why): the caller says so."""
    from viewer.base.io import atomic_write_bytes

    old = load(key, folder, entry.sum.shape, report)
    if old is not None and old.spp >= entry.spp:
        return False
    buf = io.BytesIO()
    np.savez(buf, sum=entry.sum.astype(np.float32), sum2=entry.sum2.astype(np.float32),
             spp=np.int64(entry.spp), engine=np.str_(entry.engine), seed=np.int64(entry.seed))
    p = path_for(key, folder)
    try:
        p.parent.mkdir(parents=True, exist_ok=True)
        atomic_write_bytes(p, buf.getvalue())
    except OSError as e:   # the folder cannot be made, or the write failed (viewer.base.io: OutputError)
        why = str(e) if isinstance(e, ViewerError) else f"{p}: cannot be written ({e.strerror or e})"
        raise CacheError(f"reference cache: {short(why, 300)}; set BRDF_VIEWER_CACHE to a writable "
                         "folder") from None
    except ViewerError as e:   # e.g. the folder vanished between mkdir and the write
        raise CacheError(f"reference cache: {short(str(e), 300)}") from None
    return True
