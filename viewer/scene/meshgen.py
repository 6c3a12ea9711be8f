"""Procedural generators for the built-in shapes (numpy only, deterministic).

Every generator returns a :class:`Shape`: ``positions`` (V,3), ``normals`` (V,3, unit),
``indices`` (F,3, counter-clockwise seen from the side the normals point to) and ``uvs``
(V,2) or ``None`` where no natural parametrization exists (``sphere``, ``teapot``,
the Cornell blocks have per-face uvs). World frame: +y up, right-handed.

Where uvs exist, ``dP/du`` (the tangent, the anisotropy axis) points "to the right" when
looking at a flat face with +y up, like the mesh loader's fallback ``cross(+y, n)``; on the
surfaces of revolution (torus, shader ball) it runs around the +y axis, clockwise seen from
above, which is the fallback's direction wherever the normal points away from the axis.

Shapes (see ``GENERATORS``):

- ``sphere``: icosphere of radius 1, 5 subdivisions (20480 faces), exact normals.
- ``plane``: [-1,1]^2 in the xz plane at y = 0, facing +y, 8x8 quads.
- ``cube``: [-1,1]^3 with split (flat) normals per face.
- ``prism``: a 60 degree glass prism (equilateral section, circumradius 1) along z.
- ``torus``: major radius 0.7, minor 0.3, around the y axis.
- ``teapot``: Newell's 32 bicubic Bezier patches (rim, body, handle, spout, lid, bottom),
  rotated from the data's z-up to y-up, the body axis on the y axis, the bounding box
  centred on y = 0 (not resting on the floor: like the sphere, it frames at the origin;
  use ``translate`` in a scene to put it on a floor) and scaled so that its farthest
  point is at distance 1 from the origin. The original proportions are kept (no 1.3
  vertical stretch). Not watertight: as in the original data the spout tip is open,
  the lid does not touch the rim and handle and spout pierce the body.
- ``shader_ball``: a lathe (surface of revolution) with a grooved sphere on a neck and a
  pedestal base, standing on y = 0.
- ``cornell_*``: a Cornell-box style room, x and z in [-1, 1], y in [0, 2], open towards +z.
"""

from __future__ import annotations

from typing import Callable, NamedTuple

import numpy as np


class Shape(NamedTuple):
    positions: np.ndarray          # float64 (V,3)
    normals: np.ndarray            # float64 (V,3), unit length
    indices: np.ndarray            # int64 (F,3)
    uvs: np.ndarray | None         # float64 (V,2) or None


def _normalize(v: np.ndarray) -> np.ndarray:
    n = np.linalg.norm(v, axis=-1, keepdims=True)
    return v / np.where(n > 0.0, n, 1.0)


def _concat(parts: list[Shape]) -> Shape:
    """Concatenate shapes into one (uvs kept only when every part has them)."""
    pos, nrm, idx, uv = [], [], [], []
    offset = 0
    for p in parts:
        pos.append(p.positions)
        nrm.append(p.normals)
        idx.append(p.indices + offset)
        uv.append(p.uvs)
        offset += len(p.positions)
    uvs = None if any(u is None for u in uv) else np.concatenate(uv)
    return Shape(np.concatenate(pos), np.concatenate(nrm), np.concatenate(idx), uvs)


def _grid_indices(nu: int, nv: int) -> np.ndarray:
    """Two triangles per cell of a (nu+1) x (nv+1) vertex grid stored row-major in v
    (vertex (i, j) at j * (nu + 1) + i). Counter-clockwise around dP/du x dP/dv."""
    i, j = np.meshgrid(np.arange(nu), np.arange(nv), indexing="xy")
    a = (j * (nu + 1) + i).ravel()
    b = a + 1
    c = a + nu + 2
    d = a + nu + 1
    return np.concatenate([np.stack([a, b, c], 1), np.stack([a, c, d], 1)]).reshape(2, -1, 3) \
        .transpose(1, 0, 2).reshape(-1, 3)


# --------------------------------------------------------------------------- quads, boxes

def _quad(origin, edge_u, edge_v, nu: int = 1, nv: int = 1) -> Shape:
    """A flat parallelogram origin + s * edge_u + t * edge_v (s, t in [0,1]) facing
    normalize(edge_u x edge_v), subdivided into nu x nv cells, uvs = (s, t)."""
    o, eu, ev = (np.asarray(x, dtype=np.float64) for x in (origin, edge_u, edge_v))
    s, t = np.meshgrid(np.linspace(0.0, 1.0, nu + 1), np.linspace(0.0, 1.0, nv + 1), indexing="xy")
    s, t = s.ravel(), t.ravel()
    pos = o + s[:, None] * eu + t[:, None] * ev
    n = _normalize(np.cross(eu, ev))
    nrm = np.broadcast_to(n, pos.shape).copy()
    return Shape(pos, nrm, _grid_indices(nu, nv), np.stack([s, t], 1))


