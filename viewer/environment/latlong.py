"""Lat-long (equirectangular) environment maps: directions, texels, lookups, cube maps.

Orientation (docs/conventions.md): a world direction d (right-handed, +y up) maps to

    u = 0.5 + atan2(d.x, -d.z) / (2 pi)        (u = 0.5 looks along -z, u = 0.75 along +x)
    v = acos(d.y) / pi                         (v = 0 at the zenith = row 0, the top row)

and back: with phi = 2 pi (u - 0.5) and theta = pi v,
d = (sin(theta) sin(phi), cos(theta), -sin(theta) cos(phi)).

A map is a float32 array (H, W, 3) of linear radiance; texel (row i, column j) covers
u in [j/W, (j+1)/W], v in [i/H, (i+1)/H] and its value is the radiance at its centre.
Lookups are bilinear between texel centres, wrapping around in u and clamping in v.

Rotation: the scene's ``rotation_deg`` turns the *map* by that angle about +y, right-handed
(``viewer.scene``): L(d) = map(R_y(-rotation_deg) d), with R_y(a) = [[c, 0, s], [0, 1, 0],
[-s, 0, c]] (+90 degrees takes +x to -z).
"""

from __future__ import annotations

import math

import numpy as np

TWO_PI = 2.0 * np.pi

# OpenGL cube map faces in the order of GL_TEXTURE_CUBE_MAP_POSITIVE_X + k.
CUBE_FACES = ("+X", "-X", "+Y", "-Y", "+Z", "-Z")


def rotation_y(deg: float) -> np.ndarray:
    """3x3 right-handed rotation about +y by ``deg`` degrees (for column vectors)."""
    a = math.radians(deg)
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def dir_to_uv(d) -> tuple[np.ndarray, np.ndarray]:
    """(u, v) in [0, 1] of directions ``d`` (..., 3) (need not be unit length)."""
    d = np.asarray(d, dtype=np.float64)
    n = np.linalg.norm(d, axis=-1)
    n = np.where(n > 0, n, 1.0)
    u = 0.5 + np.arctan2(d[..., 0], -d[..., 2]) / TWO_PI
    v = np.arccos(np.clip(d[..., 1] / n, -1.0, 1.0)) / np.pi
    return u, v


def uv_to_dir(u, v) -> np.ndarray:
    """Unit directions (..., 3) for lat-long coordinates (u, v)."""
    phi = TWO_PI * (np.asarray(u, dtype=np.float64) - 0.5)
    theta = np.pi * np.asarray(v, dtype=np.float64)
    st = np.sin(theta)
    return np.stack([st * np.sin(phi), np.cos(theta), -st * np.cos(phi)], axis=-1)


def texel_centers(height: int, width: int) -> tuple[np.ndarray, np.ndarray]:
    """(u, v) of every texel centre, each (H, W)."""
    u = (np.arange(width) + 0.5) / width
    v = (np.arange(height) + 0.5) / height
    uu, vv = np.meshgrid(u, v)
    return uu, vv


def texel_directions(height: int, width: int) -> np.ndarray:
    """(H, W, 3) unit direction of every texel centre."""
    return uv_to_dir(*texel_centers(height, width))


def pixel_of(d, height: int, width: int) -> tuple[np.ndarray, np.ndarray]:
    """(row, column) integer indices of the texel that contains direction ``d``."""
    u, v = dir_to_uv(d)
    col = np.minimum((u * width).astype(np.int64), width - 1) % width
    row = np.clip((v * height).astype(np.int64), 0, height - 1)
    return row, col


def row_solid_angles(height: int, width: int) -> np.ndarray:
    """(H,) solid angle of one texel of each row, exactly: the band between the polar angles
    theta0 = pi i / H and theta1 = pi (i + 1) / H split in W equal parts,
    (2 pi / W) (cos theta0 - cos theta1) (= sin(theta) dtheta dphi to first order)."""
    edges = np.cos(np.pi * np.arange(height + 1) / height)
    return (TWO_PI / width) * (edges[:-1] - edges[1:])


def solid_angles(height: int, width: int) -> np.ndarray:
    """(H, W) solid angle of every texel (sr); they sum to 4 pi."""
    return np.broadcast_to(row_solid_angles(height, width)[:, None], (height, width)).copy()


