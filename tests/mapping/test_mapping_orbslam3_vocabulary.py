"""exobench's ORB vocabulary: DBoW2's clustering rules, its text format (checked by a parser of this
file's own, written from DBoW2's ``loadFromTextFile``), the per-user cache, and ORB-SLAM3 loading
it through the worker."""

from __future__ import annotations

import math

import cv2
import numpy as np
import pytest

from exobench.mapping.odometry.orbslam3 import vocabulary as voc


@pytest.fixture
def orbslam3_calibration():
    from orbslam3_support import calibration

    return calibration()


def _images(n: int, seed: int = 0) -> list[np.ndarray]:
    """Grey images with corners: random rectangles of random grey levels on a grey background."""
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(n):
        img = np.full((240, 424), 128, np.uint8)
        for _ in range(60):
            x, y = rng.integers(0, 400), rng.integers(0, 220)
            w, h = rng.integers(8, 60), rng.integers(8, 60)
            cv2.rectangle(img, (int(x), int(y)), (int(x + w), int(y + h)), int(rng.integers(0, 256)), -1)
        out.append(img)
    return out


def parse_dbow2_text(text: str) -> dict:
    """DBoW2's ``loadFromTextFile`` in Python: header ``k L scoring weighting`` (refused outside
    k 0-20, L 1-10, scoring 0-5, weighting 0-3, as DBoW2 does), then per line
    ``parent is_leaf d0..d31 weight``, node ids from 1 in line order."""
    lines = text.split("\n")
    k, L, scoring, weighting = (int(x) for x in lines[0].split())
    assert 0 <= k <= 20 and 1 <= L <= 10 and 0 <= scoring <= 5 and 0 <= weighting <= 3
    parent, leaf, desc, weight, children = [-1], [False], [None], [0.0], {0: []}
    for line in lines[1:]:
        f = line.split()
        assert len(f) == 2 + 32 + 1, line
        nid = len(parent)
        p = int(f[0])
        assert 0 <= p < nid, "a parent comes before its children"
        children.setdefault(p, []).append(nid)
        children[nid] = []
        parent.append(p)
        leaf.append(int(f[1]) > 0)
        d = [int(x) for x in f[2:34]]
        assert all(0 <= x <= 255 for x in d)
        desc.append(np.array(d, np.uint8))
        weight.append(float(f[34]))
    return {"k": k, "L": L, "scoring": scoring, "weighting": weighting, "parent": parent, "leaf": leaf,
            "desc": desc, "weight": weight, "children": children}  # fmt: skip


def _depth(parsed: dict, nid: int) -> int:
    d = 0
    while nid:
        nid = parsed["parent"][nid]
        d += 1
    return d


def test_hamming_and_majority_are_dbow2s():
    rng = np.random.default_rng(1)
    a = rng.integers(0, 256, (7, 32), dtype=np.uint8)
    b = rng.integers(0, 256, (5, 32), dtype=np.uint8)
    bits = lambda x: np.unpackbits(x, axis=-1).astype(int)  # noqa: E731
    expected = np.abs(bits(a)[:, None, :] - bits(b)[None, :, :]).sum(axis=2)
    np.testing.assert_array_equal(voc.hamming(a, b), expected)
    # a bit is set when at least half the descriptors set it (FORB::meanValue: sum >= ceil(n / 2))
    three = np.zeros((3, 32), np.uint8)
    three[0, 0], three[1, 0], three[2, 0] = 0b1110_0000, 0b1100_0000, 0b1000_0000
    assert voc.majority(three)[0] == 0b1100_0000
    four = np.zeros((4, 32), np.uint8)
    four[:2, 0] = 0b0000_0001  # two of four: set
    four[:1, 1] = 0b0000_0001  # one of four: not set
    m = voc.majority(four)
    assert m[0] == 1 and m[1] == 0


def test_a_node_of_at_most_k_descriptors_gives_one_leaf_each_with_idf_weights(monkeypatch):
    # DBoW2's trivial case: as many children as descriptors, each its descriptor
    rng = np.random.default_rng(2)
    d = rng.integers(0, 256, (3, 32), dtype=np.uint8)
    per_image = iter([d[:2], d[2:]])  # image 0 holds words 0 and 1, image 1 holds word 2
    monkeypatch.setattr(voc, "orb_descriptors", lambda img, params: next(per_image))
    tree = voc.build_tree([None, None], voc.VocabularyParams(k=10, levels=3))
    assert len(tree.parent) == 4 and list(tree.parent[1:]) == [0, 0, 0]
    assert tree.is_leaf[1:].all()
    got = sorted(map(bytes, tree.descriptor[1:]))
    assert got == sorted(map(bytes, d))
    np.testing.assert_allclose(tree.weight[1:], math.log(2 / 1))


