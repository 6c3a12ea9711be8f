"""Mesh loading: built-in shapes and files (OBJ, PLY, STL, OFF, GLB/GLTF via trimesh).

Both renderers use a mesh exactly as :func:`load_mesh` returns it (same triangles, same
vertex normals, same tangents). What loading does, in order:

1. Read the file with trimesh without its processing (``process=False``), so the file's
   vertices stay as they are: an OBJ's ``v/vt/vn`` corners that differ in ``vn`` remain
   separate vertices (flat-shaded split normals survive). A scene (GLB/GLTF, multi-object
   files) is flattened into one mesh with every node's transform applied (normals with the
   inverse transpose, winding reversed under a mirroring transform).
2. Reject non-finite coordinates and out-of-range face indices; drop degenerate faces
   (repeated indices, or area ~ 0 relative to the mesh size or to the triangle's longest
   edge) and vertices no face uses. No faces left = an error.
3. Normals: the file's vertex normals, normalised, where present and valid; otherwise
   smooth area-weighted normals, accumulated over all vertices at the same position (so
   vertices split only by uv seams still shade smoothly).
4. Vertices identical in position, normal and uv are merged (an STL's triangle soup
   becomes an indexed mesh).
5. Tangents (xyz unit, orthogonal to the normal; w = bitangent sign) from the uvs where the
   mesh has non-degenerate uvs (per-triangle dP/du accumulated per vertex with the
   triangle's area as weight, then Gram-Schmidt against the normal), else the fallback
   t = normalize(cross(+y, n)), or +x projected where n is parallel to y, with w = +1.
   The tangent is the +x axis of the shading frame, along which an anisotropic BRDF's
   ``nu`` / ``alpha_x`` runs (docs/conventions.md).

Built-in names load ``models/<name>.ply`` when present, else the same shape generated in
memory by :mod:`viewer.scene.meshgen`; both go through the same steps from float32 data, so the
result is identical either way. A file reference ``sphere.ply`` (no folder) that does not
exist next to the scene falls back to the built-in of that name.

Every problem is a :class:`viewer.ViewerError` with the one-line message
``"{where}: {path}: {problem}"``. Results are cached (key: resolved path, mtime, size);
each call returns fresh arrays, so callers may modify them.
"""

from __future__ import annotations

import contextlib
import io
import os
import threading
from collections import OrderedDict
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from viewer import ViewerError
from viewer.scene import meshgen
from viewer.base.input_bounds import mesh_problem
from viewer.base.io import expand_user, one_line_errors, stat_file
from viewer.base.resources import MODEL_DIR

EXTENSIONS = (".obj", ".ply", ".stl", ".off", ".glb", ".gltf")

_CACHE: "OrderedDict[tuple, MeshData]" = OrderedDict()
_CACHE_SIZE = 64
_CACHE_LOCK = threading.Lock()


@dataclass
class MeshData:
    name: str
    positions: np.ndarray   # float32 (V,3)
    normals: np.ndarray     # float32 (V,3), unit length
    tangents: np.ndarray    # float32 (V,4): xyz unit tangent orthogonal to the normal, w = bitangent sign
    uvs: np.ndarray         # float32 (V,2), zeros if the file has none
    indices: np.ndarray     # uint32 (F,3)

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """(min xyz, max xyz) of the vertex positions, float32; kept for the positions array they
        were taken of (a tiled frame asks for them each tile, for every object)."""
        kept = self.__dict__.get("_bounds")
        if kept is None or kept[0] is not self.positions:
            kept = self.__dict__["_bounds"] = (self.positions, self.positions.min(axis=0), self.positions.max(axis=0))
        return kept[1], kept[2]

    def copy(self) -> "MeshData":
        return MeshData(self.name, self.positions.copy(), self.normals.copy(), self.tangents.copy(),
                        self.uvs.copy(), self.indices.copy())


def builtin_names() -> list[str]:
    """Every built-in mesh name, in a fixed order."""
    return list(meshgen.GENERATORS)


# --------------------------------------------------------------------------- public loading

