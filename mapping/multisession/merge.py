"""Multi-session factor graph optimisation of LT-Exosense (seeds/000 III-B.2, eq. 1).

Each session is a keyframe pose graph (:class:`SessionGraph`): vertices ``T_s_b`` (base pose in
the session's own map frame ``s``) with a place label, odometry edges between consecutive
vertices (their relative pose, with the odometry noise of :class:`MergeConfig`) and
intra-session loop edges. Inter-session edges (:class:`PoseEdge`, from place recognition and
PnP, :mod:`.matching`) add the cost of eq. 1::

    J_inter = sum_{(b_p, b_q) in M} || ln( T^_{b_p,b_q}^-1 (T_{m,b_p}^-1 T_{m,b_q}) )^v ||^2_Sigma

which is gtsam's ``BetweenFactorPose3`` between ``b_p`` and ``b_q`` with the PnP covariance.

The first session anchors the merged map (a prior on its first vertex at its own pose, so
``m`` is session 1's frame). Sessions are grouped by the inter-session edges that join them, and
a join wants evidence (:func:`_groups`): every edge between two groups is a hypothesis of the
groups' relative transform, and the groups are joined only when at least
:attr:`MergeConfig.min_join_edges` edges agree on one (within :attr:`MergeConfig.join_tolerance_m`
and :attr:`MergeConfig.join_tolerance_deg`), the best supported pair first, until no pair has
that support. A lone edge, or edges that disagree, join nothing: place recognition with PnP
verifies views of a look-alike room as readily as of the same one, and a single such edge that
is all that ties a group to the map is outvoted by nothing (docs/multisession.md). The group
holding session 1 is optimised as one map; any session (or group) not joined to it stays its own
map in its own frame and is reported in :attr:`MergeResult.separate_sessions` (the decisions in
:attr:`MergeResult.joins`), never forced into place. Each map is optimised by
Levenberg-Marquardt with a Cauchy loss on the loop and inter-session edges (the edges a place
recogniser proposes, which may be wrong); odometry edges stay Gaussian. The Cauchy kernel is
annealed (:attr:`MergeConfig.cauchy_annealing`): LM runs with a wide kernel first, then with the
configured one.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import gtsam
import numpy as np

from exobench.core.errors import ConfigError, check_int, check_range

from .keyframes import KeyframeId

__all__ = ["GroupJoin", "MergeConfig", "MergeResult", "MergedMap", "PoseEdge", "SessionGraph", "merge_sessions"]

_MAX_KEYFRAMES = 1_000_000  # gtsam key = session * this + index


@dataclass(frozen=True)
class PoseEdge:
    """A relative-pose constraint: ``T_a_b`` is the pose of vertex ``b`` in vertex ``a``.

    Attributes:
        a / b: the two keyframes (session, index).
        T_a_b: 4x4 relative pose (base frames).
        covariance: 6x6 in gtsam's tangent order (rotation rad, translation m), or None for the
            loop noise of :class:`MergeConfig`.
    """

    a: KeyframeId
    b: KeyframeId
    T_a_b: np.ndarray
    covariance: np.ndarray | None = None


@dataclass
class SessionGraph:
    """One session's keyframe pose graph.

    Attributes:
        session: session id (>= 0).
        T_s_b: (n, 4, 4) base poses of the keyframes in the session's map frame.
        place_labels: one label per keyframe (room or corridor type; "" when none was given).
        loops: intra-session loop edges (both ends in this session).
    """

    session: int
    T_s_b: np.ndarray
    place_labels: Sequence[str] = ()
    loops: Sequence[PoseEdge] = field(default_factory=tuple)

    def __post_init__(self) -> None:
        check_int("session_graph.session", self.session, 0, None)
        self.T_s_b = np.asarray(self.T_s_b, dtype=float)
        if self.T_s_b.ndim != 3 or self.T_s_b.shape[1:] != (4, 4) or not len(self.T_s_b):
            raise ConfigError("session_graph.T_s_b", self.T_s_b.shape, "(n, 4, 4) with n >= 1")
        if len(self.T_s_b) >= _MAX_KEYFRAMES:
            raise ConfigError("session_graph.T_s_b", len(self.T_s_b), f"fewer than {_MAX_KEYFRAMES} keyframes")
        if self.place_labels and len(self.place_labels) != len(self.T_s_b):
            raise ConfigError("session_graph.place_labels", len(self.place_labels),
                              f"one label per keyframe ({len(self.T_s_b)})")
        for e in self.loops:
            if e.a[0] != self.session or e.b[0] != self.session:
                raise ConfigError("session_graph.loops", (e.a, e.b), f"edges within session {self.session}")

    def __len__(self) -> int:
        return len(self.T_s_b)


@dataclass(frozen=True)
class MergeConfig:
    """Noise, robust loss and Levenberg-Marquardt settings.

    Attributes:
        odom_sigma_rad / odom_sigma_m: odometry edge noise between consecutive keyframes (0.3 m
            or 15 degrees apart). The rotation's 0.003 rad (0.17 deg) a keyframe is 30 times the
            sessions' heading drift (0.02 deg/m) and about the odometry kind's former default
            (0.5 deg/m). At 0.01 rad a session's chain bent to whichever edge held it at one end:
            general/3's first edge, 1.9 degrees off, turned the 4 m of the session before it (up
            to 1.4 degrees, 0.17 m at its start) and bent the anchor session, whose map came out
            worse than its own odometry's (docs/tracks/multisession.md, general/3).
        loop_sigma_rad / loop_sigma_m: noise of an edge given without covariance.
        prior_sigma: noise of the anchor's prior (rad and m).
        cauchy_scale: Cauchy kernel scale ``c`` in whitened units (weight ``1 / (1 + (r/c)^2)``);
            2.0 keeps weight 0.4 for an inlier at 1 sigma in all six dimensions
            (``r = sqrt(6)``) and cuts a 10-sigma outlier to 0.007. None: Gaussian edges.
        cauchy_annealing: factors of ``cauchy_scale`` of successive LM runs, each from the last
            one's solution, ending at 1. PnP covariances are a few mm: from an initial guess
            that drift or a wrong first edge puts 0.1 m off, every true edge starts as a
            20-sigma outlier and a single Cauchy run stops there; a wide kernel first lets the
            true edges pull the graph in before the narrow one rejects the outliers
            (docs/multisession.md).
        max_iterations / relative_error_tol: Levenberg-Marquardt stopping rule.
        min_join_edges: edges agreeing on one relative transform that two groups of sessions
            need to be joined (1: any edge joins, as a union of the edges' sessions would).
        join_tolerance_m / join_tolerance_per_m: two edges agree when the transforms they imply
            map each one's vertex to within ``join_tolerance_m`` plus ``join_tolerance_per_m``
            times the distance between the two edges' vertices (the odometry drifts between
            them) of each other...
        join_tolerance_deg: ... and their rotations differ by at most this.
    """

    odom_sigma_rad: float = 0.003
    odom_sigma_m: float = 0.02
    loop_sigma_rad: float = 0.02
    loop_sigma_m: float = 0.05
    prior_sigma: float = 1e-6
    cauchy_scale: float | None = 2.0
    cauchy_annealing: tuple[float, ...] = (100.0, 10.0, 1.0)
    max_iterations: int = 100
    relative_error_tol: float = 1e-8
    min_join_edges: int = 2
    join_tolerance_m: float = 0.3
    join_tolerance_per_m: float = 0.05
    join_tolerance_deg: float = 10.0

    def __post_init__(self) -> None:
        for name in ("odom_sigma_rad", "odom_sigma_m", "loop_sigma_rad", "loop_sigma_m", "prior_sigma"):
            check_range(f"merge.{name}", getattr(self, name), 0.0, None, low_open=True)
        if self.cauchy_scale is not None:
            check_range("merge.cauchy_scale", self.cauchy_scale, 0.0, None, low_open=True)
        factors = tuple(self.cauchy_annealing)
        if not factors or any(not (isinstance(f, (int, float)) and f > 0) for f in factors) or factors[-1] != 1:
            raise ConfigError("merge.cauchy_annealing", self.cauchy_annealing, "positive factors ending with 1")
        check_int("merge.max_iterations", self.max_iterations, 1, 100_000)
        check_range("merge.relative_error_tol", self.relative_error_tol, 0.0, 1.0, low_open=True)
        check_int("merge.min_join_edges", self.min_join_edges, 1, 1000)
        check_range("merge.join_tolerance_m", self.join_tolerance_m, 0.0, 100.0)
        check_range("merge.join_tolerance_per_m", self.join_tolerance_per_m, 0.0, 10.0)
        check_range("merge.join_tolerance_deg", self.join_tolerance_deg, 0.0, 180.0)


@dataclass(frozen=True)
class MergedMap:
    """One optimised map: its anchor session's frame and the keyframe poses in it.

    Attributes:
        anchor: session whose frame is the map frame ``m``.
        sessions: the sessions of the map, in input order.
        T_m_b: base pose of each keyframe in ``m``.
        T_m_s: pose of each session's own frame in ``m`` (through its first keyframe).
        n_inter_edges: inter-session edges inside this map.
    """

    anchor: int
    sessions: tuple[int, ...]
    T_m_b: dict[tuple[int, int], np.ndarray]
    T_m_s: dict[int, np.ndarray]
    n_inter_edges: int


@dataclass(frozen=True)
class GroupJoin:
    """A decision on two groups of sessions that inter-session edges connect.

    Attributes:
        sessions_a / sessions_b: the two groups (``a`` holds the earlier session).
        n_edges: the edges between them.
        n_consistent: the most of those edges that agree on one relative transform of the groups.
        joined: whether that reached :attr:`MergeConfig.min_join_edges` (the groups became one).
    """

    sessions_a: tuple[int, ...]
    sessions_b: tuple[int, ...]
    n_edges: int
    n_consistent: int
    joined: bool


@dataclass(frozen=True)
class MergeResult:
    """The merged maps: ``maps[0]`` is anchored at the first session; ``separate_sessions`` are
    the sessions outside it (each in a map of its own or with the sessions joined to it);
    ``joins``: the groups joined, in order, then the pairs of maps left apart that edges connect."""

    maps: tuple[MergedMap, ...]
    separate_sessions: tuple[int, ...]
    joins: tuple[GroupJoin, ...] = ()


def _key(k: KeyframeId) -> int:
    return int(k[0]) * _MAX_KEYFRAMES + int(k[1])


def _noise(cov: np.ndarray | None, sig_rad: float, sig_m: float, cauchy: float | None) -> gtsam.noiseModel.Base:
    if cov is None:
        base = gtsam.noiseModel.Diagonal.Sigmas(np.array([sig_rad] * 3 + [sig_m] * 3))
    else:
        base = gtsam.noiseModel.Gaussian.Covariance(np.asarray(cov, dtype=float))
    if cauchy is None:
        return base
    return gtsam.noiseModel.Robust.Create(gtsam.noiseModel.mEstimator.Cauchy.Create(cauchy), base)


def _hypotheses(edges: list[PoseEdge], in_a: set[int], T_g_s: dict[int, np.ndarray],
                graphs: dict[int, SessionGraph]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per edge between groups A and B: the transform ``T_A_B`` it implies, and its vertices'
    positions in A and in B (each group in the frame of its first session)."""
    H, p_a, p_b = [], [], []
    for e in edges:
        x, y, T_x_y = (e.a, e.b, e.T_a_b) if e.a[0] in in_a else (e.b, e.a, np.linalg.inv(e.T_a_b))
        T_A_x = T_g_s[x[0]] @ graphs[x[0]].T_s_b[x[1]]
        T_B_y = T_g_s[y[0]] @ graphs[y[0]].T_s_b[y[1]]
        H.append(T_A_x @ np.asarray(T_x_y, dtype=float) @ np.linalg.inv(T_B_y))
        p_a.append(T_A_x[:3, 3])
        p_b.append(T_B_y[:3, 3])
    return np.array(H), np.array(p_a), np.array(p_b)