def _box_taps(src: int, dst: int, on_sphere: bool) -> tuple[np.ndarray, np.ndarray]:
    """(dst, taps) source indices and weights of a box filter from ``src`` texels to ``dst``
    along one axis: destination texel p covers source coordinates [p src / dst, (p + 1) src / dst]
    and each source texel under it weighs its overlap, as a length (u) or, ``on_sphere`` (v),
    as the solid angle of the overlap band: integral over [a, b] of sin(pi v) pi dv =
    cos(pi a) - cos(pi b) = 2 sin(pi (a + b) / 2) sin(pi (b - a) / 2) (the product keeps its
    precision near the poles). Taps past a texel's footprint weigh 0."""
    p = np.arange(dst, dtype=np.float64)
    lo, hi = p * src / dst, (p + 1) * src / dst
    taps = src // dst if src % dst == 0 else src // dst + 2  # texels a footprint can overlap
    idx = np.floor(lo).astype(np.int64)[:, None] + np.arange(taps)
    a = np.maximum(lo[:, None], idx)
    b = np.minimum(hi[:, None], idx + 1)
    w = np.clip(b - a, 0.0, None)
    if on_sphere:
        w = np.where(w > 0, 2.0 * np.sin(0.5 * math.pi * (a + b) / src) * np.sin(0.5 * math.pi * w / src), 0.0)
    return np.minimum(idx, src - 1), w


def mip_level(level: np.ndarray, width: int, height: int) -> np.ndarray:
    """The (height, width, 3) float32 mip level below ``level`` (H, W, 3): each texel the
    solid-angle weighted mean of the texels under its footprint, a box filter on the sphere
    (a plain box filter would weigh the small polar texels like the equatorial ones), exact for
    any sizes, odd ones included. The weights are separable (overlap in u times solid angle in
    v), so rows are filtered first, then columns, in float64."""
    src = np.asarray(level, dtype=np.float32)
    iy, wy = _box_taps(src.shape[0], height, True)
    ix, wx = _box_taps(src.shape[1], width, False)
    wy = wy / wy.sum(1, keepdims=True)  # normalised: the mean is the weighted sum
    wx = wx / wx.sum(1, keepdims=True)
    rows = np.zeros((height, src.shape[1], 3))
    for t in range(iy.shape[1]):
        rows += wy[:, t, None, None] * src[iy[:, t]]
    out = np.zeros((height, width, 3))
    for t in range(ix.shape[1]):
        out += wx[None, :, t, None] * rows[:, ix[:, t]]
    return out.astype(np.float32)