@one_line_errors
def load_mesh(ref: str, base_dir: Path | None = None, where: str = "mesh") -> MeshData:
    """Load a built-in mesh by name or a mesh file (relative paths against ``base_dir``,
    else the working directory). Raises ViewerError on any problem, with a one-line message
    (a line break in a file name is written as an escape). The same file unchanged (or the same
    built-in) gives the same object, its arrays read-only (``copy()`` for one to edit)."""
    if not isinstance(ref, (str, os.PathLike)) or str(ref).strip() == "":
        raise ViewerError(f"{where}: {ref!r}: expected a built-in mesh name "
                          f"({', '.join(builtin_names())}) or a mesh file path")
    ref_s = str(ref)
    if ref_s in meshgen.GENERATORS:
        return _load_builtin(ref_s, where)

    path = expand_user(ref_s)
    if not path.is_absolute() and base_dir is not None:
        path = Path(base_dir) / path
    try:
        path = path.resolve()
    except (OSError, RuntimeError, ValueError):  # a symlink loop, a NUL character
        path = path.absolute()

    ext = path.suffix.lower()
    if ext not in EXTENSIONS:
        what = f"unsupported extension '{path.suffix}'" if path.suffix else "not a built-in mesh name and no file extension"
        raise ViewerError(f"{where}: {path}: {what} (allowed: {', '.join(EXTENSIONS)}; "
                          f"or a built-in name: {', '.join(builtin_names())})")
    st, problem = stat_file(path)
    if problem is not None:
        stem = Path(ref_s).stem
        if (Path(ref_s).name == ref_s and ext == ".ply" and stem in meshgen.GENERATORS):
            return _load_builtin(stem, where)
        raise ViewerError(f"{where}: {path}: {problem}")
    problem = mesh_problem(path, st.st_size)  # its size and header, before a parser reads it
    if problem is not None:
        raise ViewerError(f"{where}: {path}: {problem}")

    key = ("file", str(path), st.st_mtime_ns, st.st_size)
    cached = _cache_get(key)
    if cached is not None:
        return cached
    mesh = read_mesh_file(path, path.stem, where)
    _cache_put(key, mesh)
    return mesh


def _load_builtin(name: str, where: str) -> MeshData:
    path = MODEL_DIR / f"{name}.ply"
    try:
        st = path.stat() if path.is_file() else None
    except OSError:
        st = None
    if st is not None:
        key = ("file", str(path.resolve()), st.st_mtime_ns, st.st_size)
        cached = _cache_get(key)
        if cached is None:
            try:
                own = read_own_ply(path)
            except OSError:
                own = None
            if own is not None:  # the format models/generate.py writes: no trimesh needed
                cached = build_mesh(name, *own[:2], own[3], own[2], where=where, label=str(path))
            else:
                cached = read_mesh_file(path, name, where)
            _cache_put(key, cached)
        return cached
    key = ("builtin", name)
    cached = _cache_get(key)
    if cached is None:
        shape = meshgen.generate(name)
        cached = build_mesh(name, shape.positions, shape.normals, shape.indices, shape.uvs,
                            where=where, label=f"built-in {name}")
        _cache_put(key, cached)
    return cached


def clear_cache() -> None:
    with _CACHE_LOCK:
        _CACHE.clear()


def _cache_get(key):
    with _CACHE_LOCK:
        m = _CACHE.get(key)
        if m is not None:
            _CACHE.move_to_end(key)
        return m


def _cache_put(key, mesh: MeshData) -> None:
    """Keep ``mesh`` for its file (or built-in name), its arrays made read-only: every scene
    that loads the same mesh gets this one object, so what is made per mesh object (the GPU's
    vertex buffers, the shadow atlas over the objects, the traced BVH's key) is made once, not
    again for a scene opened again (``MeshData.copy`` gives an array that may be edited)."""
    for a in (mesh.positions, mesh.normals, mesh.tangents, mesh.uvs, mesh.indices):
        a.setflags(write=False)
    with _CACHE_LOCK:
        _CACHE[key] = mesh
        _CACHE.move_to_end(key)
        while len(_CACHE) > _CACHE_SIZE:
            _CACHE.popitem(last=False)


