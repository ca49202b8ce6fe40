"""LiDAR faults on a short office walk: each fault shows at its configured rate, the truth stays
aligned with the frames, the other streams do not change, and every LiDAR pipeline survives.

Rates are checked against binomial bounds (two-sided, 1e-6 per tail) on a 1 m corridor walk
(44 sweeps, about 1.2 M returns); the streams are seeded, so the checks are deterministic.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from scipy.stats import binom

from exobench.core import ConfigError, LidarScan, ReturnKind
from exobench.core.counters import admitted
from exobench.envs.sensors.lidar import LidarConfig
from exobench.envs.sensors.lidar.faults import LATE_PERIODS
from exobench.envs.sim.scenarios.office import OfficeScenario, simulate_office

pytestmark = pytest.mark.long(seconds=17)  # the workers take it first (tests/conftest.py); 17: the file at -n 0 in one run at load 12-15, scaled to that run's CPU

BASE = {"route": "corridor", "max_distance_m": 1.0}
FAULTS = {
    "scan_dropout": {"lidar_scan_dropout": 0.5},
    "point_dropout": {"lidar_point_dropout": 0.3},
    "nan": {"lidar_nan_points": 0.1},
    "duplicate": {"lidar_duplicate_scans": 0.5},
    "late": {"lidar_out_of_order": 0.5},
    "jump": {"lidar_time_jump_prob": 0.3, "lidar_time_jump_s": -0.25},
}
ALL = {"lidar_point_dropout": 0.05, "lidar_nan_points": 0.05, "lidar_scan_dropout": 0.1, "lidar_duplicate_scans": 0.2,
       "lidar_out_of_order": 0.2, "lidar_time_jump_prob": 0.1, "lidar_time_jump_s": 0.3}  # fmt: skip
PERIOD_S = 0.1  # 10 Hz


def _walk(extra: dict) -> object:
    return simulate_office(OfficeScenario.from_dict({**BASE, **extra}), 0)


@pytest.fixture(scope="module")
def eps():
    return {"base": _walk({}), **{k: _walk(v) for k, v in FAULTS.items()}}


def _scans(ep) -> list[LidarScan]:
    return [f for f in ep.frames if isinstance(f, LidarScan)]


def _in_binom(k: int, n: int, p: float) -> bool:
    return binom.ppf(1e-6, n, p) <= k <= binom.isf(1e-6, n, p)


def _same(a, b) -> bool:
    """Two frames (or truths) equal field by field, arrays bit for bit (NaN equal to NaN)."""
    if type(a) is not type(b):
        return False
    for f in dataclasses.fields(a):
        x, y = getattr(a, f.name), getattr(b, f.name)
        if isinstance(x, np.ndarray):
            if x.shape != y.shape or x.dtype != y.dtype or not np.array_equal(x, y, equal_nan=x.dtype.kind == "f"):
                return False
        elif x != y:
            return False
    return True


def _aligned(ep) -> None:
    """episode.truth.lidar is one truth per scan, in frame order, of the scan's stamp and length."""
    scans = _scans(ep)
    assert len(ep.truth.lidar) == len(scans)
    for s, t in zip(scans, ep.truth.lidar, strict=True):
        assert t.stamp_s == s.stamp_s and len(t.kind) == len(s.points_xyz) == len(t.true_range_m)
    stamps = [s.stamp_s for s in scans]
    assert stamps == sorted(stamps)
    from exobench.benchmarks.tracks.office_walks import lidar_pairs

    pairs = lidar_pairs(ep)
    assert len(pairs) == len(scans) and all(t is u for (_, t), u in zip(pairs, ep.truth.lidar, strict=True))


# ------------------------------------------------------------------ config


@pytest.mark.parametrize(
    ("field", "value"),
    [("nan_point_prob", 1.5), ("nan_point_prob", -0.1), ("duplicate_prob", math.nan), ("out_of_order_prob", 2.0),
     ("time_jump_prob", -1.0), ("time_jump_s", 11.0), ("time_jump_s", math.inf), ("point_dropout_prob", 1.0)],
)  # fmt: skip
def test_fault_parameters_are_checked(field, value):
    with pytest.raises(ConfigError):
        LidarConfig(**{field: value})


def test_faults_are_off_by_default():
    c = LidarConfig()
    assert (c.dropout_prob, c.point_dropout_prob, c.nan_point_prob, c.duplicate_prob, c.out_of_order_prob,
            c.time_jump_prob) == (0.0,) * 6  # fmt: skip
    sc = OfficeScenario.from_dict(BASE).lidar_config()
    names = ("dropout_prob", "point_dropout_prob", "nan_point_prob", "duplicate_prob", "out_of_order_prob", "time_jump_prob")
    assert all(getattr(sc, k) == getattr(c, k) for k in names)


