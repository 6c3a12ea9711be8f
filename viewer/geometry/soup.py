"""The scene as one world-space triangle soup for the ray kernels, with what shading needs.

Exactly the rasterizer's triangles and transforms (``shaders/passes/forward.vert``):
positions by the model matrix, vertex normals by the normal matrix (inverse transpose of its
3x3; normalized here, the fragment shader normalizes after interpolation), tangents' xyz by the
model matrix's 3x3 with w (the bitangent sign) kept.

The geometric normal of a triangle is ``normalize(cross(v1 - v0, v2 - v0))``: its winding
decides front and back as ``gl_FrontFacing`` does (the built-in meshes wind
counter-clockwise around their outward vertex normals), and, for transmissive objects, inside
and outside.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: rays leaving a surface point p start at p + eps n_g on the side they leave, eps = EPS_REL (1 + max|p|),
#: in both reference engines and the rasterizer's traced chains (``generated/constants.glsl``)
EPS_REL = 1e-4


@dataclass
class SceneGeometry:
    triangles: np.ndarray      # (T, 3, 3) float64 world-space corners
    geo_normals: np.ndarray    # (T, 3) unit winding normals (zero for degenerate triangles)
    normals: np.ndarray        # (T, 3, 3) unit world vertex normals per corner
    tangents: np.ndarray       # (T, 3, 4) world tangents per corner (xyz, w = bitangent sign)
    object_index: np.ndarray   # (T,) int32 index into scene.objects
    material_index: np.ndarray  # (T,) int32 index into material_names
    material_names: list       # material names, in the order of scene.materials

    @property
    def n_triangles(self) -> int:
        return int(self.triangles.shape[0])

    def extent(self) -> float:
        """max |coordinate| over all corners (0 for an empty scene)."""
        return float(np.abs(self.triangles).max()) if self.n_triangles else 0.0


def build_geometry(scene) -> SceneGeometry:
    names = list(scene.materials)
    tris, nrm, tan, obj_idx, mat_idx = [], [], [], [], []
    for k, obj in enumerate(scene.objects):
        md = obj.mesh_data
        if md is None:
            raise ValueError("scene was loaded without meshes (load_meshes=False)")
        idx = np.asarray(md.indices, dtype=np.int64).reshape(-1, 3)
        if len(idx) == 0:
            continue
        m = obj.model_matrix()
        m3 = m[:3, :3]
        p = np.asarray(md.positions, dtype=np.float64) @ m3.T + m[:3, 3]
        nm = np.linalg.inv(m3).T
        n = np.asarray(md.normals, dtype=np.float64) @ nm.T
        n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-300)
        t4 = np.asarray(md.tangents, dtype=np.float64)
        t = np.concatenate([t4[:, :3] @ m3.T, t4[:, 3:4]], axis=1)
        tris.append(p[idx])
        nrm.append(n[idx])
        tan.append(t[idx])
        obj_idx.append(np.full(len(idx), k, dtype=np.int32))
        mat_idx.append(np.full(len(idx), names.index(obj.material), dtype=np.int32))
    if tris:
        triangles = np.concatenate(tris)
        normals = np.concatenate(nrm)
        tangents = np.concatenate(tan)
        object_index = np.concatenate(obj_idx)
        material_index = np.concatenate(mat_idx)
    else:
        triangles = np.zeros((0, 3, 3))
        normals = np.zeros((0, 3, 3))
        tangents = np.zeros((0, 3, 4))
        object_index = np.zeros(0, dtype=np.int32)
        material_index = np.zeros(0, dtype=np.int32)
    ng = np.cross(triangles[:, 1] - triangles[:, 0], triangles[:, 2] - triangles[:, 0])
    ln = np.linalg.norm(ng, axis=1, keepdims=True)
    ng = np.where(ln > 0, ng / np.where(ln > 0, ln, 1.0), 0.0)
    return SceneGeometry(np.ascontiguousarray(triangles), ng, normals, tangents, object_index,
                         material_index, names)


def hit_points(geom: SceneGeometry, prim, u, v) -> np.ndarray:
    """(N, 3) points (1 - u - v) v0 + u v1 + v v2 in float64."""
    tri = geom.triangles[prim]
    w = 1.0 - u - v
    return w[:, None] * tri[:, 0] + u[:, None] * tri[:, 1] + v[:, None] * tri[:, 2]


def interpolate_shading(geom: SceneGeometry, prim, u, v) -> tuple[np.ndarray, np.ndarray]:
    """Shading normal (N, 3), normalized barycentric interpolation of the vertex normals, and
    the interpolated tangent (N, 4) (xyz not yet orthogonalized; w interpolated as the
    rasterizer's varying is, its sign is the bitangent sign)."""
    w = 1.0 - u - v
    nv = geom.normals[prim]
    n = w[:, None] * nv[:, 0] + u[:, None] * nv[:, 1] + v[:, None] * nv[:, 2]
    ln = np.linalg.norm(n, axis=1, keepdims=True)
    n = np.where(ln > 1e-300, n / np.where(ln > 1e-300, ln, 1.0), geom.geo_normals[prim])
    tv = geom.tangents[prim]
    t = w[:, None] * tv[:, 0] + u[:, None] * tv[:, 1] + v[:, None] * tv[:, 2]
    return n, t


def shading_frame(n: np.ndarray, tangent: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(t, b) completing n to the shading frame exactly as ``forward.frag`` does:
    t = tangent - n (n . tangent) normalized (fallback: a perpendicular from cross(n, x) or
    cross(n, y)), b = cross(n, t) * sign(tangent.w)."""
    tx = tangent[:, :3]
    t = tx - n * np.sum(n * tx, axis=1, keepdims=True)
    l2 = np.sum(t * t, axis=1)
    ok = l2 > 1e-12
    if not np.all(ok):
        ax = np.where((np.abs(n[:, 0]) < 0.9)[:, None], np.array([1.0, 0.0, 0.0]), np.array([0.0, 1.0, 0.0]))
        fb = np.cross(n, ax)
        fb /= np.linalg.norm(fb, axis=1, keepdims=True)
        t = np.where(ok[:, None], t, fb)
        l2 = np.where(ok, l2, 1.0)
    t = t / np.sqrt(l2)[:, None]
    b = np.cross(n, t) * np.where(tangent[:, 3] < 0.0, -1.0, 1.0)[:, None]
    return t, b
