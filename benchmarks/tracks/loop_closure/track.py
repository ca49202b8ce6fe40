"""The loop-closure track's spec: place recognition with SC++ and Gaussian Scan Context (seeds/003 4.2.3, 5.2.3).

A walker with a trunk LiDAR (VLP-16) and IMU walks the office ``"loop"`` route
(:mod:`exobench.envs.sim.scenarios.office`: round the corridor ring and back to the start, then a second
lap through the meeting room) in offices with glass partitions (panes reflect, ghosts appear
behind them) and polished floors. Every keyframe of a pipeline is matched against the earlier
ones; the match is scored against the true LiDAR poses (``EpisodeTruth.trajectory_w``) as the
thesis does (:mod:`.metrics`): a true loop exists when an earlier keyframe, at least
``exclude_recent_s`` older, lies within ``revisit_m`` = 5 m; a detection at threshold ``tau`` is a
true positive when its match is within 5 m. Metrics: the exact precision-recall curve over
``tau`` (stored with the record), its area (``pr_auc``), the maximum recall at 100 % precision
(Table 5.5's figure), best F1, time per keyframe, keyframes, revisits, invalid keyframes and the
relative-yaw error of the correct matches.

Scenario: the office walk's parameters (every row of ``OfficeScenario``'s table, up to 24
offices) plus the office's size (:data:`OFFICE_EXTRA`: parameters of
:class:`~exobench.models.office.OfficeParams` that ``OfficeScenario`` does not expose) and the
LiDAR's azimuth step. ``revisit_m`` and ``exclude_recent_s`` are its scoring settings
(``scoring_keys``): set like the scenario's values and stored with each record, they never reach
the simulation; the runner hands them to ``score``.

Suites (the run seed drives the sensor noise; the office layout is ``office_seed``):

- ``quick``: one short loop in a small glassy office (8 m corridors, one office, 60 % glass,
  polished floors), walked briskly (0.45 m steps, 0.5 s swings), cut 3 m after closing the ring;
  the LiDAR fires every 0.6 deg instead of 0.2 deg (a third of the rays, for speed).
- ``paper``: the whole loop route (two laps) in the default office (24 m corridors, 3 offices),
  as built (40 % glass, 30 % polished) and fully glazed and polished ("reflective").
- ``full``: the paper cases, two more office layouts, an office without glass, and a VLP-32.

Memory: a run streams its walks (:meth:`LoopClosureTrack.stream`): the frames go through the
pipelines as they are simulated, and no per-point LiDAR truth is kept (the scores and the
figure read the true LiDAR trajectory only), so a two-lap loop's memory does not grow with its
length. ``simulate`` (sessions, rerun recordings, which draw the scans) holds the whole walk.
"""

from __future__ import annotations

import dataclasses
import functools
from collections.abc import Mapping
from pathlib import Path
from typing import Any, ClassVar

from exobench.core.episode import Episode, EpisodeStream
from exobench.core.errors import UnknownNameError
from exobench.core.estimates import PlaceRecognitionEstimate
from exobench.models.world_params import ParamSpec

from ..office_walks import office_params, validate_office_scenario
from ..spec import Case, ParamInfo, Reference, SummaryRow
from .metrics import EXCLUDE_RECENT_S, REVISIT_M, failure_metrics, score_place_recognition
from .report import figure_arrays

SCORING_KEYS = ("revisit_m", "exclude_recent_s")
OFFICE_EXTRA: dict[str, ParamSpec] = {  # rows of the walk's table beyond OfficeScenario's (they reach the simulation)
    "n_offices": ParamSpec(3, 1, 24, "", "cellular offices along the north corridor (as many as fit corridor_length_m: "
                           "2.52 m each)", feeds=("office.n_offices",)),
    "corridor_length_m": ParamSpec(24.0, 8.0, 80.0, "m", "inside length of the building (office.corridor_length_m)",
                                   feeds=("office.corridor_length_m",)),
    "room_depth_m": ParamSpec(4.0, 1.6, 10.0, "m", "depth of the offices and meeting room (an open door, 0.94 m, and 0.6 m "
                              "must fit); the two corridors are this + 2 m apart", feeds=("office.room_depth_m",)),
    "meeting_room_m": ParamSpec(6.0, 1.5, 30.0, "m", "length of the meeting room (office.meeting_room_m)",
                                feeds=("office.meeting_room_m",)),
    "lidar_azimuth_step_deg": ParamSpec(0.0, 0.0, 2.0, "deg", "azimuth step of the spinning LiDAR (0 = the pattern's own; "
                                        "coarser = fewer rays, faster)"),
}  # fmt: skip
EXTRA: dict[str, ParamSpec] = {  # scoring only
    "revisit_m": ParamSpec(REVISIT_M, 0.5, 50.0, "m", "a revisit: an earlier keyframe within this distance (scoring)", low_open=True),
    "exclude_recent_s": ParamSpec(EXCLUDE_RECENT_S, 0.0, 600.0, "s", "keyframes younger than this are no revisit (scoring; the thesis' xi)"),
}
BRISK = {"step_length_m": 0.45, "swing_s": 0.5}
QUICK = {
    "route": "loop", "max_distance_m": 33.0, "n_offices": 1, "corridor_length_m": 8.0, "meeting_room_m": 2.5,
    "glass_fraction": 0.6, "polished_fraction": 0.6, "lidar_azimuth_step_deg": 0.6, **BRISK,
}  # fmt: skip
PAPER = {
    "office-loop": {"route": "loop", "max_distance_m": 500.0, **BRISK},
    "reflective-loop": {"route": "loop", "max_distance_m": 500.0, "glass_fraction": 1.0, "polished_fraction": 1.0, **BRISK},
}
FULL_EXTRA = {
    "office-loop/layout1": {**PAPER["office-loop"], "office_seed": 1},
    "office-loop/layout2": {**PAPER["office-loop"], "office_seed": 2},
    "no-glass-loop": {**PAPER["office-loop"], "glass_fraction": 0.0, "polished_fraction": 0.0},
    "reflective-loop/vlp32": {**PAPER["reflective-loop"], "lidar": "vlp32"},
}

