"""Measured anisotropic BRDFs in the MIT CSAIL format (Ngan, Durand and Matusik 2005,
"Experimental Analysis of BRDF Models", EGSR; the data published at
people.csail.mit.edu/addy/research/brdf/), the format BRDF Explorer opens as ``.dat``.

File format (facts of the format as documented with the data and read by BRDF Explorer,
``src/brdf/BRDFMeasuredAniso.cpp`` and ``src/shaderTemplates/measuredAniso.func``):
- a header of 16 little-endian int32: [0..3] the bins of the four dimensions (theta_in,
  theta_out, phi_diff, phi_in), [6] paramType (1: the standard parameterization), [7] binType
  (0: uniform bins), [9] half_data (0: phi_diff over [0, 2 pi), 1: over [0, pi)), [10] the
  channels (3, RGB); the other entries are reserved;
- then channels x n_ti x n_to x n_pd x n_pi little-endian float32 values, the red block, then
  green, then blue; within a block entry (t_i, t_o, p_d, p_i) is at
  p_i + n_pi (p_d + n_pd (t_o + n_to t_i)) (phi_in varies fastest);
- coordinates: theta_in, theta_out in [0, pi/2] (n_ti, n_to bins), phi_in in [0, 2 pi) and
  phi_diff = phi_out - phi_in in [0, 2 pi) (n_pi, n_pd bins), uniform: the index of an angle a
  in a dimension of n bins over a range R is floor(a n / R), clamped. The azimuths are those of
  the reversed directions in the tangent frame: phi = atan2(-(w . bitangent), -(w . tangent));
- BRDF = 10 x stored value (BRDF Explorer's shader scales the data by 10);
- a negative entry marks a bin without a reliable measurement: where a channel is negative the
  entry is read as 0 (BRDF Explorer returns black there), counted in one warning line.
The published files are 45 x 45 x 180 x 180 (about 787 MB); BRDF Explorer halves phi_in on
upload to fit a GL texture buffer, this reader keeps the file's resolution.

Interpolation (both twins; ``shaders/brdf/measured.glsl`` with ``MEASURED_ANISO``): quadrilinear
on the index grid, entry i at its bin's centre (as for MERL tables, ``viewer.brdf.merl``):
c = a n / R - 1/2, clamped to [0, n - 1] for the two thetas, periodic (mod n) for the two
azimuths. At the grid points (``grid_angles``) the lookup returns the stored values exactly.

Files with half_data = 1, another parameterization or binning, or channels other than 3 are
refused with one line (the reader does not guess their layout).
"""

from __future__ import annotations

import logging
import os
import struct
from pathlib import Path

import numpy as np

from viewer import ViewerError
from viewer.brdf import merl
from viewer.base.io import atomic_write_file, one_line, stat_file

log = logging.getLogger(__name__)

HEADER = struct.Struct("<16i")
#: BRDF = SCALE x stored (BRDF Explorer's measuredAniso.func)
SCALE = 10.0
HALF_PI = 0.5 * np.pi
TWO_PI = 2.0 * np.pi
#: the published resolution (theta_in, theta_out, phi_diff, phi_in)
PUBLISHED = (45, 45, 180, 180)
#: the most bins of a theta dimension (the rasterizer's texture stacks n_ti x n_to layers, at
#: most 2,048 in OpenGL 4.1's minimum 3D texture size), and of an azimuth dimension
MAX_THETA_BINS = 45
MAX_PHI_BINS = 360
#: the most bytes of a file: the published size (which the bounds above also give)
MAX_BYTES = HEADER.size + 4 * 3 * PUBLISHED[0] * PUBLISHED[1] * PUBLISHED[2] * PUBLISHED[3]
SUFFIX = ".dat"
ALLOWED = "allowed: an MIT anisotropic BRDF file (.dat)"


def is_mit_file(path) -> bool:
    """Whether a measured material's ``file`` names an MIT anisotropic file (by its suffix, as
    BRDF Explorer tells them: ``.dat``; MERL files are ``.binary``)."""
    return str(path).lower().endswith(SUFFIX)


# ---------------------------------------------------------------- coordinates
def _azimuth(w):
    x, y = w[..., 0], w[..., 1]
    phi = np.arctan2(-y, -x)
    phi = np.where(x * x + y * y > 0.0, phi, 0.0)
    return np.mod(phi, TWO_PI)


