"""Measured isotropic BRDFs in the MERL format (Matusik, Pfister, Brand and McMillan 2003, "A
Data-Driven Reflectance Model", SIGGRAPH; the MERL BRDF database).

File format (facts of the format as published with the database's reference reader):
- a header of three little-endian int32: the table's dimensions 90 (theta_h) x 90 (theta_d) x
  180 (phi_d), then 3 x 90 x 90 x 180 little-endian float64 values, the red block, then green,
  then blue; within a block entry (i_h, i_d, i_p) is at i_p + 180 (i_d + 90 i_h);
- values are stored scaled: BRDF = stored x (1/1500, 1.15/1500, 1.66/1500) for R, G, B;
- coordinates are Rusinkiewicz's (1998) half / difference angles with phi_h dropped (isotropy):
  i_h = floor(sqrt(theta_h / (pi/2)) * 90) (a square-root mapping that puts half of the bins in
  theta_h < 22.5 degrees, where specular peaks are), i_d = floor(theta_d / (pi/2) * 90),
  i_p = floor(phi_d / pi * 180) after folding phi_d into [0, pi) by reciprocity
  (f(phi_d) = f(phi_d + pi)); every index is clamped to the table.
- negative entries mark configurations without a measurement (the reference reader reports
  them as "below horizon"); they are read as 0 and counted in one warning line.

Interpolation (both twins, shaders/brdf/measured.glsl does the same with texelFetch): trilinear
on the index grid, entry i standing at its bin's centre (an entry is the mean of the
measurements in its bin, so between centres it is interpolated; on average this is the reference
reader's floor lookup): continuous coordinates c_h = sqrt(theta_h / (pi/2)) * 90 - 1/2,
c_d = theta_d / (pi/2) * 90 - 1/2 (both clamped to [0, 89]: the half bins at either end hold
their entry), c_p = phi_d / pi * 180 - 1/2 (periodic, 180). At the grid points (the centres,
``grid_angles``) the lookup returns the stored values exactly. (Placing entries at the lower
edges, as before, read a smooth lobe written at the centres back with a 2.2% median error.)

Importance sampling (exact about its pdf): a mixture of the cosine-weighted hemisphere and a
half-vector density tabulated from the data, piecewise constant per solid angle within each of
the 90 theta_h bins (weights: the luminance of the table at small theta_d, averaged over phi_d,
minus its minimum over theta_h, times cos theta_h, the shape of D(h) cos theta_h of a microfacet
BRDF's peak), phi_h uniform; the mixture weight of the cosine part is the diffuse share of that
profile (its minimum against its mean) clamped to [0.1, 0.9]. The diffuse floor is the cosine
part's: left in the half-vector density it gave the large theta_h bins (most of the solid
angle) weight, and 13.6% (normal view) to 20% (80 deg) of the samples fell below the horizon.
"""

from __future__ import annotations

import logging
import os
import struct
from pathlib import Path

import numpy as np

from viewer import ViewerError
from viewer.base.io import atomic_write_file, one_line, stat_file
from viewer.spectral.colorimetry import LUMINANCE_REC709

log = logging.getLogger(__name__)

N_TH, N_TD, N_PD = 90, 90, 180
SCALE = np.array([1.0 / 1500.0, 1.15 / 1500.0, 1.66 / 1500.0])  # stored value -> BRDF, R G B
HEADER = struct.Struct("<3i")
N_VALUES = 3 * N_TH * N_TD * N_PD
FILE_SIZE = HEADER.size + 8 * N_VALUES
HALF_PI = 0.5 * np.pi
LUM = LUMINANCE_REC709


