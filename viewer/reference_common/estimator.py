"""What the two reference engines share: the interface (``ReferenceEngine``: the CPU engine's
``ReferenceRenderer`` and the GPU engine's ``GpuReferenceRenderer`` both have it), the
estimator's options (``EstimatorOptions``, checked by ``check_options``) and constants (Russian
roulette's start and survival bounds, which ``viewer.gl.constants`` writes into the GPU engine's
shaders), and the mean and variance of a pixel's sums (``mean_of``, ``variance_of_mean``), so
both engines answer from their sums the same way. No GL and neither engine here: both engines
import this module."""

from __future__ import annotations

import dataclasses
import threading
from typing import Protocol, runtime_checkable

import numpy as np

FLOAT32_MAX = float(np.finfo(np.float32).max)

RR_START_DEPTH = 4          # Russian roulette from the 4th scattering event on ("after 3 bounces")
RR_MIN, RR_MAX = 0.05, 0.95  # the survival probability clamp(max(throughput), RR_MIN, RR_MAX)
STRATEGIES = ("mis", "bsdf", "light")   # how the environment is reached
STRATEGY_LABELS = {"mis": "MIS (BSDF + light)", "bsdf": "BSDF sampling", "light": "light sampling"}
MIS_HEURISTICS = ("power", "balance")   # power: beta = 2 (Veach 1997, eq. 9.13)


#: path tracing, and path tracing plus a progressive caustic photon map (viewer/reference_common/caustics.py)
INTEGRATORS = ("path", "photon")
AUTO_INTEGRATOR = "auto"   # the integrator chosen per scene (caustics.choose_integrator)


def check_options(strategy: str, mis_heuristic: str = "power", integrator: str = AUTO_INTEGRATOR) -> None:
    """One-line ViewerError for an unknown strategy, MIS heuristic or integrator."""
    from viewer import ViewerError

    if strategy not in STRATEGIES:
        raise ViewerError(f"strategy: {strategy!r} is not a sampling strategy; allowed: {', '.join(STRATEGIES)}")
    if mis_heuristic not in MIS_HEURISTICS:
        raise ViewerError(f"MIS heuristic: {mis_heuristic!r} is not a heuristic; allowed: {', '.join(MIS_HEURISTICS)}")
    if integrator != AUTO_INTEGRATOR and integrator not in INTEGRATORS:
        raise ViewerError(f"integrator: {integrator!r} is not an integrator; allowed: {', '.join(INTEGRATORS)}")


@dataclasses.dataclass(frozen=True)
class EstimatorOptions:
    """How the environment is reached (``strategy``: "mis", "bsdf" or "light"), how MIS
    weights (``mis_heuristic``: "power" or "balance"), whether Russian roulette ends paths and the ``integrator``
    ("path", "photon": path tracing plus a caustic photon map, or "auto": chosen per scene by
    ``viewer.reference_common.caustics.choose_integrator``); checked on creation (a one-line
    ViewerError)."""

    strategy: str = "mis"
    mis_heuristic: str = "power"
    russian_roulette: bool = True
    integrator: str = "path"

    def __post_init__(self):
        check_options(self.strategy, self.mis_heuristic, self.integrator)
        object.__setattr__(self, "russian_roulette", bool(self.russian_roulette))

    def updated(self, strategy=None, mis_heuristic=None, russian_roulette=None,
                integrator=None) -> "EstimatorOptions":
        """These options with the ones given changed (None: as before)."""
        given = dict(strategy=strategy, mis_heuristic=mis_heuristic, russian_roulette=russian_roulette,
                     integrator=integrator)
        return dataclasses.replace(self, **{k: v for k, v in given.items() if v is not None})

    def as_kwargs(self) -> dict:
        """``strategy=, mis_heuristic=, russian_roulette=, integrator=`` for ``RenderSetup.from_scene``."""
        return dataclasses.asdict(self)


@runtime_checkable
class ReferenceEngine(Protocol):
    """A progressive reference renderer (``viewer.reference_common.select.make_renderer`` makes one of
    either engine). ``engine``: "cpu" or "gpu"; ``options``: its ``EstimatorOptions``;
    ``spp``: whole samples per pixel so far; ``bad_values``: NaN / inf samples dropped."""

    engine: str
    options: EstimatorOptions
    width: int
    height: int
    spp: int
    is_spectral: bool

    def step(self, spp: int = 1, cancel: threading.Event | None = None, progress=None) -> bool:
        """Add ``spp`` samples per pixel; False when ``cancel`` stopped it."""

    def mean(self) -> np.ndarray:
        """(H, W, 3) float32 running mean, row 0 = top."""

    def variance(self) -> np.ndarray:
        """(H, W, 3) float32 variance of the mean per pixel."""

    def state(self):
        """(sum, sum of squares, spp) so far, for the reference cache."""

    def resume(self, total, total2, spp: int) -> None:
        """Continue from stored sums of ``spp`` samples per pixel."""

    def reset(self, scene, camera=None, width=None, height=None, *, strategy=None, mis_heuristic=None,
              russian_roulette=None, integrator=None) -> None:
        """Start over on a changed scene, camera or size; the options given change."""

    def warm_up(self) -> None:
        """Get ready to render (workers started, programs compiled)."""

    def close(self) -> None:
        """Release what the engine holds."""


def mean_of(total, n) -> np.ndarray:
    """(H, W, 3) float32 mean of per-pixel sums ``total`` over ``n`` samples (a number, or
    (H, W, 1) per pixel); 0 where there is no sample. Radiance beyond the float32 range
    saturates at its largest value (3.4e38) instead of becoming inf: possible at the far ends
    of the parameter ranges, e.g. a Lafortune lobe |C| = 10, n = 5000, whose value is capped at
    e^80 but whose path weights multiply over the bounces."""
    n = np.asarray(n, np.float64)
    with np.errstate(invalid="ignore", divide="ignore"):
        m = np.where(n > 0, total / np.maximum(n, 1.0), 0.0)
    return np.minimum(m, FLOAT32_MAX).astype(np.float32)


def variance_of_mean(total, total2, n) -> np.ndarray:
    """(H, W, 3) float32 variance of the mean: the unbiased sample variance of the sums
    ``total``, ``total2`` (of the squares) over ``n`` samples, divided by n; inf below 2 samples
    and where the squares overflowed (never NaN)."""
    n = np.asarray(n, np.float64)
    with np.errstate(over="ignore", invalid="ignore", divide="ignore"):
        m = total / np.maximum(n, 1.0)
        var = np.maximum(total2 - n * m * m, 0.0) / np.maximum(n - 1.0, 1.0) / np.maximum(n, 1.0)
        var = np.where(np.isfinite(total2) & (var <= FLOAT32_MAX), var, np.inf)  # past float32: inf, said so
    return np.where(n >= 2, var, np.inf).astype(np.float32)
