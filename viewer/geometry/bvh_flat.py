"""The scene's triangles and BVH as float32 texel arrays for the GPU (no GL here).

``flatten_scene(geom)`` turns a ``SceneGeometry`` into ``FlatScene``: 2D arrays of RGBA float32
texels, ``TEX_WIDTH`` texels wide, that ``viewer.gl.scene_textures.SceneTextures`` uploads
as they are and ``shaders/common/bvh.glsl`` reads with ``texelFetch`` (texel ``i`` lies at
``(i % TEX_WIDTH, i // TEX_WIDTH)``). Integers travel as the bits of a float
(``floatBitsToInt`` in GLSL), so every index is exact.

The tree is the binned SAH build of ``viewer.geometry.bvh_build.build_bvh``; the triangles
are stored in its leaf order, so a leaf's triangles are contiguous and a hit names the
*reordered* index ``k`` (``prim_id[k]`` is the index in ``geom``).

Layout (``k`` = reordered triangle, ``m`` = node):

* ``nodes``  2 texels per node: ``(min.xyz, bits(a))``, ``(max.xyz, bits(count))``; an inner
  node (``count == 0``) has children ``a`` and ``a + 1``, a leaf covers triangles
  ``a .. a + count - 1``. The boxes are rounded outward to float32 (``nextafter``), so a box
  still holds its triangles' float32 corners.
* ``tris``   3 texels per triangle: ``(v0, bits(prim_id))``, ``(v1, bits(material))``,
  ``(v2, bits(object))``, world space.
* ``shading`` 6 texels per triangle: the unit world vertex normals ``(n0, 0) (n1, 0) (n2, 0)``
  and tangents ``(t0, w0) (t1, w1) (t2, w2)`` (w = bitangent sign), as the rasterizer's vertex
  stage makes them.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

TEX_WIDTH = 4096          # texels per row (GL 4.1 guarantees textures of 16384 x 16384)
STACK_SIZE = 64           # the GLSL traversal stack (bvh.glsl BVH_STACK); deeper trees are refused
NODE_TEXELS = 2
TRI_TEXELS = 3
SHADING_TEXELS = 6


@dataclass
class FlatScene:
    nodes: np.ndarray         # (rows, TEX_WIDTH, 4) float32
    tris: np.ndarray          # (rows, TEX_WIDTH, 4) float32
    shading: np.ndarray       # (rows, TEX_WIDTH, 4) float32
    prim_id: np.ndarray       # (T,) int64: reordered triangle k -> index in the SceneGeometry
    n_nodes: int
    n_triangles: int
    depth: int                # of the tree (root = 0)


def as_texels(texels: np.ndarray) -> np.ndarray:
    """(N, 4) float32 texels -> (rows, TEX_WIDTH, 4), zero-padded (at least one row)."""
    texels = np.asarray(texels, dtype=np.float32).reshape(-1, 4)
    rows = max(1, -(-len(texels) // TEX_WIDTH))
    out = np.zeros((rows * TEX_WIDTH, 4), np.float32)
    out[: len(texels)] = texels
    return out.reshape(rows, TEX_WIDTH, 4)


def int_bits(a) -> np.ndarray:
    """int32 values as the float32 whose bits they are (GLSL ``floatBitsToInt`` undoes it)."""
    return np.ascontiguousarray(np.asarray(a, dtype=np.int32)).view(np.float32)


def flatten_bvh(triangles: np.ndarray):
    """(nodes texels (2M, 4), order (T,), depth) for (T, 3, 3) corners (T >= 1)."""
    from viewer.geometry.bvh_build import build_bvh

    bounds, child, first, count, order, depth = build_bvh(triangles)
    if depth >= STACK_SIZE - 1:
        from viewer import ViewerError

        raise ViewerError(f"the scene's BVH is {depth} levels deep; the GPU traversal stack holds "
                          f"{STACK_SIZE - 1} (a degenerate mesh?)")
    lo = np.nextafter(bounds[:, :3].astype(np.float32), np.float32(-np.inf))
    hi = np.nextafter(bounds[:, 3:].astype(np.float32), np.float32(np.inf))
    a = np.where(count > 0, first, child)
    texels = np.empty((len(bounds), 2, 4), np.float32)
    texels[:, 0, :3] = lo
    texels[:, 0, 3] = int_bits(a)
    texels[:, 1, :3] = hi
    texels[:, 1, 3] = int_bits(count)
    return texels.reshape(-1, 4), order, depth


def flatten_scene(geom) -> FlatScene:
    """The textures' contents for a ``viewer.geometry.soup.SceneGeometry``."""
    T = geom.n_triangles
    if T == 0:
        # an empty scene: a root leaf with no triangles and an empty box (every ray misses)
        node = np.array([[np.inf, np.inf, np.inf, 0.0], [-np.inf, -np.inf, -np.inf, 0.0]], np.float32)
        node[:, 3] = int_bits([0, 0])
        z = np.zeros((0, 4), np.float32)
        return FlatScene(as_texels(node), as_texels(z), as_texels(z), np.zeros(0, np.int64), 1, 0, 0)
    nodes, order, depth = flatten_bvh(geom.triangles)
    tri = np.empty((T, 3, 4), np.float32)
    tri[:, :, :3] = geom.triangles[order]
    tri[:, 0, 3] = int_bits(order)
    tri[:, 1, 3] = int_bits(geom.material_index[order])
    tri[:, 2, 3] = int_bits(geom.object_index[order])
    sh = np.zeros((T, 6, 4), np.float32)
    sh[:, :3, :3] = geom.normals[order]
    sh[:, 3:, :] = geom.tangents[order]
    return FlatScene(as_texels(nodes), as_texels(tri.reshape(-1, 4)), as_texels(sh.reshape(-1, 4)),
                     order.astype(np.int64), len(nodes) // NODE_TEXELS, T, depth)