# ---------------------------------------------------------------- coordinates
def half_diff(wi, wo):
    """Rusinkiewicz coordinates (theta_h, theta_d, phi_d) of direction pairs (N, 3) in the shading
    frame; phi_d folded into [0, pi). The difference vector is wi seen from the half vector's
    frame: d = R_y(-theta_h) R_z(-phi_h) wi."""
    wi = np.asarray(wi, dtype=np.float64)
    wo = np.asarray(wo, dtype=np.float64)
    h = wi + wo
    n = np.linalg.norm(h, axis=-1, keepdims=True)
    h = h / np.where(n > 0, n, 1.0)
    th = np.arccos(np.clip(h[..., 2], -1.0, 1.0))
    ph = np.arctan2(h[..., 1], h[..., 0])
    c, s = np.cos(ph), np.sin(ph)
    # R_z(-phi_h)
    x = c * wi[..., 0] + s * wi[..., 1]
    y = -s * wi[..., 0] + c * wi[..., 1]
    z = wi[..., 2]
    # R_y(-theta_h)
    ct, st = np.cos(th), np.sin(th)
    dx = ct * x - st * z
    dz = st * x + ct * z
    td = np.arccos(np.clip(dz, -1.0, 1.0))
    pd = np.arctan2(y, dx)
    pd = np.where(pd < 0.0, pd + np.pi, pd)
    pd = np.where(pd >= np.pi, pd - np.pi, pd)
    return th, td, pd


def from_half_diff(th, td, pd, ph=0.0):
    """The direction pair (wi, wo) of Rusinkiewicz coordinates (inverse of ``half_diff``)."""
    th, td, pd, ph = np.broadcast_arrays(*(np.asarray(a, dtype=np.float64) for a in (th, td, pd, ph)))
    d = np.stack([np.sin(td) * np.cos(pd), np.sin(td) * np.sin(pd), np.cos(td)], axis=-1)
    ct, st = np.cos(th), np.sin(th)
    x = ct * d[..., 0] + st * d[..., 2]
    z = -st * d[..., 0] + ct * d[..., 2]
    c, s = np.cos(ph), np.sin(ph)
    wi = np.stack([c * x - s * d[..., 1], s * x + c * d[..., 1], z], axis=-1)
    h = np.stack([st * c, st * s, ct], axis=-1)
    wo = 2.0 * np.sum(wi * h, axis=-1, keepdims=True) * h - wi
    return wi, wo


def grid_angles():
    """The angles of the table's entries, their bins' centres in the index mapping: theta_h (90,),
    theta_d (90,), phi_d (180,) (radians)."""
    th = ((np.arange(N_TH) + 0.5) / N_TH) ** 2 * HALF_PI
    td = (np.arange(N_TD) + 0.5) / N_TD * HALF_PI
    pd = (np.arange(N_PD) + 0.5) / N_PD * np.pi
    return th, td, pd


def continuous_index(th, td, pd):
    """Continuous table coordinates (c_h, c_d, c_p): the MERL index is their floor."""
    ch = np.sqrt(np.clip(th, 0.0, HALF_PI) / HALF_PI) * N_TH
    cd = np.clip(td, 0.0, HALF_PI) / HALF_PI * N_TD
    cp = pd / np.pi * N_PD
    return ch, cd, cp


def merl_index(th, td, pd):
    """The MERL reference reader's integer indices (floor, clamped)."""
    ch, cd, cp = continuous_index(th, td, pd)
    return (np.clip(np.floor(ch), 0, N_TH - 1).astype(int), np.clip(np.floor(cd), 0, N_TD - 1).astype(int),
            np.clip(np.floor(cp), 0, N_PD - 1).astype(int))