def angles(wi, wo):
    """(theta_in, theta_out, phi_diff, phi_in) of direction pairs (N, 3) in the shading frame
    (x tangent, y bitangent, z normal); azimuths in [0, 2 pi)."""
    wi = np.asarray(wi, dtype=np.float64)
    wo = np.asarray(wo, dtype=np.float64)
    ti = np.arctan2(np.hypot(wi[..., 0], wi[..., 1]), wi[..., 2])
    to = np.arctan2(np.hypot(wo[..., 0], wo[..., 1]), wo[..., 2])
    pi_ = _azimuth(wi)
    pd = np.mod(_azimuth(wo) - pi_, TWO_PI)
    return ti, to, pd, pi_


def directions(ti, to, pd, pi_):
    """The direction pair (wi, wo) of the four angles (inverse of ``angles``)."""
    ti, to, pd, pi_ = np.broadcast_arrays(*(np.asarray(a, dtype=np.float64) for a in (ti, to, pd, pi_)))
    po = pi_ + pd

    def d(t, p):
        s = np.sin(t)
        return np.stack([-s * np.cos(p), -s * np.sin(p), np.cos(t)], axis=-1)

    return d(ti, pi_), d(to, po)


def ranges(half_data: int = 0):
    return (HALF_PI, HALF_PI, np.pi if half_data else TWO_PI, TWO_PI)


def grid_angles(dims):
    """The angles of a table's entries, their bins' centres: theta_in, theta_out, phi_diff,
    phi_in (radians), for dims (n_ti, n_to, n_pd, n_pi)."""
    return tuple((np.arange(n) + 0.5) / n * r for n, r in zip(dims, ranges()))


def index(ti, to, pd, pi_, dims):
    """BRDF Explorer's integer indices (floor of a n / R, clamped)."""
    out = []
    for a, n, r in zip((ti, to, pd, pi_), dims, ranges()):
        out.append(np.clip(np.floor(np.asarray(a) * n / r), 0, n - 1).astype(int))
    return tuple(out)


def _axis(a, n, r, periodic):
    c = np.asarray(a, dtype=np.float64) * (n / r) - 0.5
    if periodic:
        c = np.mod(c, n)
        f = np.floor(c)
        i0 = f.astype(int) % n
        return i0, (i0 + 1) % n, c - f
    c = np.clip(c, 0.0, n - 1)
    i0 = np.floor(c).astype(int)
    return i0, np.minimum(i0 + 1, n - 1), c - i0


def lookup(table, wi, wo):
    """Quadrilinear interpolation of ``table`` (n_ti, n_to, n_pd, n_pi, 3) at direction pairs,
    between the bins' centres (see the module docstring); (N, 3) float64."""
    dims = table.shape[:4]
    a = angles(wi, wo)
    axes = [_axis(v, n, r, k >= 2) for k, (v, n, r) in enumerate(zip(a, dims, ranges()))]
    out = 0.0
    (a0, a1, ta), (b0, b1, tb), (c0, c1, tc), (d0, d1, td) = axes
    for ia, wa in ((a0, 1.0 - ta), (a1, ta)):
        for ib, wb in ((b0, 1.0 - tb), (b1, tb)):
            for ic, wc in ((c0, 1.0 - tc), (c1, tc)):
                w = (wa * wb * wc)[..., None]
                out = out + w * ((1.0 - td)[..., None] * table[ia, ib, ic, d0] + td[..., None] * table[ia, ib, ic, d1])
    return np.asarray(out, dtype=np.float64)


# ---------------------------------------------------------------- files
def header_problem(h) -> str | None:
    """What is wrong with a header (16 ints), or None."""
    dims = h[:4]
    if h[6] != 1:
        return f"paramType {h[6]} (header entry 6); allowed: 1 (the standard parameterization)"
    if h[7] != 0:
        return f"binType {h[7]} (header entry 7); allowed: 0 (uniform bins)"
    if h[9] not in (0, 1):
        return f"half_data {h[9]} (header entry 9); allowed: 0 (phi_diff over 0..2 pi)"
    if h[9] == 1:
        return "half_data 1 (phi_diff over 0..pi) is not read; allowed: half_data 0 (phi_diff over 0..2 pi)"
    if h[10] != 3:
        return f"{h[10]} channels (header entry 10); allowed: 3 (RGB)"
    names = ("theta_in", "theta_out", "phi_diff", "phi_in")
    for k, (n, name) in enumerate(zip(dims, names)):
        hi = MAX_THETA_BINS if k < 2 else MAX_PHI_BINS
        if not 1 <= n <= hi:
            return f"{n} {name} bins (header entry {k}); allowed: 1 to {hi}"
    return None


