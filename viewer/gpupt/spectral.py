"""The data of the GPU engine's spectral variant (``#define SPECTRAL``,
``shaders/pathtrace/spectral.glsl``): the CPU engine's hero-wavelength estimator
(``viewer.pathtracer.spectral``) term for term.

* ``spectral_table()``: (2, 420, 4) float32 texels, row 0 the Mallett & Yuksel upsampling basis
  b_r, b_g, b_b at the 420 bins of 1 nm, row 1 the bins' CIE RGB weights W (both as the CPU's
  ``SpectralIntegrator`` builds them: ``basis_at(bin_wavelengths())``, ``bin_weights()``).
* ``pack_spectral_materials(materials, offset)``: per material its category (as the CPU
  integrator sorts them: ``rgb``, ``table``, ``hero``) and, for spectral materials, the material
  packed once per wavelength set the path may use, with the CPU's own ``viewer.brdf.params_at``: 105 sets at
  bins (c, c + 105, c + 210) (a table material's three channels) and 420 at (l, l, l) (a table
  material's fourth wavelength, a hero material's hero). A path then reads its parameters at a
  computed offset, so every substitution the CPU makes (n, k of the table for eta, k and a
  conductor Fresnel; n(lambda) for ior; RGB parameters upsampled; nested materials likewise) is
  made here by the same code, and the GLSL needs no per-model substitution functions. The sets
  are small (a metal's 12 floats, a dielectric's 8), 525 x that per spectral material.
"""

from __future__ import annotations

import numpy as np

from viewer import brdf
from viewer.gl.brdf_glsl import pack_material
from viewer.reference_common.wavelengths import N_BINS, STRIDE, bin_wavelengths, bin_weights

CATEGORY_CODE = {"rgb": 0, "table": 1, "hero": 2}   # spectral.glsl u_mat_spec[m].x


def category(m) -> str:
    """The CPU spectral integrator's category of an ``viewer.reference_common.setup.MaterialInfo``: ``rgb`` (no
    spectral table: evaluated in RGB, the value upsampled), ``hero`` (dispersive, or a spectral
    material with a delta base: one wavelength per path) or ``table`` (a spectral metal: all four
    wavelengths)."""
    p = m.params
    if not brdf.uses_spectral(p):
        return "rgb"
    if brdf.is_dispersive(p) or m.lobes.is_mixed:
        return "hero"
    return "table"


def spectral_table() -> np.ndarray:
    """(2, 420, 4) float32: row 0 rgb = basis at each bin, row 1 rgb = its CIE RGB weight."""
    from viewer.spectral import upsampling

    out = np.zeros((2, N_BINS, 4), np.float32)
    out[0, :, :3] = upsampling.basis_at(bin_wavelengths())
    out[1, :, :3] = bin_weights()
    return out


def pack_spectral_materials(materials, offset: int, max_materials: int) -> tuple[np.ndarray, np.ndarray]:
    """(info (max_materials, 4) float32 for ``u_mat_spec``, floats to append to the material
    texture at float ``offset``). info[m] = (category code, offset of the 105 sets at (c, c + 105,
    c + 210), offset of the 420 sets at (l, l, l), floats per set); RGB materials: (0, 0, 0, 0)."""
    info = np.zeros((max_materials, 4), np.float32)
    data: list[np.ndarray] = []
    bins = bin_wavelengths()
    for i, m in enumerate(materials):
        if brdf.has_film(m.params):  # params_at gives the film its wavelengths; the GLSL would not use them
            from viewer import ViewerError

            raise ViewerError(f"material {m.name}: the GPU engine's spectral pass does not trace thin films per "
                              "wavelength; use --engine cpu")
        cat = category(m)
        info[i, 0] = CATEGORY_CODE[cat]
        if cat == "rgb":
            continue
        sets = [bins[[l, l, l]] for l in range(N_BINS)]
        if cat == "table":
            sets = [bins[[c, c + STRIDE, c + 2 * STRIDE]] for c in range(STRIDE)] + sets
        size = None
        c_off = offset
        for lam3 in sets:
            _, arr = pack_material(brdf.params_at(m.params, lam3), offset, limit=None)
            if size is None:
                size = arr.size
            elif arr.size != size:  # one stride per material: every set must have the same layout
                raise AssertionError(f"material {m.name}: parameter sets of {size} and {arr.size} floats")
            data.append(arr)
            offset += arr.size
        h_off = c_off + (STRIDE * size if cat == "table" else 0)
        info[i, 1:] = (c_off, h_off, size)
    floats = np.concatenate(data).astype(np.float32) if data else np.zeros(0, np.float32)
    return info, floats
