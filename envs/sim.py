"""Simulated episodes: run a kinematic motion in a MuJoCo world and record every sensor.

:func:`record` is the loop: it samples the motion only at the instants some sensor measures
(all streams run on exact multiples of their periods, so 50/100/200 Hz streams share instants),
runs MuJoCo's kinematics there (plus velocities and ``mj_rnePostConstraint`` where the IMU
measures), casts the ToF rays, and merges the frames in time order, ties broken by
:data:`SENSOR_ORDER` (state before ranges, so a pipeline has the encoders and IMU of an
instant when its ToF frame arrives). :func:`simulate_stairs` builds the staircase of a
:class:`~exobench.envs.scenarios.StairScenario`, plans the paper's climbing step and returns a
complete :class:`~exobench.core.Episode`. Compiled worlds are cached per (staircase, body), so
a batch of episodes compiles each world once. Same scenario and seed, same frames bit for bit.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace
from functools import lru_cache

import numpy as np

from exobench.core import Episode, EpisodeTruth, Frame, SceneTruth, StairTruth, ToFTruth
from exobench.core.transforms import make_T
from exobench.models.exo_spec import CONTACT_IDS, TOF_IDS, ExoSpec

from .motion import Motion, climb_step
from .scenarios import StairScenario
from .sensors import (
    ENCODER_ID,
    ContactSensor,
    EncoderSensor,
    ImuSensor,
    SensorsConfig,
    ToFSensor,
    contact_forces,
    imu_dynamics,
    sample_times,
)
from .terrain import Terrain

IMU_ID = "imu_trunk"
SENSOR_ORDER = (ENCODER_ID, IMU_ID, *CONTACT_IDS, *TOF_IDS)
TRACKED_BODIES = ("pelvis", "thigh_l", "shank_l", "foot_l", "thigh_r", "shank_r", "foot_r", "head")
TRACK_RATE_HZ = 50.0
FOOT_TRACK_RATE_HZ = 100.0
PENETRATION_RATE_HZ = 1000.0


@dataclass(frozen=True, eq=False)
class Recording:
    """Output of :func:`record`: frames in time order, the ToF truth in ToF-frame order, body tracks."""

    frames: tuple[Frame, ...]
    tof_truth: tuple[ToFTruth, ...]
    body_tracks: dict[str, np.ndarray]


def step_through(
    model: object,
    motion: Motion,
    t_mj: np.ndarray,
    imu: ImuSensor,
    is_imu: np.ndarray,
    is_trk: np.ndarray,
    on_sample: Callable[[object, int, float], None] | None = None,
) -> dict[str, np.ndarray]:
    """Put MuJoCo in the motion's state at each instant of ``t_mj``: full dynamics where the IMU
    measures (so its accelerations follow the motion), kinematics elsewhere. Calls
    ``on_sample(data, k, t)`` at every instant and returns the tracked link poses,
    body -> (N, 8) rows ``[t, x, y, z, qw, qx, qy, qz]`` at the ``is_trk`` instants."""
    import mujoco

    sample = motion.sample(model, t_mj)
    body_ids = [mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, b) for b in TRACKED_BODIES]
    tracks: dict[str, list[np.ndarray]] = {b: [] for b in TRACKED_BODIES}
    data = mujoco.MjData(model)
    for k, t in enumerate(t_mj):
        tk = float(t)
        if is_imu[k]:
            imu_dynamics(model, data, sample.qpos[k], sample.qvel[k], sample.qacc[k])
            imu.observe(model, data, tk)
        else:
            data.qpos[:] = sample.qpos[k]
            mujoco.mj_kinematics(model, data)
        if on_sample is not None:
            on_sample(data, k, tk)
        if is_trk[k]:
            for b, i in zip(TRACKED_BODIES, body_ids):
                tracks[b].append(np.concatenate([[tk], data.xpos[i], data.xquat[i]]))
    return {b: np.array(v).reshape(-1, 8) for b, v in tracks.items()}


def record(
    model: object, truth: SceneTruth, exo: ExoSpec, motion: Motion, config: SensorsConfig, seed: int
) -> Recording:
    """Every sensor's frames over ``motion`` (see the module docstring)."""
    import mujoco

    dur = motion.duration_s
    t_tof = sample_times(config.tof.rate_hz, dur)
    t_imu = sample_times(config.imu.rate_hz, dur)
    t_trk = sample_times(TRACK_RATE_HZ, dur)
    t_mj = np.union1d(np.union1d(t_tof, t_imu), t_trk)
    is_tof, is_imu, is_trk = np.isin(t_mj, t_tof), np.isin(t_mj, t_imu), np.isin(t_mj, t_trk)
    tofs = [ToFSensor(sid, config.tof, model, seed) for sid in TOF_IDS]
    imu = ImuSensor(IMU_ID, config.imu, model, seed)

    def observe_tof(data: object, k: int, tk: float) -> None:
        if is_tof[k]:
            for s in tofs:
                s.observe(model, data, tk)

    body_tracks = step_through(model, motion, t_mj, imu, is_imu, is_trk, observe_tof)

    streams: dict[str, list] = {sid: [] for sid in SENSOR_ORDER}
    tof_truth: dict[int, ToFTruth] = {}
    for s in tofs:
        for fr, tt in s.frames(model, truth):
            streams[s.sensor_id].append(fr)
            tof_truth[id(fr)] = tt
    streams[IMU_ID] = imu.frames()

    t_enc = sample_times(config.encoders.rate_hz, dur)
    streams[ENCODER_ID] = EncoderSensor(config.encoders, seed).frames(t_enc, motion.state(t_enc).joints)

    t_con = sample_times(config.contact.rate_hz, dur)
    st = motion.state(t_con)
    rv = int(model.jnt_dofadr[mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, "root")])  # type: ignore[attr-defined]
    acc_z = motion.sample(model, t_con).qacc[:, rv + 2]
    pads = {}
    for pid in CONTACT_IDS:
        _, T = exo.contact_mount(pid)
        pads[pid] = st.sole_points_w(pid.split("_")[1], T[:3, 3][None, :])[:, 0]
    g = float(-model.opt.gravity[2])  # type: ignore[attr-defined]
    forces = contact_forces(
        Terrain(truth), pads, st.ankle_w, st.pelvis_w, acc_z, exo.user_mass_kg + exo.exo_mass_kg,
        config.contact.contact_tol_m, g,
    )  # fmt: skip
    for pid in CONTACT_IDS:
        streams[pid] = ContactSensor(pid, config.contact, seed).frames(t_con, forces[pid])

    rank = {sid: i for i, sid in enumerate(SENSOR_ORDER)}
    merged = [(f.stamp_s, rank[f.sensor_id], f) for sid in SENSOR_ORDER for f in streams[sid]]
    merged.sort(key=lambda x: (x[0], x[1]))  # stable: each stream is already in time order
    frames = tuple(f for _, _, f in merged)
    tof_t = tuple(tof_truth[id(f)] for f in frames if id(f) in tof_truth)
    return Recording(frames, tof_t, body_tracks)