def mip_chain(latlong: np.ndarray) -> list[np.ndarray]:
    """Every level of the map's full mip chain (GL's sizes: halved, at least 1, down to 1 x 1),
    the map itself first, each level ``mip_level`` of the one above (so each keeps the map's
    total power, the sum of L dOmega)."""
    out = [np.ascontiguousarray(latlong, dtype=np.float32)]
    while out[-1].shape[:2] != (1, 1):
        h, w = out[-1].shape[:2]
        out.append(mip_level(out[-1], max(1, w // 2), max(1, h // 2)))
    return out


def lookup(latlong: np.ndarray, dirs, rotation_deg: float = 0.0) -> np.ndarray:
    """Bilinear radiance (N, 3) (or (..., 3)) of the map for world directions ``dirs``, with the
    map turned by ``rotation_deg`` about +y: L(d) = map(R_y(-rotation_deg) d)."""
    img = np.asarray(latlong)
    h, w = img.shape[:2]
    d = np.asarray(dirs, dtype=np.float64)
    shape = d.shape[:-1]
    d = d.reshape(-1, 3)
    if rotation_deg:
        d = d @ rotation_y(-rotation_deg).T
    u, v = dir_to_uv(d)
    x = u * w - 0.5
    y = np.clip(v * h - 0.5, 0.0, h - 1.0)
    x0 = np.floor(x)
    y0 = np.minimum(np.floor(y), h - 2) if h > 1 else np.zeros_like(y)
    fx = (x - x0)[:, None]
    fy = (y - y0)[:, None] if h > 1 else np.zeros((len(y), 1))
    x0 = x0.astype(np.int64) % w
    x1 = (x0 + 1) % w
    y0 = y0.astype(np.int64)
    y1 = np.minimum(y0 + 1, h - 1)
    top = img[y0, x0] * (1.0 - fx) + img[y0, x1] * fx
    bot = img[y1, x0] * (1.0 - fx) + img[y1, x1] * fx
    out = top * (1.0 - fy) + bot * fy
    return out.reshape(shape + (img.shape[2],))


# ---------------------------------------------------------------------------------- cube maps

def cube_face_directions(face: int, size: int, offset: tuple[float, float] = (0.0, 0.0)) -> np.ndarray:
    """(size, size, 3) unit directions through the texel centres of cube face ``face``
    (0..5 = +X, -X, +Y, -Y, +Z, -Z), indexed [t, s]: row i has t = (i + 0.5) / size and
    column j has s = (j + 0.5) / size, which is the order glTexImage2D reads the rows in
    (the first row uploaded is t = 0). ``offset`` = (ds, dt) moves every point by that many
    texels (for supersampling).

    The OpenGL 4.6 core specification, section 8.13 "Cube Map Texture Selection", table
    "Selection of cube map images based on major axis direction" (table 3.23 in the 4.2
    compatibility profile), picks the face by the major axis ma of the direction r and sets
        +X: sc = -rz, tc = -ry     -X: sc = +rz, tc = -ry
        +Y: sc = +rx, tc = +rz     -Y: sc = +rx, tc = -rz
        +Z: sc = +rx, tc = -ry     -Z: sc = -rx, tc = -ry
    s = (sc / |ma| + 1) / 2, t = (tc / |ma| + 1) / 2. Inverting with
    sc = 2 s - 1, tc = 2 t - 1 and |ma| = 1 gives the directions below."""
    if face not in range(6):
        raise ValueError(f"cube face {face} is not in 0..5")
    idx = np.arange(size) + 0.5
    sc = np.broadcast_to(((idx + offset[0]) / size * 2.0 - 1.0)[None, :], (size, size))
    tc = np.broadcast_to(((idx + offset[1]) / size * 2.0 - 1.0)[:, None], (size, size))
    one = np.ones((size, size))
    d = [(one, -tc, -sc), (-one, -tc, sc), (sc, one, tc), (sc, -one, -tc), (sc, -tc, one),
         (-sc, -tc, -one)][face]
    d = np.stack(d, axis=-1)
    return d / np.linalg.norm(d, axis=-1, keepdims=True)


def to_cubemap(latlong: np.ndarray, size: int, rotation_deg: float = 0.0, supersample: int = 1) -> np.ndarray:
    """(6, size, size, 3) float32 cube map of a lat-long map, faces in GL order (+X, -X, +Y, -Y,
    +Z, -Z), each face indexed [t, s] as ``cube_face_directions`` says (upload face k as is to
    GL_TEXTURE_CUBE_MAP_POSITIVE_X + k). Each texel is the mean of ``supersample``^2 bilinear
    lookups spread over the texel (1: one lookup at its centre). This is the numpy reference
    for the GPU conversion."""
    n = max(1, int(supersample))
    out = np.zeros((6, size, size, 3), dtype=np.float64)
    offs = (np.arange(n) + 0.5) / n - 0.5  # sub-texel offsets in texels
    for f in range(6):
        for oy in offs:
            for ox in offs:
                d = cube_face_directions(f, size, (ox, oy)).reshape(-1, 3)
                out[f] += lookup(latlong, d, rotation_deg).reshape(size, size, 3)
    return (out / (n * n)).astype(np.float32)


def cube_direction_to_face(d) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(face, s, t) of directions ``d`` (..., 3) by the GL selection rule above (for tests)."""
    d = np.asarray(d, dtype=np.float64)
    ax = np.abs(d)
    rx, ry, rz = d[..., 0], d[..., 1], d[..., 2]
    major = np.argmax(ax, axis=-1)
    face = np.where(major == 0, np.where(rx > 0, 0, 1),
                    np.where(major == 1, np.where(ry > 0, 2, 3), np.where(rz > 0, 4, 5)))
    sc = np.choose(face, [-rz, rz, rx, rx, rx, -rx])
    tc = np.choose(face, [-ry, -ry, rz, -rz, -ry, -ry])
    ma = np.choose(face, [ax[..., 0], ax[..., 0], ax[..., 1], ax[..., 1], ax[..., 2], ax[..., 2]])
    return face, 0.5 * (sc / ma + 1.0), 0.5 * (tc / ma + 1.0)