TABLE_5_5 = {  # sequence -> (SC++, GSC height, GSC Huber) max recall at 100 % precision, %
    "KITTI 02": (57.8, 59.4, 69.7), "KITTI 05": (81.2, 82.6, 83.1), "KITTI 00": (80.8, 81.2, 83.7),
    "VBR Pincio": (36.1, 42.3, 49.3), "VBR Colosseo": (18.4, 16.2, 14.5),
}  # fmt: skip

SUMMARY_ROWS = [
    SummaryRow("max_recall_at_full_precision", "max recall at 100 % precision (%)", scale=100, digits=1, better="higher"),
    SummaryRow("pr_auc", "PR AUC", digits=3, better="higher"),
    SummaryRow("best_f1", "best F1", digits=3, better="higher"),
    SummaryRow("time_per_keyframe_ms", "time per keyframe (ms)", digits=1),
    SummaryRow("n_keyframes", "keyframes", digits=0),
    SummaryRow("n_revisits", "keyframes with a true loop", digits=0),
    SummaryRow("invalid_keyframes", "invalid keyframes", digits=0, terminal=False),
    SummaryRow("correct_match_fraction", "best match within 5 m, of revisits (%)", scale=100, digits=1, terminal=False),
    SummaryRow("yaw_error_deg", "yaw error of correct matches, median (deg)", digits=1, terminal=False),
    SummaryRow("tau_best_f1", "tau at best F1 (1 - sim)", digits=3, terminal=False),
]


@functools.cache  # one class, so that equal scenarios are equal (and checked once)
def _scenario_class() -> type:
    from exobench.envs.sim.scenario import scenario_base
    from exobench.envs.sim.scenarios.office import PARAMS, OfficeScenario

    table = {**PARAMS, **OFFICE_EXTRA}
    base = scenario_base("LoopOfficeScenario", "loop-closure office", table, OfficeScenario)

    class LoopOfficeScenario(base):  # type: ignore[misc,valid-type]
        """``OfficeScenario`` over :data:`OFFICE_EXTRA` too: the office's size (its rows feed
        ``office_params``) and the LiDAR's azimuth step."""

        def lidar_config(self) -> Any:
            cfg = super().lidar_config()
            pat = cfg.pattern
            step = float(self.lidar_azimuth_step_deg)
            if step <= 0 or pat.scan_kind != "spinning" or step <= pat.azimuth_step_deg:
                return cfg
            f = step / pat.azimuth_step_deg  # same sweep time: firing blocks further apart
            pat = dataclasses.replace(pat, azimuth_step_deg=step, firing_period_s=pat.firing_period_s * f)
            return dataclasses.replace(cfg, pattern=pat)

    return LoopOfficeScenario


def simulate_loop(scenario: Mapping[str, Any], seed: int) -> Episode:
    """One office walk of a validated scenario (the scoring keys dropped)."""
    from exobench.envs.sim.scenarios.office import simulate_office

    values = {k: v for k, v in scenario.items() if k not in SCORING_KEYS}
    return simulate_office(_scenario_class()(**values), seed)


def stream_loop(scenario: Mapping[str, Any], seed: int) -> EpisodeStream:
    """:func:`simulate_loop` as a stream, without per-point LiDAR truth: the scores and the
    figure read the LiDAR's true trajectory only, so a walk's memory stays flat in its length."""
    from exobench.envs.sim.scenarios.office import stream_office

    values = {k: v for k, v in scenario.items() if k not in SCORING_KEYS}
    return stream_office(_scenario_class()(**values), seed, lidar_truth=False)


def scoring_settings(scoring: Mapping[str, Any] | None) -> dict[str, float]:
    """``revisit_m`` and ``exclude_recent_s`` of the given settings, the thesis' values for those not given."""
    given = dict(scoring or {})
    return {"revisit_m": float(given.get("revisit_m", REVISIT_M)),
            "exclude_recent_s": float(given.get("exclude_recent_s", EXCLUDE_RECENT_S))}  # fmt: skip