def lookup(table, th, td, pd):
    """Trilinear interpolation of ``table`` (90, 90, 180, 3) at Rusinkiewicz coordinates, between
    the bins' centres."""
    ch, cd, cp = continuous_index(th, td, pd)
    ch = np.clip(ch - 0.5, 0.0, N_TH - 1)
    cd = np.clip(cd - 0.5, 0.0, N_TD - 1)
    cp = cp - 0.5
    h0 = np.minimum(np.floor(ch).astype(int), N_TH - 2)
    d0 = np.minimum(np.floor(cd).astype(int), N_TD - 2)
    fp = np.floor(cp)
    p0 = fp.astype(int) % N_PD
    p1 = (p0 + 1) % N_PD
    th_ = (ch - h0)[..., None]
    td_ = (cd - d0)[..., None]
    tp = (cp - fp)[..., None]
    if table.flags.c_contiguous:
        # np.take of rows of the flat (90 * 90 * 180, 3) view: five times faster than indexing
        # table[a, b, p] with three index arrays (the same entries)
        flat = table.reshape(-1, table.shape[-1])

        def entries(a, b, p):
            return np.take(flat, (a * table.shape[1] + b) * table.shape[2] + p, axis=0)
    else:
        def entries(a, b, p):
            return table[a, b, p]
    out = 0.0
    for a, wa in ((h0, 1.0 - th_), (h0 + 1, th_)):
        for b, wb in ((d0, 1.0 - td_), (d0 + 1, td_)):
            out = out + wa * wb * ((1.0 - tp) * entries(a, b, p0) + tp * entries(a, b, p1))
    return out


# ---------------------------------------------------------------- files
def read(path) -> np.ndarray:
    """The BRDF table (90, 90, 180, 3) float64 of a MERL .binary file (scales applied).

    One-line ViewerError naming the file: missing, unreadable, a header that is not 90 90 180,
    a size that does not match the header, NaN or infinite values. Negative entries (missing
    measurements) become 0 with one warning line."""
    path = Path(path)
    st, problem = stat_file(path)
    if problem:
        raise ViewerError(one_line(f"{path}: {problem}; allowed: a MERL BRDF file (.binary)"))
    if st.st_size < HEADER.size:
        raise ViewerError(one_line(f"{path}: not a MERL BRDF file: {st.st_size} bytes, shorter than "
                                   f"the 12-byte header of three int32 dimensions"))
    try:
        with open(path, "rb") as f:
            dims = HEADER.unpack(f.read(HEADER.size))
            if dims != (N_TH, N_TD, N_PD):
                raise ViewerError(one_line(
                    f"{path}: not a MERL BRDF file: the header gives dimensions {dims[0]} x {dims[1]} x {dims[2]}; "
                    f"allowed: {N_TH} x {N_TD} x {N_PD} (theta_h x theta_d x phi_d)"))
            if st.st_size != FILE_SIZE:
                raise ViewerError(one_line(
                    f"{path}: truncated or padded MERL BRDF file: {st.st_size} bytes, expected {FILE_SIZE} "
                    f"(12-byte header + 3 x {N_TH} x {N_TD} x {N_PD} float64 values)"))
            raw = np.fromfile(f, dtype="<f8", count=N_VALUES)
    except OSError as e:
        raise ViewerError(one_line(f"{path}: cannot be read ({e.strerror or e})")) from None
    if raw.size != N_VALUES:
        raise ViewerError(one_line(f"{path}: truncated MERL BRDF file (the file changed while read)"))
    bad = ~np.isfinite(raw)
    if np.any(bad):
        first = int(np.argmax(bad))
        ch, rest = divmod(first, N_TH * N_TD * N_PD)
        ih, r2 = divmod(rest, N_TD * N_PD)
        idd, ip = divmod(r2, N_PD)
        raise ViewerError(one_line(
            f"{path}: {int(bad.sum())} NaN or infinite values in the MERL BRDF table, the first in the "
            f"{'RGB'[ch]} block at theta_h index {ih}, theta_d index {idd}, phi_d index {ip}; "
            f"allowed: finite numbers (negative ones mark missing measurements)"))
    neg = raw < 0
    if np.any(neg):
        log.warning("%s: %d negative values (missing measurements) read as 0", path, int(neg.sum()))
        raw = np.where(neg, 0.0, raw)
    table = raw.reshape(3, N_TH, N_TD, N_PD).transpose(1, 2, 3, 0)
    return np.ascontiguousarray(table * SCALE)


