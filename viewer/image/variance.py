"""Monte Carlo error of a progressive reference image, from its running per-pixel variance
(``ReferenceRenderer.variance()``: the sample variance of the mean, per pixel and channel).

Per pixel, over the three channels as the RMSE of ``viewer.image.compare`` is (mean of squares):
  standard error   sigma = sqrt(mean_c Var[mean_c])
  relative error   sigma / (mean_c L_c + eps), eps = ``REL_MSE_EPS`` (as ``compare``'s relMSE, so
                   black pixels do not dominate)
  samples needed   n (relative error / target)^2: the error of a mean falls as 1 / sqrt(n), so
                   this many samples bring the pixel to the target relative error
For the whole image, ``rmse_estimate`` = sqrt(mean over pixels and channels of Var[mean]) is the
expected RMSE of the image against its own converged (infinite-sample) mean, the quantity a
convergence plot draws against spp: a line of slope -1/2 on log-log axes for any unbiased
estimator, shifted down by a lower variance per sample.
"""

from __future__ import annotations

import numpy as np

from viewer.image.compare import REL_MSE_EPS

ERROR_VIEWS = ("standard error", "relative error", "samples needed")


def standard_error(variance: np.ndarray) -> np.ndarray:
    """(H, W) standard error of each pixel's mean (inf where fewer than 2 samples)."""
    return np.sqrt(np.asarray(variance).mean(axis=-1, dtype=np.float64))


def relative_error(mean: np.ndarray, variance: np.ndarray) -> np.ndarray:
    return standard_error(variance) / (np.asarray(mean).mean(axis=-1, dtype=np.float64) + REL_MSE_EPS)


def samples_needed(mean: np.ndarray, variance: np.ndarray, spp: int, target: float) -> np.ndarray:
    """(H, W) samples per pixel for a relative error of ``target`` (e.g. 0.01 = 1%)."""
    if not (np.isfinite(target) and target > 0):
        raise ValueError(f"target relative error must be > 0, got {target}")
    return spp * (relative_error(mean, variance) / target) ** 2


def error_view(kind: str, mean: np.ndarray, variance: np.ndarray, spp: int, target: float = 0.01) -> np.ndarray:
    """One of ``ERROR_VIEWS`` as an (H, W) float64 map."""
    if kind == "standard error":
        return standard_error(variance)
    if kind == "relative error":
        return relative_error(mean, variance)
    if kind == "samples needed":
        return samples_needed(mean, variance, spp, target)
    raise ValueError(f"error view {kind!r}: unknown; allowed: {', '.join(ERROR_VIEWS)}")


def rmse_estimate(variance: np.ndarray) -> float:
    """Expected RMSE of the image against its converged mean: sqrt(mean of Var[mean])."""
    v = np.asarray(variance, np.float64)
    return float(np.sqrt(v.mean())) if v.size else float("nan")


class ConvergenceCurve:
    """RMSE estimate against spp for one render (one strategy): ``add`` after each pass."""

    def __init__(self, label: str = ""):
        self.label = label
        self.spp: list[int] = []
        self.rmse: list[float] = []

    def add(self, spp: int, rmse: float) -> None:
        if spp >= 2 and np.isfinite(rmse) and rmse > 0:
            self.spp.append(int(spp))
            self.rmse.append(float(rmse))

    def __len__(self) -> int:
        return len(self.spp)

    def slope_line(self) -> tuple[np.ndarray, np.ndarray]:
        """The -1/2 slope through the curve's last point, over the curve's spp range."""
        if not self.spp:
            return np.zeros(0), np.zeros(0)
        x = np.array([self.spp[0], self.spp[-1]], np.float64)
        return x, self.rmse[-1] * np.sqrt(self.spp[-1] / x)

    def fitted_slope(self) -> float:
        """Least-squares slope of log RMSE against log spp (-1/2 for Monte Carlo)."""
        if len(self.spp) < 2:
            return float("nan")
        return float(np.polyfit(np.log(self.spp), np.log(self.rmse), 1)[0])

    def copy(self, label: str | None = None) -> "ConvergenceCurve":
        c = ConvergenceCurve(self.label if label is None else label)
        c.spp, c.rmse = list(self.spp), list(self.rmse)
        return c
