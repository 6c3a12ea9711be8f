"""Traced frames ready in advance: an on-disk cache of the window's finished progressive traces.

*Prepare lecture* (the window) and ``brdf-viewer bake --lecture`` trace every lecture step that
has traced chains for one window size and store the result here, so a prepared step opens fully
traced, without rendering a frame. An entry is the finished view as float32 texels (the untraced
frame where no chain starts, the traced pixels where one does: see
``viewer.gl.raytrace.ProgressiveTrace``).

**One entry serves every view of its height.** The camera's projection keeps the vertical field
of view, so a view ``w`` pixels wide is the centre of a wider view ``W`` of the same height, shifted
by ``(W - w) / 2`` pixels: exactly whole pixels when ``W - w`` is even. The window lays its 3D view
out with an even width (``viewer.app.layout.view_columns``), so one entry traced at the window's full width (rounded
down to even) holds the view of every layout at that window height: the lecture strip or the side
panel, plots docked or not, any UI scale. ``load`` crops it; a view of the entry's own width is
the live trace bit for bit, a narrower one equals a live trace of that width up to float rounding
in the projection (a few edge pixels whose coverage flips).

An entry's key is the SHA-256 of everything that changes the traced pixels: this module's
``VERSION``, the renderer version (the content of every shader file and the OpenGL renderer
string: another driver rounds differently), the scene as TOML (``scene_to_toml``: materials,
lights, environment, render switches), every object's mesh arrays and model matrix, the
environment map's texels, the camera's view and projection matrices, the view size, the view
mode and the untraced frame's MSAA, but of the view size only the height and the width's parity
(the projection is hashed at aspect 1: the field of view and the clip planes). Files: ``<cache folder>/traced/<key>.npz`` (``image``:
(H, W, 4) float32, 33 MB at 1920 x 1080), written atomically; an entry that cannot be read or
does not match the view it is keyed for is moved aside to ``<key>.npz.damaged`` and traced
again, and so is one of implausible texels (negative, or above ``viewer.base.io.MAX_CACHED_RADIANCE``:
finite garbage such as 3e38 everywhere). The folder is ``viewer.base.io.cache_root()``, beside the reference cache; it keeps the
newest ``MAX_ENTRIES`` entries.
"""

from __future__ import annotations

import hashlib
import io
import os
import zipfile
from pathlib import Path

import numpy as np

from viewer import ViewerError
from viewer.base.io import MAX_CACHED_RADIANCE, cache_root

#: bump when what the progressive trace stores (or how it composes) changes
VERSION = "2"
MAX_ENTRIES = 24

_shader_hash: dict = {}
_last_failure: list[str] = []   # why the last store wrote nothing (store_failure)
_array_hash: dict = {}


def cache_folder() -> Path:
    return cache_root() / "traced"


def renderer_version(gl_renderer: str = "") -> str:
    """The SHA-256 of every shader file (path and content) and ``gl_renderer``: a shader edit or
    another driver makes older entries unused. The file hash is kept per (path, mtime, size)."""
    from viewer.gl.shaders import shader_root

    root = Path(shader_root())
    files = sorted(p for p in root.rglob("*") if p.is_file() and p.suffix in (".glsl", ".vert", ".frag", ".geom"))
    stamp = tuple((str(p.relative_to(root)), p.stat().st_mtime_ns, p.stat().st_size) for p in files)
    if _shader_hash.get("stamp") != stamp:
        h = hashlib.sha256()
        for p in files:
            h.update(str(p.relative_to(root)).replace("\\", "/").encode())
            h.update(p.read_bytes())
        _shader_hash.update(stamp=stamp, digest=h.hexdigest())
    return hashlib.sha256((_shader_hash["digest"] + "\n" + gl_renderer).encode()).hexdigest()


def _hash_array(a) -> str:
    """SHA-256 of an array's dtype, shape and bytes; kept per object for read-only arrays (mesh
    data and environment maps are not edited in place)."""
    a = np.asarray(a)
    key = id(a)
    hit = _array_hash.get(key)
    if hit is not None and hit[0] is a:
        return hit[1]
    h = hashlib.sha256(str((a.dtype.str, a.shape)).encode())
    h.update(np.ascontiguousarray(a).tobytes())
    digest = h.hexdigest()
    if not a.flags.writeable:
        _array_hash[key] = (a, digest)
        if len(_array_hash) > 256:
            _array_hash.pop(next(iter(_array_hash)))
    return digest


def frame_key(scene, camera, width: int, height: int, view_mode: int = 0, msaa=None,
              gl_renderer: str = "") -> str:
    """The content hash (hex) of one traced view: see the module's docstring."""
    from viewer.scene.camera import OrbitCamera, gl_bytes
    from viewer.scene import scene_to_toml

    camera = camera or OrbitCamera.from_scene(scene)
    h = hashlib.sha256()

    def add(tag, value):
        h.update(tag.encode() + b"\0")
        h.update(value if isinstance(value, bytes) else repr(value).encode())

    add("version", VERSION)
    add("renderer", renderer_version(gl_renderer))
    add("scene", scene_to_toml(scene).encode())
    for o in scene.objects:
        m = o.mesh_data
        add("object", (o.material, _hash_array(m.positions), _hash_array(m.normals), _hash_array(m.tangents),
                       _hash_array(m.indices)))
        add("model", np.asarray(o.model_matrix(), np.float64).tobytes())
    env_map = scene.environment.radiance_map() if scene.environment.map is not None else None
    if env_map is not None:
        add("envmap", _hash_array(env_map))
    add("view", gl_bytes(camera.view()))
    add("projection", gl_bytes(camera.projection(1.0)))  # every aspect's: see the module's docstring
    add("size", (int(width) % 2, int(height), int(view_mode), scene.render.msaa if msaa is None else int(msaa)))
    return h.hexdigest()


