"""The vio report's top views and trajectory files, from a figure file written as the track writes it."""

from __future__ import annotations

import logging
import warnings

import numpy as np
import pytest

from exobench.benchmarks.tracks.vio.metrics import aligned_or_centred
from exobench.benchmarks.tracks.vio.report import vio_sections


def _figure_file(folder, n=40):
    t = np.linspace(0.0, 4.0, n)
    xyz = np.stack([t, 0.5 * np.sin(t), np.full(n, 1.6)], axis=1)
    truth = np.hstack([t[:, None], xyz, np.tile([0.0, 0.0, 0.0, 1.0], (n, 1))])
    poses = np.tile(np.eye(4), (n, 1, 1))
    poses[:, :3, 3] = xyz + [0.2, -0.1, 0.0]  # a shifted estimate: the top view aligns it, the TUM file keeps it
    plan = np.array([[[-1.0, -2.0], [6.0, -2.0]], [[-1.0, 2.0], [6.0, 2.0]]])
    folder.mkdir(parents=True)
    np.savez(folder / "quick__office-head.npz", truth=truth, plan=plan,
             est_stamps__dvio=t, est_poses__dvio=poses, est_scored__dvio=np.ones(n, dtype=bool))  # fmt: skip
    return t, poses


def test_top_view_keeps_its_limits_without_warning_and_writes_the_scored_trajectory(tmp_path, caplog):
    t, poses = _figure_file(tmp_path / "figures")
    with warnings.catch_warnings(), caplog.at_level(logging.WARNING):
        warnings.simplefilter("error")
        lines = vio_sections([], ["dvio"], tmp_path)
    # matplotlib logs "Ignoring fixed y limits ..." when an equal aspect may change fixed limits
    assert not [r.getMessage() for r in caplog.records if r.name.startswith("matplotlib")]
    assert "![quick__office-head](figures/quick__office-head_top.png)" in lines
    assert (tmp_path / "figures" / "quick__office-head_top.png").stat().st_size > 1000
    tum = np.loadtxt(tmp_path / "trajectories" / "quick__office-head__dvio.tum")
    np.testing.assert_allclose(tum[:, 0], t)
    np.testing.assert_allclose(tum[:, 1:4], poses[:, :3, 3])
    np.testing.assert_allclose(tum[:, 4:8], np.tile([0.0, 0.0, 0.0, 1.0], (len(t), 1)), atol=1e-12)


def test_a_straight_estimate_is_drawn_at_the_ates_minimum_though_umeyama_refuses_a_line(tmp_path):
    """An estimate whose positions lie on one line (11 poses on a straight corridor): the metrics
    score it (the minimum every rotation about the line shares) but the report used to stop the
    whole run with Umeyama's refusal. Its drawn positions must reach that minimum."""
    n = 11
    t = np.linspace(0.0, 2.0, n)
    xyz = np.stack([t, 0.3 * np.sin(t), np.full(n, 1.6)], axis=1)
    truth = np.hstack([t[:, None], xyz, np.tile([0.0, 0.0, 0.0, 1.0], (n, 1))])
    poses = np.tile(np.eye(4), (n, 1, 1))
    poses[:, :3, 3] = np.outer(t, [0.0, 1.0, 0.0]) + [3.0, 1.0, 0.0]  # a line, along y
    folder = tmp_path / "figures"
    folder.mkdir()
    np.savez(folder / "general__03.npz", truth=truth, plan=np.zeros((0, 2, 2)), est_stamps__dvio=t, est_poses__dvio=poses,
             est_scored__dvio=np.ones(n, dtype=bool))  # fmt: skip
    lines = vio_sections([], ["dvio"], tmp_path)
    assert "![general__03](figures/general__03_top.png)" in lines
    p = aligned_or_centred(truth, t, poses)
    # the minimum over rigid motions, computed here: centred, a rotation only chooses where the
    # line's direction goes (a unit w); sum |yc_i - a_i w|^2 = |yc|^2 + |a|^2 - 2 w . (yc^T a) is
    # least for w along yc^T a
    a, yc = t - t.mean(), xyz - xyz.mean(0)
    w = yc.T @ a / np.linalg.norm(yc.T @ a)
    best = np.sqrt(np.mean(np.sum((yc - np.outer(a, w)) ** 2, axis=1)))
    assert np.sqrt(np.mean(np.sum((p - xyz) ** 2, axis=1))) == pytest.approx(best, rel=1e-9)