def _box_faces(half: np.ndarray, n_sub: int = 1) -> list[Shape]:
    """The six faces of an axis-aligned box [-half, half], outward, u to the right and
    v up when seen from outside (top: u = +x, v = -z; bottom: u = +x, v = +z)."""
    hx, hy, hz = half
    return [
        _quad((hx, -hy, hz), (0, 0, -2 * hz), (0, 2 * hy, 0), n_sub, n_sub),     # +x
        _quad((-hx, -hy, -hz), (0, 0, 2 * hz), (0, 2 * hy, 0), n_sub, n_sub),    # -x
        _quad((-hx, hy, hz), (2 * hx, 0, 0), (0, 0, -2 * hz), n_sub, n_sub),     # +y
        _quad((-hx, -hy, -hz), (2 * hx, 0, 0), (0, 0, 2 * hz), n_sub, n_sub),    # -y
        _quad((-hx, -hy, hz), (2 * hx, 0, 0), (0, 2 * hy, 0), n_sub, n_sub),     # +z
        _quad((hx, -hy, -hz), (-2 * hx, 0, 0), (0, 2 * hy, 0), n_sub, n_sub),    # -z
    ]


def _rotate_y(deg: float) -> np.ndarray:
    """Rotation about +y by deg (counter-clockwise seen from above)."""
    a = np.radians(deg)
    c, s = np.cos(a), np.sin(a)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def _transformed(shape: Shape, rot: np.ndarray, offset) -> Shape:
    return Shape(shape.positions @ rot.T + np.asarray(offset, dtype=np.float64),
                 shape.normals @ rot.T, shape.indices, shape.uvs)


def plane(n: int = 8) -> Shape:
    """[-1,1] x [-1,1] in the xz plane at y = 0, facing +y; u = +x, v = -z."""
    return _quad((-1.0, 0.0, 1.0), (2.0, 0.0, 0.0), (0.0, 0.0, -2.0), n, n)


def cube() -> Shape:
    """[-1,1]^3, 24 vertices (split normals), 12 triangles, per-face uvs."""
    return _concat(_box_faces(np.array([1.0, 1.0, 1.0])))


def prism() -> Shape:
    """A 60 degree prism: the equilateral triangle of circumradius 1 in the xy plane (apex at
    (0, 1), base at y = -0.5) extruded over z in [-1, 1]; flat normals, per-face uvs."""
    tri = np.array([[0.0, 1.0], [-np.sqrt(0.75), -0.5], [np.sqrt(0.75), -0.5]])  # counter-clockwise
    parts = []
    for a, b in ((0, 1), (1, 2), (2, 0)):
        p, q = tri[a], tri[b]
        parts.append(_quad((p[0], p[1], -1.0), (q[0] - p[0], q[1] - p[1], 0.0), (0.0, 0.0, 2.0)))
    for z, order in ((1.0, (0, 1, 2)), (-1.0, (0, 2, 1))):
        pos = np.array([[tri[i][0], tri[i][1], z] for i in order])
        nrm = np.broadcast_to([0.0, 0.0, z], (3, 3)).copy()
        parts.append(Shape(pos, nrm, np.array([[0, 1, 2]]), 0.5 * (pos[:, :2] + 1.0)))
    return _concat(parts)


# --------------------------------------------------------------------------- icosphere

