"""Change detection between a prior map and a new session (seeds/000 III-B.3, eq. 2-3).

Both inputs are merged clouds in the same (map) frame, as scans: each scan a cloud of points and
the sensor origin it was taken from (keyframe submaps at their optimised poses).

``kind = "octree"`` (:func:`octree_changes`), the paper's volumetric differencing after LiSTA:
each side is integrated into an OctoMap (``pyoctomap``) at 5 cm, casting free space along every
ray from the sensor origin to its point. Occupancy comes only from hits, so every occupied voxel
of either octree holds one of its points, and a voxel that holds one is occupied on its side
(OctoMap would read a thin surface's voxel free when its own rays cross it: a desk top): the
differencing visits the voxels of both sides' points and reads each octree's state there
(occupied / free / unknown)::

    O_r = occupied in O_p and free in O_c         (removed octree)
    O_a = occupied in O_c and free in O_p         (added octree)
    O~_p = O_p - O_r                              (eq. 2, change-free prior: node deletion)
    O_l = O~_p + O_c                              (eq. 3, occupied overwrites free)

A voxel occupied on one side and unknown on the other (not seen) is no change: the paper's
"overlapping region". The outputs are the occupied voxel sets and the points in them: removed
points are prior points in ``O_r``, added points current points in ``O_a``, the updated map is the
prior points outside ``O_r`` plus the current points.

``kind = "dufomap"`` (:func:`dufomap_changes`), the peer: DUFOMap (``dufomap`` package) is
built from one side's scans and labels the other side's points dynamic where they lie in space
it saw free: prior points in the current session's free space are removed, current points in
the prior's free space are added; the updated map is assembled the same way.

"Both directions" (Table II) is :func:`detect_changes` called with the sessions swapped;
:func:`update_map` runs the update session after session, each against the map so far.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, field

import numpy as np

from exobench.core.errors import ConfigError, check_int, check_range

__all__ = ["CHANGE_KINDS", "ChangeClassifier", "ChangeConfig", "ChangeResult", "DufomapConfig", "OctreeConfig", "Scan",
           "ScanSource", "change_classifier", "load_stage",
           "VoxelChanges", "detect_changes", "dufomap_changes", "octree_changes", "update_map", "updated_scans",
           "voxel_changes", "voxel_keys"]

CHANGE_KINDS = ("octree", "dufomap")


@dataclass(frozen=True)
class Scan:
    """One cloud in the map frame and the sensor origin it was seen from.

    Attributes:
        points_m: (n, 3) points, m: the map's, which the stage classifies.
        origin_m: (3,) sensor position, m.
        far_m: (k, 3) points measured beyond the map's depth cut, m: the stage integrates their
            rays (the free space in front of them, and their hits) but never classifies them, and
            they never enter the map. Without them the space a camera saw through to a far wall
            counts as unseen, and a change there is missed (docs/tracks/multisession.md).
    """

    points_m: np.ndarray
    origin_m: np.ndarray
    far_m: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))

    def __post_init__(self) -> None:
        origin = np.asarray(self.origin_m, dtype=float)
        if origin.shape != (3,) or not np.all(np.isfinite(origin)):
            raise ConfigError("scan.origin_m", origin.shape, "a finite (3,) position")
        object.__setattr__(self, "points_m", _finite_rows(self.points_m))
        object.__setattr__(self, "origin_m", origin)
        object.__setattr__(self, "far_m", _finite_rows(self.far_m))

    @property
    def rays_m(self) -> np.ndarray:
        """The end points of every ray the stage integrates: the map's points, then the far ones."""
        return np.concatenate([self.points_m, self.far_m]) if len(self.far_m) else self.points_m


def _finite_rows(points: np.ndarray) -> np.ndarray:
    pts = np.asarray(points, dtype=float).reshape(-1, 3) if np.size(points) else np.zeros((0, 3))
    return pts[np.all(np.isfinite(pts), axis=1)]


