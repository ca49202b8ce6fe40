"""The set of terrain planes, updated from each frame's detected planes by IoU with scores
(seeds/002, II-F, eq. 23).

A plane is eta = <c, n, a, s, w>: centre ``center_m``, unit normal ``normal``, area ``area_m2``,
id ``plane_id`` and score ``score``. The paper leaves the regions of eq. 23 open; here a plane's
region is its support: the set of world voxels (edge ``cell_m``) holding its points, so
IoU_ij = |cells_i ∩ cells_j| / |cells_i ∪ cells_j| (eq. 23) needs no common image or frame.
The existing plane's region is first restricted to the voxels observed in the current frame
(``observed_cells``, the valid points of the smoothed depth image I_D^s): a frame that sees part
of a large plane compares that part only.

Update rules of the paper, per frame:
1. a detected plane with IoU >= ``iou_min`` to an existing plane is merged into it and the
   existing plane's score is incremented by 1; a detected plane matching several existing planes
   merges them all into one ("merging multiple planes"): the survivor is the one with the highest
   score (then the lowest id) and its score becomes the highest score of the group + 1;
2. a detected plane with no match is added with score 1 and a new id;
3. an existing plane in the scope of I_D^s (at least ``scope_min_cells`` of its voxels, and at
   least ``scope_min_fraction`` of them, observed)
   without a matching detected plane has its score decremented by 1; out-of-scope planes keep
   their score;
4. planes whose score reaches 0 are deleted.

Geometric gate [deviation]: a pair counts as a match only if, besides the IoU, their normals
differ by at most ``match_angle_deg`` [A: 6 deg] and each centre lies within ``match_offset_m``
[A: 0.05 m] of the other plane (None disables either gate: eq. 23 alone); the voxels that a
detection incompatible with an existing plane covers do not count as that plane's seen part
(neither for its IoU nor for its scope). Regions alone match
neighbouring planes of different slope: the voxels of a ramp and of the landing it meets share
the crease, a frame sees only a strip of each, and IoU >= 0.5 on the seen part merged a
11.8 deg ramp into its landing (one "horizontal" plane 5 deg off), so the ramp vanished from
the terrain on the ramp courses.

Choices the text leaves open [A]: ``iou_min`` = 0.5 ("high IoU"), ``cell_m`` = 0.05 m,
``scope_min_cells`` = 10, ``scope_min_fraction`` = 0.3 (a plane mostly out of view, e.g. the
landing under the walker's feet while a head camera looks at the ramp beyond it, shows only a
strip at the image border that the segmentation often misses: that is not a plane gone); a score rises by 1 per frame however many detections merge into a plane;
no upper bound on the score (``max_score`` = None). Merging two planes p, q (areas a_p, a_q):
n = normalise(a_p n_p + a_q sign(n_p . n_q) n_q); the plane offset is the area-weighted mean of
n . c_p and n . c_q; the centre is the mean of the union's voxel centres moved onto that plane;
a = a_p + a_q (1 - |cells_p ∩ cells_q| / |cells_q|) (q's part not already covered); the voxels are
the union. Pure numpy.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from exobench.core import check_int, check_range

_BITS = 21
_OFFSET = 1 << (_BITS - 1)  # voxel indices in [-2^20, 2^20): +-52 km at 5 cm
_MASK = (1 << _BITS) - 1


def voxel_keys(points_m: np.ndarray, cell_m: float) -> np.ndarray:
    """Sorted unique int64 keys of the voxels (edge ``cell_m``) holding the points (N, 3)."""
    idx = np.floor(np.asarray(points_m, dtype=float).reshape(-1, 3) / cell_m).astype(np.int64) + _OFFSET
    keys = (idx[:, 0] << (2 * _BITS)) | (idx[:, 1] << _BITS) | idx[:, 2]
    return np.unique(keys)


def voxel_centers(keys: np.ndarray, cell_m: float) -> np.ndarray:
    """Centres (N, 3) of the voxels of :func:`voxel_keys`."""
    k = np.asarray(keys, dtype=np.int64)
    idx = np.column_stack([(k >> (2 * _BITS)) & _MASK, (k >> _BITS) & _MASK, k & _MASK]) - _OFFSET
    return (idx + 0.5) * cell_m


def iou(cells_a: np.ndarray, cells_b: np.ndarray) -> float:
    """Eq. 23 on two sorted unique voxel key sets; 0 when both are empty."""
    inter = np.intersect1d(cells_a, cells_b, assume_unique=True).size
    union = cells_a.size + cells_b.size - inter
    return inter / union if union else 0.0


@dataclass(frozen=True)
class DetectedPlane:
    """A plane detected in one frame (e.g. one AHC cluster): centre, unit normal, area and its
    support voxels (sorted unique keys of :func:`voxel_keys`)."""

    center_m: np.ndarray
    normal: np.ndarray
    area_m2: float
    cells: np.ndarray


@dataclass
class TrackedPlane:
    """A plane of the existing set: eta = <c, n, a, s, w> plus its support voxels."""

    plane_id: int
    center_m: np.ndarray
    normal: np.ndarray
    area_m2: float
    score: int
    cells: np.ndarray


def plane_from_points(points_m: np.ndarray, cell_m: float, toward_m: np.ndarray | None = None) -> DetectedPlane:
    """A :class:`DetectedPlane` from a cluster's points (N >= 3, world frame): centre = mean,
    normal = PCA direction of least spread (towards ``toward_m`` if given, else z >= 0), area =
    number of occupied ``cell_m`` squares in the plane's own 2-D grid times cell_m^2."""
    p = np.asarray(points_m, dtype=float).reshape(-1, 3)
    if len(p) < 3:
        raise ValueError(f"a plane needs at least 3 points, got {len(p)}")
    c = p.mean(axis=0)
    _, vecs = np.linalg.eigh(np.cov((p - c).T))
    n = vecs[:, 0]
    ref = (np.asarray(toward_m, dtype=float) - c) if toward_m is not None else np.array([0.0, 0.0, 1.0])
    if n @ ref < 0:
        n = -n
    uv = np.floor((p - c) @ vecs[:, 1:] / cell_m).astype(np.int64)
    area = len(np.unique(uv, axis=0)) * cell_m * cell_m
    return DetectedPlane(c, n, float(area), voxel_keys(p, cell_m))