def sphere(subdivisions: int = 5) -> Shape:
    """Icosphere of radius 1: 20 * 4^subdivisions faces; normals = positions."""
    t = (1.0 + np.sqrt(5.0)) / 2.0
    v = np.array([[-1, t, 0], [1, t, 0], [-1, -t, 0], [1, -t, 0],
                  [0, -1, t], [0, 1, t], [0, -1, -t], [0, 1, -t],
                  [t, 0, -1], [t, 0, 1], [-t, 0, -1], [-t, 0, 1]], dtype=np.float64)
    f = np.array([[0, 11, 5], [0, 5, 1], [0, 1, 7], [0, 7, 10], [0, 10, 11],
                  [1, 5, 9], [5, 11, 4], [11, 10, 2], [10, 7, 6], [7, 1, 8],
                  [3, 9, 4], [3, 4, 2], [3, 2, 6], [3, 6, 8], [3, 8, 9],
                  [4, 9, 5], [2, 4, 11], [6, 2, 10], [8, 6, 7], [9, 8, 1]], dtype=np.int64)
    v = _normalize(v)
    # Make every face counter-clockwise seen from outside (independent of the table).
    c = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])
    flip = np.einsum("ij,ij->i", c, v[f].sum(1)) < 0.0
    f[flip] = f[flip][:, ::-1]
    for _ in range(subdivisions):
        # One new vertex per unique edge, projected onto the sphere.
        e = np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]])
        e_sorted = np.sort(e, axis=1)
        uniq, inv = np.unique(e_sorted, axis=0, return_inverse=True)
        inv = inv.reshape(-1)
        mid = _normalize(v[uniq[:, 0]] + v[uniq[:, 1]])
        m = inv.reshape(3, -1).T + len(v)      # (F,3): midpoints of edges ab, bc, ca
        v = np.concatenate([v, mid])
        a, b, cc = f[:, 0], f[:, 1], f[:, 2]
        ab, bc, ca = m[:, 0], m[:, 1], m[:, 2]
        f = np.stack([np.stack([a, ab, ca], 1), np.stack([b, bc, ab], 1),
                      np.stack([cc, ca, bc], 1), np.stack([ab, bc, ca], 1)], 1).reshape(-1, 3)
    return Shape(v, v.copy(), f, None)


# --------------------------------------------------------------------------- lathe

def _profile_piece(prims: list[tuple], n_per_unit: float) -> tuple[np.ndarray, np.ndarray]:
    """Sample a smooth piece of a 2D profile in the (r, y) plane.

    ``prims`` are consecutive ("line", p0, p1) or ("arc", centre, radius, a0, a1) primitives
    (angles in radians; a1 < a0 runs clockwise). Returns points (K,2) and unit profile
    normals (K,2) = the tangent turned clockwise, which is the outward side when the profile
    runs from the bottom of the solid up to its top (and outward in r)."""
    pts, tans = [], []
    for k, prim in enumerate(prims):
        if prim[0] == "line":
            p0, p1 = np.asarray(prim[1], float), np.asarray(prim[2], float)
            length = np.linalg.norm(p1 - p0)
            n = max(1, int(np.ceil(length * n_per_unit - 1e-9)))
            s = np.linspace(0.0, 1.0, n + 1)
            p = p0 + s[:, None] * (p1 - p0)
            tg = np.broadcast_to((p1 - p0) / length, p.shape)
        else:
            _, c, rad, a0, a1 = prim
            length = abs(a1 - a0) * rad
            n = max(2, int(np.ceil(length * n_per_unit - 1e-9)))
            a = np.linspace(a0, a1, n + 1)
            p = np.asarray(c, float) + rad * np.stack([np.cos(a), np.sin(a)], 1)
            sgn = 1.0 if a1 > a0 else -1.0
            tg = sgn * np.stack([-np.sin(a), np.cos(a)], 1)
        if k > 0:                         # shared end point of consecutive primitives
            p, tg = p[1:], tg[1:]
        pts.append(p)
        tans.append(tg)
    p = np.concatenate(pts)
    tg = _normalize(np.concatenate(tans))
    return p, np.stack([tg[:, 1], -tg[:, 0]], 1)


def _lathe(pieces: list[tuple[np.ndarray, np.ndarray]], segments: int) -> Shape:
    """Revolve profile pieces (r, y) about +y. P(u, v) = (r cos phi, y, -r sin phi) with
    phi = 2 pi u, so dP/du is along cross(+y, n); v is the arc length along the whole
    profile, normalised to [0, 1]. Hard creases between pieces (duplicated rings); rings
    with r = 0 are poles (one triangle per segment instead of two)."""
    lengths = [np.linalg.norm(np.diff(p, axis=0), axis=1).sum() for p, _ in pieces]
    total = float(sum(lengths))
    phi = np.linspace(0.0, 2.0 * np.pi, segments + 1)
    phi[-1] = 0.0                                     # seam: exactly the same positions
    cphi, sphi = np.cos(phi), np.sin(phi)
    u = np.linspace(0.0, 1.0, segments + 1)
    positions, normals, uvs, faces = [], [], [], []
    count = 0
    v0 = 0.0
    for (prof, pn), length in zip(pieces, lengths):
        arc = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(prof, axis=0), axis=1))])
        r, y = prof[:, 0], prof[:, 1]
        pos = np.stack([r[:, None] * cphi[None, :], np.broadcast_to(y[:, None], (len(r), segments + 1)),
                        -r[:, None] * sphi[None, :]], -1)
        nrm = np.stack([pn[:, 0:1] * cphi[None, :], np.broadcast_to(pn[:, 1:2], (len(r), segments + 1)),
                        -pn[:, 0:1] * sphi[None, :]], -1)
        vv = (v0 + arc) / total
        uv = np.stack(np.broadcast_arrays(u[None, :], vv[:, None]), -1)
        positions.append(pos.reshape(-1, 3))
        normals.append(nrm.reshape(-1, 3))
        uvs.append(uv.reshape(-1, 2))
        cells = _grid_indices(segments, len(r) - 1).reshape(len(r) - 1, segments, 2, 3)
        tri = []
        for j in range(len(r) - 1):
            if r[j] <= 1e-12:            # pole below: keep only (a, c, d)
                tri.append(cells[j, :, 1])
            elif r[j + 1] <= 1e-12:      # pole above: keep only (a, b, c)
                tri.append(cells[j, :, 0])
            else:
                tri.append(cells[j].reshape(-1, 3))
        faces.append(np.concatenate(tri) + count)
        count += pos.shape[0] * pos.shape[1]
        v0 += length
    return Shape(np.concatenate(positions), _normalize(np.concatenate(normals)),
                 np.concatenate(faces), np.concatenate(uvs))


