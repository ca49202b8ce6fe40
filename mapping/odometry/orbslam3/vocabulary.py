"""An ORB vocabulary in DBoW2's text format, built from images (the ``ORBvoc.txt`` ORB-SLAM3 loads).

ORB-SLAM3 ships a vocabulary trained on real images and downloads it on first use from a host
these machines cannot reach, so exobench builds its own: ORB descriptors (OpenCV, ORB-SLAM3's
own defaults: 1000 features, scale 1.2, 8 levels) of simulated images, clustered into DBoW2's
vocabulary tree exactly as DBoW2's ``TemplatedVocabulary::create`` does for binary descriptors:

- hierarchical k-means, branching ``k`` and depth ``L``: the root's descriptors are split into
  ``k`` clusters, each cluster again, down to ``L`` levels; a cluster of one descriptor stops
  there (a leaf), as does a node with at most ``k`` descriptors, each of which becomes a child;
- clustering of binary descriptors on the Hamming distance: k-means++ seeding, each centre the
  bitwise majority of its members (DBoW2's ``FORB::meanValue``: a bit is set when at least half
  the members set it, ``>= ceil(n / 2)``), until the assignment stops changing;
- nodes numbered depth first (a node's children consecutive, then the subtree of each child),
  the order in which DBoW2 creates them and in which its text loader needs parents first;
- TF-IDF weighting: a word's weight is ``log(N / n_i)`` over the ``N`` training images, ``n_i``
  of which hold it; L1 scoring. Inner nodes weigh 0.

The text format (DBoW2's ``saveToTextFile`` / ``loadFromTextFile``, as ORB-SLAM3 reads it):
a header line ``k L scoring weighting`` (``10 5 0 0``), then one line per node after the root,
in id order: ``parent is_leaf d0 ... d31 weight`` (the 32 descriptor bytes as integers). The last
line has no newline: DBoW2's loader reads lines until end of file and would take an empty last
line for a node.

The file is cached per user under ``~/.cache/exobench/`` (``$EXOBENCH_CACHE`` overrides), named by
a hash of everything that decides its content (:func:`vocabulary_path`), and written atomically.
This module builds from images it is given; rendering them is the harness's business
(``exobench.benchmarks.orbvoc``), as mapping code never imports the simulator.
"""

from __future__ import annotations

import hashlib
import json
import math
import os
import tempfile
from collections.abc import Iterable
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

from exobench.core.errors import ConfigError, check_int, check_range

DESCRIPTOR_BYTES = 32  # ORB: 256 bits
FORMAT_VERSION = 1  # bump when the builder changes what it writes for the same parameters


@dataclass(frozen=True)
class VocabularyParams:
    """What decides a vocabulary's content (its cache name hashes these).

    Attributes:
        k: branching factor (DBoW2 / ORBvoc.txt: 10).
        levels: depth L of the tree (ORBvoc.txt: 6; here 5, see docs/orbslam3.md).
        n_features: ORB features per training image.
        scale_factor / n_levels: ORB pyramid.
        max_iters: k-means iterations per node at most.
        seed: seed of the k-means++ draws.
        images: a description of the training images (what rendered them), part of the hash.
    """

    k: int = 10
    levels: int = 5
    n_features: int = 1000
    scale_factor: float = 1.2
    n_levels: int = 8
    max_iters: int = 10
    seed: int = 0
    images: str = ""

    def __post_init__(self) -> None:
        # DBoW2's loader refuses k outside 0-20 and L outside 1-10
        object.__setattr__(self, "k", check_int("vocabulary.k", self.k, 2, 20))
        object.__setattr__(self, "levels", check_int("vocabulary.levels", self.levels, 1, 10))
        object.__setattr__(self, "n_features", check_int("vocabulary.n_features", self.n_features, 50, 10000))
        check_range("vocabulary.scale_factor", self.scale_factor, 1.0, 2.0, low_open=True)
        object.__setattr__(self, "n_levels", check_int("vocabulary.n_levels", self.n_levels, 1, 16))
        object.__setattr__(self, "max_iters", check_int("vocabulary.max_iters", self.max_iters, 1, 100))

    def digest(self) -> str:
        text = json.dumps({**asdict(self), "format": FORMAT_VERSION}, sort_keys=True)
        return hashlib.sha256(text.encode()).hexdigest()[:16]


