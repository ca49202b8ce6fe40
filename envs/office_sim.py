"""Office walks for the LiDAR track: a walker with a trunk LiDAR, IMU and encoders in a procedural office.

:class:`OfficeScenario` holds the parameters (:data:`PARAMS`, validated like
:mod:`exobench.envs.scenarios`); :func:`simulate_office` builds the office
(:func:`exobench.models.office.build_office`), plans a stop-and-go walk along the office route
(:func:`exobench.envs.motion.plan_walk`) cut to ``max_distance_m``, and records:

- ``lidar_trunk`` :class:`~exobench.core.LidarScan` sweeps starting at ``k / lidar_rate_hz``
  (only sweeps that end within the walk), each ray cast from the sensor pose at its firing
  block's time. The pose is exact: the trunk is rigid with the pelvis, so ``T_world_sensor(t) =
  T_world_pelvis(t) @ T_pelvis_sensor`` with the pelvis pose from the motion's coordinates
  (no kinematics call per block). The legs and head, which the beams can hit, are frozen at their
  pose in the middle of each sweep;
- the trunk IMU, joint encoders and insole contacts as in :mod:`exobench.envs.sim`.

Frames are time-ordered (ties: encoders, IMU, contacts, LiDAR). The truth keeps one
``LidarTruth`` per scan (``EpisodeTruth.lidar``), the sensor pose at each scan start
(``trajectory_w``), link tracks at 50 Hz (plus the ``lidar_trunk`` pose) and the deepest foot
penetration. ``T_world_estimator`` is the LiDAR pose at t = 0. Same scenario and seed, same
frames bit for bit.

Route handling: the office routes turn by 90 and 180 degrees at corners and doors; the planner
(:func:`exobench.envs.motion.plan_walk`) tracks its progress monotonically along the polyline (the
loop passes corridors twice) and walks up to every corner sharper than 45 deg and turns there on
the spot, ``max_turn_deg`` per step. Waypoints closer than :data:`MIN_SEGMENT_M` to the previous
kept one are dropped, and the polyline is cut at ``max_distance_m``. The walker starts facing
the first segment; a closed route (the whole ``"loop"``, not cut) ends with a turn on the spot
to that heading, so the final pose equals the start pose (up to the feet's placement, a few
cm) as the thesis' TE / OE / TVE protocol assumes (seeds/003 section 5.2.2).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, replace
from functools import lru_cache
from typing import Any

import numpy as np

from exobench.core import ConfigError, Episode, EpisodeTruth, Frame, LidarTruth, compact_truth
from exobench.core.transforms import invert_T, make_T, matrix_to_quat_wxyz
from exobench.models.exo_spec import CONTACT_IDS, ExoSpec
from exobench.models.world_params import ParamSpec, from_dict_checked, validate_fields

from .motion import Motion, Route, plan_walk, rot_yaw_pitch
from .sensors import (
    ENCODER_ID,
    ContactConfig,
    ContactSensor,
    EncoderConfig,
    EncoderSensor,
    ImuConfig,
    ImuSensor,
    LidarConfig,
    LidarPattern,
    LidarSensor,
    SensorsConfig,
    contact_forces,
    sample_times,
)
from .sim import TRACK_RATE_HZ, step_through
from .terrain import Terrain

LIDAR_ID = "lidar_trunk"
IMU_ID = "imu_trunk"
SENSOR_ORDER = (ENCODER_ID, IMU_ID, *CONTACT_IDS, LIDAR_ID)
PENETRATION_RATE_HZ = 1000.0
MIN_SEGMENT_M = 0.3  # shorter route segments are merged into the next one
LIDAR_PATTERNS = ("vlp16", "vlp32", "ouster64", "livox")
ROUTES = ("loop", "ring", "corridor")
LIDAR_TRUTHS = ("full", "labels")

PARAMS: dict[str, ParamSpec] = {
    "office_seed": ParamSpec(0, 0, 2**31 - 1, "", "random seed of the office layout"),
    "n_offices": ParamSpec(3, 1, 24, "", "cellular offices along the north corridor"),
    "glass_fraction": ParamSpec(0.4, 0.0, 1.0, "", "share of corridor partitions that are glass (the meeting room's south one first)"),
    "polished_fraction": ParamSpec(0.3, 0.0, 1.0, "", "share of floor areas that are polished stone (the south corridor first)"),
    "route": ParamSpec("corridor", None, None, "", "office route walked (loop: every office and two laps, "
                       "~130 m; ring: once round the corridor ring back to the start; corridor: the south corridor)",
                       choices=ROUTES),
    "lidar_truth": ParamSpec("full", None, None, "", "per-point LiDAR truth kept: full, or labels only "
                             "(kind, surface, range; ~8x smaller, for long walks)", choices=LIDAR_TRUTHS),
    "max_distance_m": ParamSpec(20.0, 0.5, 500.0, "m", "the route is cut after this length (keeps quick runs short)"),
    "step_length_m": ParamSpec(0.35, 0.1, 0.8, "m", "nominal step length"),
    "swing_s": ParamSpec(0.8, 0.3, 5.0, "s", "duration of one swing"),
    "max_turn_deg": ParamSpec(30.0, 5.0, 60.0, "deg", "largest heading change per step (sharper corners are turned on the spot over several steps)"),
    "lidar": ParamSpec("vlp16", None, None, "", "LiDAR scan pattern", choices=LIDAR_PATTERNS),
    "lidar_rate_hz": ParamSpec(10.0, 5.0, 20.0, "Hz", "LiDAR sweeps per second"),
    "lidar_noise_m": ParamSpec(0.015, 0.0, 0.1, "m", "LiDAR range noise, standard deviation"),
    "lidar_resolution_m": ParamSpec(0.002, 0.0, 0.1, "m", "LiDAR range quantisation (0 = off)"),
    "user_height_m": ParamSpec(1.75, 1.55, 1.95, "m", "user's standing height (scales every segment)"),
    "user_mass_kg": ParamSpec(75.0, 40.0, 130.0, "kg", "user's body mass"),
    "imu_noise_scale": ParamSpec(1.0, 0.0, 20.0, "", "multiplier of the IMU noise densities and random walks"),
    "encoder_noise_rad": ParamSpec(1e-4, 0.0, 0.05, "rad", "joint encoder white noise, standard deviation"),
}


@dataclass(frozen=True)
class OfficeScenario:
    """One office-walk episode; see :data:`PARAMS` for units, ranges and meaning."""

    office_seed: int = PARAMS["office_seed"].default
    n_offices: int = PARAMS["n_offices"].default
    glass_fraction: float = PARAMS["glass_fraction"].default
    polished_fraction: float = PARAMS["polished_fraction"].default
    route: str = PARAMS["route"].default
    lidar_truth: str = PARAMS["lidar_truth"].default
    max_distance_m: float = PARAMS["max_distance_m"].default
    step_length_m: float = PARAMS["step_length_m"].default
    swing_s: float = PARAMS["swing_s"].default
    max_turn_deg: float = PARAMS["max_turn_deg"].default
    lidar: str = PARAMS["lidar"].default
    lidar_rate_hz: float = PARAMS["lidar_rate_hz"].default
    lidar_noise_m: float = PARAMS["lidar_noise_m"].default
    lidar_resolution_m: float = PARAMS["lidar_resolution_m"].default
    user_height_m: float = PARAMS["user_height_m"].default
    user_mass_kg: float = PARAMS["user_mass_kg"].default
    imu_noise_scale: float = PARAMS["imu_noise_scale"].default
    encoder_noise_rad: float = PARAMS["encoder_noise_rad"].default

    def __post_init__(self) -> None:
        validate_fields(self, PARAMS)

    @classmethod
    def from_dict(cls, values: dict[str, Any]) -> OfficeScenario:
        """Validated scenario from plain values (strings are converted); unknown names refused."""
        return from_dict_checked(cls, "office scenario", PARAMS, values)

    def as_dict(self) -> dict[str, Any]:
        return asdict(self)

    def exo_spec(self) -> ExoSpec:
        return ExoSpec(user_height_m=self.user_height_m, user_mass_kg=self.user_mass_kg)

    def office_params(self) -> object:
        from exobench.models.office import OfficeParams

        return OfficeParams(seed=self.office_seed, n_offices=self.n_offices, glass_fraction=self.glass_fraction,
                            polished_fraction=self.polished_fraction)

    def lidar_config(self) -> LidarConfig:
        r = self.lidar_rate_hz
        pattern = {
            "vlp16": lambda: LidarPattern.vlp16(r),
            "vlp32": lambda: LidarPattern.vlp32(r),
            "ouster64": lambda: LidarPattern.ouster(64, 1024, r),
            "livox": lambda: LidarPattern.livox_like(rate_hz=r),
        }[self.lidar]()
        return LidarConfig(pattern=pattern, range_noise_m=self.lidar_noise_m, resolution_m=self.lidar_resolution_m)


@lru_cache(maxsize=8)
def compiled_office(params: object, exo: ExoSpec) -> object:
    """The composed office world (``models.worlds.CompiledScene``), compiled once per key."""
    from exobench.models.office import build_office
    from exobench.models.worlds import compose

    return compose(build_office(params), exo)  # type: ignore[arg-type]


def route_waypoints(waypoints: list[tuple[float, float]], max_distance_m: float) -> tuple[tuple[float, float], ...]:
    """The route's waypoints without stubs shorter than :data:`MIN_SEGMENT_M`, cut at ``max_distance_m``."""
    pts = [np.asarray(waypoints[0], dtype=float)]
    for p in waypoints[1:]:
        q = np.asarray(p, dtype=float)
        if np.linalg.norm(q - pts[-1]) >= MIN_SEGMENT_M:
            pts.append(q)
    if len(pts) < 2:
        raise ConfigError("route", waypoints, f"a route with a segment of at least {MIN_SEGMENT_M} m")
    out, left = [pts[0]], float(max_distance_m)
    for q in pts[1:]:
        d = float(np.linalg.norm(q - out[-1]))
        if d >= left:
            out.append(out[-1] + (q - out[-1]) * (left / d))
            break
        out.append(q)
        left -= d
    return tuple((float(p[0]), float(p[1])) for p in out)


