"""Loop-closure proposals between keyframes: place recognition, then PnP (seeds/000 III-B.1-2).

:class:`PlaceMatcher` reads keyframe images and depth from a :class:`KeyframeStore` when it
needs them (the features it computes go back to the store, not to memory), ranks database
keyframes by bag-of-words score, verifies the ``top_k`` by SIFT + PnP-RANSAC and keeps the one
with most inliers: one :class:`PoseEdge` per query keyframe at most. The same machinery gives
inter-session edges (accept keyframes of other sessions) and intra-session loops (accept the
query's session, ``min_index_gap`` keyframes away), as the paper uses the descriptors for both.

The PnP pose is between cameras; the edge is between bases: ``T_bp_bq = X T_cp_cq X^-1`` with
``X = T_base_cam``, and its covariance (right perturbation) becomes ``Ad_X Sigma Ad_X^T``.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, field

import gtsam
import numpy as np

from exobench.core.errors import ConfigError, check_int, check_range

from .keyframes import KeyframeId, KeyframeStore
from .merge import PoseEdge
from .place_recognition import KeyframeDatabase, OrbConfig, Vocabulary, VocabularyConfig, orb_features
from .relative_pose import PnpConfig, best_candidate, relative_pose, sift_features

__all__ = ["MatchConfig", "PlaceMatcher", "other_sessions", "same_session_apart"]


@dataclass(frozen=True)
class MatchConfig:
    """Place recognition and verification settings.

    Attributes:
        orb / vocabulary / pnp: the stages' settings.
        top_k: database candidates verified by PnP per query keyframe.
        min_score: candidates below this L1 score are not verified (0: PnP decides alone).
        min_index_gap: an intra-session loop joins keyframes at least this many apart.
    """

    orb: OrbConfig = field(default_factory=OrbConfig)
    vocabulary: VocabularyConfig = field(default_factory=VocabularyConfig)
    pnp: PnpConfig = field(default_factory=PnpConfig)
    top_k: int = 5
    min_score: float = 0.0
    min_index_gap: int = 10

    def __post_init__(self) -> None:
        check_int("match.top_k", self.top_k, 1, 100)
        check_range("match.min_score", self.min_score, 0.0, 1.0)
        check_int("match.min_index_gap", self.min_index_gap, 1, None)


def other_sessions(candidate: KeyframeId, query: KeyframeId) -> bool:
    """Acceptance rule of inter-session edges."""
    return candidate[0] != query[0]


def same_session_apart(min_gap: int) -> Callable[[KeyframeId, KeyframeId], bool]:
    """Acceptance rule of intra-session loops: same session, ``min_gap`` keyframes apart."""
    return lambda c, q: c[0] == q[0] and abs(c[1] - q[1]) >= min_gap


class PlaceMatcher:
    """Place recognition database plus PnP verification over the keyframes of a store.

    Args:
        store: the keyframes; each has ``image`` (uint8 grey or RGB) and ``depth`` (m) arrays.
        K: 3x3 camera intrinsics of the images.
        T_base_cam: 4x4 camera pose in the base frame (the vertices' frame).
        vocabulary: a trained vocabulary (:meth:`train_vocabulary`).
    """

    def __init__(self, store: KeyframeStore, K: np.ndarray, T_base_cam: np.ndarray, vocabulary: Vocabulary,
                 config: MatchConfig | None = None) -> None:
        self.store = store
        self.K = np.asarray(K, dtype=float)
        self.T_base_cam = np.asarray(T_base_cam, dtype=float)
        if self.K.shape != (3, 3) or self.T_base_cam.shape != (4, 4):
            raise ConfigError("place_matcher.K/T_base_cam", (self.K.shape, self.T_base_cam.shape), "(3, 3) and (4, 4)")
        self.vocabulary = vocabulary
        self.config = config or MatchConfig()
        self.database = KeyframeDatabase()
        self._Ad = gtsam.Pose3(self.T_base_cam).AdjointMap()

    @staticmethod
    def train_vocabulary(images: Iterable[np.ndarray], config: MatchConfig | None = None) -> Vocabulary:
        """A vocabulary trained on the ORB descriptors of the given images."""
        cfg = config or MatchConfig()
        return Vocabulary.train([orb_features(img, cfg.orb)[1] for img in images], cfg.vocabulary)

    def _orb(self, key: KeyframeId) -> np.ndarray:
        if not self.store.has(key, "orb"):
            self.store.put(key, orb=orb_features(self.store.get(key, "image"), self.config.orb)[1])
        return self.store.get(key, "orb")

    def _sift(self, key: KeyframeId) -> tuple[np.ndarray, np.ndarray]:
        if not self.store.has(key, "sift_uv"):
            uv, desc = sift_features(self.store.get(key, "image"), self.config.pnp)
            self.store.put(key, sift_uv=uv, sift_desc=desc)
        return self.store.get(key, "sift_uv"), self.store.get(key, "sift_desc")

    def add(self, keys: Iterable[KeyframeId]) -> None:
        """Add keyframes of the store to the place recognition database."""
        for key in keys:
            self.database.add(key, self.vocabulary.transform(self._orb(key)))

    def match(self, query: KeyframeId, accept: Callable[[KeyframeId, KeyframeId], bool]) -> PoseEdge | None:
        """The edge from the best verified candidate to ``query`` (``T_a_b`` = pose of the query
        base in the candidate base), or None when no candidate passes PnP."""
        cfg = self.config
        cands = self.database.query(self.vocabulary.transform(self._orb(query)), cfg.top_k, cfg.min_score,
                                    accept=lambda c: accept(c, query))
        if not cands:
            return None
        feats_q = self._sift(query)
        rels = [relative_pose(self._sift(c.key), self.store.get(c.key, "depth"), feats_q, self.K, cfg.pnp)
                for c in cands]
        best = best_candidate(rels)
        if best is None:
            return None
        rel = rels[best]
        X = self.T_base_cam
        T_bp_bq = X @ rel.T_p_q @ np.linalg.inv(X)
        return PoseEdge(cands[best].key, query, T_bp_bq, self._Ad @ rel.covariance @ self._Ad.T)

    def edges(self, queries: Sequence[KeyframeId],
              accept: Callable[[KeyframeId, KeyframeId], bool] = other_sessions) -> list[PoseEdge]:
        """One verified edge per query keyframe at most (:meth:`match`)."""
        return [e for e in (self.match(q, accept) for q in queries) if e is not None]
