"""RGB -> spectrum upsampling that round-trips: Mallett & Yuksel, "Spectral Primary Decomposition
for Rendering with sRGB Reflectance", EGSR 2019.

Three basis spectra b_r, b_g, b_b (``data/rgb_basis.csv``, 360-780 nm at 5 nm, linear in
between) with
  * 0 <= b_c(lambda) <= 1 and b_r + b_g + b_b = 1 at every wavelength (so a reflectance in
    [0, 1]^3 becomes a spectrum in [0, 1], and white becomes the flat spectrum 1),
  * to_rgb(b_c) = the c-th unit vector (under the CIE 1931 observer and D65 of ``colorimetry``),
found as in the paper by minimizing the roughness sum (b(l+1) - b(l))^2 under these constraints
(``compute_basis``, scipy's SLSQP; run by ``tools/spectral_tables.py --basis``). The spectrum of
an RGB colour is rgb_r b_r + rgb_g b_g + rgb_b b_b, linear in the colour, so
to_rgb(spectrum(rgb)) = rgb for every colour (exactly for the resampled 1 nm sums; outside
[0, 1]^3 the spectrum may leave [0, 1]).
"""

from __future__ import annotations

import functools
import pathlib

import numpy as np

from viewer.spectral import colorimetry

GRID = np.arange(360.0, 781.0, 5.0)


def _interp_matrix(grid: np.ndarray, fine: np.ndarray) -> np.ndarray:
    """(len(fine), len(grid)) linear-interpolation matrix."""
    eye = np.eye(grid.size)
    return np.stack([np.interp(fine, grid, eye[j]) for j in range(grid.size)], axis=1)


def compute_basis() -> np.ndarray:
    """(len(GRID), 3) basis (slow: seconds; the result is shipped in ``data/rgb_basis.csv``)."""
    from scipy.optimize import minimize

    wl = colorimetry.tables()[0]
    a = colorimetry.weights() @ _interp_matrix(GRID, wl)           # (3, G): RGB of a grid spectrum
    g = GRID.size
    d = np.diff(np.eye(g), axis=0)
    h = d.T @ d
    one = np.ones(g)

    # unknowns b_r, b_g; b_b = 1 - b_r - b_g (the sum constraint, which also makes to_rgb(b_b)
    # the blue unit vector once b_r and b_g map to theirs, since the flat spectrum is white)
    def obj(x):
        r, gg = x[:g], x[g:]
        bb = one - r - gg
        val = r @ h @ r + gg @ h @ gg + bb @ h @ bb
        gb = 2.0 * (h @ bb)
        return float(val), np.concatenate([2.0 * (h @ r) - gb, 2.0 * (h @ gg) - gb])

    aeq = np.block([[a, np.zeros_like(a)], [np.zeros_like(a), a]])
    beq = np.array([1.0, 0.0, 0.0, 0.0, 1.0, 0.0])
    ain = np.hstack([-np.eye(g), -np.eye(g)])                     # 1 - b_r - b_g >= 0
    x0 = np.full(2 * g, 1.0 / 3.0)
    res = minimize(obj, x0, jac=True, method="SLSQP", bounds=[(0.0, 1.0)] * (2 * g),
                   constraints=[{"type": "eq", "fun": lambda x: aeq @ x - beq, "jac": lambda x: aeq},
                                {"type": "ineq", "fun": lambda x: 1.0 + ain @ x, "jac": lambda x: ain}],
                   options={"maxiter": 3000, "ftol": 1e-15})
    if not res.success:
        raise RuntimeError(f"basis optimization failed: {res.message}")
    r, gg = res.x[:g], res.x[g:]
    res_x = np.stack([r, gg, one - r - gg])
    b = np.clip(res_x, 0.0, 1.0)
    b = b / b.sum(axis=0, keepdims=True)
    # remove the optimizer's last residual (about 1e-9) of the round trip exactly
    b = np.linalg.solve((a @ b.T).T, b)
    return b.T


def write_basis(path: pathlib.Path) -> None:
    b = compute_basis()
    head = ("# RGB -> spectrum basis (Mallett & Yuksel 2019, Spectral Primary Decomposition), for the\n"
            "# CIE 1931 2 degree observer, D65 and linear Rec.709 of viewer.spectral; computed by\n"
            "# tools/spectral_tables.py --basis\n"
            "wavelength_nm,r,g,b\n")
    from viewer.base.io import atomic_write_bytes

    atomic_write_bytes(path, (head + "".join(f"{w:.0f},{r:.9f},{g:.9f},{bb:.9f}\n"
                                             for w, (r, g, bb) in zip(GRID, b))).encode())


@functools.lru_cache(maxsize=None)
def basis() -> tuple[np.ndarray, np.ndarray]:
    """(wavelengths (G,), basis (G, 3))."""
    a = colorimetry.read_csv(colorimetry.DATA / "rgb_basis.csv")
    return a[:, 0], a[:, 1:4]


def basis_at(wavelength_nm) -> np.ndarray:
    """b_r, b_g, b_b at the given wavelengths: (..., 3)."""
    wl, b = basis()
    lam = np.asarray(wavelength_nm, dtype=np.float64)
    return np.stack([np.interp(lam, wl, b[:, c]) for c in range(3)], axis=-1)


def rgb_to_spectrum(rgb, wavelength_nm) -> np.ndarray:
    """The upsampled spectrum of linear Rec.709 colours ``rgb`` (..., 3) at ``wavelength_nm``:
    (..., ) for a scalar wavelength broadcast against rgb's leading axes, i.e.
    sum_c rgb[..., c] b_c(lambda)."""
    return np.sum(np.asarray(rgb, dtype=np.float64) * basis_at(wavelength_nm), axis=-1)
