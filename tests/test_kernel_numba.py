"""The numba BVH ray kernel (viewer.pathtracer.kernel_numba) against a brute-force reference
(every ray against every triangle, Moller & Trumbore 1997, numpy float64) and, where the
module exists, against the Embree kernel; plus self-intersection and degenerate rays.

The first run compiles the kernel (numba, tens of seconds); numba's on-disk cache makes
later runs fast.
"""

from __future__ import annotations

import importlib.util

import numpy as np
import pytest

pytest.importorskip("numba")

from viewer.scene.mesh import load_mesh  # noqa: E402
from viewer.pathtracer.kernel_numba import NumbaKernel  # noqa: E402

CORNELL = ["cornell_room", "cornell_left", "cornell_right", "cornell_short_block", "cornell_tall_block"]


def _triangles(names) -> np.ndarray:
    tris = []
    for name in names:
        m = load_mesh(name)
        tris.append(m.positions.astype(np.float64)[m.indices.astype(np.int64)])
    return np.concatenate(tris)


_MESHES = {"teapot": ["teapot"], "sphere": ["sphere"], "cornell": CORNELL}
_KERNELS: dict = {}


def _scene(name):
    if name not in _KERNELS:
        tri = _triangles(_MESHES[name])
        _KERNELS[name] = (tri, NumbaKernel(tri))
    return _KERNELS[name]


def brute_force(tri, o, d, tmin=0.0, tmax=np.inf):
    """Closest hit of every ray against every triangle: Moller & Trumbore 1997,
    "Fast, Minimum Storage Ray/Triangle Intersection", in float64. Returns t, prim, u, v
    and, per ray, the smallest barycentric coordinate of the hit (how close to an edge)."""
    n = len(o)
    tmax = np.broadcast_to(np.asarray(tmax, dtype=np.float64), (n,))
    v0, e1, e2 = tri[:, 0], tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]
    t_out = np.full(n, np.inf)
    p_out = np.full(n, -1)
    u_out = np.zeros(n)
    v_out = np.zeros(n)
    edge = np.full(n, np.inf)
    for s in range(0, n, 64):
        oo, dd = o[s:s + 64, None, :], d[s:s + 64, None, :]
        pvec = np.cross(dd, e2[None])
        det = np.einsum("rtk,tk->rt", pvec, e1)
        with np.errstate(divide="ignore", invalid="ignore"):
            inv = 1.0 / det
            tvec = oo - v0[None]
            u = np.einsum("rtk,rtk->rt", tvec, pvec) * inv
            qvec = np.cross(tvec, e1[None])
            v = np.einsum("rtk,rtk->rt", dd, qvec) * inv
            t = np.einsum("rtk,tk->rt", qvec, e2) * inv
            ok = (det != 0) & (u >= 0) & (v >= 0) & (u + v <= 1) & (t > tmin) & (t < tmax[s:s + 64, None])
        t = np.where(ok, t, np.inf)
        j = np.argmin(t, axis=1)
        r = np.arange(len(j))
        hit = np.isfinite(t[r, j])
        t_out[s:s + 64] = np.where(hit, t[r, j], np.inf)
        p_out[s:s + 64] = np.where(hit, j, -1)
        u_out[s:s + 64] = np.where(hit, u[r, j], 0.0)
        v_out[s:s + 64] = np.where(hit, v[r, j], 0.0)
        edge[s:s + 64] = np.where(hit, np.minimum(np.minimum(u[r, j], v[r, j]), 1 - u[r, j] - v[r, j]), np.inf)
    return t_out, p_out, u_out, v_out, edge


def _random_rays(tri, n, rng):
    """Half from a sphere around the scene towards random points in its box, half from
    random points inside the box in random directions (unnormalized: t is in units of |d|)."""
    lo, hi = tri.reshape(-1, 3).min(0), tri.reshape(-1, 3).max(0)
    c, r = 0.5 * (lo + hi), 0.5 * np.linalg.norm(hi - lo)
    h = n // 2
    g = rng.normal(size=(h, 3))
    o1 = c + 1.5 * r * g / np.linalg.norm(g, axis=1, keepdims=True)
    d1 = lo + rng.random((h, 3)) * (hi - lo) - o1
    o2 = lo + rng.random((n - h, 3)) * (hi - lo)
    d2 = rng.normal(size=(n - h, 3)) * rng.uniform(0.5, 2.0, size=(n - h, 1))
    return np.concatenate([o1, o2]), np.concatenate([d1, d2])