@dataclass(frozen=True)
class OctreeConfig:
    """OctoMap settings (OctoMap's sensor-model defaults, the paper's 5 cm resolution).

    Attributes:
        resolution_m: voxel edge (the paper: 5 cm).
        prob_hit / prob_miss: occupancy update of a voxel with a hit / a ray through it.
        clamping_min / clamping_max: occupancy clamping (keeps the map updatable).
        occupancy_threshold: probability above which a voxel is occupied.
        max_range_m: rays are cut here (free space beyond is not trusted; the point is dropped);
            None (the default) integrates every ray in full. The pipeline already bounds what it
            gives: its map's points by depth (4 m along the optical axis, up to 5.7 m from the
            camera at the image's edge), its far rays by the camera's range. A cut at 5 m left
            the map's own points beyond it unknown in their session's octree, never a change
            (the *Human* case's cabinet2, docs/tracks/multisession.md).
        hit_guard_voxels: a voxel is removed (added) only if no point of the other side lies
            within this many voxels of it (0: no guard). Rays grazing a floor or a wall cross
            the voxels of its surface, so OctoMap marks voxels free that the same session also
            hit; without the guard those surfaces read as changes (module docstring).
    """

    resolution_m: float = 0.05
    prob_hit: float = 0.7
    prob_miss: float = 0.4
    clamping_min: float = 0.1192
    clamping_max: float = 0.971
    occupancy_threshold: float = 0.5
    max_range_m: float | None = None
    hit_guard_voxels: int = 1

    def __post_init__(self) -> None:
        check_int("octree.hit_guard_voxels", self.hit_guard_voxels, 0, 10)
        check_range("octree.resolution_m", self.resolution_m, 0.005, 1.0)
        check_range("octree.prob_hit", self.prob_hit, 0.5, 1.0, low_open=True, high_open=True)
        check_range("octree.prob_miss", self.prob_miss, 0.0, 0.5, low_open=True, high_open=True)
        check_range("octree.clamping_min", self.clamping_min, 0.0, 0.5, low_open=True, high_open=True)
        check_range("octree.clamping_max", self.clamping_max, 0.5, 1.0, low_open=True, high_open=True)
        check_range("octree.occupancy_threshold", self.occupancy_threshold, self.clamping_min, self.clamping_max,
                    low_open=True, high_open=True)
        if self.max_range_m is not None:
            check_range("octree.max_range_m", self.max_range_m, 0.0, None, low_open=True)


@dataclass(frozen=True)
class DufomapConfig:
    """DUFOMap settings (its paper's names; its defaults are for LiDAR at 10 cm).

    Attributes:
        resolution_m: voxel edge ``v`` (5 cm as the octree stage, so both compare alike).
        inflate_hits_m: ``d_s``, free space closer than this to a hit is not trusted (absorbs
            range noise; DUFOMap's default 0.2 m for LiDAR, 0.1 m = 2 voxels for RGB-D).
        inflate_unknown: ``d_p`` (voxels), free voxels next to unknown ones are not trusted
            (DUFOMap's default 1).
        num_threads: DUFOMap's threads (0: all cores).
        hit_guard_voxels: a point is removed (added) only if no point of the other side lies
            within this many voxels (0: none). This is eq. 3's "occupied overwrites free" for a
            prior of several sessions: DUFOMap keeps a voxel free once any scan saw it free, so
            an object a later session added to the prior would read as standing in free space.
    """

    resolution_m: float = 0.05
    inflate_hits_m: float = 0.1
    inflate_unknown: int = 1
    num_threads: int = 1
    hit_guard_voxels: int = 1

    def __post_init__(self) -> None:
        check_range("dufomap.resolution_m", self.resolution_m, 0.005, 1.0)
        check_range("dufomap.inflate_hits_m", self.inflate_hits_m, 0.0, 5.0)
        check_int("dufomap.inflate_unknown", self.inflate_unknown, 0, 10)
        check_int("dufomap.num_threads", self.num_threads, 0, 256)
        check_int("dufomap.hit_guard_voxels", self.hit_guard_voxels, 0, 10)


@dataclass(frozen=True)
class ChangeConfig:
    """The change detection stage: ``kind`` picks it (one of :data:`CHANGE_KINDS`), the nested
    config of that name holds its parameters (``change.octree.resolution_m``, ...)."""

    kind: str = "octree"
    octree: OctreeConfig = field(default_factory=OctreeConfig)
    dufomap: DufomapConfig = field(default_factory=DufomapConfig)

    def __post_init__(self) -> None:
        if self.kind not in CHANGE_KINDS:
            raise ConfigError("change.kind", self.kind, " or ".join(repr(k) for k in CHANGE_KINDS))


