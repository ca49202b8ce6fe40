"""Visual place recognition of LT-Exosense (seeds/000 III-B.1): ORB bag of binary words, DBoW2 style.

- :func:`orb_features`: ORB keypoints and 256-bit descriptors of a grey image (OpenCV).
- :class:`Vocabulary`: a hierarchical vocabulary tree trained in the project on the descriptors
  of images the caller gives (branching ``k``, depth ``L``; the leaves are the words). Each node
  is split by k-means on the unpacked bits (scikit-learn) and its centroid binarised by the
  majority of its members' bits, so descriptors descend the tree by Hamming distance, as DBoW2's
  k-majority does. Word weights are DBoW2's TF-IDF: ``idf_i = ln(N / n_i)`` over the ``N``
  training images, ``n_i`` of which contain word ``i``; an image's vector holds
  ``tf_i * idf_i`` (``tf_i`` = share of its descriptors in word ``i``), L1-normalised.
- :func:`l1_score`: DBoW2's L1 score ``s(v, w) = 1 - 0.5 * |v - w|_1`` of two L1-normalised
  vectors, in [0, 1].
- :class:`KeyframeDatabase`: keyframe vectors behind an inverted index (word -> keyframes);
  :meth:`KeyframeDatabase.query` returns candidates ranked by score.
"""

from __future__ import annotations

import os
import tempfile
from collections.abc import Callable, Hashable, Sequence
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from exobench.core.errors import ConfigError, check_int, check_range

__all__ = ["BowVector", "KeyframeDatabase", "OrbConfig", "PlaceCandidate", "Vocabulary", "VocabularyConfig", "to_grey",
           "l1_score", "orb_features"]

BowVector = dict[int, float]
"""Sparse bag-of-words vector: word id -> weight (L1-normalised)."""


@dataclass(frozen=True)
class OrbConfig:
    """ORB detector settings (OpenCV's ``ORB_create``; ORB-SLAM2's values for VGA-size images).

    Attributes:
        n_features: keypoints kept per image (ORB-SLAM2: 1000 at 640x480; 500 at 424x240).
        scale_factor: pyramid scale between levels.
        n_levels: pyramid levels.
        fast_threshold: FAST corner threshold (grey levels).
        edge_threshold_px: border without keypoints (also the descriptor patch size).
    """

    n_features: int = 500
    scale_factor: float = 1.2
    n_levels: int = 8
    fast_threshold: int = 20
    edge_threshold_px: int = 31

    def __post_init__(self) -> None:
        check_int("orb.n_features", self.n_features, 10, 100_000)
        check_range("orb.scale_factor", self.scale_factor, 1.0, 2.0, low_open=True)
        check_int("orb.n_levels", self.n_levels, 1, 16)
        check_int("orb.fast_threshold", self.fast_threshold, 1, 255)
        check_int("orb.edge_threshold_px", self.edge_threshold_px, 3, 100)


def to_grey(image: np.ndarray) -> np.ndarray:
    """The uint8 grey image of a uint8 grey or RGB image (ConfigError for other dtypes)."""
    img = np.asarray(image)
    if img.ndim == 3:
        img = cv2.cvtColor(img, cv2.COLOR_RGB2GRAY)
    if img.dtype != np.uint8:
        raise ConfigError("image.dtype", str(img.dtype), "uint8 grey (H, W) or RGB (H, W, 3)")
    return img


def orb_features(image: np.ndarray, config: OrbConfig | None = None) -> tuple[np.ndarray, np.ndarray]:
    """ORB keypoints ``(N, 2)`` pixel (u, v) and descriptors ``(N, 32)`` uint8 of an image
    (uint8, grey or RGB). An image without features gives ``(0, 2)`` and ``(0, 32)``."""
    cfg = config or OrbConfig()
    orb = cv2.ORB_create(nfeatures=cfg.n_features, scaleFactor=cfg.scale_factor, nlevels=cfg.n_levels,
                         edgeThreshold=cfg.edge_threshold_px, patchSize=cfg.edge_threshold_px,
                         fastThreshold=cfg.fast_threshold)
    kps, desc = orb.detectAndCompute(to_grey(image), None)
    if desc is None or not kps:
        return np.zeros((0, 2)), np.zeros((0, 32), dtype=np.uint8)
    return np.array([k.pt for k in kps], dtype=float), desc