def _ref(metric: str, text: str, source: str, pipelines: tuple[str, ...] = (), value: float | None = None) -> Reference:
    return Reference(metric, text, source, (), pipelines, value=value)


def published_references() -> list[Reference]:
    """Table 5.5 (max recall at 100 % precision) and section 5.2.3's time per keyframe."""
    refs = []
    for col, pipe in enumerate(("sc++", "gsc-height", "gsc-huber")):
        v = [vals[col] for vals in TABLE_5_5.values()]
        text = f"KITTI 02/05/00 {v[0]:g}/{v[1]:g}/{v[2]:g}, VBR Pincio/Colosseo {v[3]:g}/{v[4]:g}"
        refs.append(_ref("max_recall_at_full_precision", text, "Tab. 5.5", (pipe,)))
    refs.append(_ref("time_per_keyframe_ms", "54", "Sec. 5.2.3, i9-11950H", ("sc++",), 54.0))
    refs.append(_ref("time_per_keyframe_ms", "67", "Sec. 5.2.3, i9-11950H", ("gsc-huber",), 67.0))
    return refs


# ------------------------------------------------------------------------- the track


class LoopClosureTrack:
    """Track protocol implementation for place recognition (see the module docstring)."""

    name: ClassVar[str] = "loop-closure"
    suites: ClassVar[tuple[str, ...]] = ("quick", "paper", "full")
    default_suite: ClassVar[str] = "quick"
    streams: ClassVar[tuple[str, ...]] = ("lidar", "imu", "joints", "contact")
    estimate_type: ClassVar[type] = PlaceRecognitionEstimate
    smoke_scenario: ClassVar[Mapping[str, Any]] = {"max_distance_m": 1.5, "lidar_azimuth_step_deg": 1.0}
    timing_metrics: ClassVar[frozenset[str]] = frozenset({"time_per_keyframe_ms"})
    scoring_keys: ClassVar[frozenset[str]] = frozenset(SCORING_KEYS)
    headline_metrics: ClassVar[tuple[str, ...]] = ("max_recall_at_full_precision", "pr_auc", "best_f1")
    report_intro: ClassVar[str] = (
        "Published figures: Table 5.5 and section 5.2.3 of seeds/003 (KITTI and VBR sequences, "
        "i9-11950H); ours from simulated office loops with a trunk VLP-16."
    )

    def params(self) -> list[ParamInfo]:
        return office_params(EXTRA, _scenario_class())

    def validate_scenario(self, values: Mapping[str, Any]) -> dict[str, Any]:
        return validate_office_scenario(dict(values), EXTRA, _scenario_class())

    def group_label(self, case: Case, scenario: Mapping[str, Any]) -> str:
        return case.group

    def cases(self, suite: str, run_seed: int = 0) -> list[Case]:
        if suite == "quick":
            return [Case("small-loop", "small-loop", dict(QUICK), figure=True)]
        paper = [Case(n, n, dict(v), figure=True) for n, v in PAPER.items()]
        if suite == "paper":
            return paper
        if suite == "full":
            return paper + [Case(n, n, dict(v), figure=False) for n, v in FULL_EXTRA.items()]
        raise UnknownNameError("suite", suite, self.suites)

    def simulate(self, scenario: dict[str, Any], seed: int) -> Episode:
        return simulate_loop(scenario, seed)

    def stream(self, scenario: dict[str, Any], seed: int) -> EpisodeStream:
        return stream_loop(scenario, seed)

    def score(self, episode: Episode, estimate: Any, scoring: Mapping[str, Any] | None = None) -> dict[str, Any]:
        try:
            return score_place_recognition(episode, estimate, **scoring_settings(scoring))
        except Exception as e:  # a malformed estimate is a failed result, never a crash
            return failure_metrics(episode, f"scoring raised {type(e).__name__}: {e}")

    def failed_metrics(self, episode: Episode | None, reason: str) -> dict[str, Any]:
        return failure_metrics(episode, reason)

    def references(self) -> list[Reference]:
        return published_references()

    def summary_rows(self) -> list[SummaryRow]:
        return list(SUMMARY_ROWS)

    def figure_data(self, episode: Episode, estimates: dict[str, Any],
                    scoring: Mapping[str, Any] | None = None) -> dict[str, Any]:
        return figure_arrays(episode, estimates, **scoring_settings(scoring))

    def report_sections(self, records: list[dict[str, Any]], pipelines: list[str], out: Path) -> list[str]:
        """PR curves per episode (up to 12) and the figure cases' trajectories with their matches."""
        from .report import report_sections

        return report_sections(records, pipelines, out)

    def write_recording(self, episode: Episode, estimates_by_pipeline: dict[str, Any], path: Path,
                        scoring: Mapping[str, Any] | None = None) -> Path:
        """Scans, true surfaces and trajectory, and each pipeline's detections (see :mod:`.recording`)."""
        from .recording import write_recording

        return write_recording(episode, estimates_by_pipeline, path, **scoring_settings(scoring))