@dataclass(frozen=True)
class VoxelChanges:
    """Occupied voxel sets (keys of :func:`voxel_keys`, (m, 3) int64, sorted) of the
    differencing (module docstring)."""

    removed: np.ndarray
    added: np.ndarray
    change_free_prior: np.ndarray
    updated: np.ndarray


@dataclass(frozen=True)
class ChangeResult:
    """Points of a change detection run (map frame, m).

    Attributes:
        removed_points: prior points where the new session saw free space.
        added_points: new points where the prior saw free space.
        updated_points: the updated map: prior points not removed, plus the new points.
        kept_prior: (n_prior,) bool, which prior points (scans concatenated in order) stay.
        voxels: the voxel sets (octree kind only; None for DUFOMap, which labels points).
    """

    removed_points: np.ndarray
    added_points: np.ndarray
    updated_points: np.ndarray
    kept_prior: np.ndarray
    voxels: VoxelChanges | None = None


def voxel_keys(points: np.ndarray, resolution_m: float) -> np.ndarray:
    """Integer voxel keys (n, 3) int64 of points on OctoMap's grid, computed as OctoMap does
    (float32 point times the double ``1 / resolution``, floored): a point on a voxel boundary
    (a box face at 0.6 m) falls in the voxel OctoMap put it in, not the one below."""
    p = np.asarray(points, dtype=float).reshape(-1, 3).astype(np.float32).astype(np.float64)
    return np.floor(p * (1.0 / resolution_m)).astype(np.int64)


_CHUNK = 1 << 14  # voxel keys looked up at a time (:func:`_own_hits_occupied`)
_BITS = 21  # voxel keys packed into one int64: +-2^20 voxels a side, +-52 km at 5 cm


def _pack(keys: np.ndarray) -> np.ndarray:
    k = np.asarray(keys, dtype=np.int64).reshape(-1, 3) + (1 << (_BITS - 1))
    if len(k) and (k.min() < 0 or k.max() >= 1 << _BITS):
        raise ConfigError("points", "beyond +-2^20 voxels of the origin", "a map within +-2^20 voxels")
    return (k[:, 0] << (2 * _BITS)) | (k[:, 1] << _BITS) | k[:, 2]


def _unpack(packed: np.ndarray) -> np.ndarray:
    mask = (1 << _BITS) - 1
    p = np.asarray(packed, dtype=np.int64)
    return np.stack([p >> (2 * _BITS), (p >> _BITS) & mask, p & mask], axis=1) - (1 << (_BITS - 1))


def _rows(keys: np.ndarray) -> np.ndarray:
    return _unpack(np.unique(_pack(keys)))


def _isin(keys: np.ndarray, table: np.ndarray) -> np.ndarray:
    return np.isin(_pack(keys), _pack(table))


def _near(keys: np.ndarray, table: np.ndarray, radius: int) -> np.ndarray:
    """Whether each voxel key lies within ``radius`` voxels (a cube) of a voxel of ``table``
    (sorted unique packed keys). The same as membership in the table dilated by the cube, without
    building it: that is 27 times the hits at a radius of one, and the hits of a prior grow with
    its sessions (each one's noise fills neighbouring voxels), so it was the merge's peak memory."""
    keys = np.asarray(keys, dtype=np.int64).reshape(-1, 3)
    out = np.zeros(len(keys), dtype=bool)
    if not len(table) or not len(keys):
        return out
    r = np.arange(-radius, radius + 1)
    for offset in np.stack(np.meshgrid(r, r, r, indexing="ij"), -1).reshape(-1, 3):
        p = _pack(keys + offset)  # the cube is symmetric: key + offset in the table
        out |= table[np.minimum(np.searchsorted(table, p), len(table) - 1)] == p
    return out


