"""Directional albedo rho(wo) = integral of f(wi, wo) cos(theta_i) dwi, estimated with the
model's own importance sampler (the mean of ``weight``), on a fixed stratified pattern so the
result is deterministic.

The rasterizer uses a table of it over cos(theta_o) for the light of a constant environment:
L_o(wo) = L_env * rho(wo) exactly, since L_env leaves the integral (no occlusion)."""

from __future__ import annotations

import numpy as np

TABLE_SIZE = 32
N_SIDE = 24  # n_side^2 = 576 multi-jittered samples per azimuth
PHIS = (0.0, np.pi / 4, np.pi / 2, 3 * np.pi / 4)  # azimuths of wo averaged over


def stratified_u(n_side: int, seed: int = 0) -> np.ndarray:
    """n_side^2 multi-jittered points (Chiu, Shirley & Wang 1994): stratified in the
    n_side x n_side grid and, in each coordinate alone, one point per 1/n_side^2 stratum. The
    second property bounds the error of a lobe choice (u0 < R) by 1 / n_side^2."""
    rng = np.random.default_rng(seed)
    n = n_side
    i, j = np.meshgrid(np.arange(n), np.arange(n), indexing="ij")
    i, j = i.ravel(), j.ravel()
    x = (i + (j + rng.random(i.size)) / n) / n
    y = (j + (i + rng.random(i.size)) / n) / n
    u = np.stack([x, y], axis=-1)
    return np.clip(u, 0.0, np.nextafter(1.0, 0.0))


def directional_albedo(model, p, cos_o, n_side: int = N_SIDE, phis=PHIS, split: bool = False):
    """(len(cos_o), 3) albedo averaged over the azimuths ``phis`` (anisotropic models vary with
    the azimuth of wo; isotropic ones do not). With ``split``: (reflected, transmitted) parts,
    by the side of the surface the sampled wi lies on."""
    cos_o = np.asarray(cos_o, dtype=np.float64)
    refl = np.zeros((cos_o.size, 3))
    trans = np.zeros((cos_o.size, 3))
    for seed, phi in enumerate(phis):
        u = stratified_u(n_side, seed)  # a different jitter per azimuth: more distinct samples
        sin_o = np.sqrt(np.maximum(0.0, 1.0 - cos_o ** 2))
        wo = np.stack([sin_o * np.cos(phi), sin_o * np.sin(phi), cos_o], axis=-1)
        wo_rep = np.repeat(wo, len(u), axis=0)
        u_rep = np.tile(u, (cos_o.size, 1))
        wi, weight, pdf = model.sample(p, wo_rep, u_rep)
        weight = np.where(np.isfinite(weight) & (np.asarray(pdf)[:, None] > 0), weight, 0.0)
        below = (wi[:, 2] < 0)[:, None]
        refl += np.where(below, 0.0, weight).reshape(cos_o.size, len(u), 3).mean(axis=1)
        trans += np.where(below, weight, 0.0).reshape(cos_o.size, len(u), 3).mean(axis=1)
    refl /= len(phis)
    trans /= len(phis)
    return (refl, trans) if split else refl + trans


def albedo_tables(model, p, size: int = TABLE_SIZE) -> tuple[np.ndarray, np.ndarray]:
    """(reflected, transmitted) albedo, each (size, 3), at cos(theta_o) = (k + 0.5) / size."""
    cos_o = (np.arange(size) + 0.5) / size
    return directional_albedo(model, p, cos_o, split=True)


def albedo_table(model, p, size: int = TABLE_SIZE) -> np.ndarray:
    """(size, 3) albedo at cos(theta_o) = (k + 0.5) / size, k = 0..size-1."""
    r, t = albedo_tables(model, p, size)
    return r + t
