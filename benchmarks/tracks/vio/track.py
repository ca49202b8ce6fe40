"""The vio track's spec: RGB-D-inertial odometry of a worn camera (seeds/002 II-C, Tables IV and V).

A walker wears an RGB-D camera (D455-like, 424x240 at 30 Hz) and its IMU (200 Hz) on the head,
the chest or the right thigh, through an office or along a stair or ramp course
(:mod:`.scenario`); each pipeline receives the camera's ``rgbd`` frames and its ``imu`` samples
with the calibration and returns a :class:`TrajectoryEstimate` of the camera's optical frame at
each frame stamp, in its own gravity-aligned world, scored against the true camera pose
(:mod:`.metrics`).

Suites (cases deterministic; the run seed drives the sensor noise and the view process):

- ``quick``: 0.8 m office walks with the head, chest and thigh camera and a 1.2 m walk there and
  back with the chest camera (a closed loop), on textured walls;
- ``paper``: the ten EuRoC-like office sequences of Table IV (35-90 m, wander to jog), two closed
  loops (Table V) and three course walks (:mod:`.paper`);
- ``course``: the paper's course walks alone;
- ``general``: eight sequences drawn from the run seed (:mod:`.general`).

Memory: a run streams its walks (:meth:`VioTrack.stream`): the frames go through the pipelines
as they are rendered and the episode keeps the camera's and the IMU's true poses only.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any, ClassVar

from exobench.core.episode import Episode, EpisodeStream
from exobench.core.errors import UnknownNameError
from exobench.core.estimates import TrajectoryEstimate

from ..spec import Case, ParamInfo, Reference, SummaryRow
from . import paper
from .general import general_cases
from .metrics import failure_metrics, score_vio
from .scenario import simulate_vio, stream_vio, validate_vio, vio_params

SUMMARY_ROWS = [
    SummaryRow("ate_m", "ATE RMSE (m)", digits=3, better="lower"),
    SummaryRow("rpe_1m_m", "RPE RMSE, 1 m (m)", digits=3, better="lower"),
    SummaryRow("drift_per_m", "drift (% of path)", scale=100, digits=2, better="lower"),
    SummaryRow("te_m", "loop TE (m)", digits=3, better="lower"),
    SummaryRow("oe_rad", "loop OE (rad)", digits=4),
    SummaryRow("tve_x_m", "loop drift x (m)", digits=3, absolute=True, terminal=False),
    SummaryRow("tve_y_m", "loop drift y (m)", digits=3, absolute=True, terminal=False),
    SummaryRow("tve_z_m", "loop drift z (m)", digits=3, absolute=True, terminal=False),
    SummaryRow("lost_frac", "frames without a pose (%)", scale=100, digits=1, better="lower"),
    SummaryRow("init_s", "time to the first pose (s)", digits=2),
    SummaryRow("time_per_frame_ms", "time per frame, median (ms)", digits=1),
    SummaryRow("time_per_frame_ms_p95", "time per frame, p95 (ms)", digits=1, terminal=False),
    SummaryRow("path_m", "true path (m)", digits=1, terminal=False),
]


class VioTrack:
    """Track protocol implementation for worn-camera visual-inertial odometry (module docstring)."""

    name: ClassVar[str] = "vio"
    suites: ClassVar[tuple[str, ...]] = ("quick", "paper", "course", "general")
    default_suite: ClassVar[str] = "quick"
    streams: ClassVar[tuple[str, ...]] = ("rgbd", "imu")
    estimate_type: ClassVar[type] = TrajectoryEstimate
    smoke_scenario: ClassVar[Mapping[str, Any]] = {"max_distance_m": 0.5, "surfaces": "textured"}
    timing_metrics: ClassVar[frozenset[str]] = frozenset({"time_per_frame_ms", "time_per_frame_ms_p95"})
    scoring_keys: ClassVar[frozenset[str]] = frozenset()
    headline_metrics: ClassVar[tuple[str, ...]] = ("ate_m", "rpe_1m_m", "drift_per_m", "te_m", "lost_frac")
    report_intro = (
        "Published figures come from the EuRoC MAV sequences (Tab. IV) and one real closed loop walked with a "
        "head/chest RGB-D camera (Tab. V) of seeds/002; ours from simulated office and course walks."
    )

    def params(self) -> list[ParamInfo]:
        return vio_params()

    def validate_scenario(self, values: Mapping[str, Any]) -> dict[str, Any]:
        return validate_vio(values)

    def group_label(self, case: Case, scenario: Mapping[str, Any]) -> str:
        return case.group

    def cases(self, suite: str, run_seed: int = 0) -> list[Case]:
        if suite == "quick":
            return paper.quick_cases()
        if suite == "paper":
            return paper.paper_cases()
        if suite == "course":
            return paper.course_cases()
        if suite == "general":
            return list(general_cases(int(run_seed)))
        raise UnknownNameError("suite", suite, self.suites)

    def simulate(self, scenario: dict[str, Any], seed: int) -> Episode:
        return simulate_vio(scenario, seed)

    def stream(self, scenario: dict[str, Any], seed: int) -> EpisodeStream:
        return stream_vio(scenario, seed)

    def score(self, episode: Episode, estimate: Any, scoring: Mapping[str, Any] | None = None) -> dict[str, Any]:
        return score_vio(episode, estimate)

    def failed_metrics(self, episode: Episode | None, reason: str) -> dict[str, Any]:
        return failure_metrics(episode, reason)

    def references(self) -> list[Reference]:
        """The published figures of the pipelines that are registered (the paper's D-VIO and its
        VINS-Mono-like ablation until ``dvio`` and ``dvio-no-depth`` are installed have none to
        stand beside; the report's Tables IV and V print them all)."""
        from ...registry import default_registry

        have = set(default_registry().names(track=self.name))
        return [r for r in paper.references() if set(r.pipelines) <= have]

    def summary_rows(self) -> list[SummaryRow]:
        return list(SUMMARY_ROWS)

    def figure_data(self, episode: Episode, estimates: dict[str, Any],
                    scoring: Mapping[str, Any] | None = None) -> dict[str, Any]:
        from .report import vio_figure_data

        return vio_figure_data(episode, estimates)

    def report_sections(self, records: list[dict[str, Any]], pipelines: list[str], out: Path) -> list[str]:
        from .report import vio_sections

        return vio_sections(records, pipelines, out)

    def write_recording(self, episode: Episode, estimates_by_pipeline: dict[str, Any], path: Path,
                        scoring: Mapping[str, Any] | None = None) -> Path:
        from .recording import write_vio_recording

        return write_vio_recording(episode, estimates_by_pipeline, path)
