"""Ray queries with Embree (through the ``embreex`` bindings).

``EmbreeKernel`` has the same interface as ``NumbaKernel`` (``kernel_numba.py``)::

    k = EmbreeKernel(triangles)                               # (T, 3, 3) world-space corners
    t, prim, u, v = k.intersect(origins, dirs, tmin, tmax)    # closest hit, (N,) each
    blocked = k.occluded(origins, dirs, tmin, tmax)           # any hit, (N,) bool

A hit lies at ``origin + t * dir`` with ``tmin < t < tmax`` (``t`` in units of ``dir``'s
length) and at ``(1 - u - v) v0 + u v1 + v v2`` on triangle ``prim``; a miss has
``prim = -1``, ``t = inf``, ``u = v = 0``. ``tmax`` is a scalar or one value per ray.

Precision: Embree works in float32. The triangles are stored relative to the centre of their
bounding box (so coordinates are as small as they can be), the ray origins are shifted the
same way in float64 before rounding. ``embreex`` has no ``tnear`` argument: ``tmin`` is
applied by moving the origin to ``origin + tmin * dir`` and shortening ``tmax`` by ``tmin``.
The integrator does not rely on ``tmin`` for robustness: it spawns secondary rays from the
hit point offset along the geometric normal by ``1e-4 (1 + max|p|)`` to the side the ray
leaves, and shortens shadow rays by the same amount (see ``integrator.py``); it computes hit
points from the barycentrics in float64, not from ``origin + t dir``.
"""

from __future__ import annotations

import numpy as np

__all__ = ["EmbreeKernel"]

_F32_MAX_T = 1e30


class EmbreeKernel:
    def __init__(self, triangles: np.ndarray):
        from embreex import rtcore_scene
        from embreex.mesh_construction import TriangleMesh

        tri = np.asarray(triangles, dtype=np.float64).reshape(-1, 3, 3)
        self.n_triangles = tri.shape[0]
        if self.n_triangles:
            lo = tri.reshape(-1, 3).min(axis=0)
            hi = tri.reshape(-1, 3).max(axis=0)
            self.centre = 0.5 * (lo + hi)
        else:
            self.centre = np.zeros(3)
        self._scene = None
        if self.n_triangles:
            self._scene = rtcore_scene.EmbreeScene()
            verts = np.ascontiguousarray((tri.reshape(-1, 3) - self.centre).astype(np.float32))
            idx = np.arange(verts.shape[0], dtype=np.int32).reshape(-1, 3)
            TriangleMesh(scene=self._scene, vertices=verts, indices=idx)

    def _prep(self, origins, dirs, tmin, tmax):
        o = np.asarray(origins, dtype=np.float64).reshape(-1, 3)
        d = np.asarray(dirs, dtype=np.float64).reshape(-1, 3)
        n = o.shape[0]
        tmin = float(tmin)
        tmax = np.broadcast_to(np.asarray(tmax, dtype=np.float64), (n,))
        from viewer.pathtracer.compiled import embree_rays  # numba: only where rays are traced

        o32, d32, far32, live = embree_rays(o, d, self.centre, tmin, tmax, _F32_MAX_T)
        return o32, d32, far32, tmin, n, live

    def intersect(self, origins, dirs, tmin: float = 0.0, tmax=np.inf):
        o32, d32, far32, tmin, n, live = self._prep(origins, dirs, tmin, tmax)
        if self._scene is None or n == 0:
            return np.full(n, np.inf), np.full(n, -1, dtype=np.int64), np.zeros(n), np.zeros(n)
        from viewer.pathtracer.compiled import embree_hits  # numba: only where rays are traced

        return embree_hits(self._scene.run(o32, d32, dists=far32, output=1), live, tmin)

    def occluded(self, origins, dirs, tmin: float = 0.0, tmax=np.inf) -> np.ndarray:
        o32, d32, far32, tmin, n, live = self._prep(origins, dirs, tmin, tmax)
        if self._scene is None or n == 0:
            return np.zeros(n, dtype=bool)
        res = self._scene.run(o32, d32, dists=far32, query="OCCLUDED")
        return (np.asarray(res) != -1) & live