def plan_office_walk(scenario: OfficeScenario) -> tuple[object, Motion]:
    """(compiled office scene, walking motion) of a scenario, without sensing."""
    from exobench.models.office import office_route

    exo = scenario.exo_spec()
    scene = compiled_office(scenario.office_params(), exo)
    wps = route_waypoints(office_route(scene.truth, scenario.route), scenario.max_distance_m)  # type: ignore[attr-defined]
    pts = np.asarray(wps)
    length = float(np.sum(np.linalg.norm(np.diff(pts, axis=0), axis=1)))
    d0 = pts[1] - pts[0]
    start_yaw = float(np.degrees(np.arctan2(d0[1], d0[0])))
    closed = bool(np.linalg.norm(pts[-1] - pts[0]) < 1e-9)
    turns = np.arctan2(np.diff(pts, axis=0)[:, 1], np.diff(pts, axis=0)[:, 0])
    turning_steps = int(np.sum(np.abs((np.diff(turns) + np.pi) % (2 * np.pi) - np.pi)) / np.radians(scenario.max_turn_deg))
    route = Route(
        wps, step_length_m=scenario.step_length_m, swing_s=scenario.swing_s, max_turn_deg=scenario.max_turn_deg,
        start_yaw_deg=start_yaw, end_yaw_deg=start_yaw if closed else None,
        max_steps=min(10000, int(3.0 * length / scenario.step_length_m) + 2 * turning_steps + 100),
    )  # fmt: skip
    return scene, plan_walk(exo, scene.truth, route)  # type: ignore[attr-defined]


