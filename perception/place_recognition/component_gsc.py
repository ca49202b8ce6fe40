"""Gaussian Scan Context cells computed from only the statistics eq. (4.28) reads."""

from __future__ import annotations

import numpy as np

from .gaussian_scan_context import GaussianScanContext


class ComponentGaussianScanContext(GaussianScanContext):
    """GSC whose cells compute only what eq. (4.28) reads: per bin the (Huber-weighted) mean and
    variance of the one component (z, or psi for ``"intensity"``).

    The same statistics as the ``[c]`` / ``[c, c]`` entries of
    :func:`~exobench.perception.place_recognition.gaussian_scan_context.bin_gaussians` (eq. 4.26-4.27, or the
    residual over x, y, z to the plain mean, eq. 4.29, the weight of eq. 4.31 and eq. 4.32-4.33),
    equal to rounding (the residual's norm is summed axis by axis); the other 15 covariance
    entries are not formed (the thesis' own remedy for GSC's overhead, section 5.2.3).
    """

    def _cells(self, p4: np.ndarray, flat_bin: np.ndarray, n_bins: int) -> np.ndarray:
        from .gaussian_scan_context import huber_weights

        cfg = self.config
        c = 3 if cfg.variant == "intensity" else 2
        p = np.asarray(p4, dtype=float)
        v = p[:, 3] * cfg.intensity_scale if c == 3 else p[:, 2]
        b = np.asarray(flat_bin, dtype=np.int64)
        counts_all = np.bincount(b, minlength=n_bins)
        bins = np.flatnonzero(counts_all)
        dense = np.full(n_bins, -1, dtype=np.int64)
        dense[bins] = np.arange(len(bins))
        k = dense[b]
        K = len(bins)
        counts = counts_all[bins].astype(float)
        ones = np.ones(len(p))
        sw = np.bincount(k, weights=ones, minlength=K)
        if cfg.variant == "huber":
            r2 = np.zeros(len(p))
            for j in range(3):  # eq. (4.29): squared distance to the plain mean, axis by axis
                dj = p[:, j] - (np.bincount(k, weights=p[:, j], minlength=K) / sw)[k]
                r2 += dj * dj
            w = huber_weights(np.sqrt(r2), cfg.delta_m)  # eq. (4.31)
            sw = np.bincount(k, weights=w, minlength=K)
            denom = sw  # eq. (4.33)
        else:
            w = ones
            denom = counts - 1.0  # eq. (4.27)
        mu = np.bincount(k, weights=w * v, minlength=K) / sw  # eq. (4.26) / (4.32)
        d = v - mu[k]
        S = np.bincount(k, weights=w * d * d, minlength=K)
        with np.errstate(invalid="ignore", divide="ignore"):
            var = np.where(denom > 0, S / denom, 0.0)
        C = np.zeros(n_bins)
        C[bins] = mu + cfg.alpha * var  # eq. (4.28)
        return C


