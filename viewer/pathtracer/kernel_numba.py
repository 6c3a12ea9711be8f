"""Ray queries without Embree: a BVH over the triangles, traversed in numba.

``NumbaKernel`` has the interface of ``EmbreeKernel`` (``kernel_embree.py``)::

    k = NumbaKernel(triangles)                    # (T, 3, 3) world-space corners
    t, prim, u, v = k.intersect(origins, dirs, tmin, tmax)   # closest hit, (N,) each
    blocked = k.occluded(origins, dirs, tmin, tmax)          # any hit, (N,) bool

A hit is the point ``origin + t * dir`` with ``tmin < t < tmax`` (an open interval; ``dir``
need not be unit, ``t`` is in units of its length) and lies at
``(1 - u - v) * v0 + u * v1 + v * v2`` on triangle ``prim``. A miss has ``prim = -1``,
``t = inf`` and ``u = v = 0``. ``tmax`` is a scalar or one value per ray. Everything is
double precision (the triangles as given, the rays, the boxes and the hit test).

How it works
------------
* **Build** (``_build_bvh``, numba, one thread): top-down binned SAH after Wald 2007, "On fast
  Construction of SAH-based Bounding Volume Hierarchies" (IEEE RT'07), as in pbrt-v3/v4
  chapter 4.3: at each node the triangle centroids are binned into ``N_BINS`` equal bins along
  each axis, the split planes between bins are scored with the surface area heuristic
  ``C_trav + (A_L N_L + A_R N_R) / A * C_isect`` (MacDonald & Booth 1990), and the node
  becomes a leaf when no split is cheaper than intersecting all of its triangles (and it
  holds at most ``MAX_LEAF``), else the best split partitions the triangles in place. Nodes
  whose centroids coincide are split at the median. The tree is flattened into arrays: the
  two children of a node are stored next to each other (``child[node]``, ``child[node] + 1``);
  a leaf stores ``first`` / ``count`` into the triangles, which are reordered so every leaf's
  triangles are contiguous.
* **Closest hit** (``_trace``): a stack-based traversal that tests both children's boxes and
  visits the nearer first, pushing the farther one with its entry distance, so a popped
  node whose entry lies beyond the closest hit found so far is skipped. Box test: the slab
  method (Kay & Kajiya 1986; Williams et al. 2005) with the exit distance enlarged by
  ``1 + 2 gamma(3)`` (Ize 2013, "Robust BVH Ray Traversal", JCGT 2(2); pbrt-v3 3.9.2), so
  rounding never culls a box the ray touches. An axis the ray is parallel to gives 0 * inf =
  NaN when the origin lies on a slab plane; the comparisons ignore NaN, which keeps that
  slab (conservative).
* **Ray-triangle test**: the watertight test of Woop, Benthin and Wald 2013, "Watertight
  Ray/Triangle Intersection", JCGT 2(1): the triangle is translated to the ray origin,
  sheared and scaled so the ray runs along +z, and the three 2D edge functions U, V, W
  decide the hit by their signs alone. No ray passes between two triangles sharing an
  edge, and a ray through an edge or a vertex hits at least one of the triangles there.
  No back-face culling. ``u = V / det``, ``v = W / det``.
* **Any hit** (``occluded``): the same traversal without ordering that returns at the first
  hit in (tmin, tmax).
* Rays run in parallel with ``prange`` over chunks of ``CHUNK`` rays (one traversal stack
  per chunk); the thread count is numba's (``numba.set_num_threads``).

The functions are compiled with ``cache=True``: the first call in a fresh environment
compiles them (tens of seconds), later processes load them from numba's cache.
"""

from __future__ import annotations

import time

import numpy as np
from numba import njit, prange

__all__ = ["NumbaKernel", "build_bvh", "N_BINS", "MAX_LEAF"]

N_BINS = 32          # SAH bins per axis (Wald 2007 uses 16-32)
MAX_LEAF = 8         # a node with more triangles than this is always split
C_TRAV = 1.0         # SAH cost of visiting a node (two box tests), relative to...
C_ISECT = 1.0        # ...one ray-triangle test
CHUNK = 128          # rays per parallel work item

_EPS = np.finfo(np.float64).eps * 0.5            # unit roundoff of float64
# pbrt's gamma(n) = n u / (1 - n u); Ize 2013 enlarges the slab exit by 1 + 2 gamma(3).
_BOX_PAD = 1.0 + 2.0 * (3.0 * _EPS / (1.0 - 3.0 * _EPS))