# ------------------------------------------------------------------ each fault at its rate


def test_scan_dropout_rate(eps):
    n, k = len(_scans(eps["base"])), len(_scans(eps["scan_dropout"]))
    assert n == 44 and _in_binom(k, n, 0.5)
    base = {s.stamp_s: s for s in _scans(eps["base"])}
    assert all(_same(s, base[s.stamp_s]) for s in _scans(eps["scan_dropout"]))


def test_point_dropout_rate(eps):
    base, got = _scans(eps["base"]), _scans(eps["point_dropout"])
    assert [s.stamp_s for s in got] == [s.stamp_s for s in base]
    n, k = sum(len(s.ring) for s in base), sum(len(s.ring) for s in got)
    assert _in_binom(k, n, 0.7)
    for s, b in zip(got, base, strict=True):  # the kept points are the fault-free ones (same noise)
        assert np.isin(s.time_offset_s, b.time_offset_s).all()


def test_nan_points_rate_and_truth(eps):
    base, got = _scans(eps["base"]), _scans(eps["nan"])
    n = sum(len(s.ring) for s in base)
    nan = [np.isnan(s.points_xyz).any(axis=1) for s in got]
    assert _in_binom(int(sum(m.sum() for m in nan)), n, 0.1)
    for s, b, m, t, tb in zip(got, base, nan, eps["nan"].truth.lidar, eps["base"].truth.lidar, strict=True):
        assert np.isnan(s.points_xyz[m]).all() and (s.intensity[m] == 0).all()
        assert np.array_equal(s.points_xyz[~m], b.points_xyz[~m]) and np.array_equal(s.ring, b.ring)
        assert np.array_equal(t.kind == ReturnKind.NAN, m)  # marked in the truth, entry kept
        assert np.array_equal(t.kind[~m], tb.kind[~m]) and np.array_equal(t.hit_w, tb.hit_w)


def test_duplicated_scans_rate(eps):
    base, got = _scans(eps["base"]), _scans(eps["duplicate"])
    assert _in_binom(len(got) - len(base), len(base), 0.5)
    truths = eps["duplicate"].truth.lidar
    for i in range(1, len(got)):
        if got[i].stamp_s == got[i - 1].stamp_s:
            assert _same(got[i], got[i - 1]) and got[i] is not got[i - 1]
            assert _same(truths[i], truths[i - 1])
    assert sorted({s.stamp_s for s in got}) == [s.stamp_s for s in base]


def test_out_of_order_rate(eps):
    base, got = _scans(eps["base"]), _scans(eps["late"])
    assert len(got) == len(base)
    late = [s for s in got if s.stamp_s - s.sweep_start_s > PERIOD_S + 1e-9]
    # the sweep after a late one overtakes it and is on time: the others are late at the rate
    flags = [s.stamp_s - s.sweep_start_s > PERIOD_S + 1e-9 for s in sorted(got, key=lambda s: s.sweep_start_s)]
    assert not any(a and b for a, b in zip(flags, flags[1:]))
    assert _in_binom(len(late), 1 + sum(not f for f in flags[:-1]), 0.5)
    for s in late:
        assert s.stamp_s - s.sweep_start_s == pytest.approx((1 + LATE_PERIODS) * PERIOD_S)
    starts = np.array([s.sweep_start_s for s in got])
    assert np.any(np.diff(starts) < 0)  # delivered after a later sweep
    assert sorted(starts) == [s.sweep_start_s for s in base]
    assert np.array_equal(eps["late"].truth.trajectory_w, eps["base"].truth.trajectory_w)


def test_time_jumps_rate(eps):
    base, got = _scans(eps["base"]), _scans(eps["jump"])
    assert len(got) == len(base)
    true_start = {s.points_xyz.tobytes(): s.sweep_start_s for s in base}  # the noise makes every sweep unique
    t_true = np.array([true_start[s.points_xyz.tobytes()] for s in got])
    offsets = np.array([s.sweep_start_s for s in got]) - t_true
    steps = np.round(offsets / -0.25).astype(int)
    assert np.allclose(offsets, -0.25 * steps, atol=1e-9)
    assert np.all(np.diff(steps[np.argsort(t_true)]) >= 0)  # the clock steps hold for every later sweep
    assert _in_binom(int(steps.max()), len(base), 0.3)
    assert np.any(np.diff([s.sweep_start_s for s in got]) < 0)  # a step back in time shows as disorder
    for s in got:
        assert s.stamp_s - s.sweep_start_s == pytest.approx(PERIOD_S)
    # the truth trajectory stays in true time
    assert np.array_equal(eps["jump"].truth.trajectory_w, eps["base"].truth.trajectory_w)