@dataclass(frozen=True)
class PlaneTrackingConfig:
    """Thresholds of the update (see the module docstring for the [A] choices)."""

    cell_m: float = 0.05
    iou_min: float = 0.5
    scope_min_cells: int = 10
    scope_min_fraction: float = 0.3
    max_score: int | None = None
    match_angle_deg: float | None = 6.0
    match_offset_m: float | None = 0.05

    def __post_init__(self) -> None:
        check_range("plane_tracking.cell_m", self.cell_m, 0.0, 10.0, low_open=True)
        if self.match_angle_deg is not None:
            check_range("plane_tracking.match_angle_deg", self.match_angle_deg, 0.0, 90.0, low_open=True)
        if self.match_offset_m is not None:
            check_range("plane_tracking.match_offset_m", self.match_offset_m, 0.0, 10.0, low_open=True)
        check_range("plane_tracking.iou_min", self.iou_min, 0.0, 1.0, low_open=True)
        object.__setattr__(self, "scope_min_cells", check_int("plane_tracking.scope_min_cells", self.scope_min_cells, 1))
        check_range("plane_tracking.scope_min_fraction", self.scope_min_fraction, 0.0, 1.0)
        if self.max_score is not None:
            object.__setattr__(self, "max_score", check_int("plane_tracking.max_score", self.max_score, 1))


@dataclass
class UpdateReport:
    """What one update did: ids merged into each survivor, matched, added, decremented, deleted."""

    merged: dict[int, list[int]] = field(default_factory=dict)
    matched: list[int] = field(default_factory=list)
    added: list[int] = field(default_factory=list)
    decremented: list[int] = field(default_factory=list)
    deleted: list[int] = field(default_factory=list)


def compatible(p: TrackedPlane | DetectedPlane, q: TrackedPlane | DetectedPlane, config: PlaneTrackingConfig) -> bool:
    """The geometric gate of a match (module docstring): normals within ``match_angle_deg`` (either
    orientation) and each centre within ``match_offset_m`` of the other plane."""
    if config.match_angle_deg is not None:
        cos = abs(float(np.asarray(p.normal) @ np.asarray(q.normal)))
        if cos < np.cos(np.radians(config.match_angle_deg)):
            return False
    if config.match_offset_m is not None:
        d = np.asarray(q.center_m, dtype=float) - np.asarray(p.center_m, dtype=float)
        if abs(float(d @ p.normal)) > config.match_offset_m or abs(float(d @ q.normal)) > config.match_offset_m:
            return False
    return True


def merge_planes(p: TrackedPlane | DetectedPlane, q: TrackedPlane | DetectedPlane,
                 cell_m: float) -> tuple[np.ndarray, np.ndarray, float, np.ndarray]:
    """(centre, normal, area, cells) of q merged into p (rules in the module docstring)."""
    ap, aq = float(p.area_m2), float(q.area_m2)
    sign = 1.0 if float(p.normal @ q.normal) >= 0 else -1.0
    n = ap * p.normal + aq * sign * q.normal
    n = n / np.linalg.norm(n)
    offset = (ap * float(n @ p.center_m) + aq * float(n @ q.center_m)) / (ap + aq)
    cells = np.union1d(p.cells, q.cells)
    m = voxel_centers(cells, cell_m).mean(axis=0) if cells.size else (ap * p.center_m + aq * q.center_m) / (ap + aq)
    center = m - (float(n @ m) - offset) * n
    overlap = np.intersect1d(p.cells, q.cells, assume_unique=True).size
    area = ap + aq * (1.0 - overlap / q.cells.size) if q.cells.size else ap + aq
    return center, n, area, cells