def _check_against(tri, res, ref, n_edge_tol=1e-6, coincident_faces=False):
    t, p, u, v = res
    rt, rp, ru, rv = ref[:4]
    assert t.shape == p.shape == u.shape == v.shape == rt.shape
    assert np.array_equal(p >= 0, rp >= 0), "hit/miss disagree"
    miss = p < 0
    assert np.all(np.isinf(t[miss])) and np.all(u[miss] == 0) and np.all(v[miss] == 0)
    hit = ~miss
    assert np.all(np.isfinite(t[hit])) and np.all(np.isfinite(u[hit])) and np.all(np.isfinite(v[hit]))
    same = hit & (p == rp)
    np.testing.assert_allclose(t[same], rt[same], rtol=1e-9)
    assert np.max(np.abs(u[same] - ru[same]), initial=0) < 1e-6
    assert np.max(np.abs(v[same] - rv[same]), initial=0) < 1e-6
    other = hit & (p != rp)
    # a different triangle only where two triangles are hit at the same distance: a shared
    # edge or vertex (rare for random rays), or coincident faces (the Cornell blocks stand
    # on the floor: their bottoms and the floor overlap)
    np.testing.assert_allclose(t[other], rt[other], rtol=n_edge_tol)
    if not coincident_faces:
        assert other.sum() <= 2
    # the point is where the triangle and barycentrics say it is
    q = tri[p[hit]]
    pt = (1 - u[hit] - v[hit])[:, None] * q[:, 0] + u[hit][:, None] * q[:, 1] + v[hit][:, None] * q[:, 2]
    return hit, pt


# teapot and sphere: -m slow (6 s and 13 s: their triangles brute-forced in numpy); cornell keeps
# the kernel's check in the default run
@pytest.mark.parametrize("name", [pytest.param("teapot", marks=pytest.mark.slow),
                                  pytest.param("sphere", marks=pytest.mark.slow), "cornell"])
def test_closest_hit_matches_brute_force(name):
    tri, k = _scene(name)
    rng = np.random.default_rng(1)
    o, d = _random_rays(tri, 1200, rng)
    res = k.intersect(o, d, 0.0, np.inf)
    ref = brute_force(tri, o, d)
    hit, pt = _check_against(tri, res, ref, coincident_faces=name == "cornell")
    assert 0.2 < hit.mean() <= 1.0
    np.testing.assert_allclose(pt, o[hit] + res[0][hit, None] * d[hit], atol=1e-9)
    # tmax per ray and tmin cut the interval the same way in both
    tmax = rng.uniform(0.0, 3.0, len(o))
    _check_against(tri, k.intersect(o, d, 0.3, tmax), brute_force(tri, o, d, 0.3, tmax),
                   coincident_faces=name == "cornell")


@pytest.mark.parametrize("name", [pytest.param("teapot", marks=pytest.mark.slow), "cornell"])  # teapot: -m slow (6 s)
def test_occlusion_matches_brute_force(name):
    tri, k = _scene(name)
    rng = np.random.default_rng(2)
    o, d = _random_rays(tri, 1000, rng)
    rt = brute_force(tri, o, d)[0]
    # shadow rays ending before / after the first hit, and at random lengths
    for tmax in (np.where(np.isfinite(rt), rt * 0.999, 5.0), np.where(np.isfinite(rt), rt * 1.001, 5.0),
                 rng.uniform(0.0, 2.0, len(o))):
        expect = brute_force(tri, o, d, 1e-9, tmax)[1] >= 0
        assert np.array_equal(k.occluded(o, d, 1e-9, tmax), expect)
    assert not k.occluded(o, d, 0.0, np.where(np.isfinite(rt), rt * 0.999, 0.0)).any()
    assert k.occluded(o, d, 0.0, np.inf).sum() == np.isfinite(rt).sum()


