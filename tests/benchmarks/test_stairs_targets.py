"""The stairs track meets the issue's accuracy targets on a small suite run through the CLI.

Scored against the simulator's exact ground truth; the thresholds are the published figures
of the staircase paper (S2 alpha < 3 deg and d < 3 mm in cases A and B, touch-down elevation
error < 1 cm in every pose, riser and tread errors below 5 %) and, with every sensor noise
off, the tighter alpha < 0.5 deg.
"""

from __future__ import annotations

import json

import pytest
from click.testing import CliRunner

from exobench.benchmarks.cli import cli

NOISE_OFF = ["tof_noise_m=0", "imu_noise_scale=0", "imu_orientation_deg=0", "encoder_noise_rad=0"]


def _run(tmp_path, name, sets=()):
    out = tmp_path / name
    args = ["run", "quick", "--track", "stairs", "--pipeline", "rtls", "--pipeline", "rtls-htvr", "--out", str(out), "--no-report"]
    for s in sets:
        args += ["--set", s]
    result = CliRunner().invoke(cli, args, catch_exceptions=False)
    assert result.exit_code == 0, result.output
    return [json.loads(line) for line in (out / "results.jsonl").read_text().splitlines()]


@pytest.fixture(scope="module")
def noisy(tmp_path_factory):
    return _run(tmp_path_factory.mktemp("targets"), "noisy")


def test_every_episode_identifies_s2_and_touchdown_error_below_1cm(noisy):
    assert len(noisy) == 12
    for r in noisy:
        m = r["metrics"]
        assert not m["failed"], (r["episode"], r["pipeline"], m.get("failure"))
        assert abs(m["touchdown_error_m"]) < 0.01, (r["episode"], r["pipeline"])


def test_cases_a_and_b_meet_the_published_s2_figures(noisy):
    for r in noisy:
        if r["episode"].split("/")[0] in ("A", "B"):
            m = r["metrics"]
            assert m["alpha_deg_S2"] < 3.0 and abs(m["d_m_S2"]) < 3e-3, (r["episode"], r["pipeline"])


def test_riser_and_tread_errors_below_5_percent_on_average(noisy):
    for pipe in ("rtls", "rtls-htvr"):
        rows = [r["metrics"] for r in noisy if r["pipeline"] == pipe]
        risers = [m["riser_error_pct"] for m in rows if m["riser_error_pct"] is not None]
        treads = [m["tread_error_pct"] for m in rows if m["tread_error_pct"] is not None]
        assert len(risers) >= 5 and sum(risers) / len(risers) < 5.0, pipe
        assert len(treads) >= 3 and sum(treads) / len(treads) < 5.0, pipe


def test_without_noise_s2_orientation_is_within_half_a_degree(tmp_path):
    for r in _run(tmp_path, "quiet", NOISE_OFF):
        m = r["metrics"]
        assert not m["failed"], (r["episode"], r["pipeline"])
        assert m["alpha_deg_S2"] < 0.5 and abs(m["d_m_S2"]) < 1e-3, (r["episode"], r["pipeline"])
        assert m["riser_error_pct"] is None or m["riser_error_pct"] < 5.0


# Staircases outside the paper's three, across the building codes' range (issue 14, section 5):
# a low riser with a long tread seen from far, a high riser at -22 deg, a tall user at -29 deg
# close to the stairs, the lowest riser with the shortest tread. (riser, tread, yaw, L, user)
UNSEEN = [
    (0.1105, 0.3185, 9.10, 0.4977, 1.797),
    (0.2105, 0.2946, -22.36, 0.2981, 1.711),
    (0.1511, 0.2662, -28.88, 0.2967, 1.950),
    (0.1053, 0.2203, -2.08, 0.4632, 1.741),
]


@pytest.fixture(scope="module")
def unseen():
    from exobench.envs.sim import StairScenario, simulate_stairs

    keys = ("riser_m", "tread_m", "yaw_deg", "distance_m", "user_height_m")
    return [simulate_stairs(StairScenario.from_dict(dict(zip(keys, v, strict=True))), seed=7 + k) for k, v in enumerate(UNSEEN)]


@pytest.mark.parametrize("name", ["rtls", "rtls-htvr"])
def test_staircases_outside_the_paper_are_read_within_5_percent(unseen, name):
    from exobench.benchmarks.tracks.stairs.metrics import score_staircase
    from exobench.perception.stairs import RtlsHtvrStairs, RtlsStairs

    cls = {"rtls": RtlsStairs, "rtls-htvr": RtlsHtvrStairs}[name]
    for ep in unseen:
        pipe = cls()
        pipe.reset(ep.calibration)
        for frame in ep.frames:
            pipe.process(frame)
        m = score_staircase(ep, pipe.finalize())
        where = (name, ep.scenario["riser_m"], ep.scenario["tread_m"], ep.scenario["yaw_deg"])
        assert not m["failed"], where
        assert m["riser_error_pct"] < 5.0, (where, m["riser_error_pct"])
        assert m["tread_error_pct"] < 5.0, (where, m["tread_error_pct"])  # NaN (not read) fails too
        assert abs(m["touchdown_error_m"]) < 0.01, where


def test_general_suite_is_drawn_from_the_run_seed_within_the_building_codes_range():
    from exobench.benchmarks.tracks import get_track
    from exobench.benchmarks.tracks.stairs import general

    track = get_track("stairs")
    a, b = track.cases("general", 0), track.cases("general", 1)
    assert len(a) == len(b) == general.GENERAL_EPISODES
    assert [c.scenario for c in a] == [c.scenario for c in track.cases("general", 0)]  # same seed, same draw
    assert [c.scenario for c in a] != [c.scenario for c in b]  # another seed, another draw
    for c in a + b:
        s = c.scenario
        assert general.RISER_RANGE_M[0] <= s["riser_m"] <= general.RISER_RANGE_M[1]
        assert general.TREAD_RANGE_M[0] <= s["tread_m"] <= general.TREAD_RANGE_M[1]
        assert abs(s["yaw_deg"]) <= 30.0 and 0.25 <= s["distance_m"] <= 0.50
        assert 1.55 <= s["user_height_m"] <= 1.95 and c.group == "general"
    # the draw covers the range, not one corner of it
    risers = [c.scenario["riser_m"] for c in a]
    assert min(risers) < 0.12 and max(risers) > 0.20


# Two episodes of the general suite that missed a target with the read-out and riser exit of
# before (run seed 2, general/03: a riser-top point tilted S2, riser error 28.6 %, touch-down
# 12.9 mm; run seed 1, general/33: S2 never reliable, riser unread).
@pytest.mark.parametrize("run_seed,case_name", [(2, "general/03"), (1, "general/33")])
def test_general_suite_episodes_that_failed_before_meet_every_target(run_seed, case_name):
    from exobench.benchmarks.runner import episode_seed
    from exobench.benchmarks.tracks import get_track
    from exobench.benchmarks.tracks.stairs.metrics import score_staircase
    from exobench.perception.stairs import RtlsStairs

    track = get_track("stairs")
    case = next(c for c in track.cases("general", run_seed) if c.name == case_name)
    ep = track.simulate(track.validate_scenario(case.scenario), episode_seed(run_seed, case_name))
    pipe = RtlsStairs()
    pipe.reset(ep.calibration)
    for frame in ep.frames:
        pipe.process(frame)
    m = score_staircase(ep, pipe.finalize())
    assert m["riser_error_pct"] < 5.0 and m["tread_error_pct"] < 5.0, m  # NaN (not read) fails too
    assert abs(m["touchdown_error_m"]) < 0.01, m["touchdown_error_m"]