class SensorPose:
    """``T_world_sensor`` of a site rigid with the pelvis, at any time of a motion (``PoseFn``)."""

    def __init__(self, model: object, motion: Motion, site: str) -> None:
        import mujoco

        sid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, site)
        pelvis = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, "pelvis")
        if sid < 0 or int(model.site_bodyid[sid]) != pelvis:  # type: ignore[attr-defined]
            raise ConfigError("site", site, "a site on the pelvis body")
        data = mujoco.MjData(model)
        mujoco.mj_kinematics(model, data)
        T_w_p = make_T(data.xmat[pelvis].reshape(3, 3), data.xpos[pelvis])
        T_w_s = make_T(data.site_xmat[sid].reshape(3, 3), data.site_xpos[sid])
        self.T_pelvis_sensor = invert_T(T_w_p) @ T_w_s
        self.motion = motion

    def __call__(self, times_s: np.ndarray) -> np.ndarray:
        st = self.motion.state(np.atleast_1d(np.asarray(times_s, dtype=float)), solve_legs=False)
        T = np.repeat(np.eye(4)[None], len(st.t), axis=0)
        T[:, :3, :3] = rot_yaw_pitch(st.yaw, st.pitch)
        T[:, :3, 3] = st.pelvis_w
        return T @ self.T_pelvis_sensor


def _pose_rows(t: np.ndarray, T: np.ndarray) -> np.ndarray:
    q = np.array([matrix_to_quat_wxyz(R) for R in T[:, :3, :3]]).reshape(-1, 4)
    return np.column_stack([t, T[:, :3, 3], q])


