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
from collections.abc import Iterable
from dataclasses import dataclass, field

import numpy as np

from exobench.core.errors import ConfigError, check_int, check_range

__all__ = [
    "ContextDescriptor",
    "PlaceMatch",
    "ScanContextConfig",
    "accumulate_submap",
    "best_shift",
    "level_frame",
    "polar_bins",
    "ring_key",
    "sector_key",
    "shift_similarities",
]


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
        object.__setattr__(self, "n_rings", check_int("n_rings", self.n_rings, 1, 1000))
        object.__setattr__(self, "n_sectors", check_int("n_sectors", self.n_sectors, 1, 3600))
        check_range("max_radius_m", self.max_radius_m, 0.0, None, low_open=True)
        check_range("height_offset_m", self.height_offset_m, -100.0, 100.0)
        if self.max_height_m is not None:
            check_range("max_height_m", self.max_height_m)
        _check_choice("beyond_max_radius", self.beyond_max_radius, ("clamp", "drop"))
        _check_choice("ring_key_mode", self.ring_key_mode, ("l0", "mean"))
        object.__setattr__(self, "num_candidates", check_int("num_candidates", self.num_candidates, 1, 10000))
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
        object.__setattr__(self, "min_points", check_int("min_points", self.min_points, 1, 10**9))


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
