"""lt-exosense's vocabulary of another office (issue 28): the tree written and read back word for
word, the pipeline using the file it is given and not its first session, a missing file refused
naming the field, and the harness building the file once and reusing it; the pipeline's
intra-session loops on a session that walks round a room and back."""

import math

import numpy as np
import pytest
from textured_room import K, TexturedRoom, look_at

from exobench.benchmarks import ltvoc
from exobench.core.calibration import Calibration, SensorMount
from exobench.core.errors import ConfigError
from exobench.core.frames import OdometrySample, RgbdFrame, SessionStart
from exobench.mapping.multisession.other_office import other_office_vocabulary_path
from exobench.mapping.multisession.pipeline import LtExosense, LtExosenseConfig
from exobench.mapping.multisession.place_recognition import Vocabulary, orb_features

pytestmark = pytest.mark.long(seconds=26)  # the workers take it first (tests/conftest.py); 26: the file at -n 0 in one run at load 12-15, scaled to that run's CPU


def _views(room, n, radius=0.8, phase=0.0):
    """Camera poses on a circle in the room, each looking outwards at a wall, and their views."""
    c = room.size / 2
    out = []
    for i in range(n):
        a = phase + 2 * math.pi * i / n
        eye = np.array([c[0] + radius * math.cos(a), c[1] + radius * math.sin(a), 1.2])
        T = look_at(eye, eye + np.array([math.cos(a), math.sin(a), -0.1]))
        img, depth = room.render(T)
        out.append((T, img, depth))
    return out


def test_saved_vocabulary_gives_the_same_words(tmp_path):
    room = TexturedRoom(seed=21)
    descs = [orb_features(img)[1] for _, img, _ in _views(room, 8)]
    vocab = Vocabulary.train(descs)
    loaded = Vocabulary.load(vocab.save(tmp_path / "v.npz"))
    held_out = orb_features(_views(room, 5, radius=0.5, phase=0.3)[2][1])[1]
    assert loaded.n_words == vocab.n_words and np.array_equal(loaded.idf, vocab.idf)
    assert np.array_equal(loaded.words(held_out), vocab.words(held_out))
    assert loaded.transform(held_out) == vocab.transform(held_out)
    (tmp_path / "not.npz").write_text("no vocabulary")
    with pytest.raises(ConfigError, match="vocabulary file"):
        Vocabulary.load(tmp_path / "not.npz")


CALIBRATION = Calibration(robot_urdf="", base_link="pelvis", joint_names=(), sole_height_m=0.1, foot_length_m=0.26,
                          heel_to_ankle_m=0.05, extra={"camera": "rgbd_thigh"},
                          mounts=(SensorMount("rgbd_thigh", "rgbd", "thigh", np.eye(4)),
                                  SensorMount("odom_thigh", "odometry", "thigh", np.eye(4))))  # fmt: skip


def _frames(room):
    """Two sessions of the same room, their camera poses as odometry (each in its own frame)."""
    t = 0.0
    for session, phase in ((0, 0.0), (1, 0.15)):
        yield SessionStart(t, "session", session, 0)
        T0 = None
        for T, img, depth in _views(room, 10, phase=phase):
            t += 0.1
            T0 = T if T0 is None else T0
            yield OdometrySample(t, "odom_thigh", np.linalg.inv(T0) @ T, np.zeros(3))
            yield RgbdFrame(t, "rgbd_thigh", np.repeat(img[..., None], 3, axis=2), depth, K)
        t += 1.0


def _run(config, room):
    pipe = LtExosense(config)
    pipe.reset(CALIBRATION)
    for f in _frames(room):
        pipe.process(f)
    return pipe.finalize()