def write(path, table) -> Path:
    """Write a BRDF table (90, 90, 180, 3) (BRDF values, 1/sr) as a MERL .binary file, atomically."""
    table = np.asarray(table, dtype=np.float64)
    if table.shape != (N_TH, N_TD, N_PD, 3):
        raise ValueError(f"a MERL table has shape {(N_TH, N_TD, N_PD, 3)}, got {table.shape}")
    stored = (table / SCALE).transpose(3, 0, 1, 2).astype("<f8")
    data = HEADER.pack(N_TH, N_TD, N_PD) + stored.tobytes()

    def w(tmp):
        with open(tmp, "r+b") as f:
            f.write(data)

    return atomic_write_file(path, w)


def tabulate(fn, chunk: int = 16_384) -> np.ndarray:
    """The table (90, 90, 180, 3) of a BRDF ``fn(wi, wo) -> (N, 3)`` at the grid's angles; entries
    whose directions fall below the horizon are 0. (The directions too are made a chunk at a time:
    arrays of that size stay in the CPU caches, 2 to 3 times faster than the whole grid at once.)"""
    th, td, pd = grid_angles()
    TH, TD, PD = (g.ravel() for g in np.meshgrid(th, td, pd, indexing="ij"))
    out = np.zeros((TH.shape[0], 3))
    for s in range(0, len(TH), chunk):
        a, b = from_half_diff(TH[s:s + chunk], TD[s:s + chunk], PD[s:s + chunk])
        ok = (a[:, 2] > 0) & (b[:, 2] > 0)
        v = np.zeros((len(a), 3))
        if np.any(ok):
            v[ok] = np.asarray(fn(a[ok], b[ok]), dtype=np.float64)
        out[s:s + chunk] = v
    return out.reshape(N_TH, N_TD, N_PD, 3)


# ---------------------------------------------------------------- loaded data + sampling tables
class HalfVectorSampler:
    """The sampler's tables (see the module docstring) and the split-sum fit of a BRDF given by
    its profile: the mean RGB value (90, 3) at each theta_h bin centre at small theta_d."""

    def __init__(self, profile_rgb: np.ndarray):
        self.profile_rgb = np.maximum(np.asarray(profile_rgb, dtype=np.float64), 0.0)
        # theta_h bin edges (the sqrt mapping) and their solid angles
        u = np.arange(N_TH + 1) / N_TH
        self.edges = u * u * HALF_PI
        self.d_omega = 2.0 * np.pi * (np.cos(self.edges[:-1]) - np.cos(self.edges[1:]))
        profile = np.maximum(self.profile_rgb @ LUM, 0.0)
        centre = 0.5 * (self.edges[:-1] + self.edges[1:])
        dens = (profile - profile.min()) * np.cos(centre)  # the peak: the floor is the cosine part's
        floor_ = 1e-3 * dens.max() if dens.max() > 0 else 1.0
        dens = np.maximum(dens, floor_)  # no empty bin: every h has some density
        mass = dens * self.d_omega
        self.cdf = np.cumsum(mass) / mass.sum()
        self.cdf[-1] = 1.0
        self.bin_pdf = (mass / mass.sum()) / self.d_omega  # density per solid angle of h, per bin
        # diffuse share: the profile's minimum (a floor every theta_h has) against its mean
        mean = float(np.sum(profile * self.d_omega) / np.sum(self.d_omega))
        share = float(profile.min() / mean) if mean > 0 else 1.0
        self.w_cos = float(np.clip(share, 0.1, 0.9))

    def split_sum_fit(self) -> tuple[np.ndarray, float]:
        """(diffuse albedo (3,), alpha) for the rasterizer's split-sum environment lighting. The
        table near the specular plane (theta_d < 10 degrees, where cos_i ~ cos_o ~ cos_h) is read
        as rho_d / pi plus a microfacet peak c D(theta_h) / (4 cos_h^2) (F and G taken constant
        there). Given alpha, rho_d and c follow by linear least squares over theta_h < 60 degrees
        (beyond, both directions graze and measurements are least reliable); given rho_d, alpha
        = 1 / sqrt(pi D(0)) of the peak normalised to integral D cos_h = 1, exact for GGX and
        Beckmann (both have D(0) = 1 / (pi alpha^2)). Two rounds from rho_d = 0."""
        profile = self.profile_rgb  # (90, 3)
        centre = 0.5 * (self.edges[:-1] + self.edges[1:])
        ch = np.cos(centre)
        fit = centre < np.radians(60.0)
        rho_d, alpha = np.zeros(3), 1.0
        for _ in range(3):
            peak = np.maximum(profile - rho_d / np.pi, 0.0) @ LUM * ch * ch
            mass = float(np.sum(peak * ch * self.d_omega))
            if not (mass > 0 and peak[0] > 0):
                return np.pi * profile.min(axis=0), 1.0
            alpha = float(np.clip(1.0 / np.sqrt(np.pi * peak[0] / mass), 1e-3, 1.0))
            a2, t2 = alpha * alpha, np.tan(centre) ** 2
            g = a2 / (np.pi * ch ** 4 * (a2 + t2) ** 2) / (4.0 * ch * ch)  # GGX D / (4 cos_h^2)
            # relative residuals (weights 1 / value): the floor is small beside the peak
            w = 1.0 / np.maximum(profile[fit] @ LUM, 1e-12)
            basis = np.stack([np.full(fit.sum(), 1.0 / np.pi), g[fit]], axis=1) * w[:, None]
            coef = np.linalg.lstsq(basis, profile[fit] * w[:, None], rcond=None)[0]
            rho_d = np.maximum(coef[0], 0.0)
        return rho_d, alpha


