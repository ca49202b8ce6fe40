"""Gaussian Scan Context (seeds/003 section 4.2.3, eq. 4.26-4.33).

Scan Context++ (:mod:`exobench.perception.place_recognition.scan_context`) with each cell filled from a Gaussian
fitted to the points of its bin instead of their maximum height. Binning, ring/sector keys,
k-d tree retrieval, column-shift alignment and the threshold ``tau`` are those of SC++.

Every point is ``p = (x, y, z, psi)`` (eq. 4.20's ``R^4`` point) with ``z`` offset by
``height_offset_m`` and ``psi`` the intensity byte times ``intensity_scale``. Per bin with
``N`` points:

- Eq. (4.26)-(4.27), :func:`bin_gaussians`: ``mu = mean p``; ``Sigma = sum (p - mu)(p - mu)^T /
  (N - 1)``. A bin with one point has ``Sigma = 0`` (the unbiased estimator is undefined).
- Eq. (4.29)-(4.33) (``huber_delta`` given): residual ``r_k = ||p_k - mu||_2`` to the plain mean
  of eq. (4.26), over x, y, z (metres: ``delta`` is a distance; the intensity is not a length);
  weight ``w_k = 1`` if ``r_k <= delta`` else ``delta / r_k`` (eq. 4.31);
  ``mu_h = sum w p / sum w``, ``Sigma_h = sum w (p - mu_h)(p - mu_h)^T / sum w`` (one pass, as
  written; eq. 4.30's loss only motivates the weight).
- Eq. (4.28): ``C_ij = mu^z + alpha * Sigma^zz`` (variance, as the equation writes it; the
  text's "standard deviation" in section 5.2.3 is read as this).

Variants (``variant``): ``"height"`` (eq. 4.26-4.28), ``"huber"`` (Huber-weighted height,
eq. 4.29-4.33 then 4.28) and ``"intensity"`` (eq. 4.28 on ``psi``: ``mu^psi + alpha *
Sigma^psipsi``, plain statistics). Defaults ``alpha = 2``, ``delta = 1`` m (section 5.2.3).
``intensity_scale = 1/255`` maps the byte to the 0-1 reflectance of the KITTI clouds the
thesis used, so ``alpha`` weighs mean and variance as it did there. Empty bins are 0.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from exobench.core.errors import ConfigError, check_range
from exobench.perception.place_recognition.recognizer import PlaceRecognizer
from exobench.perception.place_recognition.scan_context import ScanContextConfig

__all__ = ["VARIANTS", "GaussianScanContext", "GaussianScanContextConfig", "bin_gaussians", "huber_weights"]

VARIANTS = ("height", "huber", "intensity")


@dataclass(frozen=True)
class GaussianScanContextConfig(ScanContextConfig):
    """SC++ parameters plus the Gaussian ones.

    Attributes:
        variant: ``"height"``, ``"huber"`` or ``"intensity"``.
        alpha: weight of the variance in eq. (4.28), > 0.
        delta_m: Huber threshold of eq. (4.31), m, > 0.
        intensity_scale: factor from the intensity byte to the value binned, > 0.
    """

    variant: str = "huber"
    alpha: float = 2.0
    delta_m: float = 1.0
    intensity_scale: float = 1.0 / 255.0

    def __post_init__(self) -> None:
        super().__post_init__()
        if self.variant not in VARIANTS:
            raise ConfigError("variant", self.variant, f"one of {', '.join(VARIANTS)}")
        check_range("alpha", self.alpha, 0.0, None, low_open=True)
        check_range("delta_m", self.delta_m, 0.0, None, low_open=True)
        check_range("intensity_scale", self.intensity_scale, 0.0, None, low_open=True)


def huber_weights(residual: np.ndarray, delta: float) -> np.ndarray:
    """Eq. (4.31): 1 where ``|r| <= delta``, else ``delta / |r|``."""
    r = np.abs(np.asarray(residual, dtype=float))
    w = np.ones_like(r)
    far = r > delta
    w[far] = delta / r[far]
    return w


def bin_gaussians(
    p4: np.ndarray, flat_bin: np.ndarray, n_bins: int, huber_delta: float | None = None
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Gaussian of every occupied bin: ``(bins, counts, mu (K, 4), Sigma (K, 4, 4))``.

    Plain (eq. 4.26-4.27) or, with ``huber_delta``, Huber-weighted (eq. 4.29-4.33).
    """
    p = np.asarray(p4, dtype=float)
    b = np.asarray(flat_bin, dtype=np.int64)
    counts_all = np.bincount(b, minlength=n_bins)
    bins = np.flatnonzero(counts_all)
    dense = np.full(n_bins, -1, dtype=np.int64)
    dense[bins] = np.arange(len(bins))
    k = dense[b]  # occupied-bin index per point
    K = len(bins)
    counts = counts_all[bins].astype(float)

    def weighted_mean(w: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        sw = np.bincount(k, weights=w, minlength=K)
        mu = np.column_stack([np.bincount(k, weights=w * p[:, c], minlength=K) for c in range(4)]) / sw[:, None]
        return mu, sw

    mu, _ = weighted_mean(np.ones(len(p)))  # eq. (4.26)
    if huber_delta is None:
        w = np.ones(len(p))
        denom = counts - 1.0  # eq. (4.27)
    else:
        r = np.linalg.norm(p[:, :3] - mu[k, :3], axis=1)  # eq. (4.29)
        w = huber_weights(r, huber_delta)  # eq. (4.31)
        mu, denom = weighted_mean(w)  # eq. (4.32)
    d = p - mu[k]
    outer = (w[:, None, None] * d[:, :, None] * d[:, None, :]).reshape(len(p), 16)
    S = np.column_stack([np.bincount(k, weights=outer[:, c], minlength=K) for c in range(16)]).reshape(K, 4, 4)
    with np.errstate(invalid="ignore", divide="ignore"):
        Sigma = np.where(denom[:, None, None] > 0, S / denom[:, None, None], 0.0)  # eq. (4.27)/(4.33)
    return bins, counts, mu, Sigma


class GaussianScanContext(PlaceRecognizer):
    """Gaussian Scan Context with the ``height``, ``huber`` or ``intensity`` cell (eq. 4.28)."""

    config: GaussianScanContextConfig

    def __init__(self, config: GaussianScanContextConfig | None = None) -> None:
        super().__init__(config or GaussianScanContextConfig())
        self.name = f"gsc-{self.config.variant}"

    def _needs_intensity(self) -> bool:
        return self.config.variant == "intensity"

    def _cells(self, p4: np.ndarray, flat_bin: np.ndarray, n_bins: int) -> np.ndarray:
        cfg = self.config
        p = p4.copy()
        p[:, 3] *= cfg.intensity_scale
        delta = cfg.delta_m if cfg.variant == "huber" else None
        bins, _, mu, Sigma = bin_gaussians(p, flat_bin, n_bins, delta)
        c = 3 if cfg.variant == "intensity" else 2
        C = np.zeros(n_bins)
        C[bins] = mu[:, c] + cfg.alpha * Sigma[:, c, c]  # eq. (4.28)
        return C