class PlaneSet:
    """The existing plane set, updated frame by frame with :meth:`update`."""

    def __init__(self, config: PlaneTrackingConfig | None = None) -> None:
        self.config = config or PlaneTrackingConfig()
        self.planes: dict[int, TrackedPlane] = {}
        self._next_id = 0

    def add(self, plane: DetectedPlane, score: int = 1) -> int:
        """Add a plane to the set with a new id and ``score``; returns the id."""
        pid = self._next_id
        self._next_id += 1
        self.planes[pid] = TrackedPlane(pid, np.array(plane.center_m, dtype=float), np.array(plane.normal, dtype=float),
                                        float(plane.area_m2), int(score), np.asarray(plane.cells, dtype=np.int64))
        return pid

    def update(self, detected: list[DetectedPlane], observed_cells: np.ndarray | None = None) -> UpdateReport:
        """Apply eq. 23 and rules 1-4 for one frame. ``observed_cells``: voxel keys seen in this
        frame (None = every existing plane is entirely in scope)."""
        c = self.config
        report = UpdateReport()
        ids = sorted(self.planes)
        existing = [self.planes[i] for i in ids]
        if observed_cells is None:
            visible = [e.cells for e in existing]
        else:
            seen = np.union1d(np.asarray(observed_cells, dtype=np.int64), np.concatenate(
                [d.cells for d in detected] + [np.zeros(0, np.int64)]))
            visible = [np.intersect1d(e.cells, seen, assume_unique=True) for e in existing]
        comp = [[compatible(e, d, c) for d in detected] for e in existing]  # the geometric gate, once per pair
        # voxels a detection of another (incompatible) plane claims are not this plane's seen
        # part: a ramp detection reaching over the crease onto a landing that is out of view
        # neither matches nor decrements the landing
        for j in range(len(existing)):
            other = [d.cells for i, d in enumerate(detected) if not comp[j][i]]
            if other and visible[j].size:
                visible[j] = np.setdiff1d(visible[j], np.concatenate(other), assume_unique=False)
        in_scope = [v.size >= max(c.scope_min_cells, c.scope_min_fraction * e.cells.size) for v, e in zip(visible, existing)]

        # components of the graph (existing + detected, edges IoU >= iou_min): union-find
        n_e = len(existing)
        parent = list(range(n_e + len(detected)))

        def find(i: int) -> int:
            while parent[i] != i:
                parent[i] = parent[parent[i]]
                i = parent[i]
            return i

        for i, d in enumerate(detected):
            for j in range(n_e):
                if comp[j][i] and visible[j].size and iou(d.cells, visible[j]) >= c.iou_min:
                    parent[find(n_e + i)] = find(j)
        groups: dict[int, list[int]] = {}
        for k in range(n_e + len(detected)):
            groups.setdefault(find(k), []).append(k)

        for members in groups.values():
            olds = [k for k in members if k < n_e]
            news = [detected[k - n_e] for k in members if k >= n_e]
            if not olds:  # rule 2
                (d,) = news
                report.added.append(self.add(d))
                continue
            if not news:  # rule 3
                e = existing[olds[0]]
                if in_scope[olds[0]]:
                    e.score -= 1
                    report.decremented.append(e.plane_id)
                continue
            # rule 1: merge the group into its best existing plane
            olds.sort(key=lambda k: (-existing[k].score, existing[k].plane_id))
            survivor = existing[olds[0]]
            top = survivor.score
            for other in [existing[k] for k in olds[1:]] + news:
                survivor.center_m, survivor.normal, survivor.area_m2, survivor.cells = merge_planes(survivor, other, c.cell_m)
            for k in olds[1:]:
                del self.planes[existing[k].plane_id]
            survivor.score = top + 1 if c.max_score is None else min(top + 1, c.max_score)
            report.matched.append(survivor.plane_id)
            if len(olds) > 1:
                report.merged[survivor.plane_id] = [existing[k].plane_id for k in olds[1:]]

        for pid in [p for p, e in self.planes.items() if e.score <= 0]:  # rule 4
            del self.planes[pid]
            report.deleted.append(pid)
        for key in ("matched", "added", "decremented", "deleted"):
            getattr(report, key).sort()
        return report