# ----------------------------------------------------------------------------------- build

@njit(cache=True, error_model="numpy")
def _half_area(x0, y0, z0, x1, y1, z1):
    dx = x1 - x0
    dy = y1 - y0
    dz = z1 - z0
    return dx * dy + dy * dz + dz * dx


@njit(cache=True, error_model="numpy")
def _bin_of(c, cmin, scale, n_bins):
    b = int((c - cmin) * scale)
    if b >= n_bins:
        b = n_bins - 1
    if b < 0:
        b = 0
    return b


@njit(cache=True, error_model="numpy")
def _build_bvh(lo, hi, cent, max_leaf, n_bins, c_trav, c_isect):
    """Binned SAH build (Wald 2007). ``lo``/``hi``: (T, 3) triangle bounds, ``cent``: (T, 3)
    centroids. Returns (bounds (M, 6), child (M,), first (M,), count (M,), order (T,),
    max_depth); ``count == 0`` marks an inner node whose children are ``child`` and
    ``child + 1``; a leaf covers ``order[first:first + count]``."""
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
    sp = 0
    st_node[0] = 0
    st_start[0] = 0
    st_end[0] = n
    st_depth[0] = 0
    sp = 1
    n_nodes = 1
    max_depth = 0

    bin_cnt = np.zeros((3, n_bins), np.int64)
    bin_box = np.empty((3, n_bins, 6))
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
        if depth > max_depth:
            max_depth = depth

        # node bounds and centroid bounds
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

        cnt = end - start
        if cnt <= 1:
            first[node] = start
            count[node] = cnt
            continue

        parent_area = _half_area(bx0, by0, bz0, bx1, by1, bz1)
        best_cost = np.inf
        best_axis = -1
        best_split = -1
        if parent_area > 0.0:
            for a in range(3):
                ext = cmax[a] - cmin[a]
                if not ext > 0.0:
                    continue
                scale = n_bins / ext
                for b in range(n_bins):
                    bin_cnt[a, b] = 0
                    bin_box[a, b, 0] = np.inf
                    bin_box[a, b, 1] = np.inf
                    bin_box[a, b, 2] = np.inf
                    bin_box[a, b, 3] = -np.inf
                    bin_box[a, b, 4] = -np.inf
                    bin_box[a, b, 5] = -np.inf
                for i in range(start, end):
                    p = order[i]
                    b = _bin_of(cent[p, a], cmin[a], scale, n_bins)
                    bin_cnt[a, b] += 1
                    for k in range(3):
                        if lo[p, k] < bin_box[a, b, k]:
                            bin_box[a, b, k] = lo[p, k]
                        if hi[p, k] > bin_box[a, b, 3 + k]:
                            bin_box[a, b, 3 + k] = hi[p, k]
                # sweep from the right: area and count of bins b..n_bins-1
                rx0 = np.inf
                ry0 = np.inf
                rz0 = np.inf
                rx1 = -np.inf
                ry1 = -np.inf
                rz1 = -np.inf
                rc = 0
                for b in range(n_bins - 1, 0, -1):
                    rc += bin_cnt[a, b]
                    if bin_cnt[a, b] > 0:
                        rx0 = min(rx0, bin_box[a, b, 0])
                        ry0 = min(ry0, bin_box[a, b, 1])
                        rz0 = min(rz0, bin_box[a, b, 2])
                        rx1 = max(rx1, bin_box[a, b, 3])
                        ry1 = max(ry1, bin_box[a, b, 4])
                        rz1 = max(rz1, bin_box[a, b, 5])
                    right_cnt[b] = rc
                    right_area[b] = _half_area(rx0, ry0, rz0, rx1, ry1, rz1) if rc > 0 else 0.0
                # sweep from the left; split s puts bins < s on the left
                lx0 = np.inf
                ly0 = np.inf
                lz0 = np.inf
                lx1 = -np.inf
                ly1 = -np.inf
                lz1 = -np.inf
                lc = 0
                for s in range(1, n_bins):
                    b = s - 1
                    lc += bin_cnt[a, b]
                    if bin_cnt[a, b] > 0:
                        lx0 = min(lx0, bin_box[a, b, 0])
                        ly0 = min(ly0, bin_box[a, b, 1])
                        lz0 = min(lz0, bin_box[a, b, 2])
                        lx1 = max(lx1, bin_box[a, b, 3])
                        ly1 = max(ly1, bin_box[a, b, 4])
                        lz1 = max(lz1, bin_box[a, b, 5])
                    nr = right_cnt[s]
                    if lc == 0 or nr == 0:
                        continue
                    al = _half_area(lx0, ly0, lz0, lx1, ly1, lz1)
                    cost = c_trav + (al * lc + right_area[s] * nr) / parent_area * c_isect
                    if cost < best_cost:
                        best_cost = cost
                        best_axis = a
                        best_split = s

        if best_axis < 0:
            # all centroids coincide (or a zero-area box): no plane separates them
            if cnt <= max_leaf:
                first[node] = start
                count[node] = cnt
                continue
            mid = (start + end) // 2
        else:
            if cnt <= max_leaf and best_cost >= cnt * c_isect:
                first[node] = start
                count[node] = cnt
                continue
            a = best_axis
            scale = n_bins / (cmax[a] - cmin[a])
            i = start
            j = end - 1
            while i <= j:
                if _bin_of(cent[order[i], a], cmin[a], scale, n_bins) < best_split:
                    i += 1
                else:
                    tmp = order[i]
                    order[i] = order[j]
                    order[j] = tmp
                    j -= 1
            mid = i
            if mid == start or mid == end:
                mid = (start + end) // 2

        left = n_nodes
        n_nodes += 2
        child[node] = left
        count[node] = 0
        # push the right child first so the left one is built next (depth first)
        st_node[sp] = left + 1
        st_start[sp] = mid
        st_end[sp] = end
        st_depth[sp] = depth + 1
        sp += 1
        st_node[sp] = left
        st_start[sp] = start
        st_end[sp] = mid
        st_depth[sp] = depth + 1
        sp += 1

    return (bounds[:n_nodes].copy(), child[:n_nodes].copy(), first[:n_nodes].copy(),
            count[:n_nodes].copy(), order, max_depth)