@lru_cache(maxsize=16)
def compiled_staircase(params: object, exo: ExoSpec) -> object:
    """The composed staircase world (``models.worlds.CompiledScene``), compiled once per key."""
    from exobench.models.worlds import build_staircase, compose

    return compose(build_staircase(params), exo)


def plan_climb(scenario: StairScenario) -> tuple[object, Motion]:
    """(compiled staircase scene, climbing-step motion) of a scenario, without sensing.

    Cheap (milliseconds once the world is compiled); raises :class:`ConfigError` naming
    ``distance_m``/``tread_m`` when the step cannot be made, so scenario grids can be checked.
    """
    exo = scenario.exo_spec()
    scene = compiled_staircase(scenario.staircase_params(exo), exo)
    motion = climb_step(
        exo, scene.truth, distance_m=scenario.distance_m, yaw_deg=scenario.yaw_deg, duration_s=scenario.duration_s  # type: ignore[attr-defined]
    )
    return scene, motion


def simulate_stairs(scenario: StairScenario, seed: int) -> Episode:
    """One climbing step of the staircase paper in the scenario's world, with every sensor.

    Truth: the estimator frame ``stance_ground`` (world axes, origin on the ground below the
    left ankle), the right foot's sole point over time and at touch-down, link poses at 50 Hz,
    the deepest foot penetration (sole grid every 1 ms) and the lift-off/touch-down events.
    """
    from exobench.models.exo import exo_calibration

    exo = scenario.exo_spec()
    scene, motion = plan_climb(scenario)
    model, truth = scene.model, scene.truth  # type: ignore[attr-defined]
    cfg = scenario.sensors_config()
    rec = record(model, truth, exo, motion, cfg, seed)

    stance = motion.stance_side
    swing = "r" if stance == "l" else "l"
    terrain = Terrain(truth)
    a0 = motion.state(0.0).ankle_w[stance][0]
    T_world_est = make_T(np.eye(3), np.array([a0[0], a0[1], terrain.height(a0[None, :2])[0]]))
    t_ft = sample_times(FOOT_TRACK_RATE_HZ, motion.duration_s)
    foot_track = np.column_stack([t_ft, motion.sole_point_w(swing, t_ft)])
    t_pen = sample_times(PENETRATION_RATE_HZ, motion.duration_s)
    ep_truth = EpisodeTruth(
        scene=truth,
        T_world_estimator=T_world_est,
        stairs=StairTruth(
            tof=rec.tof_truth, stance_side=stance, touchdown_w=motion.footsteps[0].sole_w.copy(), foot_track_w=foot_track
        ),
        body_tracks=rec.body_tracks,
        max_penetration_m=motion.max_penetration_m(truth, t_pen),
        events=dict(motion.events),
    )
    cal = exo_calibration(exo, cfg.calibration_params())
    enc = cfg.encoders
    cal = replace(
        cal,
        extra={
            **cal.extra,
            "encoders": {"rate_hz": enc.rate_hz, "noise_rad": enc.noise_rad, "resolution_bits": enc.resolution_bits},
        },
    )
    return Episode(scenario=scenario.as_dict(), seed=int(seed), calibration=cal, frames=rec.frames, truth=ep_truth)