def path_for(key: str, folder: Path | None = None) -> Path:
    return (folder or cache_folder()) / f"{key}.npz"


def set_aside(path: Path) -> Path | None:
    """Move a damaged entry out of the way (``.damaged``); the path it went to, or None."""
    target = path.with_name(path.name + ".damaged")
    try:
        os.replace(path, target)
    except OSError:
        return None
    return target


def entry_width(path: Path) -> int | None:
    """The width of the view an entry holds, read from its array header alone (no pixel is
    read), or None when the entry cannot be read."""
    try:
        with zipfile.ZipFile(path) as z, z.open("image.npy") as f:
            version = np.lib.format.read_magic(f)
            shape = _header_shape(f, version)
        return int(shape[1]) if len(shape) == 3 else None
    except (OSError, ValueError, KeyError, EOFError, TypeError, IndexError, zipfile.BadZipFile):
        return None


def _header_shape(f, version):
    if version == (1, 0):
        return np.lib.format.read_array_header_1_0(f)[0]
    return np.lib.format.read_array_header_2_0(f)[0]


def crop(image: np.ndarray, width: int) -> np.ndarray:
    """The centre ``width`` columns of an entry (``width`` of the entry's parity and at most its
    width): the narrower view of the same height (see the module's docstring)."""
    x0 = (image.shape[1] - int(width)) // 2
    return np.ascontiguousarray(image[:, x0:x0 + int(width)])


def load(key: str, shape, folder: Path | None = None):
    """(the stored view as (H, W, 4) float32 texels, "") or (None, why): why is "" when there
    is no entry for a view this wide (none, or one traced for a narrower window), else the
    reason the entry was set aside (unreadable, not float32, not of this view's height or
    parity, not finite, negative or beyond ``MAX_CACHED_RADIANCE``). An entry of a wider view
    is cropped to ``shape``."""
    p = path_for(key, folder)
    if not p.is_file():
        return None, ""
    h, w = int(shape[0]), int(shape[1])
    stored_w = entry_width(p)
    if stored_w is not None and stored_w < w:
        return None, ""  # prepared for a narrower window: traced live (and stored wider then)
    try:
        with np.load(p, allow_pickle=False) as z:
            stored = z["image"]
        image = np.asarray(stored, np.float32)
        why = ""
        if stored.dtype != np.float32:
            why = f"it holds {stored.dtype} values, not float32 texels"
        elif image.ndim != 3 or image.shape[0] != h or image.shape[2] != 4 or (image.shape[1] - w) % 2:
            why = f"it holds a {image.shape} image, not a view {h} high like the view's {w}x{h}"
        elif not np.all(np.isfinite(image)):
            why = "it holds values that are not finite"
        elif image.min(initial=0.0) < -1e-3:
            why = f"it holds negative radiance ({float(image.min()):.3g})"
        elif image.max(initial=0.0) > MAX_CACHED_RADIANCE:
            why = f"it holds a radiance of {float(image.max()):.3g}; plausible: at most {MAX_CACHED_RADIANCE:.0e}"
    except (OSError, ValueError, KeyError, EOFError, TypeError, zipfile.BadZipFile) as e:
        why = f"unreadable ({type(e).__name__})"
    if why:
        set_aside(p)
        return None, f"traced cache entry {p.name} set aside: {why}"
    return (image if image.shape[1] == w else crop(image, w)), ""


def store(key: str, image: np.ndarray, folder: Path | None = None) -> Path | None:
    """Write an entry ((H, W, 4) float32 texels, texture row order) atomically; its path, or
    None when the cache folder cannot be written (never an error: the view is traced live
    then). An entry of a wider view under the key is kept (it holds this view too). Keeps the
    newest ``MAX_ENTRIES``."""
    from viewer.base.io import atomic_write_bytes

    p = path_for(key, folder)
    _last_failure.clear()
    have = entry_width(p) if p.is_file() else None
    if have is not None and have > image.shape[1]:
        return p
    buf = io.BytesIO()
    np.save(buf, np.ascontiguousarray(image, np.float32))
    data = io.BytesIO()
    with zipfile.ZipFile(data, "w", zipfile.ZIP_STORED) as z:
        z.writestr("image.npy", buf.getvalue())
    try:
        p.parent.mkdir(parents=True, exist_ok=True)
        atomic_write_bytes(p, data.getvalue())
        entries = sorted(p.parent.glob("*.npz"), key=lambda q: q.stat().st_mtime_ns)
        for old in entries[:-MAX_ENTRIES]:
            old.unlink(missing_ok=True)
    except (OSError, ViewerError) as e:
        # viewer.base.io's errors name the file and why; a plain OSError (mkdir) says why
        why = str(e) if isinstance(e, ViewerError) else f"{p}: cannot be written ({e.strerror or e})"
        _last_failure.append(why.splitlines()[0] if why else type(e).__name__)
        return None
    return p


def store_failure() -> str:
    """Why the last ``store`` wrote nothing (one line naming the file and the reason, e.g. "No
    space left on device"), or "" when it wrote its entry."""
    return _last_failure[-1] if _last_failure else ""
