"""The binned SAH bounding volume hierarchy over a triangle soup (numba, no GL).

``build_bvh(triangles)`` returns the tree as flat arrays; the numba ray kernel
(``viewer.pathtracer.kernel_numba``) traverses it on the CPU and ``viewer.geometry.bvh_flat``
turns it into the GPU's textures.

Top-down binned SAH after Wald 2007, "On fast Construction of SAH-based Bounding Volume
Hierarchies" (IEEE RT'07), as in pbrt-v3/v4 chapter 4.3, in these steps per node:

1. ``_node_bounds``: the box of the node's triangles and the box of their centroids;
2. ``_fill_bins``: per axis, the centroids go into ``N_BINS`` equal bins along the centroid box;
3. ``_sweep_right`` / ``_best_plane``: the planes between bins are scored with the surface area
   heuristic ``C_trav + (A_L N_L + A_R N_R) / A * C_isect`` (MacDonald & Booth 1990), the
   right side's areas and counts swept once from the right, the left side's while scoring;
4. the node becomes a leaf when no split is cheaper than intersecting all of its triangles (and
   it holds at most ``MAX_LEAF``), else ``_partition`` splits the triangles in place at the best
   plane. Nodes whose centroids coincide are split at the median.

The two children of a node are stored next to each other (``child[node]``, ``child[node] + 1``);
a leaf stores ``first`` / ``count`` into the triangle order, so every leaf's triangles are
contiguous. Compiled with ``cache=True`` (the first call in a fresh environment compiles) and
``nogil=True``: the window builds a scene's tree on a thread of its own, and a build holding the
interpreter lock (0.2-0.7 s for the gallery's 205k triangles) would stop the window's thread for
as long, a frame that long.
"""

from __future__ import annotations

import numpy as np
from numba import njit

__all__ = ["build_bvh", "N_BINS", "MAX_LEAF", "C_TRAV", "C_ISECT"]

N_BINS = 32          # SAH bins per axis (Wald 2007 uses 16-32)
MAX_LEAF = 8         # a node with more triangles than this is always split
C_TRAV = 1.0         # SAH cost of visiting a node (two box tests), relative to...
C_ISECT = 1.0        # ...one ray-triangle test


@njit(cache=True, nogil=True, error_model="numpy")
def _half_area(x0, y0, z0, x1, y1, z1):
    dx = x1 - x0
    dy = y1 - y0
    dz = z1 - z0
    return dx * dy + dy * dz + dz * dx


