"""The LiDAR tracks stream: lidar-filter spools its scans (benchmarks.tracks.scan_spool), loop-closure keeps none.

Oracles: the whole episode of the same scenario and seed (``simulate``), scored here by an
independent count over its frames and truth (classes from ``ReturnKind`` codes, each sweep
once by its start time, KISS-ICP through ``run_kiss_icp``), and the number of scans still
alive once an episode has been run and scored, which must not grow with the walk.
"""

from __future__ import annotations

import gc
import math
import weakref

import numpy as np
import pytest

from exobench.benchmarks.runner import PipelineRun, run_pipelines
from exobench.benchmarks.tracks.lidar_filter.track import LidarFilterTrack
from exobench.benchmarks.tracks.lidar_trajectory import score_trajectory
from exobench.benchmarks.tracks.loop_closure.track import LoopClosureTrack
from exobench.benchmarks.tracks.office_walks import GROUND_KINDS, lidar_pairs
from exobench.core import LidarScan, ReturnKind
from exobench.core.counters import admitted
from exobench.core.episode import EpisodeStream
from exobench.core.estimates import FilterEstimate
from exobench.envs.sim.recorder import CHUNK_S

pytestmark = pytest.mark.long(seconds=17)  # the workers take it first (tests/conftest.py); 17: the file at -n 0 in one run at load 12-15, scaled to that run's CPU

SEED = 3
# duplicated and late sweeps and NaN points: the spool must keep the whole episode's pairing and admission
FAULTY = {"max_distance_m": 0.5, "lidar_duplicate_scans": 0.3, "lidar_out_of_order": 0.3, "lidar_nan_points": 0.05}


def _bytes(x):
    return np.asarray(x).tobytes()


@pytest.fixture(scope="module")
def filter_walk():
    track = LidarFilterTrack()
    scenario = track.validate_scenario(FAULTY)
    whole = track.simulate(scenario, SEED)
    stream = track.stream(scenario, SEED)
    assert isinstance(stream, EpisodeStream)
    frames = list(stream.frames)
    return track, whole, frames, stream.finish()


def test_spooled_scans_are_the_whole_episodes_scans_and_labels_bit_for_bit(filter_walk):
    _, whole, frames, streamed = filter_walk
    assert [_bytes(f.points_xyz) for f in frames if isinstance(f, LidarScan)] == [
        _bytes(f.points_xyz) for f in whole.frames if isinstance(f, LidarScan)]  # fmt: skip
    assert streamed.frames == () and streamed.truth.lidar == ()
    want, got = lidar_pairs(whole), lidar_pairs(streamed)
    stamps = [s.stamp_s for s, _ in want]
    assert len(set(stamps)) < len(stamps)  # the faults are at work: a duplicated sweep
    assert len(got) == len(want) > 5
    for (s0, t0), (s1, t1) in zip(want, got, strict=True):
        for name in ("points_xyz", "intensity", "ring", "time_offset_s"):
            assert _bytes(getattr(s0, name)) == _bytes(getattr(s1, name)), name
        assert (s0.stamp_s, s0.sweep_start_s, s0.sensor_id) == (s1.stamp_s, s1.sweep_start_s, s1.sensor_id)
        assert np.array_equal(t0.kind, t1.kind) and np.array_equal(t0.surface_id, t1.surface_id)
    lidar_used = [ok for f, ok in zip(whole.frames, admitted(whole.frames), strict=True) if isinstance(f, LidarScan)]
    assert got.used == lidar_used and not all(lidar_used)


def _independent_filter_score(whole, masks_by_start):
    """Fractions over the whole episode, counted here: each sweep once (the first delivery of a
    start later than every earlier one), its truth by frame order, classes from the kind codes."""
    ground_ids = [s.surface_id for s in whole.truth.scene.surfaces if s.kind in GROUND_KINDS]
    truths = iter(whole.truth.lidar)
    last = -math.inf
    cls, ground, keep, scans = [], [], [], []
    for f in whole.frames:
        if not isinstance(f, LidarScan):
            continue
        t = next(truths)
        if f.sweep_start_s <= last:
            continue
        last = f.sweep_start_s
        kind = np.asarray(t.kind)
        c = np.select([kind == ReturnKind.GLASS, kind == ReturnKind.GHOST, kind == ReturnKind.NAN], [1, 2, 3], 0)
        c[~np.all(np.isfinite(f.points_xyz), axis=1)] = 3
        cls.append(c)
        ground.append((c == 0) & np.isin(t.surface_id, ground_ids))
        keep.append(masks_by_start[f.sweep_start_s])
        scans.append(f)
    c, g, k = np.concatenate(cls), np.concatenate(ground), np.concatenate(keep)
    spur = (c == 1) | (c == 2)
    out = {
        "spurious_removed_frac": np.sum(spur & ~k) / np.sum(spur),
        "ground_kept_frac": np.sum(g & k) / np.sum(g),
        "genuine_kept_frac": np.sum((c == 0) & k) / np.sum(c == 0),
        "kept_frac": np.sum(k & (c != 3)) / np.sum(c != 3),
        "n_points": len(c), "n_glass": int(np.sum(c == 1)), "n_ghost": int(np.sum(c == 2)), "n_nan": int(np.sum(c == 3)),
    }  # fmt: skip
    return out, scans, keep


