"""A toy track on a real world, with its pipeline: weigh the walker with the insole pads.

The worked example of ``docs/adding-a-track.md``, small enough to read in one go and complete
enough to pass every conformance test a shipped track passes (``tests/test_conformance.py``
registers it beside the shipped ones). It reuses the stairs world and scenario (a climbing step,
:func:`exobench.envs.sim.simulate_stairs`) with a rig of the four insole pads only, and its
pipeline uses nothing but ``exobench.core``: the calibration, the frames, ``check_frame`` and the
input counters.

The physics the estimate rests on: the pads carry the body's weight plus its vertical
acceleration, ``sum_p F_p(t) = m (g + a_z(t))``, and a step that starts and ends at rest has a
mean ``a_z`` of about zero, so ``m ~ sum_p mean_t F_p(t) / g``. The truth is the scenario's
user mass plus the device's (:class:`exobench.models.exo_spec.ExoSpec`).
"""

from __future__ import annotations

import dataclasses
import json
import math
from collections.abc import Mapping
from pathlib import Path
from typing import Any, ClassVar

import numpy as np

from exobench.benchmarks.tracks.spec import Case, ParamInfo, Reference, SummaryRow, param_infos
from exobench.core import Calibration, ContactSample, Episode
from exobench.core.counters import FrameCounts, StreamCounters, nan_values
from exobench.core.limits import contact_absurd
from exobench.core.pipeline import check_frame


@dataclasses.dataclass(frozen=True)
class ScaleEstimate:
    """The walker's mass, kg (NaN when no pad was read), and the input counters by kind."""

    mass_kg: float
    counts: dict[str, FrameCounts] = dataclasses.field(default_factory=dict)


class ToyScaleTrack:
    """Weigh the walker (user and exoskeleton) from the insole pads of a climbing step."""

    name: ClassVar[str] = "toy-scale"
    suites: ClassVar[tuple[str, ...]] = ("quick",)
    default_suite: ClassVar[str] = "quick"
    streams: ClassVar[tuple[str, ...]] = ("contact",)
    estimate_type: ClassVar[type] = ScaleEstimate
    scoring_keys: ClassVar[frozenset[str]] = frozenset()
    smoke_scenario: ClassVar[Mapping[str, Any]] = {"duration_s": 1.5}
    timing_metrics: ClassVar[frozenset[str]] = frozenset()
    headline_metrics: ClassVar[tuple[str, ...]] = ("mass_error_kg",)
    report_intro: ClassVar[str] = "A toy track: its reference figure is invented."

    def params(self) -> list[ParamInfo]:
        from exobench.envs.sim.scenarios.stairs import PARAMS

        return param_infos(PARAMS)

    def validate_scenario(self, values: Mapping[str, Any]) -> dict[str, Any]:
        from exobench.envs.sim import StairScenario

        return dataclasses.asdict(StairScenario.from_dict(dict(values)))

    def cases(self, suite: str, run_seed: int = 0) -> list[Case]:
        from exobench.core import UnknownNameError

        if suite not in self.suites:
            raise UnknownNameError("toy-scale suite", suite, self.suites)
        return [Case("light", "users", {"user_mass_kg": 55.0}, figure=True), Case("heavy", "users", {"user_mass_kg": 110.0})]

    def group_label(self, case: Case, scenario: Mapping[str, Any]) -> str:
        return case.group

    def simulate(self, scenario: Mapping[str, Any], seed: int) -> Episode:
        from exobench.envs.sim import StairScenario, simulate_stairs

        sc = StairScenario.from_dict(dict(scenario))
        return simulate_stairs(sc, seed, rig=tuple(s for s in sc.rig() if s.kind == "contact"))

    @staticmethod
    def true_mass_kg(episode: Episode) -> float:
        from exobench.envs.sim import StairScenario

        exo = StairScenario.from_dict(dict(episode.scenario)).exo_spec()
        return exo.user_mass_kg + exo.exo_mass_kg

    def score(self, episode: Episode, estimate: ScaleEstimate, scoring: Mapping[str, Any] | None = None) -> dict[str, Any]:
        truth = self.true_mass_kg(episode)
        m = float(estimate.mass_kg) if isinstance(estimate.mass_kg, (int, float)) else math.nan
        return {"failed": False, "mass_kg": m, "true_mass_kg": truth, "mass_error_kg": m - truth}

    def failed_metrics(self, episode: Episode | None, reason: str) -> dict[str, Any]:
        truth = self.true_mass_kg(episode) if episode is not None else math.nan
        return {"failed": True, "failed_reason": reason, "mass_kg": math.nan, "true_mass_kg": truth, "mass_error_kg": math.nan}

    def references(self) -> list[Reference]:
        return [Reference("mass_error_kg", "< 5", "invented for the toy", value=5.0, bound="<")]

    def summary_rows(self) -> list[SummaryRow]:
        return [SummaryRow("mass_error_kg", "mass error (kg)", absolute=True, better="lower")]

    def figure_data(self, episode: Episode, estimates: dict[str, Any], scoring: Mapping[str, Any] | None = None) -> dict[str, Any]:
        pads = [f for f in episode.frames if isinstance(f, ContactSample)]
        return {"t_s": np.array([f.stamp_s for f in pads]), "force_n": np.array([f.force_n for f in pads])}

    def report_sections(self, records: list[dict[str, Any]], pipelines: list[str], out_dir: Path) -> list[str]:
        return ["## Weighing", "", f"{len(records)} records of {', '.join(pipelines)}.", ""]

    def write_recording(self, episode: Episode, estimates_by_pipeline: dict[str, Any], path: Path,
                        scoring: Mapping[str, Any] | None = None) -> Path:  # fmt: skip
        masses = {p: float(e.mass_kg) for p, e in estimates_by_pipeline.items()}
        Path(path).write_text(json.dumps({"true_mass_kg": self.true_mass_kg(episode), "mass_kg": masses}))
        return Path(path)


class ToyScale:
    """The pads' mean forces summed, over gravity (module docstring)."""

    name: ClassVar[str] = "toy-scale"
    track: ClassVar[str] = "toy-scale"

    @dataclasses.dataclass(frozen=True)
    class Config:
        g_m_s2: float = 9.81

    def __init__(self, config: Config | None = None) -> None:
        self.config = config or self.Config()
        self._was_reset = False

    def reset(self, calibration: Calibration) -> None:
        self._pads = {m.sensor_id for m in calibration.mounts_of_kind("contact")}
        self._counters = StreamCounters.of(calibration)
        self._sums: dict[str, list[float]] = {}
        self._was_reset = True

    def process(self, frame: Any) -> None:
        check_frame(self, frame, self._was_reset)
        c = self._counters.admit(frame, consumed=frame.sensor_id in self._pads)
        if c is None:
            return None
        n = nan_values(frame)
        if n:
            c.add_nan(n)
        elif contact_absurd(frame):
            c.add_absurd()
        else:
            c.used += 1
            s = self._sums.setdefault(frame.sensor_id, [0.0, 0.0])
            s[0] += float(frame.force_n)
            s[1] += 1.0
        return None

    def finalize(self) -> ScaleEstimate:
        total = sum(f / n for f, n in self._sums.values()) if self._sums else math.nan
        return ScaleEstimate(total / self.config.g_m_s2, self._counters.snapshot())