# --------------------------------------------------------------------------- reading files

class _BadFile(Exception):
    """A problem found while reading, already phrased for the user."""


def _one_line(e: BaseException) -> str:
    text = " ".join(str(e).split())
    if len(text) > 160:
        text = text[:157] + "..."
    return f"{type(e).__name__}: {text}" if text else type(e).__name__


def read_mesh_file(path: Path, name: str, where: str) -> MeshData:
    """Read and check one mesh file from disk (no cache: ``load_mesh`` caches what this reads;
    ``where`` starts the message of a problem)."""
    try:
        positions, normals, uvs, faces = _read_trimesh(path)
    except _BadFile as e:
        raise ViewerError(f"{where}: {path}: {e}") from None
    except ViewerError as e:  # a missing package (viewer.base.optional)
        raise ViewerError(f"{where}: {path}: {e}") from None
    except MemoryError:
        raise ViewerError(f"{where}: {path}: cannot read {path.suffix.lower()[1:].upper()} file (out of memory)") from None
    except Exception as e:  # noqa: BLE001 - any parser failure is a bad file
        raise ViewerError(f"{where}: {path}: cannot read {path.suffix.lower()[1:].upper()} file "
                          f"(corrupt or unsupported content: {_one_line(e)})") from None
    return build_mesh(name, positions, normals, faces, uvs, where=where, label=str(path))


def _load_scene(trimesh, path: Path, source, ext: str, extra: dict):
    """What ``trimesh.load_scene(source, file_type=ext, process=False, **extra)`` returns, in
    its two public steps, plus the names of the geometries whose vertex normals the file
    supplies. A loaded ``Trimesh`` does not say whether its ``vertex_normals`` came from the
    file or would be computed from the faces; the format's loader (trimesh's table
    ``trimesh.exchange.load.mesh_loaders``) returns the file's data as keyword arguments, with
    ``vertex_normals`` only when the file has them, and ``trimesh.load_scene`` builds the scene
    from those arguments as it does from a file."""
    from trimesh.exchange.load import mesh_loaders

    opts = {k: v for k, v in extra.items() if k != "resolver"}
    resolver = extra.get("resolver") or trimesh.resolvers.FilePathResolver(str(path.absolute()))
    with (open(source, "rb") if isinstance(source, str) else contextlib.nullcontext(source)) as fh:
        data = {"process": False, **opts}
        data.update(mesh_loaders[ext](file_obj=fh, file_type=ext, resolver=resolver, metadata=None,
                                      process=False, **opts))
    scene = trimesh.load_scene(data)
    if "geometry" in data:  # a scene: one set of keyword arguments per geometry name
        with_normals = {name for name, g in data["geometry"].items()
                        if isinstance(g, dict) and g.get("vertex_normals") is not None}
    else:                   # one mesh
        with_normals = set(scene.geometry) if data.get("vertex_normals") is not None else set()
    return scene, with_normals