def expected_size(dims) -> int:
    return HEADER.size + 4 * 3 * int(np.prod([int(n) for n in dims]))


def read(path) -> np.ndarray:
    """The BRDF table (n_ti, n_to, n_pd, n_pi, 3) float32 of an MIT .dat file (scale applied).

    One-line ViewerError naming the file: missing, unreadable, larger than the published size,
    shorter than the header, a header outside the format (see ``header_problem``), a size that
    does not match the header (checked before anything is allocated), NaN or infinite values.
    Entries with a negative channel (no measurement) become 0 with one warning line."""
    path = Path(path)
    st, problem = stat_file(path)
    if problem:
        raise ViewerError(one_line(f"{path}: {problem}; {ALLOWED}"))
    if st.st_size > MAX_BYTES:
        raise ViewerError(one_line(f"{path}: {st.st_size} bytes; an MIT anisotropic BRDF file holds at most "
                                   f"{MAX_BYTES} (the published 45 x 45 x 180 x 180 RGB float32 table)"))
    if st.st_size < HEADER.size:
        raise ViewerError(one_line(f"{path}: not an MIT anisotropic BRDF file: {st.st_size} bytes, shorter "
                                   f"than the 64-byte header of 16 int32"))
    try:
        with open(path, "rb") as f:
            h = HEADER.unpack(f.read(HEADER.size))
            problem = header_problem(h)
            if problem:
                raise ViewerError(one_line(f"{path}: not a readable MIT anisotropic BRDF file: {problem}"))
            dims = tuple(h[:4])
            want = expected_size(dims)
            if st.st_size != want:
                raise ViewerError(one_line(
                    f"{path}: truncated or padded MIT anisotropic BRDF file: {st.st_size} bytes, expected {want} "
                    f"(64-byte header + 3 x {dims[0]} x {dims[1]} x {dims[2]} x {dims[3]} float32 values)"))
            count = (want - HEADER.size) // 4
            raw = np.fromfile(f, dtype="<f4", count=count)
    except OSError as e:
        raise ViewerError(one_line(f"{path}: cannot be read ({e.strerror or e})")) from None
    if raw.size != count:
        raise ViewerError(one_line(f"{path}: truncated MIT anisotropic BRDF file (the file changed while read)"))
    bad = ~np.isfinite(raw)
    if np.any(bad):
        first = int(np.argmax(bad))
        ch, rest = divmod(first, count // 3)
        raise ViewerError(one_line(
            f"{path}: {int(bad.sum())} NaN or infinite values in the MIT anisotropic BRDF table, the first in "
            f"the {'RGB'[ch]} block at entry {rest}; allowed: finite numbers (negative ones mark missing "
            f"measurements)"))
    table = raw.reshape(3, *dims).transpose(1, 2, 3, 4, 0)
    neg = np.any(table < 0, axis=-1)
    table = np.ascontiguousarray(table, dtype=np.float32)
    if np.any(neg):
        log.warning("%s: %d entries with negative values (missing measurements) read as 0", path, int(neg.sum()))
        table[neg] = 0.0
    table *= np.float32(SCALE)
    return table


def write(path, table) -> Path:
    """Write a BRDF table (n_ti, n_to, n_pd, n_pi, 3) (BRDF values, 1/sr) as an MIT .dat file
    (half_data 0), atomically."""
    table = np.asarray(table, dtype=np.float64)
    if table.ndim != 5 or table.shape[-1] != 3:
        raise ValueError(f"an MIT table has shape (n_ti, n_to, n_pd, n_pi, 3), got {table.shape}")
    h = [0] * 16
    h[:4] = table.shape[:4]
    h[6], h[7], h[9], h[10] = 1, 0, 0, 3
    stored = (table / SCALE).transpose(4, 0, 1, 2, 3).astype("<f4")
    data = HEADER.pack(*h) + stored.tobytes()

    def w(tmp):
        with open(tmp, "r+b") as f:
            f.write(data)

    return atomic_write_file(path, w)


def tabulate(fn, dims, chunk: int = 200_000) -> np.ndarray:
    """The table (dims..., 3) of a BRDF ``fn(wi, wo) -> (N, 3)`` at the grid's angles (bins'
    centres); entries with a direction below the horizon are 0 (none are: theta < pi/2)."""
    g = np.meshgrid(*grid_angles(dims), indexing="ij")
    wi, wo = directions(*(a.ravel() for a in g))
    out = np.zeros((wi.shape[0], 3))
    for s in range(0, len(wi), chunk):
        out[s:s + chunk] = np.asarray(fn(wi[s:s + chunk], wo[s:s + chunk]), dtype=np.float64)
    return out.reshape(*dims, 3)


# ---------------------------------------------------------------- loaded data
class AnisoMeasured(merl.HalfVectorSampler):
    """A loaded MIT table with the sampler of the measured model: the MERL sampler's
    half-vector density (``viewer.brdf.merl.HalfVectorSampler``) built from the table's mean over
    phi_h and phi_d at small theta_d (the lobe's profile in theta_h), phi_h uniform."""

    kind = "mit"

    def __init__(self, table: np.ndarray, path: str = ""):
        self.table = table
        self.path = path
        self.dims = tuple(table.shape[:4])
        super().__init__(self.profile())

    def profile(self, n_d: int = 10, n_phi: int = 8) -> np.ndarray:
        """(90, 3): the mean of the table over phi_h, phi_d and the first ``n_d`` theta_d bins of the
        MERL grid, at each MERL theta_h bin centre (pairs below the horizon count as 0)."""
        th, td, _ = merl.grid_angles()
        pd = (np.arange(n_phi) + 0.5) / n_phi * np.pi
        ph = (np.arange(n_phi) + 0.5) / n_phi * TWO_PI
        TH, TD, PD, PH = np.meshgrid(th, td[:n_d], pd, ph, indexing="ij")
        wi, wo = merl.from_half_diff(TH.ravel(), TD.ravel(), PD.ravel(), PH.ravel())
        ok = (wi[:, 2] > 0) & (wo[:, 2] > 0)
        f = np.zeros((len(wi), 3))
        if np.any(ok):
            f[ok] = self.value(wi[ok], wo[ok])
        return f.reshape(len(th), -1, 3).mean(axis=1)

    def value(self, wi, wo):
        return lookup(self.table, wi, wo)

    def texture_data(self) -> np.ndarray:
        """float32 RGB data of a 3D texture W x n_pd x (n_ti n_to + 1) with W = max(n_pi, 96):
        x = phi_in (x < n_pi), y = phi_diff, z = theta_in n_to + theta_out; the last layer holds the
        sampler's data in its red channel, row y = 0: the 90 theta_h bins' CDF at x = 0..89, the
        cosine weight at x = 90 and the four dimensions at x = 91..94 (shaders/brdf/measured.glsl)."""
        n_ti, n_to, n_pd, n_pi = self.dims
        w = max(n_pi, 96)
        out = np.zeros((n_ti * n_to + 1, n_pd, w, 3), dtype=np.float32)
        out[:-1, :, :n_pi] = self.table.reshape(n_ti * n_to, n_pd, n_pi, 3)
        aux = out[-1, 0, :, 0]
        aux[:90] = self.cdf
        aux[90] = self.w_cos
        aux[91:95] = self.dims
        return out

    def texture_size(self) -> tuple[int, int, int]:
        """(width, height, depth) of ``texture_data``."""
        n_ti, n_to, n_pd, n_pi = self.dims
        return max(n_pi, 96), n_pd, n_ti * n_to + 1


_CACHE: dict = {}


def load(path) -> AnisoMeasured:
    """``read`` a file once per process (keyed by its path, size and modification time)."""
    path = os.path.abspath(os.fspath(path))
    st, problem = stat_file(path)
    if problem:
        raise ViewerError(one_line(f"{path}: {problem}; {ALLOWED}"))
    key = (path, st.st_size, st.st_mtime_ns)
    hit = _CACHE.get(key)
    if hit is None:
        if len(_CACHE) >= 2:
            _CACHE.pop(next(iter(_CACHE)))
        hit = _CACHE[key] = AnisoMeasured(read(path), path)
    return hit