@pytest.mark.parametrize("name", ["base", *FAULTS])
def test_truth_aligned_and_other_streams_unchanged(eps, name):
    ep = eps[name]
    _aligned(ep)
    others = [f for f in ep.frames if not isinstance(f, LidarScan)]
    ref = [f for f in eps["base"].frames if not isinstance(f, LidarScan)]
    assert len(others) == len(ref) and all(_same(a, b) for a, b in zip(others, ref, strict=True))


# ------------------------------------------------------------------ every LiDAR pipeline survives


@pytest.mark.parametrize("track", ["lidar-filter", "odometry", "loop-closure"])
def test_every_lidar_pipeline_survives_all_faults(track):
    from exobench.benchmarks.runner import plan_run, run_pipelines

    plan = plan_run(track, "quick", None, (0,), {**BASE, **ALL})
    ep_plan = plan.episodes[0]
    episode = plan.track.simulate(ep_plan.scenario, ep_plan.seed)
    _aligned(episode)
    scans = _scans(episode)
    n_nan = sum(int(np.isnan(s.points_xyz).any(axis=1).sum()) for s in scans)
    # a repeated or late sweep is counted and not used, nor scored: each instant once (core.counters)
    use = dict(zip(map(id, episode.frames), admitted(episode.frames), strict=True))
    n_unused = sum(not use[id(s)] for s in scans)
    n_nan_used = sum(int(np.isnan(s.points_xyz).any(axis=1).sum()) for s in scans if use[id(s)])
    stamps, starts = np.array([s.stamp_s for s in scans]), np.array([s.sweep_start_s for s in scans])
    assert n_nan > 0 and np.any(np.diff(stamps) == 0) and np.any(np.diff(starts) < 0)  # NaN, duplicates, disorder
    assert np.any(np.abs(stamps - starts - PERIOD_S) > 1e-9)  # late sweeps
    errors: dict[str, str] = {}
    _, metrics, _, _ = run_pipelines(plan.track, episode, plan.pipelines, scorer_errors=errors)
    assert not errors and set(metrics) == {p.name for p in plan.pipelines}
    for name, m in metrics.items():
        assert "raised" not in str(m.get("failed_reason", "")), (name, m["failed_reason"])
        for k, v in m.items():
            if k.endswith("_frac") and not (isinstance(v, float) and math.isnan(v)):
                assert 0.0 <= v <= 1.0, (name, k, v)
        assert m["frames.lidar.repeated"] + m["frames.lidar.out_of_order"] == n_unused > 0, name
        if track == "lidar-filter":
            assert m["n_nan"] == n_nan_used and not m["failed"], (name, m)


# ------------------------------------------------------------------ scoring and sessions


def test_nan_points_are_counted_not_scored_as_removed():
    from exobench.benchmarks.tracks.lidar_filter.metrics import mask_fractions
    from exobench.benchmarks.tracks.office_walks import GENUINE, GHOST, NAN_POINT

    cls = [np.array([GENUINE, GENUINE, GHOST, NAN_POINT, NAN_POINT])]
    ground = [np.array([True, False, False, False, False])]
    keep_nan = mask_fractions(cls, ground, [np.array([1, 1, 0, 1, 1], bool)])
    drop_nan = mask_fractions(cls, ground, [np.array([1, 1, 0, 0, 0], bool)])
    assert keep_nan == drop_nan
    assert keep_nan["n_nan"] == 2 and keep_nan["n_points"] == 5 and keep_nan["kept_frac"] == pytest.approx(2 / 3)
    assert keep_nan["genuine_kept_frac"] == 1.0 and keep_nan["spurious_removed_frac"] == 1.0


def test_faulty_walk_survives_a_session_round_trip(tmp_path):
    from exobench.envs.session import read_session, write_session

    ep = _walk(ALL)
    back = read_session(write_session(ep, tmp_path / "s"))
    assert len(back.frames) == len(ep.frames) and all(_same(a, b) for a, b in zip(back.frames, ep.frames, strict=True))
    assert all(_same(a, b) for a, b in zip(back.truth.lidar, ep.truth.lidar, strict=True))
    assert np.array_equal(back.truth.trajectory_w, ep.truth.trajectory_w)
    _aligned(back)