# exobench's own vocabulary: what `exobench.benchmarks.orbvoc` renders is named by ``images``
# (change the name when that image set changes, so that a cached file of another set is not used)
DEFAULT_PARAMS = VocabularyParams(images="exobench-sim-v1: office and course walks, head/chest/thigh, textured")


def cache_dir() -> Path:
    """``$EXOBENCH_CACHE``, else ``$XDG_CACHE_HOME/exobench``, else ``~/.cache/exobench``."""
    env = os.environ.get("EXOBENCH_CACHE")
    if env:
        return Path(env)
    return Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache") / "exobench"


def vocabulary_path(params: VocabularyParams) -> Path:
    """Where the vocabulary of ``params`` is cached: ``<cache>/orbvoc-<hash>.txt``."""
    return cache_dir() / f"orbvoc-{params.digest()}.txt"


# ------------------------------------------------------------------ descriptors and distances


def orb_descriptors(gray: np.ndarray, params: VocabularyParams) -> np.ndarray:
    """ORB descriptors of one grey image, (n, 32) uint8 (OpenCV's ORB, the pattern ORB-SLAM3 uses)."""
    import cv2

    orb = cv2.ORB_create(nfeatures=params.n_features, scaleFactor=params.scale_factor, nlevels=params.n_levels,
                         edgeThreshold=19, patchSize=31, fastThreshold=7)  # fmt: skip
    _, desc = orb.detectAndCompute(np.ascontiguousarray(gray, dtype=np.uint8), None)
    return np.zeros((0, DESCRIPTOR_BYTES), np.uint8) if desc is None else desc