# ------------------------------------------------------------------------------- traversal

@njit(cache=True, error_model="numpy", inline="always")
def _box_entry(bounds, node, ox, oy, oz, ix, iy, iz, tmin, tmax):
    """Slab test of a node's box. Returns the entry distance, or inf when the box is missed
    within (tmin, tmax). NaN slab distances (origin on a slab plane of an axis the ray is
    parallel to) fail every comparison and so leave the interval as it is."""
    tn = tmin
    tf = tmax
    t0 = (bounds[node, 0] - ox) * ix
    t1 = (bounds[node, 3] - ox) * ix
    if t0 > t1:
        t0, t1 = t1, t0
    if t0 > tn:
        tn = t0
    if t1 * _BOX_PAD < tf:
        tf = t1 * _BOX_PAD
    t0 = (bounds[node, 1] - oy) * iy
    t1 = (bounds[node, 4] - oy) * iy
    if t0 > t1:
        t0, t1 = t1, t0
    if t0 > tn:
        tn = t0
    if t1 * _BOX_PAD < tf:
        tf = t1 * _BOX_PAD
    t0 = (bounds[node, 2] - oz) * iz
    t1 = (bounds[node, 5] - oz) * iz
    if t0 > t1:
        t0, t1 = t1, t0
    if t0 > tn:
        tn = t0
    if t1 * _BOX_PAD < tf:
        tf = t1 * _BOX_PAD
    if tn <= tf:
        return tn
    return np.inf