def test_offset_rays_do_not_self_intersect():
    # The sphere mesh is a convex polyhedron: a ray leaving a face into the outer half-space
    # of that face's plane can hit nothing; a ray into the inner half-space hits another face
    # at a distance well away from 0.
    tri, k = _scene("sphere")
    rng = np.random.default_rng(3)
    n = 4000
    f = rng.integers(0, len(tri), n)
    b = rng.dirichlet([1, 1, 1], n)
    p = np.einsum("nc,nck->nk", b, tri[f])
    ng = np.cross(tri[f, 1] - tri[f, 0], tri[f, 2] - tri[f, 0])
    ng /= np.linalg.norm(ng, axis=1, keepdims=True)
    ng *= np.sign(np.einsum("nk,nk->n", ng, p))[:, None]          # outward
    w = rng.normal(size=(n, 3))
    w /= np.linalg.norm(w, axis=1, keepdims=True)
    cos = np.einsum("nk,nk->n", w, ng)
    w[np.abs(cos) < 1e-3] = ng[np.abs(cos) < 1e-3]
    w_out = w * np.sign(np.einsum("nk,nk->n", w, ng))[:, None]
    for origin, tmin in ((p, 1e-7), (p + 1e-7 * ng, 0.0)):
        t, prim, _, _ = k.intersect(origin, w_out, tmin, np.inf)
        assert (prim == -1).all(), f"{(prim >= 0).sum()} outward rays hit the sphere"
        assert not k.occluded(origin, w_out, tmin, np.inf).any()
    origin_in = p - 1e-7 * ng
    t, prim, _, _ = k.intersect(origin_in, -w_out, 0.0, np.inf)
    assert (prim >= 0).all() and (prim != f).all() and (t > 0).all()
    # same prim never returned with the tmin offset, also on the (non-convex) teapot
    tri, k = _scene("teapot")
    f = rng.integers(0, len(tri), n)
    p = np.einsum("nc,nck->nk", rng.dirichlet([1, 1, 1], n), tri[f])
    w = rng.normal(size=(n, 3))
    t, prim, _, _ = k.intersect(p, w, 1e-6, np.inf)
    assert not np.any(prim == f)


def test_degenerate_rays_no_nan_no_crash():
    tri, k = _scene("cornell")
    ok = lambda t, p, u, v: (np.all(np.isfinite(t[p >= 0])) and np.all(np.isinf(t[p < 0]))  # noqa: E731
                             and not np.isnan(u).any() and not np.isnan(v).any()
                             and np.all(u >= -1e-12) and np.all(v >= -1e-12) and np.all(u + v <= 1 + 1e-12))
    # axis-aligned rays (exact zeros in the direction) inside the box, some of them with the
    # origin exactly on the box's faces and slab planes
    o = np.array([[0.0, 1.0, 0.0], [0.0, 0.0, 0.0], [1.0, 1.0, 0.0], [0.0, 2.0, 0.5], [0.3, 0.6, 0.5]])
    dirs = np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]], float)
    O = np.repeat(o, len(dirs), axis=0)
    D = np.tile(dirs, (len(o), 1))
    res = k.intersect(O, D, 0.0, np.inf)
    assert ok(*res)
    # the interior of the room: every axis ray from (0, 1, 0) hits something (open front: -z... +z misses)
    t, p, _, _ = res
    assert (p[:6][[0, 1, 2, 3, 5]] >= 0).all()
    # rays lying in the floor's plane (parallel to its faces, det = 0): no NaN, and they
    # hit only the walls
    t, p, u, v = k.intersect(np.array([[0.0, 0.0, 0.0], [0.2, 0.0, -0.3]]),
                             np.array([[1.0, 0.0, 0.3], [-0.5, 0.0, -1.0]]), 0.0, np.inf)
    assert ok(t, p, u, v)
    # rays from inside a closed mesh (the cube) through its vertices and edge midpoints: a
    # watertight test never lets them slip out between the triangles that meet there
    cube = _triangles(["cube"])
    kc = NumbaKernel(cube)
    corners = cube.reshape(-1, 3)
    mids = 0.5 * (cube[:, [0, 1, 2]] + cube[:, [1, 2, 0]]).reshape(-1, 3)
    targets = np.concatenate([corners, mids])
    for src in (np.array([0.1, 0.2, -0.15]), np.zeros(3)):
        res = kc.intersect(np.broadcast_to(src, targets.shape), targets - src, 0.0, np.inf)
        assert ok(*res)
        assert (res[1] >= 0).all()
        np.testing.assert_allclose(res[0], 1.0, rtol=0, atol=1e-12)
        assert kc.occluded(np.broadcast_to(src, targets.shape), targets - src, 0.0, 1.5).all()
    # zero, NaN and infinite directions, NaN origins: misses, no NaN in the output
    O = np.array([[0.0, 1.0, 0.0]] * 4 + [[np.nan, 1.0, 0.0]])
    D = np.array([[0.0, 0.0, 0.0], [np.nan, 0.0, 1.0], [np.inf, 0.0, 0.0], [1e-300, 0.0, 0.0], [1.0, 0.0, 0.0]])
    t, p, u, v = k.intersect(O, D, 0.0, np.inf)
    assert ok(t, p, u, v) and p[0] == -1 and p[1] == -1 and p[4] == -1
    assert not k.occluded(O[[0, 1, 4]], D[[0, 1, 4]], 0.0, np.inf).any()