def _consensus(H: np.ndarray, p_a: np.ndarray, p_b: np.ndarray, cfg: MergeConfig) -> np.ndarray:
    """The largest set of edges agreeing with one of them (a boolean mask over the edges; the
    earliest such edge's set on a tie): edge ``j`` agrees with ``i`` when ``H_i`` and ``H_j`` map
    both edges' B vertices to within the tolerance of each other and their rotations differ by
    at most ``join_tolerance_deg``."""
    mapped = np.einsum("hij,vj->vhi", H[:, :3, :3], p_b) + H[None, :, :3, 3]  # [v, h] = H_h p_v
    own = mapped[np.arange(len(H)), np.arange(len(H))]  # H_i p_i
    at_i = np.linalg.norm(own[:, None] - mapped, axis=-1)  # [i, j] = |H_i p_i - H_j p_i|
    gap = np.maximum(at_i, at_i.T)
    spread = np.maximum(np.linalg.norm(p_a[:, None] - p_a[None], axis=-1), np.linalg.norm(p_b[:, None] - p_b[None], axis=-1))
    cos = (np.einsum("iab,jab->ij", H[:, :3, :3], H[:, :3, :3]) - 1.0) / 2.0  # trace(R_i^T R_j)
    angle = np.degrees(np.arccos(np.clip(cos, -1.0, 1.0)))
    agree = (gap <= cfg.join_tolerance_m + cfg.join_tolerance_per_m * spread) & (angle <= cfg.join_tolerance_deg)
    return agree[int(np.argmax(agree.sum(axis=1)))]


