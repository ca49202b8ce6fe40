"""The vio report's top views and trajectory files, from a figure file written as the track writes it."""

from __future__ import annotations

import logging
import warnings

import numpy as np

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
