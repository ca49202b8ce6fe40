"""ORB bag-of-words place recognition (seeds/000 III-B.1) on hand-rendered views of textured rooms."""

import math

import numpy as np
import pytest
from textured_room import TexturedRoom, look_at

from exobench.core.errors import ConfigError
from exobench.mapping.multisession.place_recognition import (
    KeyframeDatabase,
    Vocabulary,
    VocabularyConfig,
    l1_score,
    orb_features,
)


def _views(room, n, shift=0.0, turn_rad=0.0):
    """n cameras on a circle in the room, each looking outwards at a wall; ``shift`` moves them
    sideways and ``turn_rad`` turns them about the vertical."""
    out = []
    c = room.size / 2
    for i in range(n):
        a = 2 * math.pi * i / n
        eye = np.array([c[0] + 0.8 * math.cos(a) + shift, c[1] + 0.8 * math.sin(a), 1.2])
        b = a + turn_rad
        out.append(room.render(look_at(eye, eye + np.array([math.cos(b), math.sin(b), -0.1])))[0])
    return out


def test_l1_score_by_hand():
    v = {0: 0.5, 1: 0.5}
    w = {1: 0.25, 2: 0.75}
    # |v - w|_1 = 0.5 + 0.25 + 0.75 = 1.5 -> 1 - 0.75
    assert l1_score(v, w) == pytest.approx(0.25)
    assert l1_score(v, v) == pytest.approx(1.0)
    assert l1_score(v, {3: 1.0}) == 0.0


def test_vocabulary_tfidf_against_hand_computation():
    rng = np.random.default_rng(0)
    words = rng.integers(0, 256, (4, 32), dtype=np.uint8)  # four far-apart binary words
    # image A holds words 0, 1; image B words 0, 2, 3: word 0 is in every image (idf 0)
    a = np.repeat(words[[0, 1]], 5, axis=0)
    b = np.repeat(words[[0, 2, 3]], 5, axis=0)
    vocab = Vocabulary.train([a, b], VocabularyConfig(branching=4, depth=1))
    ids = vocab.words(words)
    assert len(set(ids.tolist())) == 4
    assert vocab.idf[ids[0]] == pytest.approx(0.0)
    assert vocab.idf[ids[1]] == pytest.approx(math.log(2))
    # query: word 1 three times, word 2 once -> tf 3/4, 1/4, both idf ln 2 -> 0.75, 0.25
    vec = vocab.transform(words[[1, 1, 1, 2]])
    assert vec == pytest.approx({int(ids[1]): 0.75, int(ids[2]): 0.25})


def test_database_ranks_the_true_place_first():
    room = TexturedRoom(seed=3)
    keyframes = _views(room, 10)
    queries = _views(room, 10, shift=0.15, turn_rad=math.radians(6))
    desc = [orb_features(img)[1] for img in keyframes]
    vocab = Vocabulary.train(desc, VocabularyConfig())
    db = KeyframeDatabase()
    for i, d in enumerate(desc):
        db.add(("s1", i), vocab.transform(d))
    for i, img in enumerate(queries):
        cands = db.query(vocab.transform(orb_features(img)[1]), top_k=3)
        assert cands[0].key == ("s1", i), (i, cands)
        assert cands[0].score > cands[1].score
    # a filter keeps candidates out (e.g. the query's own session)
    only_odd = db.query(vocab.transform(orb_features(queries[2])[1]), top_k=3, accept=lambda k: k[1] % 2 == 1)
    assert all(c.key[1] % 2 == 1 for c in only_odd)


def test_bad_input_named():
    with pytest.raises(ConfigError, match="vocabulary.branching"):
        VocabularyConfig(branching=1)
    with pytest.raises(ConfigError, match="vocabulary.training_images"):
        Vocabulary.train([np.zeros((3, 32), np.uint8)])
    db = KeyframeDatabase()
    db.add("a", {0: 1.0})
    with pytest.raises(ConfigError, match="keyframe_database.key"):
        db.add("a", {0: 1.0})