def simulate_office(scenario: OfficeScenario, seed: int) -> Episode:
    """A walk along the scenario's office route with the trunk LiDAR, IMU, encoders and contacts."""
    import mujoco

    from exobench.models.exo import exo_calibration

    exo = scenario.exo_spec()
    scene, motion = plan_office_walk(scenario)
    model, truth = scene.model, scene.truth  # type: ignore[attr-defined]
    dur = motion.duration_s
    pose_at = SensorPose(model, motion, LIDAR_ID)
    imu_cfg = ImuConfig(noise_scale=scenario.imu_noise_scale)
    enc_cfg = EncoderConfig(noise_rad=scenario.encoder_noise_rad)
    con_cfg = ContactConfig()
    lid_cfg = scenario.lidar_config()
    streams: dict[str, list[Frame]] = {sid: [] for sid in SENSOR_ORDER}

    # IMU and link tracks: kinematics (and dynamics where the IMU measures) at their instants
    t_imu, t_trk = sample_times(imu_cfg.rate_hz, dur), sample_times(TRACK_RATE_HZ, dur)
    t_mj = np.union1d(t_imu, t_trk)
    is_imu, is_trk = np.isin(t_mj, t_imu), np.isin(t_mj, t_trk)
    imu = ImuSensor(IMU_ID, imu_cfg, model, seed)
    body_tracks = step_through(model, motion, t_mj, imu, is_imu, is_trk)
    streams[IMU_ID] = list(imu.frames())
    body_tracks[LIDAR_ID] = _pose_rows(t_trk, pose_at(t_trk))

    # LiDAR sweeps that end within the walk; the legs frozen at mid-sweep
    period = lid_cfg.pattern.sweep_period_s
    n_sweeps = int(np.floor(dur / period + 1e-9))
    lidar = LidarSensor(LIDAR_ID, lid_cfg, model, seed)
    data = mujoco.MjData(model)
    lidar_truth: list[LidarTruth] = []
    starts: list[float] = []
    for k in range(n_sweeps):
        t0 = k / lid_cfg.pattern.rate_hz
        data.qpos[:] = motion.sample(model, t0 + 0.5 * period).qpos[0]
        mujoco.mj_kinematics(model, data)
        got = lidar.scan(model, data, pose_at, t0, truth)
        if got is not None:
            streams[LIDAR_ID].append(got[0])
            lidar_truth.append(got[1] if scenario.lidar_truth == "full" else compact_truth(got[1]))
            starts.append(t0)
    t_start = np.array(starts)
    trajectory = _pose_rows(t_start, pose_at(t_start)) if starts else np.zeros((0, 8))

    t_enc = sample_times(enc_cfg.rate_hz, dur)
    streams[ENCODER_ID] = list(EncoderSensor(enc_cfg, seed).frames(t_enc, motion.state(t_enc).joints))
    t_con = sample_times(con_cfg.rate_hz, dur)
    st = motion.state(t_con)
    rv = int(model.jnt_dofadr[mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, "root")])
    acc_z = motion.sample(model, t_con).qacc[:, rv + 2]
    pads = {}
    for pid in CONTACT_IDS:
        _, T = exo.contact_mount(pid)
        pads[pid] = st.sole_points_w(pid.split("_")[1], T[:3, 3][None, :])[:, 0]
    g = float(-model.opt.gravity[2])
    forces = contact_forces(
        Terrain(truth), pads, st.ankle_w, st.pelvis_w, acc_z, exo.user_mass_kg + exo.exo_mass_kg,
        con_cfg.contact_tol_m, g,
    )  # fmt: skip
    for pid in CONTACT_IDS:
        streams[pid] = list(ContactSensor(pid, con_cfg, seed).frames(t_con, forces[pid]))

    rank = {sid: i for i, sid in enumerate(SENSOR_ORDER)}
    merged = [(f.stamp_s, rank[f.sensor_id], f) for sid in SENSOR_ORDER for f in streams[sid]]
    merged.sort(key=lambda x: (x[0], x[1]))
    frames = tuple(f for _, _, f in merged)

    ep_truth = EpisodeTruth(
        scene=truth,
        T_world_estimator=pose_at(np.array([0.0]))[0],
        body_tracks=body_tracks,
        max_penetration_m=motion.max_penetration_m(truth, sample_times(PENETRATION_RATE_HZ, dur)),
        events=dict(motion.events),
        lidar=tuple(lidar_truth),
        trajectory_w=trajectory,
    )
    known = SensorsConfig(imu=imu_cfg, encoders=enc_cfg, contact=con_cfg).calibration_params()
    cal = exo_calibration(exo, {"imu": known["imu"], "contact": known["contact"], LIDAR_ID: lid_cfg.calibration_params()})
    cal = replace(cal, extra={
        **cal.extra,
        "encoders": {"rate_hz": enc_cfg.rate_hz, "noise_rad": enc_cfg.noise_rad, "resolution_bits": enc_cfg.resolution_bits},
    })  # fmt: skip
    return Episode(scenario=scenario.as_dict(), seed=int(seed), calibration=cal, frames=frames, truth=ep_truth)
