"""Recursive total least squares (RTLS) planes of the staircase paper (seeds/004, eq. 11-18).

A plane is kept as the sufficient statistics of its points: the count ``n``, the centroid ``e``
and the second-moment matrix ``V = sum p p^T``. Adding a point updates them with eq. (15)-(16),
removing one with eq. (17)-(18); the scatter ``M_p^T M_p = V - n e e^T`` (eq. 11) gives the
normal as the eigenvector of its smallest eigenvalue ``lambda_3`` and the standard deviation of
the point-to-plane distances as ``sigma_n = sqrt(lambda_3 / n)`` (the plane passes through the
centroid, so the distances have zero mean).

Numerics: ``V - n e e^T`` cancels catastrophically when the points lie metres away from the
origin. Every class here therefore stores the moments of ``p - c`` where ``c`` is a fixed
reference point, the first point the plane ever received. This is the same recursion on
translated coordinates (the scatter is translation invariant), so it is an equivalent form of
eq. (11)-(18) that stays exact to ~1e-12 m for coordinates of a few metres.

Three variants:
- :class:`RtlsPlane`: the general plane (3x3 scatter, ``numpy.linalg.eigh``).
- :class:`HorizontalPlane`: the paper's HTVR tread, normal fixed to +z; only the mean and the
  variance of z are fitted (1-D).
- :class:`VerticalPlane`: the paper's HTVR riser, normal horizontal; the 2x2 scatter of x-y is
  fitted (2-D).

All three also keep the full 3-D centroid, for reporting; eigen-decompositions are computed
lazily, once per change, when the normal or sigma is asked for.
"""

from __future__ import annotations

import numpy as np

__all__ = ["HorizontalPlane", "PlaneFit", "RtlsPlane", "VerticalPlane", "make_plane"]


class PlaneFit:
    """Common recursion: count, reference point, first and second moments of ``p - c``.

    Subclasses choose which coordinates enter the scatter (``_dims``) and how the normal is
    read from it.
    """

    _dims: tuple[int, ...] = (0, 1, 2)

    def __init__(self) -> None:
        self.n = 0
        self._ref = np.zeros(3)
        self._sum = np.zeros(3)  # sum of (p - c)
        self._idx = np.array(self._dims)
        k = len(self._dims)
        self._V = np.zeros((k, k))  # sum of (p - c)(p - c)^T over the fitted coordinates
        self._cache: tuple[np.ndarray, float] | None = None

    # --- recursions (eq. 15-18) ---
    def add(self, p: np.ndarray) -> None:
        """AddToSurf: ``V <- V + p p^T`` (15), ``e <- (n e + p) / (n + 1)`` (16)."""
        p = np.asarray(p, dtype=float)
        if self.n == 0:
            self._ref = p.copy()
            self._sum[:] = 0.0
            self._V[:] = 0.0
        d = p - self._ref
        dd = d[self._idx]
        self._V += np.outer(dd, dd)
        self._sum += d
        self.n += 1
        self._cache = None

    def remove(self, p: np.ndarray) -> None:
        """RemoveFromSurf: ``V <- V - p p^T`` (17), ``e <- (n e - p) / (n - 1)`` (18).

        The caller must only remove points it added; removing the last point empties the plane.
        """
        if self.n <= 0:
            raise ValueError("cannot remove a point from an empty plane")
        if self.n == 1:
            self.n = 0
            self._sum[:] = 0.0
            self._V[:] = 0.0
            self._cache = None
            return
        d = np.asarray(p, dtype=float) - self._ref
        dd = d[self._idx]
        self._V -= np.outer(dd, dd)
        self._sum -= d
        self.n -= 1
        self._cache = None

    # --- read-out ---
    @property
    def centroid(self) -> np.ndarray:
        """Centroid ``e`` (3,), NaN when empty."""
        if self.n == 0:
            return np.full(3, np.nan)
        return self._ref + self._sum / self.n

    def scatter(self) -> np.ndarray:
        """``M_p^T M_p = V - n e e^T`` (eq. 11) over the fitted coordinates, reference-shifted."""
        m = self._sum[self._idx]
        return self._V - np.outer(m, m) / max(self.n, 1)

    def _solve(self) -> tuple[np.ndarray, float]:
        raise NotImplementedError

    def _fit(self) -> tuple[np.ndarray, float]:
        if self._cache is None:
            self._cache = self._solve()
        return self._cache

    @property
    def normal(self) -> np.ndarray:
        """Unit normal (3,); NaN when empty. Undetermined (but finite) below 3 points."""
        if self.n == 0:
            return np.full(3, np.nan)
        return self._fit()[0]

    @property
    def sigma_m(self) -> float:
        """Standard deviation of the point-to-plane distances, ``sqrt(lambda_min / n)``."""
        if self.n == 0:
            return float("nan")
        return self._fit()[1]

    def distance(self, p: np.ndarray) -> float:
        """Signed distance of ``p`` to the plane (along :attr:`normal`), m."""
        return float(np.dot(np.asarray(p, dtype=float) - self.centroid, self.normal))


class RtlsPlane(PlaneFit):
    """General plane: normal = eigenvector of the smallest eigenvalue of the 3x3 scatter."""

    _dims = (0, 1, 2)

    def _solve(self) -> tuple[np.ndarray, float]:
        w, U = np.linalg.eigh(self.scatter())
        return U[:, 0].copy(), float(np.sqrt(max(w[0], 0.0) / self.n))


class HorizontalPlane(PlaneFit):
    """HTVR tread: normal fixed to +z; the fit is the mean and variance of z (1-D)."""

    _dims = (2,)

    def _solve(self) -> tuple[np.ndarray, float]:
        var = float(self.scatter()[0, 0]) / self.n
        return np.array([0.0, 0.0, 1.0]), float(np.sqrt(max(var, 0.0)))


class VerticalPlane(PlaneFit):
    """HTVR riser: normal horizontal, eigenvector of the smallest eigenvalue of the x-y scatter."""

    _dims = (0, 1)

    def _solve(self) -> tuple[np.ndarray, float]:
        w, U = np.linalg.eigh(self.scatter())
        return np.array([U[0, 0], U[1, 0], 0.0]), float(np.sqrt(max(w[0], 0.0) / self.n))


def make_plane(kind: str) -> PlaneFit:
    """A new empty plane of ``kind`` ``"general"``, ``"horizontal"`` or ``"vertical"``."""
    return {"general": RtlsPlane, "horizontal": HorizontalPlane, "vertical": VerticalPlane}[kind]()