def voxel_changes(keys: np.ndarray, state_prior: np.ndarray, state_current: np.ndarray,
                  hits_prior: np.ndarray | None = None, hits_current: np.ndarray | None = None,
                  hit_guard_voxels: int = 0, sets: bool = True) -> VoxelChanges:
    """Eq. 2-3 on voxels: ``keys`` (m, 3) with each octree's state there (1 occupied, 0 free,
    -1 unknown), covering every occupied voxel of both. With ``hit_guard_voxels`` > 0 a voxel
    within that many voxels of a hit of the other side (``hits_*``, voxel keys of its points)
    is no change (:class:`OctreeConfig`). Without ``sets`` only the removed and added voxels
    are found (eq. 2-3's sets left empty): the pipeline classifies points by those two alone."""
    keys = np.asarray(keys, dtype=np.int64).reshape(-1, 3)
    sp, sc = np.asarray(state_prior), np.asarray(state_current)
    occ_p, occ_c = keys[sp == 1], keys[sc == 1]
    gone, new = (sp == 1) & (sc == 0), (sc == 1) & (sp == 0)
    if hit_guard_voxels > 0:
        if hits_prior is None or hits_current is None:
            raise ConfigError("voxel_changes.hits", None, "both sides' hit keys with hit_guard_voxels > 0")
        gone &= ~_near(keys, np.unique(_pack(hits_current)), hit_guard_voxels)
        new &= ~_near(keys, np.unique(_pack(hits_prior)), hit_guard_voxels)
    removed = _rows(keys[gone])
    added = _rows(keys[new])
    if not sets:
        return VoxelChanges(removed, added, np.zeros((0, 3), dtype=np.int64), np.zeros((0, 3), dtype=np.int64))
    change_free = _rows(occ_p[~_isin(occ_p, removed)])  # eq. 2: O_p - O_r
    updated = _rows(np.concatenate([change_free, occ_c]))  # eq. 3: occupied overwrites free
    return VoxelChanges(removed, added, change_free, updated)


def _octree(scans: Sequence[Scan], cfg: OctreeConfig):  # -> pyoctomap.OcTree
    import pyoctomap  # C++ extension, loaded only when the stage runs

    tree = pyoctomap.OcTree(cfg.resolution_m)
    tree.setProbHit(cfg.prob_hit)
    tree.setProbMiss(cfg.prob_miss)
    tree.setClampingThresMin(cfg.clamping_min)
    tree.setClampingThresMax(cfg.clamping_max)
    tree.setOccupancyThres(cfg.occupancy_threshold)
    max_range = -1.0 if cfg.max_range_m is None else cfg.max_range_m
    for scan in scans:
        if len(scan.rays_m):
            # discretize: one ray per end voxel, OctoMap's own batching (0.96 s against 1.28 s for
            # 307 200 points, docs/multisession.md)
            tree.insertPointCloud(scan.rays_m, scan.origin_m, max_range, discretize=True)
    return tree


def _states(tree, keys: np.ndarray, resolution_m: float) -> np.ndarray:
    return tree.getLabels((keys.astype(float) + 0.5) * resolution_m)


def _own_hits_occupied(tree, keys: np.ndarray, hits: _Hits, resolution_m: float) -> np.ndarray:
    """Each voxel's state on one side, occupied wherever that side has a hit. The map keeps every
    point, so a voxel holding one must be occupied for eq. 2-3, but OctoMap's log-odds reads it
    free when more of the side's own rays cross it than end in it: a thin surface in a 5 cm voxel
    (a 25 mm desk top, a chair's legs), crossed by the rays to what lies beyond. Such a voxel was
    never removed nor added, whatever the other day saw (the *Human* case's desk6,
    docs/tracks/multisession.md). OctoMap still decides where no hit lies: free or unknown."""
    states = np.array(_states(tree, keys, resolution_m))
    table = hits.packed
    if not len(table):
        return states
    # a chunk at a time: the keys are as many as the area's voxels, and the ten-session merge's
    # peak is the change stage's (the memory bench: 2.6 MB more, ratio 1.71, when done at once)
    for a in range(0, len(keys), _CHUNK):
        p = _pack(keys[a:a + _CHUNK])
        states[a:a + _CHUNK][table[np.minimum(np.searchsorted(table, p), len(table) - 1)] == p] = 1
    return states


class _Hits:
    """The occupied voxels (unique keys) of scans seen one at a time: as many as the area has
    voxels, however many scans (sessions) fill them."""

    def __init__(self, resolution_m: float) -> None:
        self.resolution_m = resolution_m
        self._packed = np.zeros(0, dtype=np.int64)

    def add(self, scan: Scan) -> Scan:
        self._packed = np.union1d(self._packed, _pack(voxel_keys(scan.rays_m, self.resolution_m)))
        return scan

    @property
    def keys(self) -> np.ndarray:
        return _unpack(self._packed)

    @property
    def packed(self) -> np.ndarray:
        """The keys packed, sorted and unique (:func:`_near`'s table)."""
        return self._packed


