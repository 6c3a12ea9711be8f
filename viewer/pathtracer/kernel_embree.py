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

The calls: where numba is installed, the rays go to Embree one at a time from a compiled loop
(``compiled.embree_intersect`` / ``embree_occluded``) through Embree's C functions
``rtcIntersect1`` / ``rtcOccluded1`` of a scene built here with ``ctypes`` (``DirectScene``)
in the Embree library that ``embreex`` ships; the fused bounce (``fused.py``) calls them from
inside its loop the same way. ``embreex``'s own batched ``run`` is the fallback (no numba, or
the library not found). Both build the same float32 triangles; Embree's two scenes may split a
tie between two triangles sharing an edge differently (2 rays in 500,000 in a test), so
renders with the one and the other agree in distribution, not bit for bit.
"""

from __future__ import annotations

import ctypes
import glob
import os

import numpy as np

__all__ = ["EmbreeKernel", "DirectScene", "direct_scene", "F32_MAX_T"]

F32_MAX_T = 1e30   # the far distance of a ray without one (float32's range)

# Embree 4's C interface (rtcore_device.h, rtcore_scene.h, rtcore_geometry.h, rtcore_buffer.h)
RTC_GEOMETRY_TYPE_TRIANGLE = 0
RTC_BUFFER_TYPE_INDEX, RTC_BUFFER_TYPE_VERTEX = 0, 1
RTC_FORMAT_UINT3, RTC_FORMAT_FLOAT3 = 0x5003, 0x9003


def _embree_library():
    """Embree's shared library as ``ctypes.CDLL`` (the one ``embreex`` ships in
    ``embreex.libs``, else a system ``libembree4``), or None."""
    try:
        import embreex
    except ImportError:
        return None
    root = os.path.dirname(os.path.dirname(os.path.abspath(embreex.__file__)))
    names = sorted(glob.glob(os.path.join(root, "embreex.libs", "libembree4*.so*")))
    names += ["libembree4.so.4"]
    for name in names:
        try:
            lib = ctypes.CDLL(name)
            lib.rtcIntersect1, lib.rtcOccluded1  # noqa: B018 - both must be there
        except (OSError, AttributeError):
            continue
        vp, sz, ci = ctypes.c_void_p, ctypes.c_size_t, ctypes.c_int
        for fn, res, args in (("rtcNewDevice", vp, [ctypes.c_char_p]), ("rtcNewScene", vp, [vp]),
                              ("rtcNewGeometry", vp, [vp, ci]),
                              ("rtcSetSharedGeometryBuffer", None, [vp, ci, ctypes.c_uint, ci, vp, sz, sz, sz]),
                              ("rtcCommitGeometry", None, [vp]), ("rtcAttachGeometry", ctypes.c_uint, [vp, vp]),
                              ("rtcReleaseGeometry", None, [vp]), ("rtcCommitScene", None, [vp]),
                              ("rtcReleaseScene", None, [vp]),
                              ("rtcGetDeviceError", ci, [vp])):
            f = getattr(lib, fn)
            f.restype, f.argtypes = res, args
        return lib
    return None


_LIB: list = []   # [the library or None, its device], loaded and created once per process


class DirectScene:
    """An Embree scene of float32 triangles ``verts`` (V, 3) (three per triangle, in order)
    built through Embree's C interface on ``device`` (one per process: a device holds Embree's
    thread pool): ``scene`` (its address), ``intersect1`` and ``occluded1`` (the addresses of
    ``rtcIntersect1`` / ``rtcOccluded1``) for compiled loops. The scene is released with this
    object; it keeps the vertex and index arrays Embree reads."""

    def __init__(self, lib, device, verts: np.ndarray):
        self._lib = lib
        self._verts = np.ascontiguousarray(verts, dtype=np.float32)
        self._index = np.arange(self._verts.shape[0], dtype=np.uint32).reshape(-1, 3).copy()
        self._device = device
        self._scene = lib.rtcNewScene(self._device)
        geom = lib.rtcNewGeometry(self._device, RTC_GEOMETRY_TYPE_TRIANGLE)
        lib.rtcSetSharedGeometryBuffer(geom, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, self._verts.ctypes.data,
                                       0, 12, self._verts.shape[0])
        lib.rtcSetSharedGeometryBuffer(geom, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, self._index.ctypes.data,
                                       0, 12, self._index.shape[0])
        lib.rtcCommitGeometry(geom)
        lib.rtcAttachGeometry(self._scene, geom)
        lib.rtcReleaseGeometry(geom)
        lib.rtcCommitScene(self._scene)
        err = lib.rtcGetDeviceError(self._device)
        if err:
            raise RuntimeError(f"Embree could not build the scene (error {err})")
        self.scene = int(self._scene)
        self.intersect1 = ctypes.cast(lib.rtcIntersect1, ctypes.c_void_p).value
        self.occluded1 = ctypes.cast(lib.rtcOccluded1, ctypes.c_void_p).value
        # one RTCRayHit (80 bytes, 16-byte aligned) the compiled loops fill ray by ray
        raw = np.zeros(40, np.uint32)
        off = (-raw.ctypes.data % 16) // 4
        self.rayhit = raw[off:off + 32]
        self.rayhit_address = int(self.rayhit.ctypes.data)

    def __del__(self):
        lib = getattr(self, "_lib", None)
        if lib is not None and getattr(self, "_scene", None):
            lib.rtcReleaseScene(self._scene)
            self._scene = None


def direct_scene(verts: np.ndarray) -> DirectScene | None:
    """A ``DirectScene`` of ``verts``, or None where numba or Embree's library is missing."""
    from viewer.pathtracer.compiled import HAVE_NUMBA

    if not HAVE_NUMBA:
        return None
    if not _LIB:
        lib = _embree_library()
        # one thread: the pool has a process per core, and no thread of Embree's outlives a render
        _LIB.extend([lib, lib.rtcNewDevice(b"threads=1") if lib is not None else None])
    if _LIB[0] is None or not _LIB[1]:
        return None
    return DirectScene(_LIB[0], _LIB[1], verts)


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
        self.direct = None   # a DirectScene: the rays go to Embree from compiled loops
        if self.n_triangles:
            verts = np.ascontiguousarray((tri.reshape(-1, 3) - self.centre).astype(np.float32))
            self.direct = direct_scene(verts)
            if self.direct is None:
                self._scene = rtcore_scene.EmbreeScene()
                idx = np.arange(verts.shape[0], dtype=np.int32).reshape(-1, 3)
                TriangleMesh(scene=self._scene, vertices=verts, indices=idx)

    def _prep(self, origins, dirs, tmin, tmax):
        o = np.asarray(origins, dtype=np.float64).reshape(-1, 3)
        d = np.asarray(dirs, dtype=np.float64).reshape(-1, 3)
        n = o.shape[0]
        tmin = float(tmin)
        tmax = np.broadcast_to(np.asarray(tmax, dtype=np.float64), (n,))
        from viewer.pathtracer.compiled import embree_rays  # numba: only where rays are traced

        o32, d32, far32, live = embree_rays(o, d, self.centre, tmin, tmax, F32_MAX_T)
        return o32, d32, far32, tmin, n, live

    def intersect(self, origins, dirs, tmin: float = 0.0, tmax=np.inf):
        o32, d32, far32, tmin, n, live = self._prep(origins, dirs, tmin, tmax)
        if self.direct is not None and n:
            from viewer.pathtracer.compiled import embree_intersect

            return embree_intersect(self.direct, o32, d32, far32, live, tmin)
        if self._scene is None or n == 0:
            return np.full(n, np.inf), np.full(n, -1, dtype=np.int64), np.zeros(n), np.zeros(n)
        from viewer.pathtracer.compiled import embree_hits  # numba: only where rays are traced

        return embree_hits(self._scene.run(o32, d32, dists=far32, output=1), live, tmin)

    def occluded(self, origins, dirs, tmin: float = 0.0, tmax=np.inf) -> np.ndarray:
        o32, d32, far32, tmin, n, live = self._prep(origins, dirs, tmin, tmax)
        if self.direct is not None and n:
            from viewer.pathtracer.compiled import embree_occluded

            return embree_occluded(self.direct, o32, d32, far32, live)
        if self._scene is None or n == 0:
            return np.zeros(n, dtype=bool)
        res = self._scene.run(o32, d32, dists=far32, query="OCCLUDED")
        return (np.asarray(res) != -1) & live