def torus(major: float = 0.7, minor: float = 0.3, segments: int = 96, rings: int = 48) -> Shape:
    """Torus around +y: a circle of radius ``minor`` at distance ``major`` revolved."""
    prof = _profile_piece([("arc", (major, 0.0), minor, -np.pi, np.pi)], rings / (2 * np.pi * minor))
    return _lathe([prof], segments)


def shader_ball(segments: int = 96) -> Shape:
    """A material-test shape: a ball of radius 0.62 with a rounded groove cut around it
    25 degrees above its equator, on a neck and a round-edged pedestal, standing on y = 0
    (height 1.70). Built as a lathe with smooth normals and hard creases at the base's
    bottom edge, the groove's lips and where the neck meets the ball."""
    d = 48.0                                          # profile samples per unit length
    base_r, base_h, edge = 0.62, 0.08, 0.06
    neck_r, neck_y0, fillet = 0.20, 0.24, 0.10
    ball_r, ball_c = 0.62, 1.08
    groove_lat, groove_w = np.radians(25.0), 0.035
    neck_y1 = ball_c - np.sqrt(ball_r ** 2 - neck_r ** 2)
    a_neck = np.arctan2(neck_y1 - ball_c, neck_r)
    # The groove: a circle of radius groove_w centred on the ball's surface; its lips are
    # where it cuts the ball, at +-delta of latitude; its cross-section inside the ball runs
    # clockwise (concave) from the lower lip through the deepest point to the upper lip.
    delta = 2.0 * np.arcsin(groove_w / (2.0 * ball_r))
    g_c = (ball_r * np.cos(groove_lat), ball_c + ball_r * np.sin(groove_lat))
    beta = np.pi / 2.0 + np.arcsin(groove_w / (2.0 * ball_r))   # lip angle from the radial
    top = ball_c + ball_r
    pieces = [
        _profile_piece([("line", (0.0, 0.0), (base_r, 0.0))], d),                      # bottom
        _profile_piece([("line", (base_r, 0.0), (base_r, base_h)),                    # pedestal
                        ("arc", (base_r - edge, base_h), edge, 0.0, np.pi / 2),
                        ("line", (base_r - edge, base_h + edge), (neck_r + fillet, base_h + edge)),
                        ("arc", (neck_r + fillet, base_h + edge + fillet), fillet, -np.pi / 2, -np.pi),
                        ("line", (neck_r, neck_y0), (neck_r, neck_y1))], d),
        _profile_piece([("arc", (0.0, ball_c), ball_r, a_neck, groove_lat - delta)], d),
        _profile_piece([("arc", g_c, groove_w, groove_lat - beta, groove_lat - 2 * np.pi + beta)], d * 3),
        _profile_piece([("arc", (0.0, ball_c), ball_r, groove_lat + delta, np.pi / 2)], d),
    ]
    # Consecutive pieces meet exactly (no crack at a crease); the top is exactly a pole.
    for k in range(1, len(pieces)):
        pieces[k][0][0] = pieces[k - 1][0][-1]
    pieces[-1][0][-1] = (0.0, top)
    return _lathe(pieces, segments)


# --------------------------------------------------------------------------- teapot