ScanSource = Callable[[], Iterable[Scan]]
"""Scans to be read one at a time, as often as asked (a prior map kept on disk)."""


def _source(scans: ScanSource | Sequence[Scan]) -> ScanSource:
    return scans if callable(scans) else (lambda: iter(scans))


class ChangeClassifier:
    """One change detection run (a prior map against the current session) as tests on points:
    :meth:`removed` on prior points, :meth:`added` on current points. Built by
    :func:`change_classifier` from the prior's scans read one at a time, so that what it holds
    (octrees or DUFOMaps, voxel sets) grows with the area mapped, not with the sessions that
    mapped it; the prior's points are then classified a scan at a time as well."""

    def __init__(self, removed: Callable[[np.ndarray], np.ndarray], added: Callable[[np.ndarray], np.ndarray],
                 voxels: VoxelChanges | None = None) -> None:
        self._removed, self._added, self.voxels = removed, added, voxels

    def removed(self, prior_points: np.ndarray) -> np.ndarray:
        """(n,) bool: which prior points the current session found removed."""
        pts = np.asarray(prior_points, dtype=float).reshape(-1, 3)
        return self._removed(pts) if len(pts) else np.zeros(0, dtype=bool)

    def added(self, current_points: np.ndarray) -> np.ndarray:
        """(n,) bool: which current points are added to the prior."""
        pts = np.asarray(current_points, dtype=float).reshape(-1, 3)
        return self._added(pts) if len(pts) else np.zeros(0, dtype=bool)


def _octree_classifier(prior: ScanSource, current: Sequence[Scan], cfg: OctreeConfig,
                       sets: bool = True) -> ChangeClassifier:
    res = cfg.resolution_m
    hits_p, hits_c = _Hits(res), _Hits(res)
    tree_p = _octree((hits_p.add(s) for s in prior()), cfg)
    tree_c = _octree((hits_c.add(s) for s in current), cfg)
    keys_p, keys_c = hits_p.keys, hits_c.keys
    keys = _rows(np.concatenate([keys_p, keys_c]))
    voxels = voxel_changes(keys, _own_hits_occupied(tree_p, keys, hits_p, res),
                           _own_hits_occupied(tree_c, keys, hits_c, res), keys_p, keys_c, cfg.hit_guard_voxels,
                           sets)
    del tree_p, tree_c
    return ChangeClassifier(lambda p: _isin(voxel_keys(p, res), voxels.removed),
                            lambda p: _isin(voxel_keys(p, res), voxels.added), voxels if sets else None)


def octree_changes(prior: Sequence[Scan], current: Sequence[Scan], config: OctreeConfig | None = None) -> ChangeResult:
    """Octree differencing of the prior map and the current session (module docstring)."""
    return _result(_octree_classifier(_source(prior), current, config or OctreeConfig()), prior, current)


def _result(clf: ChangeClassifier, prior: Sequence[Scan], current: Sequence[Scan]) -> ChangeResult:
    pts_p = np.concatenate([s.points_m for s in prior] or [np.zeros((0, 3))])
    pts_c = np.concatenate([s.points_m for s in current] or [np.zeros((0, 3))])
    gone = clf.removed(pts_p)
    return ChangeResult(pts_p[gone], pts_c[clf.added(pts_c)], np.concatenate([pts_p[~gone], pts_c]), ~gone,
                        clf.voxels)


def load_stage(kind: str) -> None:
    """Import the C++ extension of stage ``kind`` (otherwise loaded when the stage first runs):
    a caller that measures the stage's memory imports it first."""
    if kind == "octree":
        import pyoctomap  # noqa: F401
    else:
        # DUFOMap logs its settings through glog at INFO on every construction; library code
        # does not print, so glog is told to keep to errors unless the user set its level
        os.environ.setdefault("GLOG_minloglevel", "2")
        import dufomap  # noqa: F401