def test_a_streamed_episode_scores_as_an_independent_count_over_the_whole_episode(filter_walk):
    from exobench.mapping.odometry.kiss_icp import KissConfig, run_kiss_icp

    track, whole, _, streamed = filter_walk
    # a fixed filter: keep the points brighter than 20, one mask per sweep (by its start)
    firsts = {}
    for f in whole.frames:
        if isinstance(f, LidarScan) and f.sweep_start_s not in firsts:
            firsts[f.sweep_start_s] = f
    masks = {t: np.asarray(f.intensity) > 20 for t, f in firsts.items()}
    est = FilterEstimate(stamps_s=np.array([f.stamp_s for f in firsts.values()]), keep=tuple(masks.values()),
                         time_per_scan_s=np.zeros(len(firsts)))  # fmt: skip
    got = track.score(streamed, est, {"score_odometry": True})
    want, scans, keep = _independent_filter_score(whole, masks)
    assert not got["failed"], got["failed_reason"]
    assert 0 < want["n_glass"] + want["n_ghost"] and 0 < want["n_nan"]
    for key, value in want.items():
        assert got[key] == value, key
    kiss = score_trajectory(whole, run_kiss_icp(scans, keep, KissConfig(downsample="single")))
    for key in ("te_m", "ate_m", "rpe_m", "drift_per_m"):
        assert _same(got[f"odom_{key}"], kiss[key]), key
    assert math.isfinite(got["odom_ate_m"])
    # and the whole episode, through the same scorer, agrees
    again = track.score(whole, est, {"score_odometry": True})
    assert again.keys() == got.keys()
    for key in got:
        if "time" not in key:
            assert _same(again[key], got[key]), key


def _same(a, b) -> bool:
    return a == b or (isinstance(a, float) and isinstance(b, float) and math.isnan(a) and math.isnan(b))


def _alive_scans_after_a_run(track, distance_m: float) -> tuple[int, int]:
    """(LiDAR scans the stream handed out, those still alive once every pipeline has run and
    the episode is scored, with the finished episode still held)."""
    scenario = track.validate_scenario({**dict(track.smoke_scenario), "max_distance_m": distance_m})
    stream = track.stream(scenario, SEED)
    refs = []

    def watched(frames):
        for f in frames:
            if isinstance(f, LidarScan):
                refs.append(weakref.ref(f))
            yield f

    stream.frames = watched(stream.frames)
    pipelines = _pipelines("filter-none" if track.name == "lidar-filter" else "sc++")
    _, metrics, _, _ = run_pipelines(track, stream, pipelines)
    assert all(not m["failed"] for m in metrics.values()), metrics
    episode = stream.finish()
    gc.collect()
    alive = sum(r() is not None for r in refs)
    del episode
    return len(refs), alive


def _pipelines(name: str) -> list[PipelineRun]:
    from exobench.benchmarks.registry import default_registry

    reg = default_registry()
    return [PipelineRun(name, reg.spec(name).entry_point, reg.make_config(name, None))]


@pytest.mark.parametrize("track", [LidarFilterTrack(), LoopClosureTrack()], ids=lambda t: t.name)
def test_a_streamed_walk_holds_no_more_scans_when_it_is_longer(track):
    short_n, short_alive = _alive_scans_after_a_run(track, 0.5)
    long_n, long_alive = _alive_scans_after_a_run(track, 1.5)
    assert long_n > short_n + 20  # the longer walk has more sweeps ...
    # ... and after the run only the last chunk's (the recorder's 0.5 s, 5 sweeps at 10 Hz) are still held
    assert long_alive == short_alive <= round(CHUNK_S * 10)


def test_a_streamed_loop_keeps_no_point_truth_and_scores_as_the_whole_walk():
    track = LoopClosureTrack()
    scenario = track.validate_scenario({**dict(track.smoke_scenario), "revisit_m": 0.6, "exclude_recent_s": 0.3})
    whole = track.simulate(scenario, SEED)
    pipelines = _pipelines("sc++")
    scoring = {"revisit_m": 0.6, "exclude_recent_s": 0.3}
    stream = track.stream(scenario, SEED)
    est_s, got, _, _ = run_pipelines(track, stream, pipelines, scoring=scoring)
    est_w, want, _, _ = run_pipelines(track, whole, pipelines, scoring=scoring)
    ep = stream.finish()
    assert ep.frames == () and ep.truth.lidar == () and len(whole.truth.lidar) > 5
    assert ep.truth.trajectory_w.tobytes() == whole.truth.trajectory_w.tobytes()
    timing = track.timing_metrics
    assert {k: v for k, v in got["sc++"].items() if k not in timing} == {k: v for k, v in want["sc++"].items() if k not in timing}
    assert got["sc++"]["n_keyframes"] > 3 and got["sc++"]["n_revisits"] > 0


def test_streamed_lidar_filter_runs_give_the_same_records_whatever_the_jobs(tmp_path):
    from exobench.benchmarks.runner import execute, plan_run, untimed_metrics

    track = LidarFilterTrack()
    over = {"max_distance_m": 0.5, "score_odometry": True, "lidar_duplicate_scans": 0.2}
    plan = plan_run(track, "quick", ["filter-threshold"], [0, 1], over)

    def records(out, jobs):
        got = execute(plan, out, jobs=jobs).records
        return sorted((r["episode"], r["pipeline"], untimed_metrics(track, r["metrics"])) for r in got)

    one, two = records(tmp_path / "one", 1), records(tmp_path / "two", 2)
    assert len(one) == 2 and all(not m["failed"] and math.isfinite(m["odom_ate_m"]) for _, _, m in one)
    assert repr(one) == repr(two)  # NaN-safe: every value printed alike
    for name in ("corridor-4m__s0.npz", "corridor-4m__s1.npz"):
        a, b = np.load(tmp_path / "one" / "figures" / name), np.load(tmp_path / "two" / "figures" / name)
        assert sorted(a.files) == sorted(b.files) and any(k.startswith("est_poses__kiss-icp+") for k in a.files)
        assert all(a[k].tobytes() == b[k].tobytes() for k in a.files)
