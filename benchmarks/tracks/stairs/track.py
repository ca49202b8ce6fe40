"""The stairs track's spec: staircase identification from calf ToF rays (seeds/004, Sec. V).

Suites (cases are deterministic; the run seed drives the sensor noise, and the draws of ``general``):

- ``quick`` (the default run): cases A, B, C and three random poses on the middle staircase.
- ``paper``: cases A (frontal, L = 0.305 m), B (yaw +23 deg, L = 0.27 m) and C (yaw -23 deg,
  L = 0.49 m) on riser/tread 0.162/0.280 m, then the staircases 0.153/0.294, 0.162/0.280 and
  0.175/0.270 m with 20 random poses each (yaw uniform in +-25 deg, distance of the climbing
  toe from the first riser uniform in 0.25-0.5 m, from a generator seeded with POSE_SEED).
- ``general``: 60 staircases never seen, drawn from the run seed across the building codes'
  range (risers 0.10-0.22 m, treads 0.22-0.35 m, yaw within +-30 deg, distance 0.25-0.50 m,
  users of 1.55-1.95 m; :mod:`.general`).
- ``full``: the paper grid, the same grid with every sensor noise off, and cases A, B, C for
  users of 1.60 m and 1.90 m.

Scoring is in :mod:`.metrics`, the report's figures in :mod:`.report`, the rerun recording in
:mod:`.recording`; the published figures below are printed beside ours.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from pathlib import Path
from typing import Any, ClassVar

import numpy as np

from exobench.core.episode import Episode
from exobench.core.errors import UnknownNameError
from exobench.core.estimates import StaircaseEstimate

from ..spec import Case, ParamInfo, Reference, SummaryRow, param_infos
from .general import general_cases
from .metrics import failure_metrics, score_staircase
from .report import side_view_data

POSE_SEED = 4  # the paper is seeds/004
POSES_PER_STAIRCASE = 20
YAW_RANGE_DEG = (-25.0, 25.0)
DISTANCE_RANGE_M = (0.25, 0.5)
STAIRCASES = ((0.153, 0.294), (0.162, 0.280), (0.175, 0.270))  # riser, tread (m), Tab. III
CASES: dict[str, dict[str, float]] = {
    "A": {"riser_m": 0.162, "tread_m": 0.280, "yaw_deg": 0.0, "distance_m": 0.305},
    "B": {"riser_m": 0.162, "tread_m": 0.280, "yaw_deg": 23.0, "distance_m": 0.27},
    "C": {"riser_m": 0.162, "tread_m": 0.280, "yaw_deg": -23.0, "distance_m": 0.49},
}
QUICK_POSES = 3
USER_HEIGHTS_M = (1.60, 1.90)
NOISE_OFF = {"tof_noise_m": 0.0, "tof_dropout": 0.0, "imu_noise_scale": 0.0, "imu_orientation_deg": 0.0, "encoder_noise_rad": 0.0}
STAIR_GROUPS = tuple(f"{r:.3f}/{t:.3f}" for r, t in STAIRCASES)


def random_poses(staircase_index: int, n: int = POSES_PER_STAIRCASE) -> list[dict[str, float]]:
    """The paper suite's poses on one staircase (deterministic, rounded to 0.01 deg / 0.1 mm)."""
    rng = np.random.default_rng([POSE_SEED, staircase_index])
    yaw = rng.uniform(*YAW_RANGE_DEG, size=n)
    dist = rng.uniform(*DISTANCE_RANGE_M, size=n)
    return [{"yaw_deg": round(float(y), 2), "distance_m": round(float(d), 4)} for y, d in zip(yaw, dist, strict=True)]


def _staircase_cases(n_poses: int, indices: tuple[int, ...] = (0, 1, 2)) -> list[Case]:
    out = []
    for k in indices:
        riser, tread = STAIRCASES[k]
        for j, pose in enumerate(random_poses(k)[:n_poses]):
            out.append(
                Case(f"{riser:.3f}-{tread:.3f}/pose{j:02d}", STAIR_GROUPS[k], {"riser_m": riser, "tread_m": tread, **pose})
            )
    return out


def _abc(figure: bool = True) -> list[Case]:
    return [Case(name, name, dict(values), figure=figure) for name, values in CASES.items()]


def _ref(metric: str, text: str, source: str, groups: tuple[str, ...] = (), pipelines: tuple[str, ...] = (), **kw: Any) -> Reference:
    return Reference(metric, text, source, groups, pipelines, **kw)