def test_other_vocabulary_is_read_from_its_file_not_trained_on_the_first_session(tmp_path):
    other = TexturedRoom(seed=31)  # the "other office": a room the episode never shows
    path = Vocabulary.train([orb_features(img)[1] for _, img, _ in _views(other, 12)]).save(tmp_path / "other.npz")
    words = Vocabulary.load(path).n_words
    room = TexturedRoom(seed=32)
    own = _run(LtExosenseConfig(), room)
    foreign = _run(LtExosenseConfig(vocabulary="other", vocabulary_file=str(path)), room)
    assert foreign.stats["vocabulary_words"] == words != own.stats["vocabulary_words"]
    # both find the second session in the first one's room: the words of another room still index it
    assert own.stats["n_inter_edges"] > 0 and foreign.stats["n_inter_edges"] > 0
    assert own.separate_sessions == foreign.separate_sessions == ()
    # the join is reported: the one pair of sessions, joined on edges that agree (the same room)
    for est in (own, foreign):
        (join,) = est.stats["merge_joins"]
        assert join["sessions_a"] == [0] and join["sessions_b"] == [1] and join["joined"]
        assert join["n_edges"] == est.stats["n_inter_edges"] and 2 <= join["n_consistent"] <= join["n_edges"]
        assert est.stats["n_inter_edges_between_maps"] == 0


def test_intra_session_loops_close_a_drifting_circle():
    """One session walks a circle and goes on over its first two places (keyframes 12 and 13
    see what 0 and 1 saw) with odometry turning 0.02 rad too far at each step: with
    ``intra_session_loops`` the pipeline verifies the loops back to the start and its merged
    keyframes come back to the true ones; without, they keep the drift."""
    room = TexturedRoom(seed=33)
    views = _views(room, 12) + _views(room, 12)[:2]
    T0 = views[0][0]
    turn = np.eye(4)
    turn[:3, :3] = [[math.cos(0.02), 0, math.sin(0.02)], [0, 1, 0], [-math.sin(0.02), 0, math.cos(0.02)]]  # about the camera's y
    odom = [np.eye(4)]
    for i in range(1, len(views)):
        odom.append(odom[-1] @ np.linalg.inv(views[i - 1][0]) @ views[i][0] @ turn)

    def run(loops):
        pipe = LtExosense(LtExosenseConfig(intra_session_loops=loops))
        pipe.reset(CALIBRATION)
        pipe.process(SessionStart(0.0, "session", 0, 0))
        for i, (_, img, depth) in enumerate(views):
            t = 0.1 * (i + 1)
            pipe.process(OdometrySample(t, "odom_thigh", odom[i], np.zeros(3)))
            pipe.process(RgbdFrame(t, "rgbd_thigh", np.repeat(img[..., None], 3, axis=2), depth, K))
        return pipe.finalize()

    def worst(est):
        return max(np.linalg.norm(est.T_map_cam[0][k][:3, 3] - (np.linalg.inv(T0) @ T)[:3, 3]) for k, (T, _, _) in enumerate(views))

    closed, open_ = run(True), run(False)
    assert len(closed.T_map_cam[0]) == len(views)
    assert closed.stats["n_intra_loops"][0] >= 2 and "n_intra_loops" not in open_.stats
    assert worst(open_) > 0.1 and worst(closed) < 0.3 * worst(open_), (worst(open_), worst(closed))


def test_missing_or_unknown_vocabulary_refused_naming_the_field(tmp_path):
    pipe = LtExosense(LtExosenseConfig(vocabulary="other", vocabulary_file=str(tmp_path / "none.npz")))
    with pytest.raises(ConfigError, match="lt-exosense.vocabulary_file"):
        pipe.reset(CALIBRATION)
    with pytest.raises(ConfigError, match="vocabulary"):
        LtExosenseConfig(vocabulary="dbow2")


def test_harness_builds_the_other_office_vocabulary_once(tmp_path, monkeypatch):
    monkeypatch.setenv("EXOBENCH_CACHE", str(tmp_path))
    calls = []

    def images():
        calls.append(1)
        return [img for _, img, _ in _views(TexturedRoom(seed=41), 6)]

    monkeypatch.setattr(ltvoc, "training_images", images)
    ltvoc.setup_pipeline(LtExosenseConfig())  # the session's vocabulary: nothing to build
    assert calls == [] and not other_office_vocabulary_path().exists()
    ltvoc.setup_pipeline(LtExosenseConfig(vocabulary="other"))
    ltvoc.setup_pipeline(LtExosenseConfig(vocabulary="other"))
    path = other_office_vocabulary_path()
    assert calls == [1] and path.parent == tmp_path and Vocabulary.load(path).n_words > 10
