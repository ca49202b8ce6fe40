"""Scan Context descriptors of clouds, and their database: describe, store, query.

:class:`PlaceRecognizer` bins a cloud (:func:`~.scan_context.polar_bins`) into a descriptor whose
cells a subclass fills (:class:`ScanContextPP`: the maximum height, eq. 4.22; Gaussian Scan
Context in :mod:`.gaussian_scan_context`); :class:`ContextDatabase` indexes the ring keys in a
k-d tree and answers a query with the best column-shifted candidate (eq. 4.23-4.25).
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod

import numpy as np

from .scan_context import (
    ContextDescriptor,
    PlaceMatch,
    ScanContextConfig,
    best_shift,
    polar_bins,
    ring_key,
    sector_key,
)

__all__ = ["ContextDatabase", "PlaceRecognizer", "ScanContextPP"]


class ContextDatabase:
    """Stored descriptors with a k-d tree on their ring keys (eq. 4.23-4.25).

    Invalid descriptors are stored too (so indices follow the caller's keyframes) but are never
    candidates.
    """

    def __init__(self, config: ScanContextConfig) -> None:
        self.config = config
        self.descriptors: list[ContextDescriptor] = []
        self._row_index: list[int] = []  # database index of each tree row
        self._row_matrix: list[np.ndarray] = []
        self._row_sector_key: list[np.ndarray] = []
        self._row_ring_key: list[np.ndarray] = []
        self._tree = None
        self._tree_rows = -1

    def __len__(self) -> int:
        return len(self.descriptors)

    def add(self, descriptor: ContextDescriptor) -> int:
        """Store a descriptor; returns its index."""
        index = len(self.descriptors)
        self.descriptors.append(descriptor)
        if descriptor.valid:
            mode = self.config.ring_key_mode
            for C in (descriptor.matrix, *descriptor.virtual):
                self._row_index.append(index)
                self._row_matrix.append(C)
                self._row_ring_key.append(ring_key(C, mode))
                self._row_sector_key.append(sector_key(C, mode))
        return index

    def _tree_for(self, n_rows: int):
        from scipy.spatial import cKDTree

        if self._tree_rows != n_rows:
            self._tree = cKDTree(np.asarray(self._row_ring_key[:n_rows]))
            self._tree_rows = n_rows
        return self._tree

    def query(self, descriptor: ContextDescriptor, exclude_recent: int = 0) -> PlaceMatch:
        """Best match of ``descriptor`` among entries ``0 .. len - 1 - exclude_recent``."""
        cfg = self.config
        ns = cfg.n_sectors
        if not descriptor.valid:
            return PlaceMatch(-1, math.nan, 0, math.nan, False, "no_descriptor", ns)
        limit = len(self.descriptors) - max(0, int(exclude_recent))
        n_rows = int(np.searchsorted(np.asarray(self._row_index, dtype=np.int64), limit, side="left"))
        if n_rows == 0:
            return PlaceMatch(-1, math.nan, 0, math.nan, False, "no_candidates", ns)
        k = min(n_rows, cfg.num_candidates * (1 + len(cfg.lateral_offsets_m)))
        _, rows = self._tree_for(n_rows).query(descriptor.ring_key, k=k)
        rows = np.atleast_1d(rows)
        best = (-math.inf, -1, 0)
        for row in rows.tolist():
            keys = (descriptor.sector_key, self._row_sector_key[row]) if cfg.shift_search == "sector_key" else None
            sim, shift = best_shift(descriptor.matrix, self._row_matrix[row], sector_keys=keys,
                                    search_ratio=cfg.search_ratio)
            if sim > best[0]:
                best = (sim, self._row_index[row], shift)
        sim, index, shift = best
        accepted = sim > cfg.tau
        status = "match" if accepted else "below_threshold"
        return PlaceMatch(index, 1.0 - sim, shift, sim, accepted, status, ns, len(rows))


# ----------------------------------------------------------------------------- recognisers


class PlaceRecognizer(ABC):
    """Common driver of context descriptors: cleaning, binning, keys, database.

    Subclasses implement :meth:`_cells`, the value of every bin from its points.
    """

    config: ScanContextConfig

    def __init__(self, config: ScanContextConfig | None = None) -> None:
        self.config = config or ScanContextConfig()
        self.database = ContextDatabase(self.config)

    # subclasses: C (N_r * N_s,) from the points p4 = (x, y, z + offset, psi) and their flat bins
    @abstractmethod
    def _cells(self, p4: np.ndarray, flat_bin: np.ndarray, n_bins: int) -> np.ndarray:
        """Descriptor cells of the points, flattened (N_r * N_s,)."""

    def _needs_intensity(self) -> bool:
        return False

    def _empty(self, status: str, n_points: int = 0) -> ContextDescriptor:
        cfg = self.config
        C = np.zeros((cfg.n_rings, cfg.n_sectors))
        return ContextDescriptor(C, np.zeros(cfg.n_rings), np.zeros(cfg.n_sectors), n_points, status)

    def _matrix(self, p4: np.ndarray) -> np.ndarray:
        cfg = self.config
        i, j, inside = polar_bins(p4[:, :3], cfg.n_rings, cfg.n_sectors, cfg.max_radius_m, cfg.beyond_max_radius)
        n_bins = cfg.n_rings * cfg.n_sectors
        cells = self._cells(p4[inside], (i * cfg.n_sectors + j)[inside], n_bins)
        return cells.reshape(cfg.n_rings, cfg.n_sectors)

    def describe(self, points_xyz: np.ndarray, intensity: np.ndarray | None = None) -> ContextDescriptor:
        """Descriptor of a cloud in a gravity-aligned sensor-centred frame (scan or submap).

        ``intensity`` (N,) bytes is optional except for the intensity descriptor.
        """
        cfg = self.config
        p = np.asarray(points_xyz, dtype=float).reshape(-1, 3)
        if intensity is None:
            if self._needs_intensity():
                return self._empty("no_intensity")
            psi = np.zeros(len(p))
        else:
            psi = np.asarray(intensity, dtype=float).reshape(-1)
            if len(psi) != len(p):
                return self._empty("no_intensity")
        ok = np.all(np.isfinite(p), axis=1) & np.isfinite(psi)
        p4 = np.column_stack([p[ok], psi[ok]])
        p4[:, 2] += cfg.height_offset_m
        if cfg.max_height_m is not None:
            p4 = p4[p4[:, 2] <= cfg.max_height_m]
        if cfg.beyond_max_radius == "drop":
            p4 = p4[np.hypot(p4[:, 0], p4[:, 1]) <= cfg.max_radius_m]
        n = len(p4)
        if n == 0:
            return self._empty("empty")
        if n < cfg.min_points:
            return self._empty("too_few_points", n)
        C = self._matrix(p4)
        virtual = []
        for d in cfg.lateral_offsets_m:
            shifted = p4.copy()
            shifted[:, 1] -= d  # the viewpoint moves by +d along y
            virtual.append(self._matrix(shifted))
        mode = cfg.ring_key_mode
        return ContextDescriptor(C, ring_key(C, mode), sector_key(C, mode), n, "ok", tuple(virtual))

    def add(self, descriptor: ContextDescriptor) -> int:
        """Store a descriptor in the database; returns its index."""
        return self.database.add(descriptor)

    def query(self, descriptor: ContextDescriptor, exclude_recent: int = 0) -> PlaceMatch:
        """Best stored match, excluding the ``exclude_recent`` most recent entries."""
        return self.database.query(descriptor, exclude_recent)

    def distance(self, a: ContextDescriptor, b: ContextDescriptor) -> tuple[float, int]:
        """``(1 - similarity, shift)`` of ``b`` against ``a`` at the best shift (NaN if invalid)."""
        if not (a.valid and b.valid):
            return math.nan, 0
        keys = (a.sector_key, b.sector_key) if self.config.shift_search == "sector_key" else None
        sim, shift = best_shift(a.matrix, b.matrix, sector_keys=keys, search_ratio=self.config.search_ratio)
        return 1.0 - sim, shift

    def __len__(self) -> int:
        return len(self.database)


class ScanContextPP(PlaceRecognizer):
    """Scan Context++: the maximum height per bin (eq. 4.22), empty bins 0."""

    name = "sc++"

    def _cells(self, p4: np.ndarray, flat_bin: np.ndarray, n_bins: int) -> np.ndarray:
        C = np.full(n_bins, -np.inf)
        np.maximum.at(C, flat_bin, p4[:, 2])
        C[~np.isfinite(C)] = 0.0
        return C