# Newell's Utah teapot (1975), the public-domain 32-patch data set (28 original patches
# plus the 4 bottom patches added later): 306 control points (z up) and 32 patches of
# 4x4 one-based indices. Data, not code.
_TEAPOT_POINTS = """
1.4 0 2.4|1.4 -.784 2.4|.784 -1.4 2.4|0 -1.4 2.4|1.3375 0 2.53125|1.3375 -.749 2.53125|
.749 -1.3375 2.53125|0 -1.3375 2.53125|1.4375 0 2.53125|1.4375 -.805 2.53125|
.805 -1.4375 2.53125|0 -1.4375 2.53125|1.5 0 2.4|1.5 -.84 2.4|.84 -1.5 2.4|0 -1.5 2.4|
-.784 -1.4 2.4|-1.4 -.784 2.4|-1.4 0 2.4|-.749 -1.3375 2.53125|-1.3375 -.749 2.53125|
-1.3375 0 2.53125|-.805 -1.4375 2.53125|-1.4375 -.805 2.53125|-1.4375 0 2.53125|
-.84 -1.5 2.4|-1.5 -.84 2.4|-1.5 0 2.4|-1.4 .784 2.4|-.784 1.4 2.4|0 1.4 2.4|
-1.3375 .749 2.53125|-.749 1.3375 2.53125|0 1.3375 2.53125|-1.4375 .805 2.53125|
-.805 1.4375 2.53125|0 1.4375 2.53125|-1.5 .84 2.4|-.84 1.5 2.4|0 1.5 2.4|.784 1.4 2.4|
1.4 .784 2.4|.749 1.3375 2.53125|1.3375 .749 2.53125|.805 1.4375 2.53125|
1.4375 .805 2.53125|.84 1.5 2.4|1.5 .84 2.4|1.75 0 1.875|1.75 -.98 1.875|.98 -1.75 1.875|
0 -1.75 1.875|2 0 1.35|2 -1.12 1.35|1.12 -2 1.35|0 -2 1.35|2 0 .9|2 -1.12 .9|1.12 -2 .9|
0 -2 .9|-.98 -1.75 1.875|-1.75 -.98 1.875|-1.75 0 1.875|-1.12 -2 1.35|-2 -1.12 1.35|
-2 0 1.35|-1.12 -2 .9|-2 -1.12 .9|-2 0 .9|-1.75 .98 1.875|-.98 1.75 1.875|0 1.75 1.875|
-2 1.12 1.35|-1.12 2 1.35|0 2 1.35|-2 1.12 .9|-1.12 2 .9|0 2 .9|.98 1.75 1.875|
1.75 .98 1.875|1.12 2 1.35|2 1.12 1.35|1.12 2 .9|2 1.12 .9|2 0 .45|2 -1.12 .45|
1.12 -2 .45|0 -2 .45|1.5 0 .225|1.5 -.84 .225|.84 -1.5 .225|0 -1.5 .225|1.5 0 .15|
1.5 -.84 .15|.84 -1.5 .15|0 -1.5 .15|-1.12 -2 .45|-2 -1.12 .45|-2 0 .45|-.84 -1.5 .225|
-1.5 -.84 .225|-1.5 0 .225|-.84 -1.5 .15|-1.5 -.84 .15|-1.5 0 .15|-2 1.12 .45|
-1.12 2 .45|0 2 .45|-1.5 .84 .225|-.84 1.5 .225|0 1.5 .225|-1.5 .84 .15|-.84 1.5 .15|
0 1.5 .15|1.12 2 .45|2 1.12 .45|.84 1.5 .225|1.5 .84 .225|.84 1.5 .15|1.5 .84 .15|
-1.6 0 2.025|-1.6 -.3 2.025|-1.5 -.3 2.25|-1.5 0 2.25|-2.3 0 2.025|-2.3 -.3 2.025|
-2.5 -.3 2.25|-2.5 0 2.25|-2.7 0 2.025|-2.7 -.3 2.025|-3 -.3 2.25|-3 0 2.25|-2.7 0 1.8|
-2.7 -.3 1.8|-3 -.3 1.8|-3 0 1.8|-1.5 .3 2.25|-1.6 .3 2.025|-2.5 .3 2.25|-2.3 .3 2.025|
-3 .3 2.25|-2.7 .3 2.025|-3 .3 1.8|-2.7 .3 1.8|-2.7 0 1.575|-2.7 -.3 1.575|-3 -.3 1.35|
-3 0 1.35|-2.5 0 1.125|-2.5 -.3 1.125|-2.65 -.3 .9375|-2.65 0 .9375|-2 -.3 .9|
-1.9 -.3 .6|-1.9 0 .6|-3 .3 1.35|-2.7 .3 1.575|-2.65 .3 .9375|-2.5 .3 1.125|-1.9 .3 .6|
-2 .3 .9|1.7 0 1.425|1.7 -.66 1.425|1.7 -.66 .6|1.7 0 .6|2.6 0 1.425|2.6 -.66 1.425|
3.1 -.66 .825|3.1 0 .825|2.3 0 2.1|2.3 -.25 2.1|2.4 -.25 2.025|2.4 0 2.025|2.7 0 2.4|
2.7 -.25 2.4|3.3 -.25 2.4|3.3 0 2.4|1.7 .66 .6|1.7 .66 1.425|3.1 .66 .825|2.6 .66 1.425|
2.4 .25 2.025|2.3 .25 2.1|3.3 .25 2.4|2.7 .25 2.4|2.8 0 2.475|2.8 -.25 2.475|
3.525 -.25 2.49375|3.525 0 2.49375|2.9 0 2.475|2.9 -.15 2.475|3.45 -.15 2.5125|
3.45 0 2.5125|2.8 0 2.4|2.8 -.15 2.4|3.2 -.15 2.4|3.2 0 2.4|3.525 .25 2.49375|
2.8 .25 2.475|3.45 .15 2.5125|2.9 .15 2.475|3.2 .15 2.4|2.8 .15 2.4|0 0 3.15|
0 -.002 3.15|.002 0 3.15|.8 0 3.15|.8 -.45 3.15|.45 -.8 3.15|0 -.8 3.15|0 0 2.85|
.2 0 2.7|.2 -.112 2.7|.112 -.2 2.7|0 -.2 2.7|-.002 0 3.15|-.45 -.8 3.15|-.8 -.45 3.15|
-.8 0 3.15|-.112 -.2 2.7|-.2 -.112 2.7|-.2 0 2.7|0 .002 3.15|-.8 .45 3.15|-.45 .8 3.15|
0 .8 3.15|-.2 .112 2.7|-.112 .2 2.7|0 .2 2.7|.45 .8 3.15|.8 .45 3.15|.112 .2 2.7|
.2 .112 2.7|.4 0 2.55|.4 -.224 2.55|.224 -.4 2.55|0 -.4 2.55|1.3 0 2.55|1.3 -.728 2.55|
.728 -1.3 2.55|0 -1.3 2.55|1.3 0 2.4|1.3 -.728 2.4|.728 -1.3 2.4|0 -1.3 2.4|
-.224 -.4 2.55|-.4 -.224 2.55|-.4 0 2.55|-.728 -1.3 2.55|-1.3 -.728 2.55|-1.3 0 2.55|
-.728 -1.3 2.4|-1.3 -.728 2.4|-1.3 0 2.4|-.4 .224 2.55|-.224 .4 2.55|0 .4 2.55|
-1.3 .728 2.55|-.728 1.3 2.55|0 1.3 2.55|-1.3 .728 2.4|-.728 1.3 2.4|0 1.3 2.4|
.224 .4 2.55|.4 .224 2.55|.728 1.3 2.55|1.3 .728 2.55|.728 1.3 2.4|1.3 .728 2.4|0 0 0|
1.5 0 .15|1.5 .84 .15|.84 1.5 .15|0 1.5 .15|1.5 0 .075|1.5 .84 .075|.84 1.5 .075|
0 1.5 .075|1.425 0 0|1.425 .798 0|.798 1.425 0|0 1.425 0|-.84 1.5 .15|-1.5 .84 .15|
-1.5 0 .15|-.84 1.5 .075|-1.5 .84 .075|-1.5 0 .075|-.798 1.425 0|-1.425 .798 0|
-1.425 0 0|-1.5 -.84 .15|-.84 -1.5 .15|0 -1.5 .15|-1.5 -.84 .075|-.84 -1.5 .075|
0 -1.5 .075|-1.425 -.798 0|-.798 -1.425 0|0 -1.425 0|.84 -1.5 .15|1.5 -.84 .15|
.84 -1.5 .075|1.5 -.84 .075|.798 -1.425 0|1.425 -.798 0
"""