class Measured(HalfVectorSampler):
    """A loaded MERL table with what its sampler needs (see the module docstring)."""

    kind = "merl"

    def __init__(self, table: np.ndarray, path: str = ""):
        self.table = table
        self.path = path
        super().__init__(table[:, : max(1, N_TD // 9)].mean(axis=(1, 2)))  # theta_d < 10 degrees

    def value(self, wi, wo):
        """The table's interpolated value at direction pairs (N, 3)."""
        return lookup(self.table, *half_diff(wi, wo))

    def texture_size(self) -> tuple[int, int, int]:
        """(width, height, depth) of ``texture_data``."""
        return N_PD, N_TD, N_TH + 1

    def texture_data(self) -> np.ndarray:
        """float32 RGB data of a 3D texture 180 x 90 x 91: x = phi_d, y = theta_d, z = theta_h for
        z < 90; the layer z = 90 holds the sampler's data in its red channel, row y = 0: the 90
        bins' CDF at x = 0..89 and the cosine weight at x = 90 (read with texelFetch: a table
        in an array of the uniform block would be indexed dynamically, which software GL
        compiles into long chains of selects)."""
        out = np.zeros((N_TH + 1, N_TD, N_PD, 3), dtype=np.float32)
        out[:N_TH] = self.table
        out[N_TH, 0, :N_TH, 0] = self.cdf
        out[N_TH, 0, N_TH, 0] = self.w_cos
        return out


_CACHE: dict = {}


def load(path) -> Measured:
    """``read`` a file once per process (keyed by its path, size and modification time)."""
    path = os.path.abspath(os.fspath(path))
    st, problem = stat_file(path)
    if problem:
        raise ViewerError(one_line(f"{path}: {problem}; allowed: a MERL BRDF file (.binary)"))
    key = (path, st.st_size, st.st_mtime_ns)
    hit = _CACHE.get(key)
    if hit is None:
        if len(_CACHE) >= 4:
            _CACHE.pop(next(iter(_CACHE)))
        hit = _CACHE[key] = Measured(read(path), path)
    return hit