def _dufomap(built_from: Iterable[Scan], cfg: DufomapConfig):  # -> dufomap.dufomap
    load_stage("dufomap")
    from dufomap import dufomap  # C++ extension, loaded only when the stage runs

    dufo = dufomap(cfg.resolution_m, cfg.inflate_hits_m, cfg.inflate_unknown, num_threads=cfg.num_threads)
    for scan in built_from:
        if len(scan.rays_m):
            pose = np.eye(4)
            pose[:3, 3] = scan.origin_m
            dufo.run(scan.rays_m, pose, cloud_transform=False)
    return dufo


def _dynamic(dufo, guard: np.ndarray | None, guard_voxels: int, resolution_m: float, points: np.ndarray) -> np.ndarray:
    # the pose only places the cloud when cloud_transform is set; the points are in the map frame;
    # each point is labelled from the map alone, so a cloud may be labelled in parts
    out = dufo.segment(points, np.eye(4), cloud_transform=False).astype(bool)
    return out if guard is None else out & ~_near(voxel_keys(points, resolution_m), guard, guard_voxels)


def _dufomap_classifier(prior: ScanSource, current: Sequence[Scan], cfg: DufomapConfig) -> ChangeClassifier:
    res = cfg.resolution_m
    hits_p, hits_c = _Hits(res), _Hits(res)
    from_prior = _dufomap((hits_p.add(s) for s in prior()), cfg)
    from_current = _dufomap((hits_c.add(s) for s in current), cfg)
    g = cfg.hit_guard_voxels
    near_c = hits_c.packed if g > 0 else None
    near_p = hits_p.packed if g > 0 else None
    return ChangeClassifier(lambda p: _dynamic(from_current, near_c, g, res, p),
                            lambda p: _dynamic(from_prior, near_p, g, res, p))


def dufomap_changes(prior: Sequence[Scan], current: Sequence[Scan], config: DufomapConfig | None = None) -> ChangeResult:
    """DUFOMap as the change stage (module docstring)."""
    return _result(_dufomap_classifier(_source(prior), current, config or DufomapConfig()), prior, current)


def change_classifier(prior: ScanSource | Sequence[Scan], current: Sequence[Scan],
                      config: ChangeConfig | None = None) -> ChangeClassifier:
    """The stage ``config.kind`` as a :class:`ChangeClassifier`; ``prior`` may be a callable
    that yields its scans afresh on each call (read from disk), read once here."""
    cfg = config or ChangeConfig()
    if cfg.kind == "octree":
        # eq. 2-3's voxel sets are not built: with every hit voxel occupied on its side they are
        # as large as the area, and the ten-session merge's peak was theirs (the memory bench)
        return _octree_classifier(_source(prior), current, cfg.octree, sets=False)
    return _dufomap_classifier(_source(prior), current, cfg.dufomap)


def updated_scans(prior: Sequence[Scan], current: Sequence[Scan], result: ChangeResult) -> list[Scan]:
    """Eq. 2-3 as scans, the prior of the next session: the prior scans without their removed
    points (their rays go with them; the current session saw that space free anyway), then the
    current scans."""
    keep = np.asarray(result.kept_prior, dtype=bool)
    n = sum(len(s.points_m) for s in prior)
    if keep.shape != (n,):
        raise ConfigError("result.kept_prior", keep.shape, f"one flag per prior point ({n})")
    out, start = [], 0
    for scan in prior:
        stop = start + len(scan.points_m)
        out.append(Scan(scan.points_m[keep[start:stop]], scan.origin_m, scan.far_m))
        start = stop
    return [*out, *current]


def update_map(sessions: Sequence[Sequence[Scan]], config: ChangeConfig | None = None) -> tuple[list[Scan], list[ChangeResult]]:
    """Sessions merged in order, each against the map updated by all before it (the paper's
    incremental update): the final map's scans and one result per session after the first."""
    if not sessions:
        raise ConfigError("sessions", 0, "at least one session of scans")
    prior, results = list(sessions[0]), []
    for current in sessions[1:]:
        results.append(detect_changes(prior, current, config))
        prior = updated_scans(prior, current, results[-1])
    return prior, results


def detect_changes(prior: Sequence[Scan], current: Sequence[Scan], config: ChangeConfig | None = None) -> ChangeResult:
    """The stage ``config.kind`` on the prior map and the current session."""
    cfg = config or ChangeConfig()
    if cfg.kind == "octree":
        return octree_changes(prior, current, cfg.octree)
    return dufomap_changes(prior, current, cfg.dufomap)