def hamming(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Hamming distances between rows of ``a`` (n, 32) and ``b`` (m, 32) uint8: (n, m)."""
    a64 = np.ascontiguousarray(a).view(np.uint64)
    b64 = np.ascontiguousarray(b).view(np.uint64)
    return np.bitwise_count(a64[:, None, :] ^ b64[None, :, :]).sum(axis=2, dtype=np.int32)


def majority(desc: np.ndarray) -> np.ndarray:
    """DBoW2's mean of binary descriptors: bit i set when at least ceil(n / 2) of them set it."""
    bits = np.unpackbits(desc, axis=1)
    need = (len(desc) + 1) // 2
    return np.packbits(bits.sum(axis=0) >= need)


def _seed_centres(desc: np.ndarray, k: int, rng: np.random.Generator) -> np.ndarray:
    """k-means++ (DBoW2's ``initiateClustersKMpp``): the first centre at random, each next one
    drawn with probability proportional to its distance to the nearest centre so far."""
    idx = [int(rng.integers(len(desc)))]
    d_min = hamming(desc, desc[idx[0]][None]).ravel().astype(float)
    while len(idx) < k:
        total = d_min.sum()
        if total <= 0:  # every descriptor equals a centre: fewer distinct clusters
            break
        nxt = int(np.searchsorted(np.cumsum(d_min), rng.random() * total, side="right"))
        nxt = min(nxt, len(desc) - 1)
        idx.append(nxt)
        d_min = np.minimum(d_min, hamming(desc, desc[nxt][None]).ravel())
    return desc[idx].copy()


def kmajority(desc: np.ndarray, k: int, max_iters: int, rng: np.random.Generator) -> list[np.ndarray]:
    """Split ``desc`` into at most ``k`` clusters (k-majority on Hamming); the member indices of each
    non-empty cluster, in centre order."""
    if len(desc) <= k:
        return [np.array([i]) for i in range(len(desc))]
    centres = _seed_centres(desc, k, rng)
    assign = None
    for _ in range(max_iters):
        new = np.argmin(hamming(desc, centres), axis=1)
        if assign is not None and np.array_equal(new, assign):
            break
        assign = new
        centres = np.array([majority(desc[assign == c]) if np.any(assign == c) else centres[c]
                            for c in range(len(centres))])  # fmt: skip
    return [g for g in (np.flatnonzero(assign == c) for c in range(len(centres))) if len(g)]


# ------------------------------------------------------------------ the tree


@dataclass(frozen=True)
class VocabularyTree:
    """DBoW2's tree, nodes by id (0 is the root, which has no line in the file).

    Attributes:
        k, levels: branching and depth.
        parent: (M,) parent id of each node (-1 for the root).
        is_leaf: (M,) bool.
        descriptor: (M, 32) uint8 (zeros for the root).
        weight: (M,) float, IDF of the leaves, 0 elsewhere.
    """

    k: int
    levels: int
    parent: np.ndarray
    is_leaf: np.ndarray
    descriptor: np.ndarray
    weight: np.ndarray

    @property
    def n_words(self) -> int:
        return int(self.is_leaf.sum())


def build_tree(images: Iterable[np.ndarray], params: VocabularyParams) -> VocabularyTree:
    """The vocabulary tree of the ORB descriptors of ``images`` (grey, uint8), TF-IDF weighted."""
    per_image = [orb_descriptors(img, params) for img in images]
    per_image = [d for d in per_image if len(d)]
    if not per_image:
        raise ConfigError("vocabulary images", 0, "images with ORB features")
    desc = np.concatenate(per_image)
    image_of = np.concatenate([np.full(len(d), i) for i, d in enumerate(per_image)])
    rng = np.random.default_rng(params.seed)
    parent, descriptor, members = [-1], [np.zeros(DESCRIPTOR_BYTES, np.uint8)], [np.arange(len(desc))]
    children: dict[int, list[int]] = {}

    def step(node: int, level: int) -> None:
        # DBoW2's HKmeansStep: create every child of the node, then descend into each in turn
        groups = kmajority(desc[members[node]], params.k, params.max_iters, rng)
        ids = []
        for g in groups:
            ids.append(len(parent))
            parent.append(node)
            sub = members[node][g]
            members.append(sub)
            descriptor.append(majority(desc[sub]) if len(sub) > 1 else desc[sub[0]].copy())
        children[node] = ids
        if level < params.levels:
            for i in ids:
                if len(members[i]) > 1:
                    step(i, level + 1)

    step(0, 1)
    n = len(parent)
    is_leaf = np.array([i not in children for i in range(n)])
    is_leaf[0] = False
    weight = np.zeros(n)
    n_images = len(per_image)
    for i in np.flatnonzero(is_leaf):
        holding = len(np.unique(image_of[members[i]]))
        weight[i] = math.log(n_images / holding)
    return VocabularyTree(params.k, params.levels, np.array(parent), is_leaf, np.array(descriptor), weight)


def vocabulary_text(tree: VocabularyTree) -> str:
    """The tree in DBoW2's text format (module docstring), without a final newline."""
    lines = [f"{tree.k} {tree.levels}  0 0"]  # TF_IDF = 0, L1_NORM = 0; DBoW2 writes two spaces here
    for i in range(1, len(tree.parent)):
        d = " ".join(str(int(b)) for b in tree.descriptor[i])
        lines.append(f"{int(tree.parent[i])} {int(tree.is_leaf[i])} {d} {float(tree.weight[i]):.6g}")
    return "\n".join(lines)


def write_vocabulary(path: Path, tree: VocabularyTree) -> Path:
    """Write ``tree`` to ``path`` atomically (a temporary sibling renamed over it)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", dir=path.parent)
    try:
        with os.fdopen(fd, "w") as f:
            f.write(vocabulary_text(tree))
            f.flush()
            os.fsync(f.fileno())
        os.chmod(tmp, 0o644)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return path