@njit(cache=True, nogil=True, error_model="numpy")
def _bin_of(c, cmin, scale, n_bins):
    b = int((c - cmin) * scale)
    if b >= n_bins:
        b = n_bins - 1
    if b < 0:
        b = 0
    return b


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _node_bounds(order, start, end, lo, hi, cent, bounds, node, cmin, cmax):
    """bounds[node] := the bounds of triangles order[start:end]; cmin, cmax := those of their centroids.
    (The box is kept in scalars in the loop: it runs over every triangle at every level.)"""
    bx0 = np.inf
    by0 = np.inf
    bz0 = np.inf
    bx1 = -np.inf
    by1 = -np.inf
    bz1 = -np.inf
    for a in range(3):
        cmin[a] = np.inf
        cmax[a] = -np.inf
    for i in range(start, end):
        p = order[i]
        bx0 = min(bx0, lo[p, 0])
        by0 = min(by0, lo[p, 1])
        bz0 = min(bz0, lo[p, 2])
        bx1 = max(bx1, hi[p, 0])
        by1 = max(by1, hi[p, 1])
        bz1 = max(bz1, hi[p, 2])
        for a in range(3):
            c = cent[p, a]
            if c < cmin[a]:
                cmin[a] = c
            if c > cmax[a]:
                cmax[a] = c
    bounds[node, 0] = bx0
    bounds[node, 1] = by0
    bounds[node, 2] = bz0
    bounds[node, 3] = bx1
    bounds[node, 4] = by1
    bounds[node, 5] = bz1


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _fill_bins(order, start, end, lo, hi, cent, a, cmin_a, scale, n_bins, bin_cnt, bin_box):
    """Count the centroids of order[start:end] per bin along axis a and bound each bin's
    triangles (bin_cnt (n_bins,), bin_box (n_bins, 6))."""
    for b in range(n_bins):
        bin_cnt[b] = 0
        for k in range(3):
            bin_box[b, k] = np.inf
            bin_box[b, 3 + k] = -np.inf
    for i in range(start, end):
        p = order[i]
        b = _bin_of(cent[p, a], cmin_a, scale, n_bins)
        bin_cnt[b] += 1
        for k in range(3):
            if lo[p, k] < bin_box[b, k]:
                bin_box[b, k] = lo[p, k]
            if hi[p, k] > bin_box[b, 3 + k]:
                bin_box[b, 3 + k] = hi[p, k]


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _grown(x0, y0, z0, x1, y1, z1, bins, b):
    """The union of the box (x0, y0, z0)-(x1, y1, z1) and bins[b] (min xyz, max xyz), as six
    scalars (kept in registers: this runs for every bin of every node)."""
    return (min(x0, bins[b, 0]), min(y0, bins[b, 1]), min(z0, bins[b, 2]),
            max(x1, bins[b, 3]), max(y1, bins[b, 4]), max(z1, bins[b, 5]))


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _sweep_right(bin_cnt, bin_box, n_bins, right_cnt, right_area):
    """right_cnt[b], right_area[b] := count and box half-area of bins b .. n_bins - 1 (b >= 1)."""
    x0 = y0 = z0 = np.inf
    x1 = y1 = z1 = -np.inf
    rc = 0
    for b in range(n_bins - 1, 0, -1):
        rc += bin_cnt[b]
        if bin_cnt[b] > 0:
            x0, y0, z0, x1, y1, z1 = _grown(x0, y0, z0, x1, y1, z1, bin_box, b)
        right_cnt[b] = rc
        right_area[b] = _half_area(x0, y0, z0, x1, y1, z1) if rc > 0 else 0.0


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _best_plane(bin_cnt, bin_box, n_bins, right_cnt, right_area, parent_area, c_trav, c_isect):
    """Sweep from the left and score every plane s (bins < s on the left) with the SAH.
    Returns (best cost, best s); (inf, -1) when no plane has triangles on both sides."""
    best_cost = np.inf
    best_split = -1
    x0 = y0 = z0 = np.inf
    x1 = y1 = z1 = -np.inf
    lc = 0
    for s in range(1, n_bins):
        b = s - 1
        lc += bin_cnt[b]
        if bin_cnt[b] > 0:
            x0, y0, z0, x1, y1, z1 = _grown(x0, y0, z0, x1, y1, z1, bin_box, b)
        nr = right_cnt[s]
        if lc == 0 or nr == 0:
            continue
        al = _half_area(x0, y0, z0, x1, y1, z1)
        cost = c_trav + (al * lc + right_area[s] * nr) / parent_area * c_isect
        if cost < best_cost:
            best_cost = cost
            best_split = s
    return best_cost, best_split


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _partition(order, start, end, cent, a, cmin_a, scale, n_bins, split):
    """Reorder order[start:end] so the triangles whose centroid bin on axis a is < split come
    first. Returns the first index of the right part (the median when one side is empty)."""
    i = start
    j = end - 1
    while i <= j:
        if _bin_of(cent[order[i], a], cmin_a, scale, n_bins) < split:
            i += 1
        else:
            tmp = order[i]
            order[i] = order[j]
            order[j] = tmp
            j -= 1
    if i == start or i == end:
        return (start + end) // 2
    return i


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _split_node(order, start, end, lo, hi, cent, bounds, node, cmin, cmax, max_leaf, n_bins, c_trav,
                c_isect, bin_cnt, bin_box, right_cnt, right_area):
    """The node over order[start:end] (its box in bounds[node]): returns the index where its
    right child starts, or -1 when it stays a leaf (steps 2-4 of the module docstring)."""
    cnt = end - start
    if cnt <= 1:
        return -1
    parent_area = _half_area(bounds[node, 0], bounds[node, 1], bounds[node, 2], bounds[node, 3],
                             bounds[node, 4], bounds[node, 5])
    best_cost = np.inf
    best_axis = -1
    best_split = -1
    if parent_area > 0.0:
        for a in range(3):
            ext = cmax[a] - cmin[a]
            if not ext > 0.0:
                continue
            scale = n_bins / ext
            _fill_bins(order, start, end, lo, hi, cent, a, cmin[a], scale, n_bins, bin_cnt, bin_box)
            _sweep_right(bin_cnt, bin_box, n_bins, right_cnt, right_area)
            cost, split = _best_plane(bin_cnt, bin_box, n_bins, right_cnt, right_area, parent_area,
                                      c_trav, c_isect)
            if cost < best_cost:
                best_cost = cost
                best_axis = a
                best_split = split
    if best_axis < 0:
        # all centroids coincide (or a zero-area box): no plane separates them
        if cnt <= max_leaf:
            return -1
        return (start + end) // 2
    if cnt <= max_leaf and best_cost >= cnt * c_isect:
        return -1
    a = best_axis
    scale = n_bins / (cmax[a] - cmin[a])
    return _partition(order, start, end, cent, a, cmin[a], scale, n_bins, best_split)


