"""The odometry track's spec: LiDAR trajectory estimation on office walks (seeds/003 Sec. 4.2.1, 5.2.1).

A walker with a trunk LiDAR walks an office route (:mod:`exobench.envs.sim.scenarios.office`); each
pipeline returns a :class:`TrajectoryEstimate` of the LiDAR, scored by
:mod:`..lidar_trajectory` against the true LiDAR pose (ATE/RPE as evo, drift per metre, loop
TE/OE/TVE when the route ends where it started, time per scan).

Suites (cases deterministic; the run seed drives the sensor noise):

- ``quick``: 4 m of the south corridor (the office LiDAR simulation runs about 1.6x real time).
- ``paper``: the whole corridor (featureless, where LiDAR odometry slides) and the ring route
  (once round the corridor ring, past the glass, back to the start: loop TE/OE/TVE), VLP-16 as
  in the thesis.
- ``full``: the paper cases with VLP-32 and Ouster-64 patterns, without range noise, and for
  users of 1.60 / 1.90 m, plus the whole office loop route (every office, two laps).

Memory: a run streams its walks (:meth:`OdometryTrack.stream`): the frames go through the
pipelines as they are simulated and no per-point LiDAR truth is kept (the scores need the
trajectory only), so a walk's peak memory does not grow with its length. ``simulate`` (sessions,
rerun recordings) holds the whole walk; the paper cases keep only the LiDAR truth's labels there
(``lidar_truth="labels"``: kind, surface and range per point, ~21 bytes instead of ~170).

Published figures (VBR outdoor sequences and a real indoor loop, not this office) are printed
beside ours: Table 5.3 (ATE/RPE per VBR sequence), Sec. 5.2.1 (185 ms per LEO-SLAM loop) and
Table 5.4 (KISS-ICP loop TE/OE without filter).
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any, ClassVar

import numpy as np

from exobench.core.episode import Episode, EpisodeStream
from exobench.core.errors import UnknownNameError
from exobench.core.estimates import TrajectoryEstimate

from ..lidar_trajectory import failure_metrics, score_trajectory, trajectory_figure_data, trajectory_sections
from ..office_recording import write_lidar_recording
from ..office_walks import (
    office_params,
    simulate_office_episode,
    stream_office_episode,
    validate_office_scenario,
)
from ..spec import Case, ParamInfo, Reference, SummaryRow

QUICK_M = 4.0
LABELS = {"lidar_truth": "labels"}
PAPER_CASES = {
    "corridor": {"route": "corridor", "max_distance_m": 60.0, **LABELS},
    "ring": {"route": "ring", "max_distance_m": 500.0, **LABELS},
}
LONG_CASES = {"loop": {"route": "loop", "max_distance_m": 500.0, **LABELS}}
FULL_VARIANTS = {
    "vlp32": {"lidar": "vlp32"},
    "ouster64": {"lidar": "ouster64"},
    "noise-off": {"lidar_noise_m": 0.0, "imu_noise_scale": 0.0, "encoder_noise_rad": 0.0},
    "h1.60": {"user_height_m": 1.60},
    "h1.90": {"user_height_m": 1.90},
}
VBR = ("Colosseum", "Diag", "Pincio", "Spagna")
TABLE_5_3 = {  # pipeline -> metric -> values per VBR sequence (m)
    "leo-slam": {"ate_m": (0.40748, 0.63319, 1.019423, 0.775329), "rpe_m": (0.33596, 0.30345, 0.328775, 1.027941)},
    "kiss-icp": {"ate_m": (1.51690, 1.39727, 0.78472, 1.04755), "rpe_m": (0.45299, 1.7908, 0.48580, 0.39860)},
}

SUMMARY_ROWS = [
    SummaryRow("ate_m", "ATE RMSE (m)", digits=3, better="lower"),
    SummaryRow("rpe_m", "RPE RMSE, consecutive (m)", digits=4, better="lower"),
    SummaryRow("rpe_1m_m", "RPE RMSE, 1 m (m)", digits=3, terminal=False),
    SummaryRow("drift_per_m", "drift (% of path)", scale=100, digits=2, better="lower"),
    SummaryRow("te_m", "loop TE (m)", digits=3, better="lower"),
    SummaryRow("oe_rad", "loop OE (rad)", digits=4),
    SummaryRow("tve_x_m", "loop TVE x (m)", digits=3, absolute=True, terminal=False),
    SummaryRow("tve_y_m", "loop TVE y (m)", digits=3, absolute=True, terminal=False),
    SummaryRow("tve_z_m", "loop TVE z (m)", digits=3, absolute=True, terminal=False),
    SummaryRow("time_per_scan_ms", "time per scan (ms)", digits=1),
    SummaryRow("failures", "poses not ok", digits=0),
    SummaryRow("path_m", "true path (m)", digits=1, terminal=False),
    SummaryRow("loop_edges", "loop edges", digits=0, terminal=False),
]


def published_references() -> list[Reference]:
    refs = []
    for pipe, metrics in TABLE_5_3.items():
        for metric, values in metrics.items():
            text = ", ".join(f"{name} {v:.3f}" for name, v in zip(VBR, values, strict=True))
            refs.append(Reference(metric, text, "Tab. 5.3, VBR", (), (pipe,), value=float(np.mean(values))))
    refs.append(Reference("time_per_scan_ms", "185 per loop", "Sec. 5.2.1", (), ("leo-slam",), value=185.0))
    refs += [
        Reference("te_m", "22.529 (no filter)", "Tab. 5.4, B1 + VLP-16 indoor", (), ("kiss-icp",), value=22.529),
        Reference("oe_rad", "0.270 (no filter)", "Tab. 5.4", (), ("kiss-icp",), value=0.270),
    ]
    return refs


class OdometryTrack:
    """Track protocol implementation for LiDAR odometry (see module docstring)."""

    name: ClassVar[str] = "odometry"
    suites: ClassVar[tuple[str, ...]] = ("quick", "paper", "full")
    default_suite: ClassVar[str] = "quick"
    streams: ClassVar[tuple[str, ...]] = ("lidar", "imu", "joints", "contact")
    estimate_type: ClassVar[type] = TrajectoryEstimate
    smoke_scenario: ClassVar[Mapping[str, Any]] = {"max_distance_m": 1.5}
    timing_metrics: ClassVar[frozenset[str]] = frozenset({"time_per_scan_ms"})
    scoring_keys: ClassVar[frozenset[str]] = frozenset()
    headline_metrics: ClassVar[tuple[str, ...]] = ("ate_m", "rpe_m", "drift_per_m", "te_m")
    report_intro = (
        "Published figures come from VBR outdoor sequences (Tab. 5.3) and a real indoor loop with a quadruped "
        "(Tab. 5.4) of seeds/003; ours from the simulated office walk."
    )

    def params(self) -> list[ParamInfo]:
        return office_params()

    def validate_scenario(self, values: Mapping[str, Any]) -> dict[str, Any]:
        return validate_office_scenario(values)

    def group_label(self, case: Case, scenario: Mapping[str, Any]) -> str:
        return case.group

    def cases(self, suite: str, run_seed: int = 0) -> list[Case]:
        if suite == "quick":
            return [Case("corridor-4m", "corridor", {"route": "corridor", "max_distance_m": QUICK_M}, figure=True)]
        paper = [Case(name, name, dict(sc), figure=True) for name, sc in PAPER_CASES.items()]
        if suite == "paper":
            return paper
        if suite == "full":
            extra = [
                Case(f"{v}/{c.name}", f"{c.group} {v}", {**c.scenario, **sv}, figure=False)
                for v, sv in FULL_VARIANTS.items()
                for c in paper
            ]
            long = [Case(name, name, dict(sc), figure=True) for name, sc in LONG_CASES.items()]
            return paper + extra + long
        raise UnknownNameError("suite", suite, self.suites)

    def simulate(self, scenario: dict[str, Any], seed: int) -> Episode:
        return simulate_office_episode(scenario, seed)

    def stream(self, scenario: dict[str, Any], seed: int) -> EpisodeStream:
        """The walk's frames as they are simulated; the trajectory scores need no per-point
        LiDAR truth, so none is kept (a walk's memory then stays flat in its length)."""
        return stream_office_episode(scenario, seed, lidar_truth=False)

    def score(self, episode: Episode, estimate: Any, scoring: Mapping[str, Any] | None = None) -> dict[str, Any]:
        return score_trajectory(episode, estimate)

    def failed_metrics(self, episode: Episode | None, reason: str) -> dict[str, Any]:
        return failure_metrics(episode, reason)

    def references(self) -> list[Reference]:
        return published_references()

    def summary_rows(self) -> list[SummaryRow]:
        return list(SUMMARY_ROWS)

    def figure_data(self, episode: Episode, estimates: dict[str, Any],
                    scoring: Mapping[str, Any] | None = None) -> dict[str, Any]:
        return trajectory_figure_data(episode, estimates)

    def report_sections(self, records: list[dict[str, Any]], pipelines: list[str], out: Path) -> list[str]:
        return trajectory_sections(out)

    def write_recording(self, episode: Episode, estimates_by_pipeline: dict[str, Any], path: Path,
                        scoring: Mapping[str, Any] | None = None) -> Path:
        return write_lidar_recording(episode, estimates_by_pipeline, path)
