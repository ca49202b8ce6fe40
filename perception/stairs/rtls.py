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
- :class:`RtlsPlane`: the general plane (3x3 scatter, LAPACK ``dsyevd`` as in
  ``numpy.linalg.eigh``).
- :class:`HorizontalPlane`: the paper's HTVR tread, normal fixed to +z; only the mean and the
  variance of z are fitted (1-D).
- :class:`VerticalPlane`: the paper's HTVR riser, normal horizontal; the 2x2 scatter of x-y is
  fitted (2-D).

All three also keep the full 3-D centroid, for reporting; eigen-decompositions are computed
lazily, once per change, when the normal or sigma is asked for.

Speed: the estimator calls this once or twice per ToF point, so the state is plain Python
floats (numpy's per-call overhead on 3-vectors costs more than the arithmetic) and the
``*3`` methods (:meth:`PlaneFit.add3`, :meth:`PlaneFit.fit3`, ...) take and return floats. The
numpy-facing properties (:attr:`PlaneFit.normal`, :attr:`PlaneFit.centroid`, ...) wrap them and
give the same numbers. The scatter is formed with the same floating-point operations as the
numpy expression ``V - outer(m, m) / n`` and decomposed by the same LAPACK routine that
``numpy.linalg.eigh`` calls, so the fits are bit-for-bit those of a plain numpy implementation.
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod

import numpy as np

__all__ = ["HorizontalPlane", "PlaneFit", "RtlsPlane", "VerticalPlane", "make_plane"]

_NAN = float("nan")


def _eigh_function():
    """``numpy.linalg.eigh`` without its Python-side checks (the gufunc it calls), if available.

    For a real float64 matrix ``numpy.linalg.eigh(A)`` is ``_umath_linalg.eigh_lo(A)`` plus input
    validation that costs more than the 3x3 decomposition; the results are identical.
    """
    try:
        from numpy.linalg import _umath_linalg

        fn = _umath_linalg.eigh_lo
        w, U = fn(np.eye(2))
        if w.shape == (2,) and U.shape == (2, 2):
            return fn
    except (ImportError, AttributeError, TypeError, ValueError):  # pragma: no cover - other numpy
        pass
    return np.linalg.eigh  # pragma: no cover


_eigh = _eigh_function()


class PlaneFit(ABC):
    """Common recursion: count, reference point, first and second moments of ``p - c``.

    Subclasses choose which coordinates enter the scatter (``_dims``), update the second moments
    (``_moments``) and read the normal from them (``_solve``).
    """

    _dims: tuple[int, ...] = (0, 1, 2)

    def __init__(self) -> None:
        self.n = 0
        self.version = 0  # incremented by every add and remove, so read-outs can be cached
        self._rx = self._ry = self._rz = 0.0  # reference point c
        self._sx = self._sy = self._sz = 0.0  # sum of (p - c)
        self._clear_moments()
        self._cache: tuple[float, float, float, float] | None = None  # nx, ny, nz, sigma

    # --- subclass hooks ---
    @abstractmethod
    def _clear_moments(self) -> None:
        """Subclass hook (see the class docstring)."""

    @abstractmethod
    def _moments(self, dx: float, dy: float, dz: float, sign: float) -> None:
        """Subclass hook (see the class docstring)."""

    @abstractmethod
    def _solve(self) -> tuple[float, float, float, float]:
        """Subclass hook (see the class docstring)."""

    @abstractmethod
    def scatter(self) -> np.ndarray:
        """``M_p^T M_p = V - n e e^T`` (eq. 11) over the fitted coordinates, reference-shifted."""

    # --- recursions (eq. 15-18) ---
    def add3(self, x: float, y: float, z: float) -> None:
        """AddToSurf on a point given as floats (see :meth:`add`)."""
        if self.n == 0:
            self._rx, self._ry, self._rz = x, y, z
            self._sx = self._sy = self._sz = 0.0
            self._clear_moments()
        dx, dy, dz = x - self._rx, y - self._ry, z - self._rz
        self._moments(dx, dy, dz, 1.0)
        self._sx += dx
        self._sy += dy
        self._sz += dz
        self.n += 1
        self.version += 1
        self._cache = None

    def remove3(self, x: float, y: float, z: float) -> None:
        """RemoveFromSurf on a point given as floats (see :meth:`remove`)."""
        if self.n <= 0:
            raise ValueError("cannot remove a point from an empty plane")
        self._cache = None
        self.version += 1
        if self.n == 1:
            self.n = 0
            self._sx = self._sy = self._sz = 0.0
            self._clear_moments()
            return
        dx, dy, dz = x - self._rx, y - self._ry, z - self._rz
        self._moments(dx, dy, dz, -1.0)
        self._sx -= dx
        self._sy -= dy
        self._sz -= dz
        self.n -= 1

    def add(self, p: np.ndarray) -> None:
        """AddToSurf: ``V <- V + p p^T`` (15), ``e <- (n e + p) / (n + 1)`` (16)."""
        x, y, z = p
        self.add3(float(x), float(y), float(z))

    def remove(self, p: np.ndarray) -> None:
        """RemoveFromSurf: ``V <- V - p p^T`` (17), ``e <- (n e - p) / (n - 1)`` (18).

        The caller must only remove points it added; removing the last point empties the plane.
        """
        x, y, z = p
        self.remove3(float(x), float(y), float(z))

    # --- read-out ---
    def centroid3(self) -> tuple[float, float, float]:
        """Centroid ``e`` as floats; NaN when empty."""
        n = self.n
        if n == 0:
            return _NAN, _NAN, _NAN
        return self._rx + self._sx / n, self._ry + self._sy / n, self._rz + self._sz / n

    def centroid_z(self) -> float:
        """Height of the centroid, NaN when empty."""
        return self._rz + self._sz / self.n if self.n else _NAN

    def fit3(self) -> tuple[float, float, float, float]:
        """``(n_x, n_y, n_z, sigma_n)`` as floats (cached until the next change); NaN when empty."""
        if self.n == 0:
            return _NAN, _NAN, _NAN, _NAN
        c = self._cache
        if c is None:
            c = self._cache = self._solve()
        return c

    def distance3(self, x: float, y: float, z: float) -> float:
        """Signed distance of a point given as floats (see :meth:`distance`)."""
        n = self.n
        if n == 0:
            return _NAN
        nx, ny, nz, _ = self.fit3()
        ex, ey, ez = self._rx + self._sx / n, self._ry + self._sy / n, self._rz + self._sz / n
        return (x - ex) * nx + (y - ey) * ny + (z - ez) * nz

    @property
    def centroid(self) -> np.ndarray:
        """Centroid ``e`` (3,), NaN when empty."""
        return np.array(self.centroid3())

    @property
    def normal(self) -> np.ndarray:
        """Unit normal (3,); NaN when empty. Undetermined (but finite) below 3 points."""
        return np.array(self.fit3()[:3])

    @property
    def sigma_m(self) -> float:
        """Standard deviation of the point-to-plane distances, ``sqrt(lambda_min / n)``."""
        return self.fit3()[3]

    def distance(self, p: np.ndarray) -> float:
        """Signed distance of ``p`` to the plane (along :attr:`normal`), m."""
        x, y, z = p
        return self.distance3(float(x), float(y), float(z))


class RtlsPlane(PlaneFit):
    """General plane: normal = eigenvector of the smallest eigenvalue of the 3x3 scatter."""

    _dims = (0, 1, 2)

    def _clear_moments(self) -> None:
        self._vxx = self._vxy = self._vxz = self._vyy = self._vyz = self._vzz = 0.0

    def _moments(self, dx: float, dy: float, dz: float, sign: float) -> None:
        if sign > 0.0:
            self._vxx += dx * dx
            self._vxy += dx * dy
            self._vxz += dx * dz
            self._vyy += dy * dy
            self._vyz += dy * dz
            self._vzz += dz * dz
        else:
            self._vxx -= dx * dx
            self._vxy -= dx * dy
            self._vxz -= dx * dz
            self._vyy -= dy * dy
            self._vyz -= dy * dz
            self._vzz -= dz * dz

    def add3(self, x: float, y: float, z: float) -> None:
        # the base recursion with the moments written out: this is the estimator's hot path
        if self.n == 0:
            self._rx, self._ry, self._rz = x, y, z
            self._sx = self._sy = self._sz = 0.0
            self._clear_moments()
        dx, dy, dz = x - self._rx, y - self._ry, z - self._rz
        self._vxx += dx * dx
        self._vxy += dx * dy
        self._vxz += dx * dz
        self._vyy += dy * dy
        self._vyz += dy * dz
        self._vzz += dz * dz
        self._sx += dx
        self._sy += dy
        self._sz += dz
        self.n += 1
        self.version += 1
        self._cache = None

    def _scatter_rows(self) -> list[list[float]]:
        n = max(self.n, 1)
        sx, sy, sz = self._sx, self._sy, self._sz
        # the operations of V - outer(m, m) / n, element by element
        xy = self._vxy - sx * sy / n
        xz = self._vxz - sx * sz / n
        yz = self._vyz - sy * sz / n
        return [[self._vxx - sx * sx / n, xy, xz], [xy, self._vyy - sy * sy / n, yz], [xz, yz, self._vzz - sz * sz / n]]

    def scatter(self) -> np.ndarray:
        return np.array(self._scatter_rows())

    def _solve(self) -> tuple[float, float, float, float]:
        w, U = _eigh(np.array(self._scatter_rows()))
        nx, ny, nz = U[:, 0].tolist()
        w0 = float(w[0])
        return nx, ny, nz, math.sqrt((w0 if w0 > 0.0 else 0.0) / self.n)


class HorizontalPlane(PlaneFit):
    """HTVR tread: normal fixed to +z; the fit is the mean and variance of z (1-D)."""

    _dims = (2,)

    def _clear_moments(self) -> None:
        self._vzz = 0.0

    def _moments(self, dx: float, dy: float, dz: float, sign: float) -> None:
        if sign > 0.0:
            self._vzz += dz * dz
        else:
            self._vzz -= dz * dz

    def scatter(self) -> np.ndarray:
        sz = self._sz
        return np.array([[self._vzz - sz * sz / max(self.n, 1)]])

    def _solve(self) -> tuple[float, float, float, float]:
        sz, n = self._sz, self.n
        var = (self._vzz - sz * sz / n) / n
        return 0.0, 0.0, 1.0, math.sqrt(var if var > 0.0 else 0.0)


class VerticalPlane(PlaneFit):
    """HTVR riser: normal horizontal, eigenvector of the smallest eigenvalue of the x-y scatter."""

    _dims = (0, 1)

    def _clear_moments(self) -> None:
        self._vxx = self._vxy = self._vyy = 0.0

    def _moments(self, dx: float, dy: float, dz: float, sign: float) -> None:
        if sign > 0.0:
            self._vxx += dx * dx
            self._vxy += dx * dy
            self._vyy += dy * dy
        else:
            self._vxx -= dx * dx
            self._vxy -= dx * dy
            self._vyy -= dy * dy

    def _scatter_rows(self) -> list[list[float]]:
        n = max(self.n, 1)
        sx, sy = self._sx, self._sy
        xy = self._vxy - sx * sy / n
        return [[self._vxx - sx * sx / n, xy], [xy, self._vyy - sy * sy / n]]

    def scatter(self) -> np.ndarray:
        return np.array(self._scatter_rows())

    def _solve(self) -> tuple[float, float, float, float]:
        w, U = _eigh(np.array(self._scatter_rows()))
        w0 = float(w[0])
        return float(U[0, 0]), float(U[1, 0]), 0.0, math.sqrt((w0 if w0 > 0.0 else 0.0) / self.n)


def make_plane(kind: str) -> PlaneFit:
    """A new empty plane of ``kind`` ``"general"``, ``"horizontal"`` or ``"vertical"``."""
    return {"general": RtlsPlane, "horizontal": HorizontalPlane, "vertical": VerticalPlane}[kind]()
