"""References ready in advance: an on-disk cache of finished reference passes.

An entry is keyed by the SHA-256 of everything that changes the image (``setup_key``): the
estimator version, the world-space triangles, vertex normals and tangents, every material's
parameters, the lights, the environment (its radiance and rotation), the camera, the
resolution and ``max_depth``. Both engines estimate the same image, so the engine and the seed
are not part of the key; an entry records them and its running sums, so a renderer resumes
from it and keeps refining (new samples continue at sample index ``spp``: independent of the
stored ones for the same engine and seed, and for the other engine by construction).

Files: ``<cache folder>/references/<key>.npz`` (float32 sums of radiance and of its squares,
the sample count, engine, seed), written atomically (``viewer.io``); a damaged entry is
ignored. The folder: ``$BRDF_VIEWER_CACHE``, else
``$XDG_CACHE_HOME/brdf-viewer``, else ``~/.cache/brdf-viewer``.
"""

from __future__ import annotations

import hashlib
import io
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from viewer.io import cache_root  # noqa: F401  (the cache folder's one definition; re-exported)

#: bump when the estimator changes what it converges to (or its noise), so old entries are unused
ESTIMATOR_VERSION = "1"


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
    for kind, a, v in setup.lights:
        add("light", (kind, tuple(np.round(np.asarray(a, float), 12)), tuple(np.round(np.asarray(v, float), 12))))
    env = setup.env
    add("env", (tuple(env.constant), env.rotation_deg, env.intensity))
    if env.image is not None:
        add("envmap", np.asarray(env.image, np.float32))
    add("camera", tuple(round(float(x), 12) for x in (*setup.cam_pos, *setup.cam_forward, *setup.cam_right,
                                                       *setup.cam_up, setup.tan_half_y)))
    add("size", (setup.width, setup.height, setup.max_depth))
    # the estimator: its mean is the same for every option, its variance (sum2) is not
    add("estimator", (setup.strategy, setup.mis_heuristic, bool(setup.russian_roulette),
                      bool(setup.extra.get("spectral", False))))
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


def path_for(key: str, folder: Path | None = None) -> Path:
    return (folder or cache_folder()) / f"{key}.npz"


def load(key: str, folder: Path | None = None) -> Entry | None:
    """The entry stored under ``key``, or None (missing or unreadable)."""
    p = path_for(key, folder)
    try:
        with np.load(p, allow_pickle=False) as z:
            e = Entry(z["sum"].astype(np.float64), z["sum2"].astype(np.float64), int(z["spp"]),
                      str(z["engine"]), int(z["seed"]))
    except (OSError, ValueError, KeyError, EOFError):
        return None
    if e.spp < 1 or e.sum.shape != e.sum2.shape or e.sum.ndim != 3 or not np.all(np.isfinite(e.sum)):
        return None
    return e


def store(key: str, entry: Entry, folder: Path | None = None) -> bool:
    """Write ``entry`` unless the stored one already has as many samples; True when written.
    A cache folder that cannot be written is not an error (False)."""
    from viewer.io import atomic_write_bytes

    old = load(key, folder)
    if old is not None and old.spp >= entry.spp:
        return False
    buf = io.BytesIO()
    np.savez(buf, sum=entry.sum.astype(np.float32), sum2=entry.sum2.astype(np.float32),
             spp=np.int64(entry.spp), engine=np.str_(entry.engine), seed=np.int64(entry.seed))
    p = path_for(key, folder)
    try:
        p.parent.mkdir(parents=True, exist_ok=True)
        atomic_write_bytes(p, buf.getvalue())
    except OSError:
        return False
    return True