@njit(cache=True, error_model="numpy")
def _trace(bounds, child, first, count, tris, ox, oy, oz, dx, dy, dz, tmin, tmax, any_hit,
           st_node, st_t):
    """One ray. Returns (t, k, u, v) with k the index into the reordered triangles, -1 on a
    miss. ``any_hit`` stops at the first hit in (tmin, tmax)."""
    best_t = tmax
    best_k = -1
    best_u = 0.0
    best_v = 0.0
    # NaN in tmax or a NaN / zero direction: nothing to find
    if not (tmax > tmin):
        return np.inf, -1, 0.0, 0.0

    # --- Woop et al. 2013, section 3: per-ray shear constants. kz = dimension where the
    # direction is largest in magnitude; kx, ky follow cyclically and are swapped when
    # d[kz] < 0 to keep the winding (and so the signs of U, V, W) consistent.
    adx = abs(dx)
    ady = abs(dy)
    adz = abs(dz)
    if adx > ady and adx > adz:
        kz = 0
    elif ady > adz:
        kz = 1
    else:
        kz = 2
    kx = kz + 1
    if kx == 3:
        kx = 0
    ky = kx + 1
    if ky == 3:
        ky = 0
    o3 = (ox, oy, oz)
    d3 = (dx, dy, dz)
    dkz = d3[kz]
    if not (abs(dkz) > 0.0):
        return np.inf, -1, 0.0, 0.0
    if dkz < 0.0:
        kx, ky = ky, kx
    sx = d3[kx] / dkz
    sy = d3[ky] / dkz
    sz = 1.0 / dkz
    okx = o3[kx]
    oky = o3[ky]
    okz = o3[kz]

    ix = 1.0 / dx
    iy = 1.0 / dy
    iz = 1.0 / dz

    if _box_entry(bounds, 0, ox, oy, oz, ix, iy, iz, tmin, best_t) == np.inf:
        return np.inf, -1, 0.0, 0.0
    sp = 0
    st_node[0] = 0
    st_t[0] = tmin
    sp = 1
    while sp > 0:
        sp -= 1
        node = st_node[sp]
        if st_t[sp] >= best_t:
            continue            # entered beyond the closest hit found since it was pushed
        while True:
            cnt = count[node]
            if cnt > 0:
                f = first[node]
                for k in range(f, f + cnt):
                    # translate to the ray origin, then shear and scale (Woop et al. eq. 1-3);
                    # the corners are read in the ray's (kx, ky, kz) order
                    akz = tris[k, kz] - okz
                    bkz = tris[k, 3 + kz] - okz
                    ckz = tris[k, 6 + kz] - okz
                    Ax = (tris[k, kx] - okx) - sx * akz
                    Ay = (tris[k, ky] - oky) - sy * akz
                    Bx = (tris[k, 3 + kx] - okx) - sx * bkz
                    By = (tris[k, 3 + ky] - oky) - sy * bkz
                    Cx = (tris[k, 6 + kx] - okx) - sx * ckz
                    Cy = (tris[k, 6 + ky] - oky) - sy * ckz
                    # scaled barycentrics: 2D edge functions of the edges opposite A, B, C
                    U = Cx * By - Cy * Bx
                    V = Ax * Cy - Ay * Cx
                    W = Bx * Ay - By * Ax
                    # (the paper's fallback to double precision when one is exactly 0 is moot:
                    # we already are in double precision)
                    if (U < 0.0 or V < 0.0 or W < 0.0) and (U > 0.0 or V > 0.0 or W > 0.0):
                        continue
                    det = U + V + W
                    if det == 0.0:
                        continue        # ray in the triangle's plane (or a degenerate triangle)
                    T = U * (sz * akz) + V * (sz * bkz) + W * (sz * ckz)
                    t = T / det
                    if t > tmin and t < best_t:
                        rcp = 1.0 / det
                        best_t = t
                        best_k = k
                        best_u = V * rcp
                        best_v = W * rcp
                        if any_hit:
                            return best_t, best_k, best_u, best_v
                break
            c0 = child[node]
            c1 = c0 + 1
            t0 = _box_entry(bounds, c0, ox, oy, oz, ix, iy, iz, tmin, best_t)
            t1 = _box_entry(bounds, c1, ox, oy, oz, ix, iy, iz, tmin, best_t)
            if t0 == np.inf:
                if t1 == np.inf:
                    break
                node = c1
            elif t1 == np.inf:
                node = c0
            else:
                # both hit: go to the nearer, keep the farther with its entry distance
                if t1 < t0:
                    st_node[sp] = c0
                    st_t[sp] = t0
                    node = c1
                else:
                    st_node[sp] = c1
                    st_t[sp] = t1
                    node = c0
                sp += 1
    if best_k < 0:
        return np.inf, -1, 0.0, 0.0
    return best_t, best_k, best_u, best_v


@njit(parallel=True, fastmath=False, cache=True, error_model="numpy")
def _intersect_all(bounds, child, first, count, tris, orig, dirs, tmin, tmax, stack_size,
                   any_hit, out_t, out_k, out_u, out_v):
    n = orig.shape[0]
    n_chunks = (n + CHUNK - 1) // CHUNK
    for c in prange(n_chunks):
        st_node = np.empty(stack_size, np.int64)
        st_t = np.empty(stack_size)
        i0 = c * CHUNK
        i1 = min(n, i0 + CHUNK)
        for i in range(i0, i1):
            t, k, u, v = _trace(bounds, child, first, count, tris,
                                orig[i, 0], orig[i, 1], orig[i, 2],
                                dirs[i, 0], dirs[i, 1], dirs[i, 2],
                                tmin, tmax[i], any_hit, st_node, st_t)
            out_t[i] = t
            out_k[i] = k
            out_u[i] = u
            out_v[i] = v