def test_the_text_file_parses_as_dbow2_and_holds_the_tree(tmp_path):
    params = voc.VocabularyParams(k=5, levels=3, n_features=300)
    images = _images(12)
    tree = voc.build_tree(images, params)
    path = voc.write_vocabulary(tmp_path / "v.txt", tree)
    text = path.read_text()
    assert not text.endswith("\n")  # DBoW2's reader would take an empty last line for a node
    parsed = parse_dbow2_text(text)
    assert (parsed["k"], parsed["L"], parsed["scoring"], parsed["weighting"]) == (5, 3, 0, 0)
    n = len(parsed["parent"])
    assert n == len(tree.parent) and n - 1 == len(text.split("\n")) - 1
    # the tree's shape: at most k children, depth at most L, leaves exactly the nodes without children
    assert all(len(c) <= 5 for c in parsed["children"].values())
    assert max(_depth(parsed, i) for i in range(1, n)) <= 3
    for i in range(1, n):
        assert parsed["leaf"][i] == (not parsed["children"][i])
    # a full tree at this size: the root has k children, and there are words at depth L
    assert len(parsed["children"][0]) == 5
    assert any(_depth(parsed, i) == 3 and parsed["leaf"][i] for i in range(1, n))
    # weights: IDF of the words (0 <= w <= log(N)), 0 for inner nodes
    for i in range(1, n):
        w = parsed["weight"][i]
        assert (0.0 <= w <= math.log(len(images)) + 1e-6) if parsed["leaf"][i] else w == 0.0
    # each descriptor of the training set reaches a word whose descriptor is its nearest child
    # at every level (DBoW2's transform), and the node descriptors are the file's
    for i in range(1, n):
        np.testing.assert_array_equal(parsed["desc"][i], tree.descriptor[i])
    d = voc.orb_descriptors(images[0], params)[:20]
    for row in d:
        node = 0
        while parsed["children"][node]:
            kids = parsed["children"][node]
            node = kids[int(np.argmin(voc.hamming(row[None], np.array([parsed["desc"][c] for c in kids]))[0]))]
        assert parsed["leaf"][node]


def test_the_cache_is_per_user_named_by_the_parameters_and_built_once(tmp_path, monkeypatch):
    from exobench.benchmarks import orbvoc

    monkeypatch.setenv("EXOBENCH_CACHE", str(tmp_path / "cache"))
    params = voc.VocabularyParams(k=4, levels=2, n_features=200, images="test")
    calls = []

    def images():
        calls.append(1)
        return _images(4)

    path = orbvoc.ensure_vocabulary(params, images)
    assert path.parent == tmp_path / "cache" and path.name.startswith("orbvoc-") and path.suffix == ".txt"
    mtime = path.stat().st_mtime_ns
    assert orbvoc.ensure_vocabulary(params, images) == path and path.stat().st_mtime_ns == mtime
    assert calls == [1]
    # other parameters, another file; no temporary file left behind
    other = voc.vocabulary_path(voc.VocabularyParams(k=4, levels=3, n_features=200, images="test"))
    assert other != path
    assert sorted(p.name for p in path.parent.iterdir()) == [path.name]


@pytest.mark.parametrize(("field", "value"), [("k", 1), ("k", 21), ("levels", 0), ("levels", 11), ("n_features", 10),
                                              ("scale_factor", 1.0), ("max_iters", 0)])  # fmt: skip
def test_bad_vocabulary_parameters_are_refused_by_name(field, value):
    from exobench.core.errors import ConfigError

    with pytest.raises(ConfigError, match=f"vocabulary.{field}"):
        voc.VocabularyParams(**{field: value})


def test_orbslam3_loads_the_vocabulary_through_the_worker_and_refuses_a_broken_one(tmp_path, orbslam3_calibration):
    from exobench.mapping.odometry.orbslam3.settings import OrbSlam3Config, settings_values, settings_yaml
    from exobench.mapping.odometry.orbslam3.worker_client import OrbSlam3Worker, WorkerError

    tree = voc.build_tree(_images(6), voc.VocabularyParams(k=5, levels=3, n_features=300))
    good = voc.write_vocabulary(tmp_path / "good.txt", tree)
    settings = tmp_path / "settings.yaml"
    settings.write_text(settings_yaml(settings_values(orbslam3_calibration, OrbSlam3Config())))
    w = OrbSlam3Worker(tmp_path)
    try:
        reply, _ = w.request({"op": "init", "vocabulary": str(good), "settings": str(settings)}, timeout_s=120)
        assert reply["op"] == "ready"
        assert "Vocabulary loaded" in w.log_path.read_text()
    finally:
        w.close()
    broken = tmp_path / "broken.txt"
    broken.write_text("30 3  0 0\n" + good.read_text().split("\n", 1)[1])  # k = 30: DBoW2 refuses the file
    (tmp_path / "b").mkdir()
    w = OrbSlam3Worker(tmp_path / "b")
    try:
        with pytest.raises(WorkerError):
            w.request({"op": "init", "vocabulary": str(broken), "settings": str(settings)}, timeout_s=120)
    finally:
        w.close()