def _read_trimesh(path: Path):
    """Read a file with trimesh (no processing) and flatten it into one triangle mesh.

    Returns positions (V,3) float64, normals (V,3) with NaN rows where the file has none,
    uvs (V,2) or None, faces (F,3) int64."""
    import logging

    from viewer.base.optional import require

    trimesh = require("trimesh")

    logging.getLogger("trimesh").setLevel(logging.ERROR)
    if path.stat().st_size == 0:
        raise _BadFile("empty file (0 bytes)")
    ext = path.suffix.lower()[1:]
    # PLY: trimesh's default fix_texture=True re-indexes the vertices when the file has uvs
    # and then silently drops the file's vertex normals; per-vertex s/t need no fixing.
    extra = {"fix_texture": False} if ext == "ply" else {}
    source = str(path)
    if ext in ("obj", "off"):
        # Text formats: trimesh needs the optional charset_normalizer for anything that is
        # not UTF-8 (a latin-1 comment from some exporter); decode such files as latin-1.
        raw = path.read_bytes()
        try:
            raw.decode("utf-8")
        except UnicodeDecodeError:
            source = io.BytesIO(raw.decode("latin-1").encode("utf-8"))
            extra["resolver"] = trimesh.resolvers.FilePathResolver(str(path))
    try:
        scene, with_normals = _load_scene(trimesh, path, source, ext, extra)
    except (UnicodeDecodeError, ImportError):
        raise _BadFile(f"cannot read {ext.upper()} file (neither valid binary data nor UTF-8 text)") from None
    parts = []
    for node in scene.graph.nodes_geometry:
        transform, geom_name = scene.graph[node]
        geom = scene.geometry.get(geom_name)
        if not isinstance(geom, trimesh.Trimesh):
            continue                             # point clouds, paths: nothing to shade
        v = np.asarray(geom.vertices, dtype=np.float64).reshape(-1, 3)
        f = np.asarray(geom.faces, dtype=np.int64).reshape(-1, 3)
        if len(f) == 0 or len(v) == 0:
            continue
        # The file's own normals, where it has them (for a mesh without them trimesh's
        # vertex_normals would compute some: NaN rows here, our own normals later).
        n = np.full_like(v, np.nan)
        if geom_name in with_normals:
            given = np.asarray(geom.vertex_normals, dtype=np.float64)
            if given.shape == v.shape:
                n = given
        uv = None
        vis_uv = getattr(geom.visual, "uv", None) if getattr(geom.visual, "kind", None) == "texture" else None
        if vis_uv is not None:
            vis_uv = np.asarray(vis_uv, dtype=np.float64)
            if vis_uv.ndim == 2 and vis_uv.shape[0] == len(v) and vis_uv.shape[1] >= 2:
                uv = vis_uv[:, :2]
        T = np.asarray(transform, dtype=np.float64)
        if not np.allclose(T, np.eye(4)):
            M = T[:3, :3]
            v = v @ M.T + T[:3, 3]
            with np.errstate(all="ignore"):
                n = n @ np.linalg.inv(M)        # (M^-T n) for row vectors
            if np.linalg.det(M) < 0.0:
                f = f[:, ::-1]
        parts.append((v, n, uv, f))
    if not parts:
        return np.zeros((0, 3)), np.zeros((0, 3)), None, np.zeros((0, 3), dtype=np.int64)
    positions = np.concatenate([p[0] for p in parts])
    normals = np.concatenate([p[1] for p in parts])
    if any(p[2] is not None for p in parts):
        uvs = np.concatenate([p[2] if p[2] is not None else np.zeros((len(p[0]), 2)) for p in parts])
    else:
        uvs = None
    faces, offset = [], 0
    for p in parts:
        faces.append(p[3] + offset)
        offset += len(p[0])
    return positions, normals, uvs, np.concatenate(faces)


def read_own_ply(path: Path | str):
    """Read a PLY exactly as ``write_ply`` writes it (the built-in ``models/*.ply``): (positions,
    normals, uvs or None, faces) as float64 / int64 arrays, or None when the file is anything
    else (then trimesh reads it). This spares the start-up trimesh's import (about 1.5 s on a
    slow machine) for the built-in shapes; tests/test_mesh.py checks it against trimesh."""
    with open(path, "rb") as f:
        data = f.read()
    end = data.find(b"end_header\n", 0, 4096)
    if end < 0:
        return None
    header = data[:end].decode("ascii", "replace").rstrip("\n").split("\n")
    if header[:3] != ["ply", "format binary_little_endian 1.0", "comment brdf-viewer models/generate.py"]:
        return None
    try:
        nv = int(header[3].removeprefix("element vertex "))
        props = [h.removeprefix("property float ") for h in header[4:-2]]
        nf = int(header[-2].removeprefix("element face "))
    except (ValueError, IndexError):
        return None
    if props not in (["x", "y", "z", "nx", "ny", "nz"], ["x", "y", "z", "nx", "ny", "nz", "s", "t"]) \
            or header[3] != f"element vertex {nv}" or header[-2] != f"element face {nf}" \
            or header[-1] != "property list uchar uint vertex_indices":
        return None
    body = memoryview(data)[end + len(b"end_header\n"):]
    vbytes = nv * len(props) * 4
    if len(body) != vbytes + nf * 13:
        return None
    v = np.frombuffer(body[:vbytes], dtype="<f4").reshape(nv, len(props)).astype(np.float64)
    fdata = np.frombuffer(body[vbytes:], dtype=[("n", "u1"), ("i", "<u4", (3,))])
    if nf and not np.all(fdata["n"] == 3):
        return None
    faces = fdata["i"].astype(np.int64).reshape(nf, 3)
    return v[:, 0:3], v[:, 3:6], (v[:, 6:8] if len(props) == 8 else None), faces