def test_sphere_vertices_hit_watertight():
    # rays aimed exactly at the sphere's vertices (where 5-6 triangles meet) all hit
    tri, k = _scene("sphere")
    verts = np.unique(tri.reshape(-1, 3), axis=0)
    o = np.zeros_like(verts) + np.array([0.0, 0.0, 4.0])
    front = verts[:, 2] > 0.3      # clear of the silhouette (z = 0.25), where rays only graze
    t, p, u, v = k.intersect(o[front], verts[front] - o[front], 0.0, np.inf)
    assert (p >= 0).all() and not np.isnan(u).any() and not np.isnan(v).any()
    np.testing.assert_allclose(t, 1.0, rtol=0, atol=1e-12)


def test_empty_and_shapes():
    k = NumbaKernel(np.zeros((0, 3, 3)))
    t, p, u, v = k.intersect(np.zeros((3, 3)), np.ones((3, 3)), 0.0, np.inf)
    assert (p == -1).all() and np.isinf(t).all()
    assert not k.occluded(np.zeros((3, 3)), np.ones((3, 3)), 0.0, 1.0).any()
    tri, k = _scene("cornell")
    t, p, u, v = k.intersect(np.zeros((0, 3)), np.zeros((0, 3)), 0.0, np.inf)
    assert t.shape == (0,) and p.dtype.kind == "i"
    with pytest.raises(ValueError):
        NumbaKernel(np.full((1, 3, 3), np.nan))


@pytest.mark.skipif(importlib.util.find_spec("viewer.pathtracer.kernel_embree") is None,
                    reason="viewer/pathtracer/kernel_embree.py not present")
# teapot and sphere: -m slow (6 s and 13 s: their triangles brute-forced in numpy); cornell keeps
# the kernel's check in the default run
@pytest.mark.parametrize("name", [pytest.param("teapot", marks=pytest.mark.slow),
                                  pytest.param("sphere", marks=pytest.mark.slow), "cornell"])
def test_agrees_with_embree(name):
    pytest.importorskip("embreex")
    from viewer.pathtracer.kernel_embree import EmbreeKernel

    tri, k = _scene(name)
    e = EmbreeKernel(tri)
    rng = np.random.default_rng(4)
    o, d = _random_rays(tri, 4000, rng)
    t, p, u, v = k.intersect(o, d, 0.0, np.inf)
    te, pe, ue, ve = (np.asarray(a) for a in e.intersect(o, d, 0.0, np.inf))
    edge = brute_force(tri, o, d)[4]
    # Embree works in float32: where the hit lies within float32 noise of an edge the two
    # may pick different triangles or disagree about a grazing hit; elsewhere they agree.
    clear = edge > 1e-4
    assert np.array_equal((p >= 0)[clear], (pe >= 0)[clear])
    assert np.mean((p >= 0) == (pe >= 0)) > 0.998
    both = (p >= 0) & (pe >= 0)
    same = both & (p == pe)
    if name != "cornell":          # (the Cornell blocks' bottoms overlap the floor)
        assert same.sum() >= 0.99 * both.sum()
    np.testing.assert_allclose(te[both], t[both], rtol=1e-4, atol=1e-5)
    # float32 barycentrics: error ~ 1e-7 * (distance / triangle size)
    assert np.max(np.abs(ue[same] - u[same]), initial=0) < 1e-3
    assert np.max(np.abs(ve[same] - v[same]), initial=0) < 1e-3
    tmax = rng.uniform(0.0, 3.0, len(o))
    occ, occ_e = k.occluded(o, d, 1e-4, tmax), np.asarray(e.occluded(o, d, 1e-4, tmax))
    assert np.mean(occ == occ_e) > 0.998