def _groups(order: list[int], graphs: dict[int, SessionGraph], edges: Sequence[PoseEdge],
            cfg: MergeConfig) -> tuple[list[list[int]], list[GroupJoin], list[PoseEdge]]:
    """Groups of sessions joined on evidence (module docstring), each in input order and listed
    by its first session; the decisions; the edges that made the joins (the consensus sets)."""
    pos = {s: i for i, s in enumerate(order)}
    root = {s: s for s in order}  # each session's group, named by its first session
    T_g_s = {s: np.eye(4) for s in order}  # each session's frame in its group's
    members = {s: [s] for s in order}
    joins: list[GroupJoin] = []
    kept: list[PoseEdge] = []
    while True:
        between: dict[tuple[int, int], list[PoseEdge]] = {}
        for e in edges:
            ra, rb = sorted((root[e.a[0]], root[e.b[0]]), key=pos.__getitem__)
            if ra != rb:
                between.setdefault((ra, rb), []).append(e)
        pairs = []
        for (ra, rb), es in between.items():
            H, p_a, p_b = _hypotheses(es, set(members[ra]), T_g_s, graphs)
            pairs.append((ra, rb, es, _consensus(H, p_a, p_b, cfg), H))
        best = max(pairs, key=lambda p: int(p[3].sum()), default=None)  # the first of the best supported
        if best is None or best[3].sum() < cfg.min_join_edges:
            joins += [GroupJoin(tuple(members[ra]), tuple(members[rb]), len(es), int(mask.sum()), False)
                      for ra, rb, es, mask, _ in pairs]  # fmt: skip
            break
        ra, rb, es, mask, H = best
        joins.append(GroupJoin(tuple(members[ra]), tuple(members[rb]), len(es), int(mask.sum()), True))
        kept += [e for e, m in zip(es, mask) if m]
        T_a_b = H[int(np.flatnonzero(mask)[0])]
        for s in members.pop(rb):
            root[s], T_g_s[s] = ra, T_a_b @ T_g_s[s]
            members[ra].append(s)
        members[ra].sort(key=pos.__getitem__)
    return [members[r] for r in sorted(members, key=pos.__getitem__)], joins, kept