def _tables_i_ii() -> list[Reference]:
    """Tables I (general surfaces, 'rtls') and II (HTVR); alpha in deg, d in mm."""
    general = {  # case -> S_i -> (alpha_deg, d_mm)
        "A": [(2.104, -0.093), (1.999, 1.10), (2.607, -0.364), (10.749, -5.90)],
        "B": [(4.340, -0.682), (5.287, -0.013), (2.350, 2.50), (8.147, -16.2)],
        "C": [(2.295, 4.90), (3.916, 2.10), (6.744, 13.2)],
    }
    htvr = {  # alpha is 0 by construction on treads ('-' in the table)
        "A": [(None, -1.64), (0.214, 1.47), (None, -6.36), (3.139, -3.50)],
        "B": [(None, -2.91), (2.541, -0.72), (None, -4.22), (5.979, -15.0)],
        "C": [(None, -1.76), (1.096, 4.12), (None, 1.65)],
    }
    refs = []
    for table, rows, pipes in (("Tab. I", general, ("rtls",)), ("Tab. II", htvr, ("rtls-htvr",))):
        for case, surfaces in rows.items():
            for i, (alpha, d_mm) in enumerate(surfaces):
                if alpha is not None:
                    refs.append(_ref(f"alpha_deg_S{i}", f"{alpha:g}", table, (case,), pipes, value=alpha))
                refs.append(_ref(f"d_m_S{i}", f"{d_mm:g}", table, (case,), pipes, value=d_mm / 1000))
    return refs


def published_references() -> list[Reference]:
    """Every figure of Sec. V the track compares with (values in the summary's units)."""
    refs = _tables_i_ii()
    refs += [
        _ref("alpha_deg_S2", "< 3", "Sec. V-A", ("A", "B"), value=3.0, bound="<"),
        _ref("d_m_S2", "|d| < 3", "Sec. V-A", ("A", "B"), value=0.003, bound="<"),
    ]
    for case, e_mm in (("A", -4.1), ("B", -1.7), ("C", -6.9)):  # 0.1579, 0.1603, 0.1551 vs 0.162
        refs.append(_ref("touchdown_error_m", f"{e_mm:g}", "Sec. V-A", (case,), ("rtls",), value=e_mm / 1000))
    for case, e_mm in (("A", -6.36), ("B", -4.22), ("C", 1.65)):  # Tab. II: d = e for S2
        refs.append(_ref("touchdown_error_m", f"{e_mm:g}", "Tab. II", (case,), ("rtls-htvr",), value=e_mm / 1000))
    refs.append(_ref("touchdown_error_m", "|e| < 10", "Sec. V-C", value=0.01, bound="<"))
    table3 = (  # riser mean, std, error %, tread mean, std, error % (HTVR)
        (0.157, 2.8, "2.61 ± 1.83", 2.61, 0.290, 3.0, "1.36 ± 1.02", 1.36),
        (0.169, 3.4, "4.32 ± 2.10", 4.32, 0.272, 3.2, "2.86 ± 1.14", 2.86),
        (0.179, 3.2, "2.29 ± 1.83", 2.29, 0.264, 3.5, "2.22 ± 1.30", 2.22),
    )
    for group, (rm, rs, rtxt, rv, tm, ts, ttxt, tv) in zip(STAIR_GROUPS, table3, strict=True):
        g = (group,)
        refs += [
            _ref("riser_est_m", f"{rm:.3f} ± {rs / 1000:.4f}", "Tab. III", g, value=rm),
            _ref("riser_error_pct", rtxt, "Tab. III", g, value=rv),
            _ref("tread_est_m", f"{tm:.3f} ± {ts / 1000:.4f}", "Tab. III", g, value=tm),
            _ref("tread_error_pct", ttxt, "Tab. III", g, value=tv),
        ]
    refs += [
        _ref("time_per_point_us", "685 ± 437", "Sec. V-B, Cortex-M4 168 MHz", (), ("rtls",), value=685.0),
        _ref("time_per_point_us", "427 ± 132", "Sec. V-B, Cortex-M4 168 MHz", (), ("rtls-htvr",), value=427.0),
    ]
    return refs


SUMMARY_ROWS = [
    SummaryRow("alpha_deg_S2", "alpha S2 (deg)"),
    SummaryRow("d_m_S2", "d S2 (mm)", scale=1000),
    SummaryRow("riser_est_m", "riser (m)", digits=4),
    SummaryRow("riser_error_pct", "riser error (%)", better="lower"),
    SummaryRow("tread_est_m", "tread (m)", digits=4),
    SummaryRow("tread_error_pct", "tread error (%)", better="lower"),
    SummaryRow("touchdown_error_m", "|e| touch-down (mm)", scale=1000, absolute=True, better="lower"),
    SummaryRow("touchdown_error_m", "e touch-down (mm)", scale=1000, terminal=False),
    SummaryRow("s2_reliable_s", "S2 reliable after lift-off (s)"),
    SummaryRow("s2_remaining_travel_m", "foot travel left then (m)", digits=3),
    SummaryRow("assignment_accuracy", "assignment accuracy (%)", scale=100, digits=1, better="higher"),
    SummaryRow("assigned_accuracy", "accuracy of kept points (%)", scale=100, digits=1, terminal=False),
    SummaryRow("discarded_fraction", "discarded (%)", scale=100, digits=1, terminal=False),
    SummaryRow("n_points", "points used", digits=0, terminal=False),
    SummaryRow("time_per_point_us", "time per point (us)", digits=1),
] + [
    SummaryRow(key, label, scale=scale, terminal=False)
    for i in (0, 1, 3, 4)
    for key, label, scale in ((f"alpha_deg_S{i}", f"alpha S{i} (deg)", 1.0), (f"d_m_S{i}", f"d S{i} (mm)", 1000.0))
]


