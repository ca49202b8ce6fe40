"""Scan Context++ place recognition (seeds/003 section 4.2.3, eq. 4.20-4.25).

A cloud, given in a gravity-aligned frame centred on the sensor (x forward, z up; a single scan
or an accumulated submap, see :func:`level_frame` and :func:`accumulate_submap`), is binned on a
polar grid of ``N_r`` rings x ``N_s`` sectors; each cell holds one number (here the maximum
height, eq. 4.22; :mod:`exobench.perception.place_recognition.gaussian_scan_context` fills it with Gaussian
statistics instead). A :class:`ContextDatabase` keeps the descriptors, indexes their ring keys
(eq. 4.23) in a ``scipy.spatial.cKDTree`` and answers a query with the candidate whose
column-shifted matrix is the most similar (eq. 4.24), accepted when the similarity exceeds the
threshold ``tau`` (eq. 4.25).

Equations to code:

- Eq. (4.20)-(4.21), :func:`polar_bins`: ``i = max(min(N_r, ceil(p_r / max_r * N_r)), 1)`` and
  the same for the azimuth over ``[0, 360)`` deg (the printed ``ceil(p_r / max_r) * N_r`` puts
  every point in the last ring; the ceiling must take the product, as in the reference code).
  Points beyond ``max_r`` are clamped into the last ring as the formula says
  (``beyond_max_radius="clamp"``); the SC++ reference code skips them (``"drop"``).
- Eq. (4.22), :class:`ScanContextPP`: ``C_ij = max z`` over the bin; an empty bin is 0. Heights
  are ``z + height_offset_m`` (the reference code's ``LIDAR_HEIGHT = 2``) so that the ground and
  everything on it are positive and a non-zero cell means an occupied bin.
- Eq. (4.23), :func:`ring_key`: ``k_i = ||C_i,:||_0``, the count of non-zero cells of ring ``i``
  (``ring_key_mode="mean"``: the row mean of the reference code). The sector key is the same
  reduction over columns.
- Eq. (4.24), :func:`shift_similarities`: ``sim(C_q, C_c^(theta)) = <C_q, C_c^(theta)> /
  (||C_q||_F ||C_c^(theta)||_F)`` for every circular column shift ``theta``; the match distance
  reported is ``1 - sim``. ``shift_search="sector_key"`` restricts the shifts to a window of
  ``search_ratio * N_s`` around the shift that best aligns the sector keys (the SC++ speed-up).
- Virtual lateral descriptors (SC++'s lateral augmentation): with ``lateral_offsets_m`` each
  stored descriptor also carries the matrices of the cloud seen from viewpoints moved by those
  offsets along y; a query is compared with all of them.
- Eq. (4.25): ``accepted = sim(C_q, C_c^(theta*)) > tau``.

Shift convention: ``yaw_shift = k`` means the query cloud is the candidate cloud rotated about
z by ``+k * 2 pi / N_s`` (``PlaceMatch.yaw_rad``, wrapped to (-pi, pi]).

Defaults: 20 rings x 60 sectors, ``max_r = 80`` m (the SC++ paper); ``num_candidates = 10`` (the
reference code). ``tau = 0.7`` and ``min_points = 10`` are not given by the text: with the
whole-matrix cosine of eq. (4.24) on positive heights unrelated places still score about 0.3-0.5
and revisits (0.3 m offset, 20 % of the points missing, noise) 0.75-0.95 in synthetic scenes;
a precision-recall evaluation should sweep ``tau`` over 0..1 as the thesis does.

The L0 ring key saturates at ``N_s`` in rings the ground covers completely, which weakens the
k-d tree pre-selection for dense ground; ``ring_key_mode="mean"`` (the reference code) does not. Indoors the thesis
removes the ceiling from submaps: set ``max_height_m`` (heights with the offset applied).

Data never makes this module raise: an empty or tiny cloud gives a descriptor with
``valid = False`` and a query with it gives ``PlaceMatch.status = "no_descriptor"``. Only invalid
configurations raise :class:`exobench.core.errors.ConfigError`.
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from collections.abc import Iterable
from dataclasses import dataclass, field

import numpy as np

from exobench.core.errors import ConfigError, check_range

__all__ = [
    "ContextDatabase",
    "ContextDescriptor",
    "PlaceMatch",
    "PlaceRecognizer",
    "ScanContextConfig",
    "ScanContextPP",
    "accumulate_submap",
    "best_shift",
    "level_frame",
    "polar_bins",
    "ring_key",
    "sector_key",
    "shift_similarities",
]


def _check_int(name: str, value: object, low: int, high: int) -> int:
    if not isinstance(value, (int, np.integer)) or isinstance(value, bool) or not low <= value <= high:
        raise ConfigError(name, value, f"an integer, {low} <= {name.rsplit('.', 1)[-1]} <= {high}")
    return int(value)


def _check_choice(name: str, value: object, choices: tuple[str, ...]) -> None:
    if value not in choices:
        raise ConfigError(name, value, f"one of {', '.join(choices)}")


@dataclass(frozen=True)
class ScanContextConfig:
    """Polar grid, key, retrieval and acceptance parameters (shared by SC++ and GSC).

    Attributes:
        n_rings: ``N_r``, radial bins.
        n_sectors: ``N_s``, azimuthal bins.
        max_radius_m: ``max_r``, m.
        height_offset_m: added to every z before binning, m (sensor height above the ground, or
            more, so that cell values are positive).
        max_height_m: points higher than this (after the offset) are removed (ceiling), m;
            None keeps all.
        beyond_max_radius: ``"clamp"`` (eq. 4.20) or ``"drop"`` (reference code).
        ring_key_mode: ``"l0"`` (eq. 4.23) or ``"mean"`` (reference code); also the sector key.
        num_candidates: ring-key nearest neighbours compared in full per query.
        tau: acceptance threshold on the similarity of eq. (4.25), 0..1.
        shift_search: ``"all"`` shifts (eq. 4.24) or ``"sector_key"`` window.
        search_ratio: half-width of the sector-key window as a fraction of ``N_s``.
        lateral_offsets_m: viewpoint offsets along y of the virtual descriptors, m.
        min_points: fewer finite points than this give no descriptor.
    """

    n_rings: int = 20
    n_sectors: int = 60
    max_radius_m: float = 80.0
    height_offset_m: float = 2.0
    max_height_m: float | None = None
    beyond_max_radius: str = "clamp"
    ring_key_mode: str = "l0"
    num_candidates: int = 10
    tau: float = 0.7
    shift_search: str = "all"
    search_ratio: float = 0.1
    lateral_offsets_m: tuple[float, ...] = ()
    min_points: int = 10

    def __post_init__(self) -> None:
        _check_int("n_rings", self.n_rings, 1, 1000)
        _check_int("n_sectors", self.n_sectors, 1, 3600)
        check_range("max_radius_m", self.max_radius_m, 0.0, None, low_open=True)
        check_range("height_offset_m", self.height_offset_m, -100.0, 100.0)
        if self.max_height_m is not None:
            check_range("max_height_m", self.max_height_m)
        _check_choice("beyond_max_radius", self.beyond_max_radius, ("clamp", "drop"))
        _check_choice("ring_key_mode", self.ring_key_mode, ("l0", "mean"))
        _check_int("num_candidates", self.num_candidates, 1, 10000)
        check_range("tau", self.tau, 0.0, 1.0)
        _check_choice("shift_search", self.shift_search, ("all", "sector_key"))
        check_range("search_ratio", self.search_ratio, 0.0, 0.5)
        try:
            offsets = tuple(float(d) for d in self.lateral_offsets_m)
        except (TypeError, ValueError):
            raise ConfigError("lateral_offsets_m", self.lateral_offsets_m, "a tuple of finite offsets in m") from None
        if not all(math.isfinite(d) for d in offsets):
            raise ConfigError("lateral_offsets_m", self.lateral_offsets_m, "a tuple of finite offsets in m")
        object.__setattr__(self, "lateral_offsets_m", offsets)
        _check_int("min_points", self.min_points, 1, 10**9)


@dataclass(frozen=True, eq=False)
class ContextDescriptor:
    """One context matrix and its keys.

    Attributes:
        matrix: ``C``, (N_r, N_s); zeros when there is no descriptor.
        ring_key: (N_r,) eq. (4.23).
        sector_key: (N_s,) the same reduction over columns.
        n_points: points binned.
        status: ``"ok"``; ``"empty"`` (no finite point); ``"too_few_points"``; ``"no_intensity"``
            (an intensity descriptor of a cloud without intensity).
        virtual: matrices of the laterally shifted viewpoints (``lateral_offsets_m``).
    """

    matrix: np.ndarray
    ring_key: np.ndarray
    sector_key: np.ndarray
    n_points: int
    status: str = "ok"
    virtual: tuple[np.ndarray, ...] = field(default=())

    @property
    def valid(self) -> bool:
        return self.status == "ok"


@dataclass(frozen=True)
class PlaceMatch:
    """Answer of a query.

    Attributes:
        index: database index of the best candidate, -1 when there is none.
        distance: ``1 - similarity`` at the best shift; NaN without a candidate.
        yaw_shift: best circular column shift ``theta*`` (see the module's convention).
        similarity: eq. (4.24) at ``theta*``.
        accepted: eq. (4.25), ``similarity > tau``.
        status: ``"match"``, ``"below_threshold"``, ``"no_descriptor"`` (the query has none),
            ``"no_candidates"`` (nothing eligible in the database).
        n_sectors: ``N_s`` of the descriptors, to convert the shift into an angle.
        n_compared: candidates compared in full.
    """

    index: int
    distance: float
    yaw_shift: int
    similarity: float
    accepted: bool
    status: str
    n_sectors: int
    n_compared: int = 0

    @property
    def yaw_rad(self) -> float:
        """The shift as an angle, rad, wrapped to (-pi, pi]."""
        a = 2.0 * math.pi * self.yaw_shift / self.n_sectors
        return a - 2.0 * math.pi if a > math.pi else a


# ------------------------------------------------------------------------- pure functions


def polar_bins(
    points_xyz: np.ndarray, n_rings: int, n_sectors: int, max_radius_m: float, beyond_max_radius: str = "clamp"
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Eq. (4.20)-(4.21) with 0-based indices: ``(ring, sector, inside)`` per point.

    ``inside`` is False for points beyond ``max_radius_m`` when ``beyond_max_radius="drop"``.
    The azimuth is ``atan2(y, x)`` in ``[0, 2 pi)``.
    """
    p = np.asarray(points_xyz, dtype=float).reshape(-1, 3)
    r = np.hypot(p[:, 0], p[:, 1])
    theta = np.mod(np.arctan2(p[:, 1], p[:, 0]), 2.0 * np.pi)
    i = np.clip(np.ceil(r / max_radius_m * n_rings), 1, n_rings).astype(np.int64) - 1
    j = np.clip(np.ceil(theta / (2.0 * np.pi) * n_sectors), 1, n_sectors).astype(np.int64) - 1
    inside = np.ones(len(p), dtype=bool) if beyond_max_radius == "clamp" else r <= max_radius_m
    return i, j, inside


def ring_key(matrix: np.ndarray, mode: str = "l0") -> np.ndarray:
    """Eq. (4.23): non-zero cells per ring (``"l0"``) or the ring mean (``"mean"``), (N_r,)."""
    C = np.asarray(matrix, dtype=float)
    return np.count_nonzero(C, axis=1).astype(float) if mode == "l0" else C.mean(axis=1)


def sector_key(matrix: np.ndarray, mode: str = "l0") -> np.ndarray:
    """The ring key's reduction over columns, (N_s,)."""
    return ring_key(np.asarray(matrix).T, mode)


def shift_similarities(C_q: np.ndarray, C_c: np.ndarray) -> np.ndarray:
    """Eq. (4.24) for every shift: ``out[t] = sim(C_q, roll(C_c, t, axis=1))``, (N_s,).

    Zero when either matrix is all zeros.
    """
    Cq = np.asarray(C_q, dtype=float)
    Cc = np.asarray(C_c, dtype=float)
    ns = Cq.shape[1]
    norm = float(np.linalg.norm(Cq) * np.linalg.norm(Cc))  # Frobenius, invariant to the roll
    if norm == 0.0:
        return np.zeros(ns)
    idx = (np.arange(ns)[None, :] - np.arange(ns)[:, None]) % ns  # [t, j] -> column of C_c
    return np.einsum("ij,itj->t", Cq, Cc[:, idx]) / norm


def best_shift(
    C_q: np.ndarray,
    C_c: np.ndarray,
    *,
    sector_keys: tuple[np.ndarray, np.ndarray] | None = None,
    search_ratio: float = 0.1,
) -> tuple[float, int]:
    """``(similarity, shift)`` at the best column shift of ``C_c`` against ``C_q``.

    With ``sector_keys = (v_q, v_c)`` only the shifts within ``search_ratio * N_s`` of the
    sector-key alignment ``argmin_s ||v_q - roll(v_c, s)||`` are searched.
    """
    sims = shift_similarities(C_q, C_c)
    ns = len(sims)
    if sector_keys is not None:
        vq, vc = (np.asarray(v, dtype=float) for v in sector_keys)
        idx = (np.arange(ns)[None, :] - np.arange(ns)[:, None]) % ns
        s0 = int(np.argmin(np.linalg.norm(vq[None, :] - vc[idx], axis=1)))
        w = max(1, int(round(search_ratio * ns)))
        window = np.arange(s0 - w, s0 + w + 1) % ns
        masked = np.full(ns, -np.inf)
        masked[window] = sims[window]
        sims = masked
    t = int(np.argmax(sims))
    return float(sims[t]), t


# --------------------------------------------------------------------------- frames, submaps


def level_frame(T_world_sensor: np.ndarray) -> np.ndarray:
    """``T_world_level``: the sensor's position with world z up and x along the sensor's heading.

    The heading is the sensor x axis projected on the horizontal plane (its z axis if x is
    vertical). Descriptors are built from points in this frame.
    """
    T = np.asarray(T_world_sensor, dtype=float)
    h = T[:3, 0].copy()
    h[2] = 0.0
    if np.linalg.norm(h) < 1e-9:
        h = T[:3, 2].copy()
        h[2] = 0.0
    h = h / np.linalg.norm(h) if np.linalg.norm(h) > 0 else np.array([1.0, 0.0, 0.0])
    z = np.array([0.0, 0.0, 1.0])
    out = np.eye(4)
    out[:3, :3] = np.column_stack([h, np.cross(z, h), z])
    out[:3, 3] = T[:3, 3]
    return out


def accumulate_submap(
    clouds: Iterable[tuple[np.ndarray, np.ndarray]], T_world_keyframe: np.ndarray
) -> np.ndarray:
    """A submap cloud in the level frame of the keyframe sensor pose, (M, 3).

    ``clouds`` yields ``(points_xyz, T_world_sensor)``: each scan in its sensor frame with the
    sensor pose of that scan. A single scan is ``accumulate_submap([(pts, T)], T)``.
    """
    T_level_world = np.linalg.inv(level_frame(T_world_keyframe))
    parts = []
    for pts, T_world_sensor in clouds:
        T = T_level_world @ np.asarray(T_world_sensor, dtype=float)
        p = np.asarray(pts, dtype=float).reshape(-1, 3)
        parts.append(p @ T[:3, :3].T + T[:3, 3])
    return np.concatenate(parts, axis=0) if parts else np.zeros((0, 3))


# ------------------------------------------------------------------------------ database


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