def _initial_frames(group: list[int], graphs: dict[int, SessionGraph], edges: list[PoseEdge]) -> dict[int, np.ndarray]:
    """T_m_s of each session of a group, chained through the first edge that reaches it."""
    T_m_s = {group[0]: np.eye(4)}
    while len(T_m_s) < len(group):
        for e in edges:
            known_a, known_b = e.a[0] in T_m_s, e.b[0] in T_m_s
            if known_a != known_b:
                break
        else:  # _groups joined every session of the group by edges
            raise AssertionError(f"sessions {sorted(set(group) - set(T_m_s))} reached by no edge")
        if known_a:  # T_m_sb = T_m_sa T_sa_a T_a_b T_b_sb
            T_m_a = T_m_s[e.a[0]] @ graphs[e.a[0]].T_s_b[e.a[1]]
            T_m_s[e.b[0]] = T_m_a @ e.T_a_b @ np.linalg.inv(graphs[e.b[0]].T_s_b[e.b[1]])
        else:
            T_m_b = T_m_s[e.b[0]] @ graphs[e.b[0]].T_s_b[e.b[1]]
            T_m_s[e.a[0]] = T_m_b @ np.linalg.inv(e.T_a_b) @ np.linalg.inv(graphs[e.a[0]].T_s_b[e.a[1]])
    return T_m_s


