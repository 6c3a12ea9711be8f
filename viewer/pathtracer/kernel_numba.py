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
* **Build**: the binned SAH tree of ``viewer.geometry.bvh_build.build_bvh`` (Wald 2007),
  flattened into arrays: the two children of a node are stored next to each other
  (``child[node]``, ``child[node] + 1``); a leaf stores ``first`` / ``count`` into the
  triangles, which are reordered so every leaf's triangles are contiguous.
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

from viewer.geometry.bvh_build import MAX_LEAF, N_BINS, build_bvh

__all__ = ["NumbaKernel"]

CHUNK = 128          # rays per parallel work item

_EPS = np.finfo(np.float64).eps * 0.5            # unit roundoff of float64
# pbrt's gamma(n) = n u / (1 - n u); Ize 2013 enlarges the slab exit by 1 + 2 gamma(3).
_BOX_PAD = 1.0 + 2.0 * (3.0 * _EPS / (1.0 - 3.0 * _EPS))


# ------------------------------------------------------------------------------- traversal

@njit(cache=True, error_model="numpy", inline="always")
def _slab(b0, b1, o, inv, tn, tf):
    """Narrow the ray interval (tn, tf) to one axis' slab [b0, b1] (exit enlarged by _BOX_PAD)."""
    t0 = (b0 - o) * inv
    t1 = (b1 - o) * inv
    if t0 > t1:
        t0, t1 = t1, t0
    if t0 > tn:
        tn = t0
    if t1 * _BOX_PAD < tf:
        tf = t1 * _BOX_PAD
    return tn, tf


@njit(cache=True, error_model="numpy", inline="always")
def _box_entry(bounds, node, ox, oy, oz, ix, iy, iz, tmin, tmax):
    """Slab test of a node's box. Returns the entry distance, or inf when the box is missed
    within (tmin, tmax). NaN slab distances (origin on a slab plane of an axis the ray is
    parallel to) fail every comparison and so leave the interval as it is."""
    tn, tf = _slab(bounds[node, 0], bounds[node, 3], ox, ix, tmin, tmax)
    tn, tf = _slab(bounds[node, 1], bounds[node, 4], oy, iy, tn, tf)
    tn, tf = _slab(bounds[node, 2], bounds[node, 5], oz, iz, tn, tf)
    if tn <= tf:
        return tn
    return np.inf


@njit(cache=True, error_model="numpy", inline="always")
def _shear(ox, oy, oz, dx, dy, dz):
    """Woop et al. 2013, section 3: the per-ray shear constants. kz = the dimension where the
    direction is largest in magnitude; kx, ky follow cyclically and are swapped when d[kz] < 0
    to keep the winding (and so the signs of U, V, W) consistent. Returns (ok, kx, ky, kz, sx,
    sy, sz, o[kx], o[ky], o[kz]); ok is False for a NaN or zero direction."""
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
        return False, kx, ky, kz, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
    if dkz < 0.0:
        kx, ky = ky, kx
    return True, kx, ky, kz, d3[kx] / dkz, d3[ky] / dkz, 1.0 / dkz, o3[kx], o3[ky], o3[kz]


@njit(cache=True, error_model="numpy", inline="always")
def _hit_triangle(tris, k, kx, ky, kz, sx, sy, sz, okx, oky, okz):
    """The watertight test of reordered triangle k (Woop et al. 2013): (t, u, v), with t = inf
    when the ray misses it (t may be NaN or negative: the caller's interval test rejects it)."""
    # translate to the ray origin, then shear and scale (Woop et al. eq. 1-3); the corners are
    # read in the ray's (kx, ky, kz) order
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
    # (the paper's fallback to double precision when one is exactly 0 is moot: we already are
    # in double precision)
    if (U < 0.0 or V < 0.0 or W < 0.0) and (U > 0.0 or V > 0.0 or W > 0.0):
        return np.inf, 0.0, 0.0
    det = U + V + W
    if det == 0.0:
        return np.inf, 0.0, 0.0     # ray in the triangle's plane (or a degenerate triangle)
    T = U * (sz * akz) + V * (sz * bkz) + W * (sz * ckz)
    rcp = 1.0 / det
    return T / det, V * rcp, W * rcp