@njit(cache=True, nogil=True, error_model="numpy", inline="always")
def _push(st_node, st_start, st_end, st_depth, sp, node, start, end, depth):
    st_node[sp] = node
    st_start[sp] = start
    st_end[sp] = end
    st_depth[sp] = depth
    return sp + 1


@njit(cache=True, nogil=True, error_model="numpy")
def _build(lo, hi, cent, max_leaf, n_bins, c_trav, c_isect):
    """Binned SAH build. ``lo``/``hi``: (T, 3) triangle bounds, ``cent``: (T, 3) centroids.
    Returns (bounds (M, 6), child (M,), first (M,), count (M,), order (T,), max_depth)."""
    n = cent.shape[0]
    order = np.arange(n)
    max_nodes = 2 * n - 1
    bounds = np.empty((max_nodes, 6))
    child = np.zeros(max_nodes, np.int64)
    first = np.zeros(max_nodes, np.int64)
    count = np.zeros(max_nodes, np.int64)

    # depth-first work stack: (node, start, end, depth); it never holds more than depth + 1
    st_node = np.empty(n + 2, np.int64)
    st_start = np.empty(n + 2, np.int64)
    st_end = np.empty(n + 2, np.int64)
    st_depth = np.empty(n + 2, np.int64)
    sp = _push(st_node, st_start, st_end, st_depth, 0, 0, 0, n, 0)
    n_nodes = 1
    max_depth = 0

    bin_cnt = np.zeros(n_bins, np.int64)
    bin_box = np.empty((n_bins, 6))
    right_area = np.empty(n_bins)
    right_cnt = np.empty(n_bins, np.int64)
    cmin = np.empty(3)
    cmax = np.empty(3)

    while sp > 0:
        sp -= 1
        node = st_node[sp]
        start = st_start[sp]
        end = st_end[sp]
        depth = st_depth[sp]
        max_depth = max(max_depth, depth)
        _node_bounds(order, start, end, lo, hi, cent, bounds, node, cmin, cmax)
        mid = _split_node(order, start, end, lo, hi, cent, bounds, node, cmin, cmax, max_leaf,
                          n_bins, c_trav, c_isect, bin_cnt, bin_box, right_cnt, right_area)
        if mid < 0:
            first[node] = start
            count[node] = end - start
            continue
        left = n_nodes
        n_nodes += 2
        child[node] = left
        count[node] = 0
        # push the right child first so the left one is built next (depth first)
        sp = _push(st_node, st_start, st_end, st_depth, sp, left + 1, mid, end, depth + 1)
        sp = _push(st_node, st_start, st_end, st_depth, sp, left, start, mid, depth + 1)

    return (bounds[:n_nodes].copy(), child[:n_nodes].copy(), first[:n_nodes].copy(),
            count[:n_nodes].copy(), order, max_depth)


def build_bvh(triangles: np.ndarray, max_leaf: int = MAX_LEAF, n_bins: int = N_BINS):
    """The binned SAH tree of ``triangles`` ((T, 3, 3) corners, T >= 1) as flat arrays:
    ``(bounds (M, 6) float64 [min xyz, max xyz], child (M,), first (M,), count (M,),
    order (T,), depth)``. ``count == 0``: an inner node with children ``child`` and
    ``child + 1``; a leaf covers the triangles ``order[first:first + count]``. Node 0 is
    the root. (The GPU's texture layout in ``viewer.geometry.bvh_flat`` is made from it.)"""
    tri = np.asarray(triangles, dtype=np.float64).reshape(-1, 3, 3)
    lo = tri.min(axis=1)
    hi = tri.max(axis=1)
    cent = 0.5 * (lo + hi)     # centroid of the triangle's box (pbrt's choice)
    bounds, child, first, count, order, depth = _build(lo, hi, cent, int(max_leaf), int(n_bins),
                                                       C_TRAV, C_ISECT)
    return bounds, child, first, count, order, int(depth)