def _hamming(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Hamming distances ``(len(a), len(b))`` between packed binary descriptors."""
    return np.unpackbits(a[:, None, :] ^ b[None, :, :], axis=-1).sum(axis=-1, dtype=np.int32)


def _majority(bits: np.ndarray) -> np.ndarray:
    """Binary centroid of unpacked descriptors: each bit set when at least half its members set it."""
    return np.packbits(bits.mean(axis=0) >= 0.5)


@dataclass(frozen=True)
class VocabularyConfig:
    """Vocabulary tree shape.

    Attributes:
        branching: children per node, ``k`` (DBoW2's ORB vocabulary: 10).
        depth: levels below the root, ``L``; at most ``k**L`` words. DBoW2 ships k=10, L=6 (1e6
            words) trained on ~1e7 descriptors; a building of a few hundred keyframes gives
            ~1e5 descriptors, which fill k=10, L=3 (1000 words) with ~100 each.
        seed: k-means initialisation seed (the vocabulary is deterministic given its images).
    """

    branching: int = 10
    depth: int = 3
    seed: int = 0

    def __post_init__(self) -> None:
        check_int("vocabulary.branching", self.branching, 2, 64)
        check_int("vocabulary.depth", self.depth, 1, 8)
        check_int("vocabulary.seed", self.seed, 0, 2**32 - 1)


class Vocabulary:
    """A trained vocabulary tree: node centroids, children and the words' idf weights.

    Build it with :meth:`train`; :meth:`transform` maps descriptors to a :data:`BowVector`.
    """

    def __init__(self, centroids: np.ndarray, children: list[list[int]], word_of_node: dict[int, int],
                 idf: np.ndarray) -> None:
        self._centroids = centroids
        self._children = children
        self._word_of_node = word_of_node
        self.idf = idf

    @property
    def n_words(self) -> int:
        return len(self.idf)

    def save(self, path: str | os.PathLike[str]) -> Path:
        """Write the tree to ``path`` (``.npz``) atomically: a temporary sibling renamed over it."""
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        parent = np.full(len(self._children), -1, dtype=np.int64)
        for node, kids in enumerate(self._children):
            parent[kids] = node
        leaves = np.array(sorted(self._word_of_node, key=self._word_of_node.__getitem__), dtype=np.int64)
        fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".npz", dir=path.parent)
        try:
            with os.fdopen(fd, "wb") as f:
                np.savez(f, centroids=self._centroids, parent=parent, leaves=leaves, idf=self.idf)
            os.replace(tmp, path)
        except BaseException:
            Path(tmp).unlink(missing_ok=True)
            raise
        return path

    @classmethod
    def load(cls, path: str | os.PathLike[str]) -> Vocabulary:
        """A vocabulary written by :meth:`save`; ConfigError naming the file when it is missing or
        not such a file."""
        try:
            with np.load(Path(path)) as z:
                centroids, parent, leaves, idf = (z[k] for k in ("centroids", "parent", "leaves", "idf"))
        except (OSError, KeyError, ValueError) as e:
            raise ConfigError("vocabulary file", str(path), f"a vocabulary written by Vocabulary.save ({e})") from None
        children: list[list[int]] = [[] for _ in range(len(parent))]
        for node, up in enumerate(parent):  # children were numbered after their parent, in order
            if up >= 0:
                children[int(up)].append(node)
        return cls(np.asarray(centroids, dtype=np.uint8), children, {int(n): w for w, n in enumerate(leaves)},
                   np.asarray(idf, dtype=float))

    @classmethod
    def train(cls, descriptors_per_image: Sequence[np.ndarray], config: VocabularyConfig | None = None) -> Vocabulary:
        """Train on the ORB descriptors of each training image (one ``(N_i, 32)`` uint8 array
        per image; the images give the idf weights)."""
        from sklearn.cluster import KMeans  # heavy imports, needed only while training
        from threadpoolctl import threadpool_limits

        cfg = config or VocabularyConfig()
        per_image = [np.asarray(d, dtype=np.uint8).reshape(-1, 32) for d in descriptors_per_image]
        if len(per_image) < 2 or sum(len(d) for d in per_image) < cfg.branching:
            raise ConfigError("vocabulary.training_images", len(per_image),
                              f"at least 2 images with {cfg.branching} descriptors in all")
        packed = np.concatenate(per_image)
        bits = np.unpackbits(packed, axis=1)
        centroids: list[np.ndarray] = [_majority(bits)]
        children: list[list[int]] = [[]]
        leaves: list[int] = []
        stack = [(0, np.arange(len(packed)), 0)]
        while stack:
            node, members, level = stack.pop()
            uniq = np.unique(packed[members], axis=0)
            if level == cfg.depth or len(uniq) <= 1:
                leaves.append(node)
                continue
            k = min(cfg.branching, len(uniq))
            # The fits are small (tens to thousands of 256-bit points): OpenMP's start-up dominates,
            # one thread trains a 1000-word tree twice as fast as two on the 2-core machine.
            with threadpool_limits(1):
                labels = KMeans(n_clusters=k, n_init=1, random_state=cfg.seed).fit_predict(
                    bits[members].astype(np.float32))
            for c in range(k):
                sub = members[labels == c]
                if not len(sub):
                    continue
                children[node].append(len(centroids))
                centroids.append(_majority(bits[sub]))
                children.append([])
                stack.append((len(centroids) - 1, sub, level + 1))
        word_of_node = {node: w for w, node in enumerate(sorted(leaves))}
        vocab = cls(np.array(centroids, dtype=np.uint8), children, word_of_node, np.zeros(len(word_of_node)))
        n_containing = np.zeros(vocab.n_words)
        for d in per_image:
            if len(d):
                n_containing[np.unique(vocab.words(d))] += 1
        # Words no training image holds keep idf 0 (DBoW2 gives them ln(N/0) = inf never used)
        vocab.idf = np.where(n_containing > 0, np.log(len(per_image) / np.maximum(n_containing, 1)), 0.0)
        return vocab

    def words(self, descriptors: np.ndarray) -> np.ndarray:
        """Word id of each descriptor: descend from the root to the Hamming-nearest child."""
        desc = np.asarray(descriptors, dtype=np.uint8).reshape(-1, 32)
        node = np.zeros(len(desc), dtype=int)
        while True:
            active = [n for n in np.unique(node) if self._children[n]]
            if not active:
                break
            for n in active:
                sel = node == n
                kids = np.array(self._children[n])
                node[sel] = kids[np.argmin(_hamming(desc[sel], self._centroids[kids]), axis=1)]
        return np.array([self._word_of_node[n] for n in node], dtype=int)

    def transform(self, descriptors: np.ndarray) -> BowVector:
        """TF-IDF bag-of-words vector (L1-normalised) of one image's descriptors."""
        if len(descriptors) == 0:
            return {}
        ids, counts = np.unique(self.words(descriptors), return_counts=True)
        weights = counts / counts.sum() * self.idf[ids]
        total = weights.sum()
        if total <= 0:
            return {}
        return {int(i): float(w / total) for i, w in zip(ids, weights) if w > 0}


def l1_score(v: BowVector, w: BowVector) -> float:
    """DBoW2's L1 score of two L1-normalised vectors: ``1 - 0.5 * |v - w|_1`` in [0, 1].

    As DBoW2 computes it from the common words only: for L1-normalised vectors
    ``|v - w|_1 = 2 - sum_common(|v_i| + |w_i| - |v_i - w_i|)``.
    """
    common = v.keys() & w.keys()
    return 0.5 * sum(abs(v[i]) + abs(w[i]) - abs(v[i] - w[i]) for i in common)


@dataclass(frozen=True)
class PlaceCandidate:
    """A database keyframe proposed for a query: its key and L1 score."""

    key: Hashable
    score: float


class KeyframeDatabase:
    """Keyframe bag-of-words vectors with DBoW2's inverted index (word -> keyframes holding it)."""

    def __init__(self) -> None:
        self._vectors: dict[Hashable, BowVector] = {}
        self._order: dict[Hashable, int] = {}  # ties rank in insertion order, whatever the keys' hashes
        self._inverted: dict[int, list[Hashable]] = {}

    def __len__(self) -> int:
        return len(self._vectors)

    def add(self, key: Hashable, vector: BowVector) -> None:
        """Add a keyframe's vector under ``key`` (unique)."""
        if key in self._vectors:
            raise ConfigError("keyframe_database.key", key, "a key not already in the database")
        self._vectors[key] = vector
        self._order[key] = len(self._order)
        for word in vector:
            self._inverted.setdefault(word, []).append(key)

    def query(self, vector: BowVector, top_k: int = 5, min_score: float = 0.0,
              accept: Callable[[Hashable], bool] | None = None) -> list[PlaceCandidate]:
        """The ``top_k`` keyframes sharing a word with ``vector``, best L1 score first, among those
        with score >= ``min_score`` that ``accept`` (when given) admits (e.g. other sessions only)."""
        check_int("keyframe_database.top_k", top_k, 1, None)
        sharing = {k for word in vector for k in self._inverted.get(word, ())}
        scored = [PlaceCandidate(k, l1_score(vector, self._vectors[k]))
                  for k in sharing if accept is None or accept(k)]
        scored = [c for c in scored if c.score >= min_score]
        scored.sort(key=lambda c: (-c.score, self._order[c.key]))
        return scored[:top_k]