def _optimise(group: list[int], graphs: dict[int, SessionGraph], edges: list[PoseEdge], chain: list[PoseEdge],
              cfg: MergeConfig) -> MergedMap:
    T_m_s = _initial_frames(group, graphs, chain)
    values = gtsam.Values()
    fixed = gtsam.NonlinearFactorGraph()  # prior and odometry: the same at every stage
    anchor = graphs[group[0]]
    fixed.add(gtsam.PriorFactorPose3(_key((anchor.session, 0)), gtsam.Pose3(anchor.T_s_b[0]),
                                     gtsam.noiseModel.Isotropic.Sigma(6, cfg.prior_sigma)))
    odom = _noise(None, cfg.odom_sigma_rad, cfg.odom_sigma_m, None)
    for s in group:
        g = graphs[s]
        for i, T in enumerate(g.T_s_b):
            values.insert(_key((s, i)), gtsam.Pose3(T_m_s[s] @ T))
            if i:
                fixed.add(gtsam.BetweenFactorPose3(_key((s, i - 1)), _key((s, i)),
                                                   gtsam.Pose3(np.linalg.inv(g.T_s_b[i - 1]) @ T), odom))
    loops = [*(loop for s in group for loop in graphs[s].loops), *edges]
    params = gtsam.LevenbergMarquardtParams()
    params.setMaxIterations(cfg.max_iterations)
    params.setRelativeErrorTol(cfg.relative_error_tol)
    scales = [None] if cfg.cauchy_scale is None else [cfg.cauchy_scale * f for f in cfg.cauchy_annealing]
    for scale in scales:
        graph = gtsam.NonlinearFactorGraph(fixed)
        for e in loops:
            graph.add(gtsam.BetweenFactorPose3(_key(e.a), _key(e.b), gtsam.Pose3(np.asarray(e.T_a_b, dtype=float)),
                                               _noise(e.covariance, cfg.loop_sigma_rad, cfg.loop_sigma_m, scale)))
        values = gtsam.LevenbergMarquardtOptimizer(graph, values, params).optimize()
    poses = {(s, i): values.atPose3(_key((s, i))).matrix() for s in group for i in range(len(graphs[s]))}
    frames = {s: poses[(s, 0)] @ np.linalg.inv(graphs[s].T_s_b[0]) for s in group}
    return MergedMap(group[0], tuple(group), poses, frames, len(edges))


def merge_sessions(sessions: Sequence[SessionGraph], inter_edges: Sequence[PoseEdge],
                   config: MergeConfig | None = None) -> MergeResult:
    """Merge session pose graphs joined by inter-session edges (module docstring); the first
    session anchors the map."""
    cfg = config or MergeConfig()
    if not sessions:
        raise ConfigError("sessions", 0, "at least one session graph")
    graphs = {g.session: g for g in sessions}
    if len(graphs) != len(sessions):
        raise ConfigError("sessions", [g.session for g in sessions], "distinct session ids")
    for e in inter_edges:
        for end in (e.a, e.b):
            if end[0] not in graphs or not 0 <= end[1] < len(graphs[end[0]]):
                raise ConfigError("inter_edges", end, "a keyframe (session, index) of the given sessions")
        if e.a[0] == e.b[0]:
            raise ConfigError("inter_edges", (e.a, e.b), "two different sessions (loops go in SessionGraph.loops)")
    groups, joins, kept = _groups([g.session for g in sessions], graphs, inter_edges, cfg)
    maps = []
    for group in groups:
        members = set(group)
        inside = [e for e in inter_edges if e.a[0] in members and e.b[0] in members]
        # the edges that made the joins first: the initial guess chains through them, not
        # through an edge the consensus did not hold (the optimiser still weighs every edge)
        made = {id(e) for e in kept}
        chain = [e for e in inside if id(e) in made] + [e for e in inside if id(e) not in made]
        maps.append(_optimise(group, graphs, inside, chain, cfg))
    return MergeResult(tuple(maps), tuple(s for m in maps[1:] for s in m.sessions), tuple(joins))
