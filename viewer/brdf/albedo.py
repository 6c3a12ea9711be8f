"""Directional albedo rho(wo) = integral of f(wi, wo) cos(theta_i) dwi, estimated with the
model's own importance sampler (the mean of ``weight``), on a fixed stratified pattern so the
result is deterministic.

The rasterizer uses a table of it over cos(theta_o) for the light of a constant environment:
L_o(wo) = L_env * rho(wo) exactly, since L_env leaves the integral (no occlusion)."""

from __future__ import annotations

import numpy as np

TABLE_SIZE = 32


def stratified_u(n_side: int, seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    i, j = np.meshgrid(np.arange(n_side), np.arange(n_side), indexing="ij")
    u = np.stack([(i.ravel() + rng.random(i.size)) / n_side, (j.ravel() + rng.random(i.size)) / n_side], axis=-1)
    return np.clip(u, 0.0, np.nextafter(1.0, 0.0))


def directional_albedo(model, p, cos_o, n_side: int = 24, phis=(0.0, np.pi / 4, np.pi / 2, 3 * np.pi / 4)):
    """(len(cos_o), 3) albedo averaged over the azimuths ``phis`` (anisotropic models vary with
    the azimuth of wo; isotropic ones do not)."""
    cos_o = np.asarray(cos_o, dtype=np.float64)
    u = stratified_u(n_side)
    out = np.zeros((cos_o.size, 3))
    for phi in phis:
        sin_o = np.sqrt(np.maximum(0.0, 1.0 - cos_o ** 2))
        wo = np.stack([sin_o * np.cos(phi), sin_o * np.sin(phi), cos_o], axis=-1)
        wo_rep = np.repeat(wo, len(u), axis=0)
        u_rep = np.tile(u, (cos_o.size, 1))
        _, weight, pdf = model.sample(p, wo_rep, u_rep)
        weight = np.where(np.isfinite(weight) & (np.asarray(pdf)[:, None] > 0), weight, 0.0)
        out += weight.reshape(cos_o.size, len(u), 3).mean(axis=1)
    return out / len(phis)


def albedo_table(model, p, size: int = TABLE_SIZE) -> np.ndarray:
    """(size, 3) albedo at cos(theta_o) = (k + 0.5) / size, k = 0..size-1."""
    cos_o = (np.arange(size) + 0.5) / size
    return directional_albedo(model, p, cos_o)