def write_ply(path: Path | str, positions, normals, indices, uvs=None) -> None:
    """Write a binary little-endian PLY with float32 x y z nx ny nz [s t] and uint32
    triangle indices (the format of ``models/*.ply``), atomically (``viewer.base.io``)."""
    P = np.asarray(positions, dtype="<f4").reshape(-1, 3)
    N = np.asarray(normals, dtype="<f4").reshape(-1, 3)
    F = np.asarray(indices, dtype="<u4").reshape(-1, 3)
    cols = [P, N]
    props = ["x", "y", "z", "nx", "ny", "nz"]
    if uvs is not None:
        cols.append(np.asarray(uvs, dtype="<f4").reshape(-1, 2))
        props += ["s", "t"]
    header = ["ply", "format binary_little_endian 1.0", "comment brdf-viewer models/generate.py",
              f"element vertex {len(P)}"]
    header += [f"property float {p}" for p in props]
    header += [f"element face {len(F)}", "property list uchar uint vertex_indices", "end_header"]
    vdata = np.concatenate(cols, axis=1).astype("<f4")
    fdata = np.zeros(len(F), dtype=[("n", "u1"), ("i", "<u4", (3,))])
    fdata["n"] = 3
    fdata["i"] = F
    from viewer.base.io import atomic_write_bytes

    atomic_write_bytes(path, ("\n".join(header) + "\n").encode("ascii") + vdata.tobytes() + fdata.tobytes())


# --------------------------------------------------------------------------- cleaning