_TEAPOT_PATCHES = """
1 2 3 4 5 6 7 8 9 10 11 12 13 14 15 16
4 17 18 19 8 20 21 22 12 23 24 25 16 26 27 28
19 29 30 31 22 32 33 34 25 35 36 37 28 38 39 40
31 41 42 1 34 43 44 5 37 45 46 9 40 47 48 13
13 14 15 16 49 50 51 52 53 54 55 56 57 58 59 60
16 26 27 28 52 61 62 63 56 64 65 66 60 67 68 69
28 38 39 40 63 70 71 72 66 73 74 75 69 76 77 78
40 47 48 13 72 79 80 49 75 81 82 53 78 83 84 57
57 58 59 60 85 86 87 88 89 90 91 92 93 94 95 96
60 67 68 69 88 97 98 99 92 100 101 102 96 103 104 105
69 76 77 78 99 106 107 108 102 109 110 111 105 112 113 114
78 83 84 57 108 115 116 85 111 117 118 89 114 119 120 93
121 122 123 124 125 126 127 128 129 130 131 132 133 134 135 136
124 137 138 121 128 139 140 125 132 141 142 129 136 143 144 133
133 134 135 136 145 146 147 148 149 150 151 152 69 153 154 155
136 143 144 133 148 156 157 145 152 158 159 149 155 160 161 69
162 163 164 165 166 167 168 169 170 171 172 173 174 175 176 177
165 178 179 162 169 180 181 166 173 182 183 170 177 184 185 174
174 175 176 177 186 187 188 189 190 191 192 193 194 195 196 197
177 184 185 174 189 198 199 186 193 200 201 190 197 202 203 194
204 204 204 204 207 208 209 210 211 211 211 211 212 213 214 215
204 204 204 204 210 217 218 219 211 211 211 211 215 220 221 222
204 204 204 204 219 224 225 226 211 211 211 211 222 227 228 229
204 204 204 204 226 230 231 207 211 211 211 211 229 232 233 212
212 213 214 215 234 235 236 237 238 239 240 241 242 243 244 245
215 220 221 222 237 246 247 248 241 249 250 251 245 252 253 254
222 227 228 229 248 255 256 257 251 258 259 260 254 261 262 263
229 232 233 212 257 264 265 234 260 266 267 238 263 268 269 242
270 270 270 270 279 280 281 282 275 276 277 278 271 272 273 274
270 270 270 270 282 289 290 291 278 286 287 288 274 283 284 285
270 270 270 270 291 298 299 300 288 295 296 297 285 292 293 294
270 270 270 270 300 305 306 279 297 303 304 275 294 301 302 271
"""


