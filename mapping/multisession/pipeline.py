"""LT-Exosense as a pipeline (seeds/000 III-A/B): the building blocks of this package chained.

Frames: a :class:`~exobench.core.frames.SessionStart` opens each session; within it the camera's
odometry (:class:`~exobench.core.frames.OdometrySample`, the camera's optical-frame pose in the
session's own odometry frame), RGB-D frames and place labels. The vertices of the pose graphs
are camera poses (``T_base_cam`` is the identity): the odometry tracks the camera itself.

Per session (``process``, online):

- a keyframe when the camera has moved ``keyframe_distance_m`` or turned
  ``keyframe_angle_deg`` since the last one (and at the session's first usable frame): its image
  and depth go to the :class:`~.keyframes.KeyframeStore` (on disk, the pipeline's own temporary
  folder), with its cloud (depth pixels every ``cloud_stride_px``, up to ``max_depth_m``, in the
  camera frame) and, with ``far_rays``, the pixels measured beyond that as far rays (for the
  change stage's free space only); in memory only its pose, stamp and the place label in force.

At the end (``finalize``, offline as the paper merges):

1. **Vocabulary** (``vocabulary``): ``session``, trained on the keyframe images of the first
   session only. The queries are the later sessions' keyframes, never seen in training; the
   database holds the earlier sessions' keyframes, which the vocabulary was made for, as a
   deployed system trains on the building it mapped first. ``other``: trained on another office
   (:mod:`.other_office`), read from ``vocabulary_file`` or, when that is empty, from the file
   the harness builds and caches before the run; nothing of the episode trains it.
2. **Place recognition**: session ``k``'s keyframes are queries against all keyframes of sessions
   before it (:class:`~.matching.PlaceMatcher`: ORB bag of words, SIFT + PnP with the depth).
   With ``use_place_labels`` a candidate of another place type than the query is not verified
   (the paper attaches place labels to vertices to restrict the search).
3. **Merge**: :func:`~.merge.merge_sessions`, session 0 anchors; a session (or group of
   sessions) that no two agreeing edges join to it stays its own map (``separate_sessions``;
   the decisions in ``stats["merge_joins"]``).
4. **Changes**: the sessions of the main map in order, each against the map updated by those
   before it (:func:`~.change.change_classifier`, ``change.kind`` octree or dufomap; eq. 2-3),
   each keyframe's far rays integrated beside its cloud but never classified or mapped.
   The map stays on disk as the paper keeps it: the current session's clouds are read from the
   store, the prior's a keyframe at a time, into octrees (or DUFOMaps) and voxel sets as large
   as the area, not as the number of sessions; in memory only a flag per point (still in the
   map or not) and the points found changed. The detected static points of each run are given
   as a mask over every session's points (``static_masks``). The outputs that grow with the
   sessions (every session's points, the merged map, the masks) are written to files of the
   store a keyframe at a time and given as read-only maps of them
   (:meth:`~.keyframes.KeyframeStore.mapped`): the scorer reads them from disk.

``merge_time_s`` is the wall time of 1-4, ``peak_memory_mb`` the peak of the allocations traced
by :mod:`tracemalloc` during them, above what was traced when they began (NumPy's and Python's;
OpenCV's and OctoMap's own heaps are not traced); the modules the merge loads are imported
before (`exobench bench multisession` measures two against ten sessions).
"""

from __future__ import annotations

import bisect
import importlib
import math
import time
import tracemalloc
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, ClassVar

import numpy as np

from exobench.core.calibration import Calibration
from exobench.core.counters import FrameCounts, StreamCounters, nan_values
from exobench.core.errors import ConfigError, check_range
from exobench.core.estimates import MultiSessionEstimate
from exobench.core.frames import Frame, OdometrySample, PlaceLabel, RgbdFrame, SessionStart
from exobench.core.limits import absurd_depth, max_depth_m, odometry_absurd
from exobench.core.pipeline import check_frame

from .change import ChangeConfig, Scan, change_classifier, load_stage
from .keyframes import KeyframeStore
from .matching import MatchConfig, PlaceMatcher
from .merge import MergeConfig, PoseEdge, SessionGraph, merge_sessions
from .other_office import other_office_vocabulary_path
from .place_recognition import Vocabulary

__all__ = ["LtExosense", "LtExosenseConfig", "LtExosenseDufomap", "LtExosenseDufomapConfig"]