def build_mesh(name: str, positions, normals, indices, uvs=None, *, where: str = "mesh",
               label: str | None = None) -> MeshData:
    """Turn raw arrays into a clean MeshData (the steps 2-5 of the module docstring).
    ``normals`` may be None or contain NaN rows (= compute those); ``label`` names the
    source in error messages (default: ``name``)."""
    label = name if label is None else label

    def fail(problem: str):
        raise ViewerError(f"{where}: {label}: {problem}")

    # Everything goes through float32, as a PLY on disk would, so a built-in generated in
    # memory is bit-identical to the same built-in read from models/<name>.ply.
    P = np.asarray(positions, dtype=np.float64).reshape(-1, 3)
    if not np.all(np.isfinite(P)):
        bad = int((~np.isfinite(P).all(axis=1)).sum())
        fail(f"{bad} vertex position(s) are NaN or infinite")
    with np.errstate(over="ignore"):
        P32 = P.astype(np.float32)
    if not np.all(np.isfinite(P32)):
        fail("vertex positions exceed the float32 range")
    P = P32.astype(np.float64)
    N = np.full_like(P, np.nan) if normals is None else \
        np.asarray(normals, dtype=np.float64).reshape(-1, 3).astype(np.float32).astype(np.float64)
    UV = None if uvs is None else np.asarray(uvs, dtype=np.float64).reshape(-1, 2).astype(np.float32).astype(np.float64)
    if N.shape != P.shape:
        N = np.full_like(P, np.nan)
    if UV is not None and (UV.shape[0] != P.shape[0] or not np.all(np.isfinite(UV))):
        UV = None
    F = np.asarray(indices)
    if F.size == 0:
        fail("empty mesh (no faces)")
    if F.ndim != 2 or F.shape[1] != 3:
        fail(f"faces must be triangles, got an index array of shape {F.shape}")
    if not np.issubdtype(F.dtype, np.integer):
        fail("face indices are not integers")
    F = F.astype(np.int64)
    if F.min() < 0 or F.max() >= len(P):
        fail(f"face index out of range (0..{len(P) - 1})")

    # Degenerate faces: repeated indices, or ~zero area (relative to the mesh's size and to
    # the triangle's own longest edge, so collinear slivers go too).
    keep = (F[:, 0] != F[:, 1]) & (F[:, 1] != F[:, 2]) & (F[:, 2] != F[:, 0])
    F = F[keep]
    if len(F):
        a, b, c = P[F[:, 0]], P[F[:, 1]], P[F[:, 2]]
        cross2 = np.linalg.norm(np.cross(b - a, c - a), axis=1)          # 2 * area
        longest2 = np.max(np.stack([np.einsum("ij,ij->i", e, e) for e in (b - a, c - b, a - c)]), axis=0)
        lo, hi = P[F.ravel()].min(0), P[F.ravel()].max(0)
        diag2 = float(np.dot(hi - lo, hi - lo))
        F = F[(cross2 > 1e-12 * diag2) & (cross2 > 1e-10 * longest2)]
    if len(F) == 0:
        fail("empty mesh (no faces left after removing degenerate ones)")

    # Drop vertices no face uses (keeping the order of the rest).
    used = np.zeros(len(P), dtype=bool)
    used[F.ravel()] = True
    if not used.all():
        remap = np.cumsum(used) - 1
        P, N = P[used], N[used]
        UV = None if UV is None else UV[used]
        F = remap[F]

    # Normals: the file's where valid, smooth area-weighted elsewhere.
    length = np.linalg.norm(N, axis=1)
    valid = np.isfinite(length) & (length > 1e-12)
    N = np.where(valid[:, None], N / np.where(valid, length, 1.0)[:, None], 0.0)
    if not valid.all():
        smooth = smooth_normals(P, F)
        N[~valid] = smooth[~valid]

    # Merge vertices identical in every attribute.
    UVm = np.zeros((len(P), 2)) if UV is None else UV
    attrs = np.ascontiguousarray(np.concatenate([P, N, UVm], axis=1))
    _, first, inv = np.unique(attrs.view(np.dtype((np.void, attrs.dtype.itemsize * attrs.shape[1]))).ravel(),
                              return_index=True, return_inverse=True)
    if len(first) < len(P):
        order = np.argsort(first)
        rank = np.empty_like(order)
        rank[order] = np.arange(len(order))
        keep_idx = first[order]
        F = rank[inv.reshape(-1)][F]
        P, N = P[keep_idx], N[keep_idx]
        UV = None if UV is None else UV[keep_idx]

    T = tangents(P, N, F, UV)
    return MeshData(
        name=name,
        positions=P.astype(np.float32),
        normals=N.astype(np.float32),
        tangents=T.astype(np.float32),
        uvs=(np.zeros((len(P), 2)) if UV is None else UV).astype(np.float32),
        indices=F.astype(np.uint32),
    )


def smooth_normals(P: np.ndarray, F: np.ndarray) -> np.ndarray:
    """Area-weighted vertex normals (sum of the unnormalised face normals around a vertex),
    shared by all vertices at exactly the same position."""
    _, pos_id = np.unique(P, axis=0, return_inverse=True)
    pos_id = pos_id.reshape(-1)
    fn = np.cross(P[F[:, 1]] - P[F[:, 0]], P[F[:, 2]] - P[F[:, 0]])     # |fn| = 2 * area
    acc = np.zeros((pos_id.max() + 1, 3))
    for k in range(3):
        np.add.at(acc, pos_id[F[:, k]], fn)
    n = acc[pos_id]
    ln = np.linalg.norm(n, axis=1)
    good = ln > 1e-30
    out = np.zeros_like(n)
    out[good] = n[good] / ln[good, None]
    # A vertex whose faces cancel exactly: take the normal of its first face.
    if not good.all():
        fallback = np.zeros_like(n)
        fn_unit = fn / np.maximum(np.linalg.norm(fn, axis=1), 1e-300)[:, None]
        for k in (2, 1, 0):
            fallback[F[:, k]] = fn_unit
        out[~good] = fallback[~good]
    return out


