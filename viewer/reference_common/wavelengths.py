"""The hero-wavelength estimator's wavelengths, the same in both engines (Wilkie et al. 2014):
420 bins of 1 nm from 360 nm, a path's four wavelengths ``STRIDE`` bins apart, and ``HERO``, the
weight of a hero-only path (the four wavelengths' share in one). ``viewer.gl.constants`` writes
them into the GPU engine's shaders (``SPEC_N_BINS``, ``SPEC_STRIDE``, ``SPEC_HERO``)."""

from __future__ import annotations

import numpy as np

from viewer import spectral

N_BINS = 420
STRIDE = N_BINS // 4
LAMBDA0 = 360.0
HERO = 4            # the hero-only path's weight: the four wavelengths' share in one


def bin_wavelengths() -> np.ndarray:
    return LAMBDA0 + np.arange(N_BINS, dtype=np.float64)


def bin_weights() -> np.ndarray:
    """(420, 3) CIE RGB weights of the 1 nm bins; they sum to (1, 1, 1)."""
    w = spectral.colorimetry.weights().T.copy()          # (421, 3) on 360..780
    out = w[:N_BINS].copy()
    out[-1] += w[N_BINS]
    return out