class StairsTrack:
    """Track protocol implementation for staircase identification (see module docstring)."""

    name: ClassVar[str] = "stairs"
    suites: ClassVar[tuple[str, ...]] = ("quick", "paper", "general", "full")
    default_suite: ClassVar[str] = "quick"
    streams: ClassVar[tuple[str, ...]] = ("tof", "imu", "joints", "contact")
    estimate_type: ClassVar[type] = StaircaseEstimate
    smoke_scenario: ClassVar[Mapping[str, Any]] = {}
    timing_metrics: ClassVar[frozenset[str]] = frozenset({"time_per_point_us"})
    scoring_keys: ClassVar[frozenset[str]] = frozenset()
    headline_metrics: ClassVar[tuple[str, ...]] = ("riser_error_pct", "tread_error_pct", "touchdown_error_m", "assignment_accuracy")

    def params(self) -> list[ParamInfo]:
        from exobench.envs.sim.scenarios.stairs import PARAMS

        return param_infos(PARAMS)

    def validate_scenario(self, values: Mapping[str, Any]) -> dict[str, Any]:
        from exobench.envs.sim import StairScenario
        from exobench.envs.sim.scenario import check_scenario

        scenario = StairScenario.from_dict(dict(values))
        check_scenario(scenario)
        return dataclasses.asdict(scenario)

    def noise_off(self) -> dict[str, Any]:
        """Scenario values that switch every sensor noise, orientation error and dropout off."""
        names = {p.name for p in self.params()}
        return {k: v for k, v in NOISE_OFF.items() if k in names}

    def cases(self, suite: str, run_seed: int = 0) -> list[Case]:
        if suite == "quick":
            return _abc() + _staircase_cases(QUICK_POSES, (1,))
        if suite == "paper":
            return _abc() + _staircase_cases(POSES_PER_STAIRCASE)
        if suite == "general":
            return list(general_cases(run_seed))
        if suite == "full":
            base = _abc() + _staircase_cases(POSES_PER_STAIRCASE)
            off = self.noise_off()
            quiet = [Case(f"noise-off/{c.name}", f"{c.group} noise-off", {**c.scenario, **off}) for c in base]
            heights = [
                Case(f"h{h:.2f}/{c.name}", f"{c.group} h={h:.2f}", {**c.scenario, "user_height_m": h})
                for h in USER_HEIGHTS_M
                for c in _abc(figure=False)
            ]
            return base + quiet + heights
        raise UnknownNameError("suite", suite, self.suites)

    def group_label(self, case: Case, scenario: Mapping[str, Any]) -> str:
        """The case's group, naming the staircase that is run when ``--set`` changed its riser or
        tread: "0.162/0.280" becomes "0.190/0.260", "A" becomes "A 0.190/0.260" (so the paper's
        figures for the case's own staircase are not printed beside it)."""
        own = (float(case.scenario.get("riser_m", np.nan)), float(case.scenario.get("tread_m", np.nan)))
        ran = (float(scenario["riser_m"]), float(scenario["tread_m"]))
        if own == ran:
            return case.group
        old, new = f"{own[0]:.3f}/{own[1]:.3f}", f"{ran[0]:.3f}/{ran[1]:.3f}"
        return case.group.replace(old, new) if old in case.group else f"{case.group} {new}"

    def simulate(self, scenario: dict[str, Any], seed: int) -> Episode:
        from exobench.envs.sim import StairScenario, simulate_stairs

        return simulate_stairs(StairScenario.from_dict(dict(scenario)), seed)

    def score(self, episode: Episode, estimate: Any, scoring: Mapping[str, Any] | None = None) -> dict[str, Any]:
        return score_staircase(episode, estimate)

    def failed_metrics(self, episode: Episode | None, reason: str) -> dict[str, Any]:
        return failure_metrics(episode, reason)

    def references(self) -> list[Reference]:
        return published_references()

    def summary_rows(self) -> list[SummaryRow]:
        return list(SUMMARY_ROWS)

    def figure_data(self, episode: Episode, estimates: dict[str, Any],
                    scoring: Mapping[str, Any] | None = None) -> dict[str, Any]:
        return side_view_data(episode, estimates)

    def write_recording(self, episode: Episode, estimates_by_pipeline: dict[str, Any], path: Path,
                        scoring: Mapping[str, Any] | None = None) -> Path:
        from .recording import write_recording

        return write_recording(episode, estimates_by_pipeline, path)

    report_intro = "Published figures come from the real exoskeleton of the staircase paper (seeds/004); ours from simulation."

    def report_sections(self, records: list[dict[str, Any]], pipelines: list[str], out: Path) -> list[str]:
        """Error distributions and the side views of the figure cases (as Fig. 4 of the paper)."""
        from .report import report_sections

        return report_sections(records, pipelines, out)