def fallback_tangents(N: np.ndarray) -> np.ndarray:
    """t = normalize(cross(+y, n)); where n is (anti)parallel to +y, +x projected onto the
    tangent plane. Around the y axis this is the azimuthal direction."""
    t = np.stack([N[:, 2], np.zeros(len(N)), -N[:, 0]], axis=1)          # cross((0,1,0), n)
    ln = np.linalg.norm(t, axis=1)
    polar = ln < 1e-6
    t[~polar] /= ln[~polar, None]
    if polar.any():
        x = np.array([1.0, 0.0, 0.0])
        tp = x - N[polar] * (N[polar] @ x)[:, None]
        t[polar] = tp / np.maximum(np.linalg.norm(tp, axis=1), 1e-30)[:, None]
    return t


def tangents(P: np.ndarray, N: np.ndarray, F: np.ndarray, UV: np.ndarray | None) -> np.ndarray:
    """(V,4) tangents: xyz unit and orthogonal to N, w = +1 or -1 such that the bitangent
    is w * cross(N, t). From the uvs (dP/du) where they are usable, else the fallback."""
    V = len(P)
    out = np.zeros((V, 4))
    t_fb = fallback_tangents(N)
    out[:, :3] = t_fb
    out[:, 3] = 1.0
    if UV is None:
        return out
    e1 = P[F[:, 1]] - P[F[:, 0]]
    e2 = P[F[:, 2]] - P[F[:, 0]]
    d1 = UV[F[:, 1]] - UV[F[:, 0]]
    d2 = UV[F[:, 2]] - UV[F[:, 0]]
    det = d1[:, 0] * d2[:, 1] - d2[:, 0] * d1[:, 1]
    uv_scale = max(float(np.ptp(UV, axis=0).max()), 1e-30)
    ok = np.abs(det) > 1e-12 * uv_scale ** 2
    if not ok.any():
        return out                               # degenerate uvs (e.g. all zero): fallback
    with np.errstate(divide="ignore", invalid="ignore"):
        inv = np.where(ok, 1.0 / np.where(ok, det, 1.0), 0.0)
    tf = (e1 * d2[:, 1:2] - e2 * d1[:, 1:2]) * inv[:, None]             # dP/du
    bf = (e2 * d1[:, 0:1] - e1 * d2[:, 0:1]) * inv[:, None]             # dP/dv
    area = 0.5 * np.linalg.norm(np.cross(e1, e2), axis=1)
    tf = tf / np.maximum(np.linalg.norm(tf, axis=1), 1e-30)[:, None] * (area * ok)[:, None]
    bf = bf / np.maximum(np.linalg.norm(bf, axis=1), 1e-30)[:, None] * (area * ok)[:, None]
    T = np.zeros((V, 3))
    B = np.zeros((V, 3))
    for k in range(3):
        np.add.at(T, F[:, k], tf)
        np.add.at(B, F[:, k], bf)
    # Gram-Schmidt against the normal; where nothing usable is left (no uv-valid face, or
    # dP/du along the normal) the vertex keeps the fallback tangent.
    before = np.linalg.norm(T, axis=1)
    T = T - N * np.einsum("ij,ij->i", N, T)[:, None]
    ln = np.linalg.norm(T, axis=1)
    good = (before > 0.0) & (ln > 1e-6 * before)
    T_unit = T / np.where(good, ln, 1.0)[:, None]
    w = np.where(np.einsum("ij,ij->i", np.cross(N, T_unit), B) < 0.0, -1.0, 1.0)
    out[good, :3] = T_unit[good]
    out[good, 3] = w[good]
    return out