# ------------------------------------------------------------------------------ public API

def build_bvh(triangles: np.ndarray, max_leaf: int = MAX_LEAF, n_bins: int = N_BINS):
    """The binned SAH tree of ``triangles`` ((T, 3, 3) corners, T >= 1) as flat arrays:
    ``(bounds (M, 6) float64 [min xyz, max xyz], child (M,), first (M,), count (M,),
    order (T,), depth)``. ``count == 0``: an inner node with children ``child`` and
    ``child + 1``; a leaf covers the triangles ``order[first:first + count]``. Node 0 is
    the root. (The GPU's texture layout in ``viewer.pathtracer.bvh_flat`` is made from it.)"""
    tri = np.asarray(triangles, dtype=np.float64).reshape(-1, 3, 3)
    lo = tri.min(axis=1)
    hi = tri.max(axis=1)
    cent = 0.5 * (lo + hi)     # centroid of the triangle's box (pbrt's choice)
    bounds, child, first, count, order, depth = _build_bvh(lo, hi, cent, int(max_leaf), int(n_bins),
                                                           C_TRAV, C_ISECT)
    return bounds, child, first, count, order, int(depth)


class NumbaKernel:
    """Closest-hit and any-hit ray queries over a triangle soup (see the module docstring).

    ``triangles``: (T, 3, 3) world-space corners ``[tri, corner, xyz]``, kept in float64.
    Attributes after the build: ``n_nodes``, ``depth`` (of the tree), ``build_seconds``.
    """

    def __init__(self, triangles: np.ndarray, max_leaf: int = MAX_LEAF, n_bins: int = N_BINS):
        tri = np.ascontiguousarray(np.asarray(triangles, dtype=np.float64).reshape(-1, 3, 3))
        if not np.all(np.isfinite(tri)):
            raise ValueError("NumbaKernel: triangle corners must be finite")
        self.n_triangles = len(tri)
        t_start = time.perf_counter()
        if self.n_triangles == 0:
            self._bounds = np.zeros((0, 6))
            self._child = self._first = self._count = np.zeros(0, np.int64)
            self._tris = np.zeros((0, 9))
            self._prim = np.zeros(0, np.int64)
            self.depth = 0
        else:
            (self._bounds, self._child, self._first, self._count, order,
             depth) = build_bvh(tri, max_leaf, n_bins)
            self._tris = np.ascontiguousarray(tri[order].reshape(-1, 9))
            self._prim = order.astype(np.int64)
            self.depth = int(depth)
        self.n_nodes = len(self._bounds)
        self._stack = self.depth + 4
        self.build_seconds = time.perf_counter() - t_start

    # -------------------------------------------------------------------------- queries
    def _run(self, origins, dirs, tmin, tmax, any_hit):
        o = np.ascontiguousarray(np.asarray(origins, dtype=np.float64).reshape(-1, 3))
        d = np.ascontiguousarray(np.asarray(dirs, dtype=np.float64).reshape(-1, 3))
        n = len(o)
        if len(d) != n:
            raise ValueError(f"NumbaKernel: {n} origins but {len(d)} directions")
        tm = np.ascontiguousarray(np.broadcast_to(np.asarray(tmax, dtype=np.float64), (n,)))
        out_t = np.full(n, np.inf)
        out_k = np.full(n, -1, np.int64)
        out_u = np.zeros(n)
        out_v = np.zeros(n)
        if n and self.n_triangles:
            _intersect_all(self._bounds, self._child, self._first, self._count, self._tris,
                           o, d, float(tmin), tm, self._stack, bool(any_hit),
                           out_t, out_k, out_u, out_v)
        return out_t, out_k, out_u, out_v

    def intersect(self, origins, dirs, tmin: float, tmax):
        """Closest hit per ray: (t, prim, u, v), each (N,); prim = -1 and t = inf on a miss."""
        t, k, u, v = self._run(origins, dirs, tmin, tmax, False)
        hit = k >= 0
        prim = np.full(len(k), -1, np.int64)
        prim[hit] = self._prim[k[hit]]
        return t, prim, u, v

    def occluded(self, origins, dirs, tmin: float, tmax) -> np.ndarray:
        """(N,) bool: does anything lie on the ray within (tmin, tmax)?"""
        _, k, _, _ = self._run(origins, dirs, tmin, tmax, True)
        return k >= 0