VOCABULARIES = ("session", "other")
ODOM_HISTORY = 64  # odometry samples kept to pair with images (a few seconds at camera rate)


@dataclass
class LtExosenseConfig:
    """Settings of :class:`LtExosense` (module docstring).

    Attributes:
        keyframe_distance_m / keyframe_angle_deg: a new keyframe after this motion.
        cloud_stride_px: a keyframe's cloud takes every this-many pixels in both directions.
        max_depth_m: depth beyond this is left out of the clouds (the D435's useful range).
        far_rays: the change stage also integrates the rays of the depth pixels beyond
            ``max_depth_m`` (up to what the camera reports, every ``cloud_stride_px``): the free
            space in front of a far wall and its hits, never map points. Without them a place
            that a camera saw through to a wall more than ``max_depth_m`` away counts as unseen,
            and a change there is missed (docs/tracks/multisession.md, "The *Human* case's
            change recall, point by point": 75 % of its misses).
        max_odometry_age_s: an image whose nearest odometry sample is further in time is skipped.
        use_place_labels: verify only candidates of the query's place type (when both have one).
        intra_session_loops: also propose loop closures within each session (keyframes at least
            ``MatchConfig.min_index_gap`` apart, the same place recognition and PnP), as loop
            edges of its own graph (the paper's LEXIS graphs); off by default
            (docs/tracks/multisession.md, "The sessions' odometry drift").
        vocabulary: ``session`` (trained on the first session's keyframes) or ``other`` (trained
            on another office, :mod:`.other_office`).
        vocabulary_file: with ``other``, the vocabulary's ``.npz`` (empty: the harness's cached one).
        change: the change detection stage (``kind`` octree or dufomap).
    """

    keyframe_distance_m: float = 0.3
    keyframe_angle_deg: float = 15.0
    cloud_stride_px: int = 4
    max_depth_m: float = 4.0
    far_rays: bool = True
    max_odometry_age_s: float = 0.06
    use_place_labels: bool = True
    intra_session_loops: bool = False
    vocabulary: str = "session"
    vocabulary_file: str = ""
    change: ChangeConfig = field(default_factory=ChangeConfig)

    def __post_init__(self) -> None:
        check_range("keyframe_distance_m", self.keyframe_distance_m, 0.0, 100.0, low_open=True)
        check_range("keyframe_angle_deg", self.keyframe_angle_deg, 0.0, 180.0, low_open=True)
        check_range("cloud_stride_px", self.cloud_stride_px, 1, 64)
        check_range("max_depth_m", self.max_depth_m, 0.0, 100.0, low_open=True)
        check_range("max_odometry_age_s", self.max_odometry_age_s, 0.0, 10.0)
        if self.vocabulary not in VOCABULARIES:
            raise ConfigError("vocabulary", self.vocabulary, " or ".join(VOCABULARIES))

    def vocabulary_path(self) -> Path:
        """The file of the ``other`` vocabulary."""
        return Path(self.vocabulary_file) if self.vocabulary_file else other_office_vocabulary_path()


@dataclass
class _Session:
    session: int
    day: int
    stamps: list[float] = field(default_factory=list)
    poses: list[np.ndarray] = field(default_factory=list)
    labels: list[str] = field(default_factory=list)


def _finite(a: Any, shape: tuple[int, ...]) -> np.ndarray | None:
    try:
        arr = np.asarray(a, dtype=float)
    except (TypeError, ValueError):
        return None
    return arr if arr.shape == shape and np.all(np.isfinite(arr)) else None


def _angle_deg(R: np.ndarray) -> float:
    return math.degrees(math.acos(max(-1.0, min(1.0, (float(np.trace(R)) - 1.0) / 2.0))))


def depth_cloud(depth_m: np.ndarray, K: np.ndarray, stride: int, max_depth: float) -> np.ndarray:
    """Points (camera frame, m) of the valid depth pixels every ``stride`` pixels."""
    d = np.asarray(depth_m, dtype=float)[::stride, ::stride]
    v, u = np.mgrid[0 : depth_m.shape[0] : stride, 0 : depth_m.shape[1] : stride]
    ok = np.isfinite(d) & (d > 0) & (d <= max_depth)
    z = d[ok]
    x = (u[ok] - K[0, 2]) * z / K[0, 0]
    y = (v[ok] - K[1, 2]) * z / K[1, 1]
    return np.stack([x, y, z], axis=1)