def teapot_data() -> tuple[np.ndarray, np.ndarray]:
    """Newell's teapot: control points (N, 3), z up, and 32 bicubic patches of indices into
    them, (32, 4, 4)."""
    pts = np.array([[float(x) for x in p.split()] for p in _TEAPOT_POINTS.replace("\n", "").split("|")])
    patches = np.array(_TEAPOT_PATCHES.split(), dtype=np.int64).reshape(32, 4, 4) - 1
    return pts, patches


def bernstein(t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Cubic Bernstein basis B_i(t) and its derivative, each (len(t), 4)."""
    s = 1.0 - t
    b = np.stack([s ** 3, 3 * t * s ** 2, 3 * t ** 2 * s, t ** 3], 1)
    db = np.stack([-3 * s ** 2, 3 * s ** 2 - 6 * t * s, 6 * t * s - 3 * t ** 2, 3 * t ** 2], 1)
    return b, db


def teapot(n: int = 16) -> Shape:
    """The Utah teapot, each of the 32 patches tessellated into n x n cells.

    Normals come from the patch derivatives, n = dP/du x dP/dv (u along a patch row of the
    control grid, v down its columns); where that cross product vanishes (the lid's knob
    and the bottom collapse a whole control row to one point, a pole) the normal is taken
    from the same formula a small step inside the patch. Coincident samples on shared patch
    edges are welded into one vertex whose normal is the normalised sum of theirs."""
    ctrl, patches = teapot_data()
    t = np.linspace(0.0, 1.0, n + 1)
    b, db = bernstein(t)
    eps = 1e-4
    b_in, db_in = bernstein(np.clip(t, eps, 1.0 - eps))
    P_all, N_all, F_all = [], [], []
    offset = 0
    for patch in patches:
        G = ctrl[patch]                                  # (4 rows v, 4 cols u, 3)
        # P(u, v) = sum_ij B_i(v) B_j(u) G_ij; arrays indexed [v, u]
        P = np.einsum("ai,bj,ijk->abk", b, b, G)
        Pu = np.einsum("ai,bj,ijk->abk", b, db, G)
        Pv = np.einsum("ai,bj,ijk->abk", db, b, G)
        N = np.cross(Pu, Pv)
        ln = np.linalg.norm(N, axis=-1)
        bad = ln < 1e-6 * max(1.0, float(np.abs(G).max())) ** 2
        if bad.any():
            Pu2 = np.einsum("ai,bj,ijk->abk", b_in, db_in, G)
            Pv2 = np.einsum("ai,bj,ijk->abk", db_in, b_in, G)
            N = np.where(bad[..., None], np.cross(Pu2, Pv2), N)
        P_all.append(P.reshape(-1, 3))
        N_all.append(_normalize(N.reshape(-1, 3)))
        F_all.append(_grid_indices(n, n) + offset)
        offset += (n + 1) ** 2
    P = np.concatenate(P_all)
    N = np.concatenate(N_all)
    F = np.concatenate(F_all)
    # With u along the rows of the control grid and v down its columns, dP/du x dP/dv
    # points out of the pot for all 32 patches (checked per patch in tests/test_mesh.py).
    # Weld coincident samples (shared patch edges, poles).
    key = np.round(P, 7)
    uniq, first, inv = np.unique(key, axis=0, return_index=True, return_inverse=True)
    inv = inv.reshape(-1)
    order = np.argsort(first)                        # keep first-seen order: deterministic, local
    rank = np.empty_like(order)
    rank[order] = np.arange(len(order))
    inv = rank[inv]
    Pw = P[first[order]]
    Nw = np.zeros_like(Pw)
    np.add.at(Nw, inv, N)
    Nw = _normalize(Nw)
    F = inv[F]
    F = F[(F[:, 0] != F[:, 1]) & (F[:, 1] != F[:, 2]) & (F[:, 2] != F[:, 0])]
    # z-up data -> y-up: (x, y, z) -> (x, z, -y), a proper rotation about x.
    rot = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]])
    Pw = Pw @ rot.T
    Nw = Nw @ rot.T
    # Body axis on the y axis, bounding box centred on y = 0, farthest point at distance 1.
    lo, hi = Pw.min(0), Pw.max(0)
    Pw = Pw - np.array([0.0, 0.5 * (lo[1] + hi[1]), 0.0])
    Pw = Pw / np.linalg.norm(Pw, axis=1).max()
    return Shape(Pw, Nw, F, None)


# --------------------------------------------------------------------------- Cornell box

# Proportions of the original Cornell box (Goral et al. 1984; the measured 2000 data set),
# mapped to a 2 x 2 x 2 room: blocks 0.6 wide, the short one 0.6 and the tall one 1.2 high,
# each turned by about 17 degrees.
_CORNELL_SHORT = dict(half=(0.3, 0.3, 0.3), rot=-17.0, centre=(0.335, 0.3, 0.395))
_CORNELL_TALL = dict(half=(0.3, 0.6, 0.3), rot=17.0, centre=(-0.326, 0.6, -0.256))


def cornell_room() -> Shape:
    """Floor (y = 0), ceiling (y = 2) and back wall (z = -1), all facing into the room."""
    return _concat([
        _quad((-1.0, 0.0, 1.0), (2.0, 0.0, 0.0), (0.0, 0.0, -2.0)),   # floor, +y
        _quad((-1.0, 2.0, -1.0), (2.0, 0.0, 0.0), (0.0, 0.0, 2.0)),   # ceiling, -y
        _quad((-1.0, 0.0, -1.0), (2.0, 0.0, 0.0), (0.0, 2.0, 0.0)),   # back wall, +z
    ])


def cornell_left() -> Shape:
    """Left wall x = -1, facing +x."""
    return _quad((-1.0, 0.0, 1.0), (0.0, 0.0, -2.0), (0.0, 2.0, 0.0))


def cornell_right() -> Shape:
    """Right wall x = +1, facing -x."""
    return _quad((1.0, 0.0, -1.0), (0.0, 0.0, 2.0), (0.0, 2.0, 0.0))


def _block(half, rot, centre) -> Shape:
    return _transformed(_concat(_box_faces(np.asarray(half, dtype=np.float64))), _rotate_y(rot), centre)


def cornell_short_block() -> Shape:
    """The short block (front right), a closed box with flat normals standing on y = 0."""
    return _block(**_CORNELL_SHORT)


def cornell_tall_block() -> Shape:
    """The tall block (back left), a closed box with flat normals standing on y = 0."""
    return _block(**_CORNELL_TALL)


def cornell_light(size: float = 0.47, height: float = 1.99) -> Shape:
    """The ceiling light: a size x size quad centred under the ceiling, facing -y."""
    h = 0.5 * size
    return _quad((-h, height, -h), (size, 0.0, 0.0), (0.0, 0.0, size))


GENERATORS: dict[str, Callable[[], Shape]] = {
    "sphere": sphere,
    "plane": plane,
    "cube": cube,
    "prism": prism,
    "torus": torus,
    "teapot": teapot,
    "shader_ball": shader_ball,
    "cornell_room": cornell_room,
    "cornell_left": cornell_left,
    "cornell_right": cornell_right,
    "cornell_short_block": cornell_short_block,
    "cornell_tall_block": cornell_tall_block,
    "cornell_light": cornell_light,
}


def generate(name: str) -> Shape:
    """The built-in shape ``name`` (a key of ``GENERATORS``)."""
    return GENERATORS[name]()
