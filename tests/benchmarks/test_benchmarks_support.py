"""Hand-built staircase episodes, a fake track and fake pipelines for the benchmark tests.

The fakes let the harness be tested without MuJoCo: ``FakeTrack`` is the real stairs track
(suites, scorer, references) with ``simulate`` replaced by :func:`make_episode`, which builds
an exactly known staircase (first riser at x = 0, ascending along +x) and a ToF stream whose
ranges depend on the seed.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, ClassVar

import numpy as np
import pytest

from exobench.benchmarks.tracks import registry as track_registry
from exobench.benchmarks.tracks.spec import ParamInfo
from exobench.benchmarks.tracks.stairs import StairsTrack
from exobench.core import (
    Calibration,
    Episode,
    EpisodeTruth,
    PlanarSurface,
    PlaneEstimate,
    PointAssignment,
    SceneTruth,
    StaircaseEstimate,
    StairTruth,
    ToFReading,
    ToFTruth,
    UnknownNameError,
    check_range,
)
from exobench.core.transforms import make_T

WIDTH = 1.2


def _rect(x0: float, x1: float, z0: float, z1: float, vertical: bool) -> np.ndarray:
    h = WIDTH / 2
    if vertical:  # plane x = x0, spanning z0..z1
        return np.array([[x0, -h, z0], [x0, h, z0], [x0, h, z1], [x0, -h, z1]])
    return np.array([[x0, -h, z0], [x1, -h, z0], [x1, h, z0], [x0, h, z0]])


def staircase_truth(riser_m: float = 0.162, tread_m: float = 0.28, n_steps: int = 2) -> SceneTruth:
    """Ground (id 0), then riser k (2k-1) and tread k (2k), the last tread a landing."""
    surfaces = [PlanarSurface(0, "ground", np.array([0.0, 0, 1]), np.zeros(3), _rect(-2.0, 0.0, 0.0, 0.0, False))]
    for k in range(1, n_steps + 1):
        x = (k - 1) * tread_m
        z0, z1 = (k - 1) * riser_m, k * riser_m
        surfaces.append(PlanarSurface(2 * k - 1, "riser", np.array([-1.0, 0, 0]), np.array([x, 0, z0]), _rect(x, x, z0, z1, True)))
        kind = "landing" if k == n_steps else "tread"
        x1 = x + (1.2 if k == n_steps else tread_m)
        surfaces.append(PlanarSurface(2 * k, kind, np.array([0.0, 0, 1]), np.array([x, 0, z1]), _rect(x, x1, z1, z1, False)))
    return SceneTruth(tuple(surfaces), {}, {"riser_m": riser_m, "tread_m": tread_m, "n_steps": n_steps}, "staircase")


def make_episode(scenario: dict[str, Any] | None = None, seed: int = 0, n_tof: int = 40) -> Episode:
    """An episode with a known staircase, foot path and ToF stream (ranges depend on ``seed``)."""
    scenario = {"riser_m": 0.162, "tread_m": 0.28, "yaw_deg": 0.0, "distance_m": 0.305, **(scenario or {})}
    truth_scene = staircase_truth(scenario["riser_m"], scenario["tread_m"])
    rng = np.random.default_rng(seed)
    frames, tof_truth = [], []
    ids = [0, 1, 2, 2, 3]
    for k in range(n_tof):
        t = 0.5 + 0.025 * k
        sid = "tof_r_lat" if k % 2 else "tof_r_med"
        rng_m = 0.4 + 0.001 * rng.standard_normal()
        frames.append(ToFReading(t, sid, rng_m))
        T = make_T(np.eye(3), np.array([-0.3 + 0.01 * k, 0.0, 0.3]))
        tof_truth.append(ToFTruth(t, sid, rng_m, np.array([0.01 * k, 0.0, 0.0]), ids[k % len(ids)], T))
    ts = np.linspace(0.5, 1.5, 21)
    foot = np.column_stack([ts, np.linspace(-0.3, 0.14, 21), np.zeros(21), 0.2 * np.sin(np.pi * (ts - 0.5))])
    truth = EpisodeTruth(
        scene=truth_scene,
        T_world_estimator=make_T(np.eye(3), np.array([-0.35, 0.05, 0.0])),
        stairs=StairTruth(tuple(tof_truth), "l", np.array([0.14, 0.0, scenario["riser_m"]]), foot),
        body_tracks={"pelvis": np.array([[0.5, -0.3, 0, 0.9, 1, 0, 0, 0], [1.5, 0.0, 0, 1.0, 1, 0, 0, 0]])},
        events={"liftoff_s": 0.5, "touchdown_s": 1.5},
    )
    calib = Calibration("<robot/>", "pelvis", (), (), 0.07, 0.26, 0.05, extra={"truth_for_fakes": scenario})
    return Episode(dict(scenario), seed, calib, tuple(frames), truth)


FAKE_PARAMS = {
    "riser_m": (0.162, 0.0, 0.30, "m", "riser height"),
    "tread_m": (0.28, 0.15, 0.60, "m", "tread depth"),
    "yaw_deg": (0.0, -90.0, 90.0, "deg", "yaw"),
    "distance_m": (0.305, 0.05, 1.0, "m", "distance"),
    "user_height_m": (1.75, 1.55, 1.95, "m", "user height"),
    "tof_noise_m": (0.0015, 0.0, 0.02, "m", "ToF noise"),
}


class FakeTrack(StairsTrack):
    """The stairs track with a hand-built episode instead of MuJoCo."""

    def params(self) -> list[ParamInfo]:
        return [ParamInfo(k, *v) for k, v in FAKE_PARAMS.items()]

    def validate_scenario(self, values: dict[str, Any]) -> dict[str, Any]:
        out = {k: v[0] for k, v in FAKE_PARAMS.items()}
        for k, v in values.items():
            if k not in FAKE_PARAMS:
                raise UnknownNameError("scenario parameter", k, FAKE_PARAMS)
            _, lo, hi, _, _ = FAKE_PARAMS[k]
            out[k] = check_range(f"scenario.{k}", v, lo, hi, low_open=(k == "riser_m"))
        return out

    def simulate(self, scenario: dict[str, Any], seed: int) -> Episode:
        return make_episode(scenario, seed)


def serve_tracks(monkeypatch: pytest.MonkeyPatch, **tracks: type) -> track_registry.TrackRegistry:
    """Make the process-wide track registry a fresh one holding only ``tracks`` (name -> class)."""
    reg = track_registry.TrackRegistry()
    for name, cls in tracks.items():
        reg.register(name, cls)
    monkeypatch.setattr(track_registry, "default_track_registry", lambda: reg)
    return reg


class FakeStairs:
    """Returns the true S0..S2 planes in the estimator frame, perturbed by the measured ranges."""

    name: ClassVar[str] = "fake"
    track: ClassVar[str] = "stairs"

    @dataclass
    class Config:
        offset_m: float = 0.0
        fail: bool = False

    def __init__(self, config: Config | None = None) -> None:
        self.config = config or self.Config()

    def reset(self, calibration: Calibration) -> None:
        self._truth = calibration.extra["truth_for_fakes"]
        self._frames: list[ToFReading] = []

    def process(self, frame: Any) -> StaircaseEstimate | None:
        if self.config.fail and len(self._frames) == 5:
            raise RuntimeError("fake failure")
        if isinstance(frame, ToFReading):
            self._frames.append(frame)
        return None

    def finalize(self) -> StaircaseEstimate:
        r = np.array([f.range_m for f in self._frames])
        wobble = float(r.mean() - 0.4)  # depends on the seed's noise
        riser, tread = self._truth["riser_m"], self._truth["tread_m"]
        to_est = np.array([0.35, -0.05, 0.0])  # world -> estimator translation (see make_episode)
        planes = (
            PlaneEstimate(0, np.array([0, 0, 1.0]), np.array([-0.2, 0, wobble]) + to_est, {"tof_r_med": 5}, 0.001, True, 0.6),
            PlaneEstimate(1, np.array([-1.0, 0, 0]), np.array([0.0, 0, riser / 2]) + to_est, {"tof_r_med": 5}, 0.001, True, 0.7),
            PlaneEstimate(
                2, np.array([0, 0, 1.0]), np.array([0.1, 0, riser + self.config.offset_m + wobble]) + to_est, {"tof_r_lat": 5}, 0.001, True, 0.9
            ),
        )
        assignments = tuple(PointAssignment(f.stamp_s, f.sensor_id, np.zeros(3), i % 3) for i, f in enumerate(self._frames))
        return StaircaseEstimate(
            planes, riser + wobble, tread - wobble, assignments, {"n_nan": 0}, np.full(len(self._frames), 1e-4)
        )


class RaisingStairs(FakeStairs):
    name: ClassVar[str] = "fake-raise"

    def process(self, frame: Any) -> StaircaseEstimate | None:
        raise RuntimeError("boom")


def test_fake_episode_matches_its_staircase():
    ep = make_episode({"riser_m": 0.17}, seed=3)
    s2 = ep.truth.scene.surface(2)
    assert s2.kind == "tread" and s2.point_w[2] == pytest.approx(0.17)
    assert len(ep.truth.stairs.tof) == sum(isinstance(f, ToFReading) for f in ep.frames)