@njit(cache=True, error_model="numpy", inline="always")
def _leaf(tris, f, cnt, kx, ky, kz, sx, sy, sz, okx, oky, okz, tmin, best_t, best_k, best_u, best_v,
          any_hit):
    """Test a leaf's triangles f .. f + cnt - 1 against the closest hit so far. Returns the
    updated (t, k, u, v) and whether ``any_hit`` may stop (a hit was found)."""
    for k in range(f, f + cnt):
        t, u, v = _hit_triangle(tris, k, kx, ky, kz, sx, sy, sz, okx, oky, okz)
        if t > tmin and t < best_t:
            best_t = t
            best_k = k
            best_u = u
            best_v = v
            if any_hit:
                return best_t, best_k, best_u, best_v, True
    return best_t, best_k, best_u, best_v, False


@njit(cache=True, error_model="numpy", inline="always")
def _next_child(bounds, child, node, ox, oy, oz, ix, iy, iz, tmin, best_t, st_node, st_t, sp):
    """The child of inner ``node`` to visit next (-1: the ray misses both boxes); when both are
    hit it goes to the nearer and pushes the farther with its entry distance. Returns (child, sp)."""
    c0 = child[node]
    c1 = c0 + 1
    t0 = _box_entry(bounds, c0, ox, oy, oz, ix, iy, iz, tmin, best_t)
    t1 = _box_entry(bounds, c1, ox, oy, oz, ix, iy, iz, tmin, best_t)
    if t0 == np.inf:
        if t1 == np.inf:
            return -1, sp
        return c1, sp
    if t1 == np.inf:
        return c0, sp
    if t1 < t0:
        st_node[sp] = c0
        st_t[sp] = t0
        return c1, sp + 1
    st_node[sp] = c1
    st_t[sp] = t1
    return c0, sp + 1


@njit(cache=True, error_model="numpy")
def _trace(bounds, child, first, count, tris, ox, oy, oz, dx, dy, dz, tmin, tmax, any_hit,
           st_node, st_t):
    """One ray. Returns (t, k, u, v) with k the index into the reordered triangles, -1 on a
    miss. ``any_hit`` stops at the first hit in (tmin, tmax)."""
    # NaN in tmax or a NaN / zero direction: nothing to find
    if not (tmax > tmin):
        return np.inf, -1, 0.0, 0.0
    ok, kx, ky, kz, sx, sy, sz, okx, oky, okz = _shear(ox, oy, oz, dx, dy, dz)
    if not ok:
        return np.inf, -1, 0.0, 0.0
    ix = 1.0 / dx
    iy = 1.0 / dy
    iz = 1.0 / dz
    best_t = tmax
    best_k = -1
    best_u = 0.0
    best_v = 0.0
    if _box_entry(bounds, 0, ox, oy, oz, ix, iy, iz, tmin, best_t) == np.inf:
        return np.inf, -1, 0.0, 0.0
    st_node[0] = 0
    st_t[0] = tmin
    sp = 1
    while sp > 0:
        sp -= 1
        node = st_node[sp]
        if st_t[sp] >= best_t:
            continue            # entered beyond the closest hit found since it was pushed
        while node >= 0:
            cnt = count[node]
            if cnt > 0:
                best_t, best_k, best_u, best_v, stop = _leaf(
                    tris, first[node], cnt, kx, ky, kz, sx, sy, sz, okx, oky, okz, tmin,
                    best_t, best_k, best_u, best_v, any_hit)
                if stop:
                    return best_t, best_k, best_u, best_v
                break
            node, sp = _next_child(bounds, child, node, ox, oy, oz, ix, iy, iz, tmin, best_t,
                                   st_node, st_t, sp)
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