class LtExosense:
    """LT-Exosense's multi-session merging with change detection (module docstring)."""

    name: ClassVar[str] = "lt-exosense"
    track: ClassVar[str] = "multisession"
    Config: ClassVar[type] = LtExosenseConfig

    def __init__(self, config: LtExosenseConfig | None = None) -> None:
        self.config = config if config is not None else self.Config()
        if not isinstance(self.config, LtExosenseConfig):
            raise ConfigError(f"{self.name}.config", type(self.config).__name__, "an LtExosenseConfig")
        self._was_reset = False
        self._store: KeyframeStore | None = None
        self._vocabulary: Vocabulary | None = None
        self._reset_state(None)

    def _reset_state(self, calibration: Calibration | None) -> None:
        if self._store is not None:
            self._store.close()
        self._store = None
        self._counters = StreamCounters.of(calibration)
        self._sessions: list[_Session] = []
        self._label = ""
        self._odom: list[tuple[float, np.ndarray]] = []
        self._K: np.ndarray | None = None
        self._stats: dict[str, Any] = {"n_images_without_odometry": 0, "n_frames_before_session": 0,
                                       "n_bad_images": 0}  # fmt: skip
        self._camera_id = ""
        self._odom_id = ""
        self._max_depth = self.config.max_depth_m
        self._sensor_max_depth = max_depth_m(None)
        self._result: MultiSessionEstimate | None = None

    def reset(self, calibration: Calibration) -> None:
        """Forget everything; find the camera and its odometry."""
        self._reset_state(calibration)
        self._was_reset = True
        if self.config.vocabulary == "other":  # refused here, before any frame, when the file is not there
            path = self.config.vocabulary_path()
            try:
                self._vocabulary = Vocabulary.load(path)
            except ConfigError:
                raise ConfigError(f"{self.name}.vocabulary_file", str(path), "a vocabulary file (.npz); empty: the one "
                                  "`exobench run` builds for vocabulary=other") from None  # fmt: skip
        self._store = KeyframeStore()
        extra = calibration.extra or {}
        cams = [m for m in calibration.mounts_of_kind("rgbd") if m.sensor_id == extra.get("camera")]
        cams = cams or list(calibration.mounts_of_kind("rgbd"))  # the calibration names the camera its odometry tracks
        if cams:
            self._camera_id = cams[0].sensor_id
            self._sensor_max_depth = max_depth_m(cams[0])
            self._max_depth = min(self.config.max_depth_m, self._sensor_max_depth)
        odom = extra.get("odometry")
        if isinstance(odom, dict):
            self._odom_id = str(odom.get("sensor_id", ""))
        elif calibration.mounts_of_kind("odometry"):
            self._odom_id = calibration.mounts_of_kind("odometry")[0].sensor_id

    # --- frames ---------------------------------------------------------------------------------
    def process(self, frame: Frame) -> MultiSessionEstimate | None:
        check_frame(self, frame, self._was_reset)
        if isinstance(frame, SessionStart):
            c = self._counters.admit(frame)
            ok = all(isinstance(v, (int, np.integer)) and v >= 0 for v in (frame.session, frame.day))
            if c is not None and c.judge(frame, not ok):
                self._counters.restart()
                self._sessions.append(_Session(int(frame.session), int(frame.day)))
                self._odom, self._label = [], ""
            return None
        if isinstance(frame, PlaceLabel):
            c = self._counters.admit(frame)
            if c is not None and c.judge(frame, not isinstance(frame.label, str)):
                self._label = frame.label
            return None
        if isinstance(frame, OdometrySample):
            c = self._counters.admit(frame, not self._odom_id or frame.sensor_id == self._odom_id)
            if c is not None:
                T = _finite(frame.T_odom_body, (4, 4))
                if c.judge(frame, T is None or odometry_absurd(frame)):
                    self._odom.append((float(frame.stamp_s), T))  # type: ignore[arg-type]
                    del self._odom[:-ODOM_HISTORY]
            return None
        if isinstance(frame, RgbdFrame):
            c = self._counters.admit(frame, not self._camera_id or frame.sensor_id == self._camera_id)
            if c is not None:
                self._on_rgbd(frame, c)
            return None
        self._counters.admit(frame, False)
        return None

    def _pose_at(self, t: float) -> np.ndarray | None:
        if not self._odom:
            return None
        stamps = [o[0] for o in self._odom]
        i = bisect.bisect_left(stamps, t)
        j = min((k for k in (i - 1, i) if 0 <= k < len(stamps)), key=lambda k: abs(stamps[k] - t))
        return self._odom[j][1] if abs(stamps[j] - t) <= self.config.max_odometry_age_s else None

    def _on_rgbd(self, frame: RgbdFrame, c: FrameCounts) -> None:
        try:
            depth = np.asarray(frame.depth_m, dtype=float)
            n_absurd = int(np.count_nonzero(absurd_depth(depth, self._sensor_max_depth)))
        except (TypeError, ValueError):
            depth, n_absurd = np.zeros(0), 0
        c.add_nan(nan_values(frame))
        c.add_absurd(n_absurd)
        K = _finite(frame.K, (3, 3))
        rgb = np.asarray(frame.rgb)
        if depth.ndim != 2 or K is None or K[0, 0] <= 0 or rgb.shape[:2] != depth.shape or rgb.dtype != np.uint8:
            self._stats["n_bad_images"] += 1
            return
        if not self._sessions:
            self._stats["n_frames_before_session"] += 1
            return
        T = self._pose_at(float(frame.stamp_s))
        if T is None:
            self._stats["n_images_without_odometry"] += 1
            return
        c.used += 1
        s = self._sessions[-1]
        if s.poses:
            rel = np.linalg.inv(s.poses[-1]) @ T
            if np.linalg.norm(rel[:3, 3]) < self.config.keyframe_distance_m and _angle_deg(rel[:3, :3]) < self.config.keyframe_angle_deg:
                return
        valid = np.isfinite(depth) & (depth > 0)
        far: dict[str, np.ndarray] = {}
        if self.config.far_rays:  # rays the map does not keep, for the change stage's free space
            beyond = np.where(valid & (depth > self._max_depth), depth, 0.0)
            far["far"] = depth_cloud(beyond, K, self.config.cloud_stride_px, self._sensor_max_depth).astype(np.float32)
        depth = np.where(valid & (depth <= self._max_depth), depth, 0.0)
        self._K = K
        assert self._store is not None
        self._store.put((s.session, len(s.poses)), image=rgb, depth=depth.astype(np.float32),
                        cloud=depth_cloud(depth, K, self.config.cloud_stride_px, self._max_depth).astype(np.float32), **far)
        s.stamps.append(float(frame.stamp_s))
        s.poses.append(T.copy())
        s.labels.append(self._label)

    # --- merging --------------------------------------------------------------------------------
    def finalize(self) -> MultiSessionEstimate:
        if self._result is None:
            # modules the merge would import: an import's memory stays traced for the rest of
            # the process and went to whichever pipeline merged first (on the quick case
            # lt-exosense's 129 MB against DUFOMap's 62, 87 MB of it scikit-learn's import)
            importlib.import_module("sklearn.cluster")
            load_stage(self.config.change.kind)
            tracing = tracemalloc.is_tracing()
            if not tracing:
                tracemalloc.start()
            tracemalloc.reset_peak()
            base = tracemalloc.get_traced_memory()[0]  # a caller's own tracing: its memory is not ours
            t0 = time.perf_counter()
            try:
                self._result = self._merge(t0)
            finally:
                peak = tracemalloc.get_traced_memory()[1] - base
                if not tracing:
                    tracemalloc.stop()
            self._result = _with(self._result, merge_time_s=time.perf_counter() - t0, peak_memory_mb=peak / 2**20)
            if self._store is not None:
                self._store.close()
        return self._result

    def _merge(self, t0: float) -> MultiSessionEstimate:
        sessions = [s for s in self._sessions if s.poses]
        stats = dict(self._stats, n_sessions=len(self._sessions), n_sessions_with_keyframes=len(sessions),
                     keyframes=[len(s.poses) for s in sessions])  # fmt: skip
        counts = self._counters.snapshot()
        if not sessions:
            return MultiSessionEstimate((), (), (), (), (), stats=stats, counts=counts)
        edges, loops = self._inter_edges(sessions, stats)
        graphs = [SessionGraph(s.session, np.stack(s.poses), s.labels, loops.get(s.session, ())) for s in sessions]
        merged = merge_sessions(graphs, edges, MergeConfig())
        map_of = {sid: i for i, m in enumerate(merged.maps) for sid in m.sessions}
        stats["merge_joins"] = [{"sessions_a": list(j.sessions_a), "sessions_b": list(j.sessions_b), "n_edges": j.n_edges,
                                 "n_consistent": j.n_consistent, "joined": j.joined} for j in merged.joins]  # fmt: skip
        stats["n_inter_edges_between_maps"] = sum(map_of[e.a[0]] != map_of[e.b[0]] for e in edges)
        T_map = tuple(np.stack([merged.maps[map_of[s.session]].T_m_b[(s.session, k)] for k in range(len(s.poses))])
                      for s in sessions)  # fmt: skip
        main = [i for i, s in enumerate(sessions) if map_of[s.session] == 0]
        ch = self._changes([sessions[i] for i in main], [T_map[i] for i in main])
        stats["time_place_recognition_s"] = stats.pop("_t_pr", float("nan"))
        stats["vocabulary_words"] = stats.get("vocabulary_words", 0)
        return MultiSessionEstimate(
            sessions=tuple(s.session for s in sessions), days=tuple(s.day for s in sessions),
            keyframe_stamps_s=tuple(np.asarray(s.stamps) for s in sessions), T_map_cam=T_map,
            map_of_session=tuple(map_of[s.session] for s in sessions), separate_sessions=tuple(merged.separate_sessions),
            inter_edges=tuple((e.a[0], e.a[1], e.b[0], e.b[1]) for e in edges), stats=stats, counts=counts, **ch,
        )  # fmt: skip

    def _changes(self, sessions: list[_Session], T_map: list[np.ndarray]) -> dict[str, Any]:
        """Change detection of each session against the map updated by those before it (eq. 2-3),
        with the map on disk: a session's clouds are read from the store when it is the current
        one, the prior's a keyframe at a time (:func:`~.change.change_classifier`); in memory
        only which of every session's points are still in the map (a flag a point) and the
        points found changed. The outputs that grow with the sessions go to files of the store
        (each run's static mask when it is found; every session's points and the merged map
        read back once, at the end, a keyframe at a time) and are given as read-only maps of
        them: the paper keeps the sessions' clouds on disk, and these are its map."""
        store = self._store
        assert store is not None
        alive: list[np.ndarray] = []  # per session, its points (keyframe after keyframe) still in the map
        sizes: list[np.ndarray] = []  # per session, the points of each keyframe
        pairs, removed, added = [], [], []

        def prior() -> Iterator[Scan]:
            for i in range(len(alive)):
                bounds = np.concatenate([[0], np.cumsum(sizes[i])])
                for k, scan in enumerate(self._scans(sessions[i], T_map[i], far=True)):
                    yield Scan(scan.points_m[alive[i][bounds[k]:bounds[k + 1]]], scan.origin_m, scan.far_m)

        for i, s in enumerate(sessions):
            current = list(self._scans(s, T_map[i], far=True))
            sizes.append(np.array([len(c.points_m) for c in current], dtype=int))
            if i:
                clf = change_classifier(prior, current, self.config.change)
                gone = []
                for j in range(i):  # the prior's points a keyframe at a time, as prior() yields them
                    bounds = np.concatenate([[0], np.cumsum(sizes[j])])
                    for k, scan in enumerate(self._scans(sessions[j], T_map[j])):
                        flags = alive[j][bounds[k]:bounds[k + 1]]
                        pts = scan.points_m[flags]
                        out = clf.removed(pts)
                        gone.append(pts[out])
                        flags[np.flatnonzero(flags)[out]] = False
                pts_c = _points(current)
                new = clf.added(pts_c)
                pairs.append((sessions[i - 1].session, s.session))
                removed.append(np.concatenate([np.zeros((0, 3)), *gone]))
                added.append(pts_c[new])
                for flags in (*alive, ~new):  # the run's static points; later sessions' padded False
                    store.append_rows(f"static_{len(pairs) - 1}", flags)
            alive.append(np.ones(int(sizes[-1].sum()), dtype=bool))
            del current
        for s, T, flags, size in zip(sessions, T_map, alive, sizes):
            bounds = np.concatenate([[0], np.cumsum(size)])
            for k, scan in enumerate(self._scans(s, T)):
                store.append_rows("every", scan.points_m)
                store.append_rows("merged", scan.points_m[flags[bounds[k]:bounds[k + 1]]])
        n = [int(z.sum()) for z in sizes]
        every = store.mapped("every", np.float64, (sum(n), 3))
        masks = tuple(store.mapped(f"static_{r}", np.bool_, (sum(n),)) for r in range(len(pairs)))
        merged = store.mapped("merged", np.float64, (sum(int(a.sum()) for a in alive), 3))
        return {"change_pairs": tuple(pairs), "removed_points": tuple(removed), "added_points": tuple(added),
                "static_masks": masks, "merged_map_points": merged,
                "map_points_no_change_detection": every, "map_points_single_session": every[sum(n) - n[-1]:]}

    def _inter_edges(self, sessions: list[_Session], stats: dict[str, Any]) -> tuple[list[PoseEdge], dict[int, list[PoseEdge]]]:
        """Inter-session edges, and with ``intra_session_loops`` each session's loop edges."""
        t0 = time.perf_counter()
        if (len(sessions) < 2 and not self.config.intra_session_loops) or self._K is None:
            return [], {}
        assert self._store is not None
        if self._vocabulary is not None:
            vocabulary = self._vocabulary
        else:
            first = [self._store.get((sessions[0].session, k), "image") for k in range(len(sessions[0].poses))]
            try:
                vocabulary = PlaceMatcher.train_vocabulary(first, MatchConfig())
            except ConfigError:  # too few keyframes or features in the first session to train on
                stats["vocabulary_error"] = "too few training descriptors"
                return [], {}
        stats["vocabulary_words"] = int(vocabulary.n_words)
        matcher = PlaceMatcher(self._store, self._K, np.eye(4), vocabulary, MatchConfig())
        labels = {(s.session, k): lab for s in sessions for k, lab in enumerate(s.labels)}
        use_labels = self.config.use_place_labels

        def accept(cand: tuple[int, int], query: tuple[int, int]) -> bool:
            if cand[0] == query[0]:
                return False
            a, b = labels.get(cand, ""), labels.get(query, "")
            return not (use_labels and a and b and a != b)

        edges: list[PoseEdge] = []
        for i, s in enumerate(sessions):
            if i:
                edges += matcher.edges([(s.session, k) for k in range(len(s.poses))], accept)
            matcher.add([(s.session, k) for k in range(len(s.poses))])
        loops: dict[int, list[PoseEdge]] = {}
        if self.config.intra_session_loops:
            gap = matcher.config.min_index_gap

            def within(cand: tuple[int, int], query: tuple[int, int]) -> bool:
                # one edge per loop: the later keyframe asks, the earlier answers
                a, b = labels.get(cand, ""), labels.get(query, "")
                return cand[0] == query[0] and query[1] - cand[1] >= gap and not (use_labels and a and b and a != b)

            for s in sessions:
                loops[s.session] = matcher.edges([(s.session, k) for k in range(len(s.poses))], within)
            stats["n_intra_loops"] = [len(loops[s.session]) for s in sessions]
        stats["_t_pr"] = time.perf_counter() - t0
        stats["n_inter_edges"] = len(edges)
        return edges, loops

    def _scans(self, s: _Session, T_map: np.ndarray, far: bool = False) -> Iterator[Scan]:
        """The session's keyframe clouds at their merged poses, read from the store one by one;
        with ``far`` their far rays too (``far_rays``), for the change stage."""
        assert self._store is not None
        for k in range(len(s.poses)):
            p = self._store.get((s.session, k), "cloud").astype(float)
            T = T_map[k]
            q = (self._store.get((s.session, k), "far").astype(float) if far and self._store.has((s.session, k), "far")
                 else np.zeros((0, 3)))  # fmt: skip
            yield Scan(p @ T[:3, :3].T + T[:3, 3], T[:3, 3].copy(), q @ T[:3, :3].T + T[:3, 3])


@dataclass
class LtExosenseDufomapConfig(LtExosenseConfig):
    """:class:`LtExosenseConfig` with DUFOMap as the default change stage."""

    change: ChangeConfig = field(default_factory=lambda: ChangeConfig(kind="dufomap"))


class LtExosenseDufomap(LtExosense):
    """:class:`LtExosense` with DUFOMap as the change stage (``change.kind = dufomap``), so that
    one run shows both stages on the same merged clouds."""

    name: ClassVar[str] = "lt-exosense-dufomap"
    Config: ClassVar[type] = LtExosenseDufomapConfig


def _points(scans: list[Scan]) -> np.ndarray:
    return np.concatenate([s.points_m for s in scans]) if scans else np.zeros((0, 3))


def _with(est: MultiSessionEstimate, **values: Any) -> MultiSessionEstimate:
    from dataclasses import replace

    return replace(est, **values)
