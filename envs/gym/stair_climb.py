"""Gymnasium environment ``exobench/StairClimb-v0``: place the next foot on a staircase from calf ToF points.

A reinforcement-learning (or planning) view of the stairs track: at each step the agent sees the
recent points of the four calf ToF sensors and the leg joint angles, and chooses where the swing
foot lands relative to the stance foot. The step is planned by the walker's step planner
(:func:`exobench.envs.motion.plan_step`) from the command alone; the true staircase only judges the
outcome (foothold, toe clearance over the nosings, foot-world penetration). See :class:`StairClimbEnv`.

It runs on the simulation core (:mod:`exobench.envs.gym`): the stairs scenario's world composed
with the rig, the walker's segments, the recorder stepped as the motion grows.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass, replace
from typing import Any

import gymnasium
import numpy as np
from gymnasium import spaces

from exobench.core import (
    ConfigError,
    ExobenchError,
    RenderError,
    UnknownNameError,
    check_int,
    check_range,
)
from exobench.models.exo_spec import JOINT_RANGES_RAD, LEG_JOINTS, TOF_IDS

from ..motion import (
    STAND_KNEE_RAD,
    SWING_SHAPES_DEEP_DIP,
    GaitError,
    Motion,
    Segment,
    StepPlan,
    StepStart,
    SwingPlan,
    heel_rises,
    leg_length_for_knee,
    plan_step,
    rot_yaw_pitch,
    sole_grid_f,
    still_segment,
)
from ..sensors import ToFConfig
from ..sensors.adapter import MountedSensor
from ..sim.compose import attached_sites, compose_rig
from ..sim.recorder import Recorder
from ..sim.rig import calf_tof_rig
from ..sim.scenarios.stairs import StairScenario
from ..terrain import Terrain
from .stair_footing import Outcome, belief_terrain, judge_swing, placement_error_m

K_READINGS = 16  # readings kept per ToF sensor in the observation
FORWARD_RANGE_M = (0.10, 0.70)  # action 0 maps [-1, 1] onto this
UP_RANGE_M = (-0.05, 0.30)  # action 1 maps [-1, 1] onto this
POINT_LIMIT_M = 10.0  # observation bound of the point coordinates (4 m range + body + one step)
RESET_OPTIONS = ("riser_m", "tread_m", "yaw_deg", "distance_m", "user_height_m")
RNG_SEED_HIGH = 2**31 - 1


@dataclass
class _Foot:
    ankle_w: np.ndarray  # (3,)
    pitch_rad: float  # toes-up sole pitch (a raised heel is negative)
    surface_id: int
    support_z_m: float  # height of the surface it stands on


def _range_pair(name: str, value: tuple[float, float], spec_name: str) -> tuple[float, float]:
    spec = StairScenario.PARAMS[spec_name]
    try:
        lo, hi = (float(v) for v in value)
    except (TypeError, ValueError):
        raise ConfigError(name, value, f"(low, high) within [{spec.low}, {spec.high}]") from None
    for v in (lo, hi):
        check_range(name, v, spec.low, spec.high, low_open=spec.low_open)
    if lo > hi:
        raise ConfigError(name, value, "low <= high")
    return lo, hi


class StairClimbEnv(gymnasium.Env):
    """Climb a staircase one foothold at a time, from what the calf ToF sensors saw.

    ## Description
    The exoskeleton and its user stand on level ground before a straight flight of ``n_steps``
    risers (the last tread is the top landing), both feet flat, facing world +x; the
    exoskeleton is turned by ``yaw_deg`` counter-clockwise relative to the flight, whose first
    riser is ``distance_m`` ahead of the right toe tip (the staircase paper's protocol,
    :func:`exobench.envs.sim.scenarios.stairs.staircase_params_for_case`). Each step the agent commands
    where the *swing* foot lands; legs alternate (the right foot swings first), so one command
    per tread climbs step-over, and a short command on the ground approaches the stairs. The
    heading stays constant (world +x).

    The step is the walker's (:func:`exobench.envs.motion.plan_step`, with the walker's
    constants): the pelvis moves to the preferred double-stance pose for the command (the
    trailing heel rises at the end of stair steps), and the foot follows a minimum-jerk parabola
    to the commanded point, flat at touch-down, then settles onto the surface (``settle_s``). The
    parabola is planned from the *command* and the feet alone (the first of the walker's
    lag/toe-down shapes the legs can follow, toes down up to 45 deg mid-swing, each with its
    lowest apex, :func:`~exobench.envs.motion.swing_apex_m`): the controller assumes that between two
    footholds the ground is no higher than the higher of them (the swing foot's support up to
    its toe, stance and target beyond) and keeps ``clearance_m`` over that. The foot goes where
    it is told; only the judge of the touch-down sees the true staircase. The four calf ToF
    sensors (the rig :attr:`rig`: :class:`~exobench.envs.sensors.tof.ToFSensor` with its noise,
    quantisation, dropout, latency and seeded streams) are sampled by the simulation core's
    recorder (:class:`~exobench.envs.sim.recorder.Recorder`) at ``k / rate_hz`` during the
    ``standing_s`` of :meth:`reset` (seeing the ground or the first riser ahead) and during every
    swing and settling: an observation holds the readings measured from the previous decision
    time up to, not including, its own (a measurement at a decision instant belongs to the
    motion that starts there) and delivered (stamped) by it.

    ## Action Space
    ``Box(-1, 1, (2,), float32)``, mapped affinely onto the target of the swing foot's sole point
    (the point of the sole below the ankle) relative to the stance foot's sole point, in the
    heading frame (x forward, y left, z up); the lateral offset is fixed at one hip width.
    :meth:`action_from_target` and :meth:`target_from_action` convert. As in gymnasium's
    continuous control environments (``Pendulum``, ``LunarLander(continuous=True)``), an action
    outside the box is clipped to it, not refused (``info`` gives the command after clipping);
    an action that is not two finite numbers raises :class:`~exobench.core.ConfigError`.

    | Num | Action                                   | Control Min | Control Max | Unit |
    |-----|------------------------------------------|-------------|-------------|------|
    | 0   | forward distance of the target (x)       | 0.10        | 0.70        | m    |
    | 1   | height of the target (z)                 | -0.05       | 0.30        | m    |

    ## Observation Space
    ``Box(float32, (262,))``. The last ``K = 16`` readings of each calf ToF sensor (oldest first,
    sensors in the order ``tof_l_med, tof_l_lat, tof_r_med, tof_r_lat``) as points in the current
    stance foot's ground frame (origin at the stance sole point, x forward along the heading, y
    left, z up): the measured range along the beam from the sensor's pose at the measurement
    time (the device's kinematics from the stance foot, exact encoders), so range noise is the
    only error. Invalid readings (no target, out of range) are zeros with ``valid = 0``, as are
    the slots before the first reading; dropped frames are absent (the last 16 delivered are
    shown). Then the six true leg joint angles at the decision time. The readings are the
    frames of ``info["frames"]``: for the episode's :attr:`motion`, :attr:`rig` and
    :attr:`sensor_seed`, :func:`exobench.envs.sim.recorder.record` gives the same frames bit for bit.

    | Num             | Observation                                       | Min   | Max   | Unit |
    |-----------------|---------------------------------------------------|-------|-------|------|
    | 64 s + 4 k + 0  | x of reading k of sensor s (k = 0 oldest, 15 newest) | -10 | 10    | m    |
    | 64 s + 4 k + 1  | y of reading k of sensor s                        | -10   | 10    | m    |
    | 64 s + 4 k + 2  | z of reading k of sensor s                        | -10   | 10    | m    |
    | 64 s + 4 k + 3  | valid flag of reading k of sensor s (1 valid)     | 0     | 1     | -    |
    | 256             | hip_l angle (flexion +)                           | -0.52 | 2.09  | rad  |
    | 257             | knee_l angle (flexion +)                          | -0.09 | 2.27  | rad  |
    | 258             | ankle_l angle (dorsiflexion +)                    | -0.70 | 0.52  | rad  |
    | 259-261         | hip_r, knee_r, ankle_r, as above                  |       |       | rad  |

    ## Rewards
    - a safe touch-down on a tread or the landing higher than the stance foot (a climbing step):
      ``1 - placement_weight * |e|``, with ``e`` (m) the distance along the heading between the
      foot centre (midpoint of the sole point below the ankle and the toe tip: the part that
      must rest on the tread) and the tread's centre line (for the landing: a virtual tread of
      ``tread_m`` at its front edge);
    - a safe touch-down that does not climb (e.g. an approach step on the ground): 0;
    - an unsafe touch-down: -1.

    A touch-down is *safe* when (1) no point of either sole goes more than
    ``penetration_tol_m`` into the terrain during the step, (2) the swing toe passes every
    nosing it crosses at least ``min_nosing_clearance_m`` above it, (3) the sole from the ankle
    to the toe rests on one walkable surface (the heel may overhang, as the gait's foothold rule
    says), (4) the foot lands at most ``max_drop_m`` above that surface (it then settles onto
    it), and (5) the legs can reach the commanded pose. Otherwise ``info["failure"]`` is
    ``"collision"``, ``"scuff"``, ``"no_foothold"``, ``"drop"`` or ``"unreachable"``.

    ## Episode End
    - Termination: an unsafe touch-down, or success: a foot reaches the top landing
      (``info["is_success"]``).
    - Truncation: after ``max_episode_steps`` (12 when made with ``gymnasium.make``; the
      ``TimeLimit`` wrapper truncates, the bare class never does).

    ## Starting State
    ``reset`` draws from ``self.np_random`` a riser height, tread depth, staircase yaw, start
    distance (right toe tip to the first riser, perpendicular) and user height uniformly within
    the ranges below (``options`` may fix any of ``riser_m, tread_m, yaw_deg, distance_m,
    user_height_m``, validated against :data:`exobench.envs.sim.scenarios.stairs.PARAMS`), builds and
    compiles the world (about 20 ms) and simulates ``standing_s`` of standing. The sensor noise
    streams are seeded from ``self.np_random`` too, so ``reset(seed=s)`` and the same actions
    give the same observations and rewards bit for bit.

    ## Info
    ``reset`` and ``step``: ``riser_m, tread_m, yaw_deg, distance_m, user_height_m, n_steps``
    (the truth), ``T_world_stairs`` (4x4, the staircase's local frame: origin at the bottom
    centre of the first riser, x up the flight), ``stance_side``, ``stance_sole_w``,
    ``stance_surface_id``, ``heading_rad``, ``time_s``, ``climbed`` (safe climbing steps so far),
    ``frames`` (the :class:`~exobench.core.ToFReading` frames delivered since the previous
    observation, in time order, ties in the rig's order: what a stairs pipeline would be fed).
    ``step`` also: ``safe``, ``failure`` ("" when safe), ``touched_surface_id`` (surface under
    the landing sole point, -1 none), ``penetration_m``, ``nosing_clearance_m`` (inf if no
    nosing was crossed), ``drop_m`` (height of the landing sole above the surface under it,
    <= 0 within the penetration tolerance), ``placement_error_m`` (signed ``e``, + beyond the
    centre; 0 off the stairs), ``forward_m``, ``up_m`` (the command after clipping),
    ``target_sole_w``, ``is_success``.

    ## Arguments
    ``gymnasium.make("exobench/StairClimb-v0", render_mode=None, n_steps=4,
    riser_range_m=(0.13, 0.19), tread_range_m=(0.26, 0.34), yaw_range_deg=(-10, 10),
    distance_range_m=(0.25, 0.5), user_height_range_m=(1.6, 1.9), standing_s=0.5, swing_s=0.8,
    settle_s=0.1, clearance_m=0.04, min_nosing_clearance_m=0.01, max_drop_m=0.03,
    penetration_tol_m=1e-3, placement_weight=1.0, tof=None)``; ``tof`` is a
    :class:`~exobench.envs.sensors.tof.ToFConfig` (default: the paper's VL53L1X). Render mode
    ``"rgb_array"`` returns a 480x640 image from a camera tracking the pelvis (headless through
    EGL or OSMesa, e.g. ``MUJOCO_GL=egl``); ``"human"`` is refused with a ConfigError
    (``gymnasium.make`` itself may instead wrap the ``rgb_array`` mode in its pygame
    ``HumanRendering`` wrapper, with a warning).

    ## Attributes
    After :meth:`reset` (read-only): :attr:`scene` (the compiled world), :attr:`motion` (the
    motion so far), :attr:`sensor_seed` (of the rig's noise streams, drawn from
    ``self.np_random``); any time: :attr:`rig` (the mounted sensors).

    ## Version History
    - v0: initial version. Its steps are planned by the walker's step planner with the walker's
      constants (before, by a copy whose constants had drifted: heel rise on long level steps,
      swings ordered by apex height and capped at 0.5 m, the apex sampled less exactly). Its
      sensors are sampled by the simulation core's recorder (before, by a loop of its own that
      also delivered a reading measured exactly at the decision instant, e.g. at ``standing_s``;
      such a reading now arrives with the next step).
    """

    metadata = {"render_modes": ["rgb_array"], "render_fps": 1}
    RENDER_SIZE = (480, 640)

    def __init__(
        self,
        render_mode: str | None = None,
        *,
        n_steps: int = 4,
        riser_range_m: tuple[float, float] = (0.13, 0.19),
        tread_range_m: tuple[float, float] = (0.26, 0.34),
        yaw_range_deg: tuple[float, float] = (-10.0, 10.0),
        distance_range_m: tuple[float, float] = (0.25, 0.5),
        user_height_range_m: tuple[float, float] = (1.6, 1.9),
        standing_s: float = 0.5,
        swing_s: float = 0.8,
        settle_s: float = 0.1,
        clearance_m: float = 0.04,
        min_nosing_clearance_m: float = 0.01,
        max_drop_m: float = 0.03,
        penetration_tol_m: float = 1e-3,
        placement_weight: float = 1.0,
        tof: ToFConfig | None = None,
    ) -> None:
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ConfigError("render_mode", render_mode, "None or 'rgb_array' (no window: 'human' is not supported)")
        self.render_mode = render_mode
        self.n_steps = check_int("n_steps", n_steps, 2, 30)
        self.riser_range_m = _range_pair("riser_range_m", riser_range_m, "riser_m")
        self.tread_range_m = _range_pair("tread_range_m", tread_range_m, "tread_m")
        self.yaw_range_deg = _range_pair("yaw_range_deg", yaw_range_deg, "yaw_deg")
        self.distance_range_m = _range_pair("distance_range_m", distance_range_m, "distance_m")
        self.user_height_range_m = _range_pair("user_height_range_m", user_height_range_m, "user_height_m")
        self.standing_s = check_range("standing_s", standing_s, 0.0, 10.0)
        self.swing_s = check_range("swing_s", swing_s, 0.3, 5.0)
        self.settle_s = check_range("settle_s", settle_s, 0.05, 5.0)
        self.clearance_m = check_range("clearance_m", clearance_m, 0.0, 0.2)
        self.min_nosing_clearance_m = check_range("min_nosing_clearance_m", min_nosing_clearance_m, 0.0, 0.2)
        self.max_drop_m = check_range("max_drop_m", max_drop_m, 0.0, 0.2)
        self.penetration_tol_m = check_range("penetration_tol_m", penetration_tol_m, 0.0, 0.05)
        self.placement_weight = check_range("placement_weight", placement_weight, 0.0, 100.0)
        if tof is not None and not isinstance(tof, ToFConfig):
            raise ConfigError("tof", tof, "a ToFConfig or None")
        self.tof_config = tof or ToFConfig()

        self.action_space = spaces.Box(-1.0, 1.0, shape=(2,), dtype=np.float32)
        n_pts = len(TOF_IDS) * K_READINGS
        low = np.tile(np.array([-POINT_LIMIT_M] * 3 + [0.0]), n_pts)
        high = np.tile(np.array([POINT_LIMIT_M] * 3 + [1.0]), n_pts)
        kinds = [j.split("_")[0] for j in LEG_JOINTS]
        low = np.concatenate([low, [JOINT_RANGES_RAD[k][0] for k in kinds]])
        high = np.concatenate([high, [JOINT_RANGES_RAD[k][1] for k in kinds]])
        self.observation_space = spaces.Box(low.astype(np.float32), high.astype(np.float32), dtype=np.float32)
        self._obs_low = self.observation_space.low.astype(np.float64)
        self._obs_high = self.observation_space.high.astype(np.float64)

        self._renderer: Any = None
        self._renderer_model: Any = None
        self._render_data: Any = None
        self._recorder: Recorder | None = None
        self._ready = False

    # --- action mapping ---------------------------------------------------------------------
    @staticmethod
    def target_from_action(action: np.ndarray) -> tuple[float, float]:
        """(forward_m, up_m) of an action (clipped to [-1, 1])."""
        a = np.clip(np.asarray(action, dtype=np.float64).reshape(2), -1.0, 1.0)
        (f0, f1), (u0, u1) = FORWARD_RANGE_M, UP_RANGE_M
        return float(f0 + 0.5 * (a[0] + 1.0) * (f1 - f0)), float(u0 + 0.5 * (a[1] + 1.0) * (u1 - u0))

    @staticmethod
    def action_from_target(forward_m: float, up_m: float) -> np.ndarray:
        """The action (float32, clipped to [-1, 1]) commanding a target ``forward_m``, ``up_m``."""
        (f0, f1), (u0, u1) = FORWARD_RANGE_M, UP_RANGE_M
        a = np.array([2.0 * (forward_m - f0) / (f1 - f0) - 1.0, 2.0 * (up_m - u0) / (u1 - u0) - 1.0])
        return np.clip(a, -1.0, 1.0).astype(np.float32)

    # --- gymnasium API ----------------------------------------------------------------------
    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None) -> tuple[np.ndarray, dict[str, Any]]:
        super().reset(seed=seed)
        from exobench.models.worlds import build_staircase

        self._ready = False  # until the new episode is built

        rng = self.np_random
        draw = {
            "riser_m": rng.uniform(*self.riser_range_m),
            "tread_m": rng.uniform(*self.tread_range_m),
            "yaw_deg": rng.uniform(*self.yaw_range_deg),
            "distance_m": rng.uniform(*self.distance_range_m),
            "user_height_m": rng.uniform(*self.user_height_range_m),
        }
        sensor_seed = int(rng.integers(0, RNG_SEED_HIGH))
        for k, v in (options or {}).items():
            if k not in RESET_OPTIONS:
                raise UnknownNameError("StairClimb reset option", str(k), RESET_OPTIONS)
            spec = StairScenario.PARAMS[k]
            draw[k] = check_range(k, v, spec.low, spec.high, low_open=spec.low_open)
        self._stairs = {k: float(v) for k, v in draw.items()}
        # the stairs track's world: its scenario's staircase and body, composed with the rig
        scenario = StairScenario.from_dict({**self._stairs, "n_steps": self.n_steps})
        exo = scenario.exo_spec()
        scene = compose_rig(build_staircase(scenario.staircase_params(exo)), exo, attached_sites(self.rig))
        self._exo, self._scene, self._model = exo, scene, scene.model
        self._terrain = Terrain(scene.truth)
        self._T_world_stairs = np.asarray(scene.truth.params["T_world_local"], dtype=float)
        self._surfaces = {s.surface_id: s for s in scene.truth.surfaces}
        self._landing_id = 2 * self.n_steps
        self._grid = sole_grid_f(exo)
        self._toe_f = np.array([exo.foot_m - exo.heel_to_ankle_m, 0.0, -exo.sole_height_m])
        self._readings: dict[str, deque] = {sid: deque(maxlen=K_READINGS) for sid in TOF_IDS}

        w, sole_h = exo.hip_width_m, exo.sole_height_m
        h_stand = leg_length_for_knee(exo, STAND_KNEE_RAD)
        self._yaw, self._pitch = 0.0, 0.0
        self._feet = {
            "l": _Foot(np.array([0.0, 0.5 * w, sole_h]), 0.0, 0, 0.0),
            "r": _Foot(np.array([0.0, -0.5 * w, sole_h]), 0.0, 0, 0.0),
        }
        for side, foot in self._feet.items():
            z, ids = self._terrain.query(foot.ankle_w[None, :2] + self._grid[:, :2])
            if np.any(ids != 0) or np.any(np.abs(z) > 1e-9):
                raise ConfigError("distance_m", self._stairs["distance_m"], f"foot_{side} standing on the ground before the stairs")
        self._stance = "l"
        self._pelvis = np.array([0.0, 0.0, sole_h + h_stand])
        t1 = max(self.standing_s, 1e-3)
        standing = SwingPlan(
            stance="l", A=self._feet["l"].ankle_w, stance_pitch=(0.0, 0.0), yaw=(0.0, 0.0), pitch=(0.0, 0.0),
            f=(0.0, 0.0), h=(h_stand, h_stand), a=(0.0, 0.0), z=(sole_h, sole_h), swing_pitch=(0.0, 0.0),
        )  # fmt: skip
        self._segments: list[Segment] = [still_segment(exo, standing, 0.0, t1, at_end=False)]
        self._t = t1
        self._motion = Motion(exo, self._segments)
        self._close_recorder()
        self._sensor_seed = sensor_seed
        self._recorder = Recorder(self._model, scene.truth, exo, self._motion, self.rig, sensor_seed)
        self._frames = self._sense()
        self._climbed = 0
        self._done = False
        self._ready = True
        return self._observation(), self._info()

    def step(self, action: np.ndarray) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        if not self._ready:
            raise ExobenchError("call reset() before step()")
        if self._done:
            raise ExobenchError("the episode has ended; call reset()")
        if np.shape(action) != (2,) or not np.all(np.isfinite(action)):
            raise ConfigError("action", action, "two finite numbers (each clipped to [-1, 1])")
        forward, up = self.target_from_action(action)
        exo = self._exo
        stance = self._stance
        swing = "r" if stance == "l" else "l"
        sg = 1.0 if stance == "l" else -1.0
        x, y, z = self._heading_axes()
        P = self._sole_point(stance)
        target_sole = P + forward * x - sg * exo.hip_width_m * y + up * z
        plan = self._plan(target_sole)
        step_info: dict[str, Any] = {"forward_m": forward, "up_m": up, "target_sole_w": target_sole}
        if plan is None:
            out = Outcome(False, "unreachable", -1, 0.0, float("inf"), 0.0)
            self._done = True
            self._frames = []  # no time passed
            return self._observation(), -1.0, True, False, self._info(out, 0.0, step_info)

        step, st = plan
        A_end, beta1, f1, h1, pitch1 = step.stance_ankle_w, step.stance_pitch, step.f_m, step.h_m, step.trunk_pitch
        t0 = self._t
        seg = step.segment(t0, t0 + self.swing_s)
        out = self._judge(st, swing)
        placement = self._placement_error(st, swing, out.touched_surface_id) if out.safe else 0.0
        gap = out.drop_m if out.safe else 0.0
        settle = replace(
            still_segment(exo, step.plan, t0 + self.swing_s, t0 + self.swing_s + self.settle_s, at_end=True),
            h=(h1, h1 - gap), z=(seg.z[1], seg.z[1] - gap),
        )
        self._segments += [seg, settle]
        self._t = settle.t1
        self._motion = Motion(exo, self._segments)
        self._frames = self._sense()

        if not out.safe:
            self._done = True
            return self._observation(), -1.0, True, False, self._info(out, 0.0, step_info)
        new_ankle = np.array(st.ankle_w[swing][-1]) - np.array([0.0, 0.0, gap])
        sid = out.touched_surface_id
        support = float(self._surfaces[sid].point_w[2])
        climbed = self._surfaces[sid].kind in ("tread", "landing") and support > self._feet[stance].support_z_m + 1e-6
        self._feet[stance] = _Foot(A_end, beta1, self._feet[stance].surface_id, self._feet[stance].support_z_m)
        self._feet[swing] = _Foot(new_ankle, 0.0, sid, support)
        self._pelvis = A_end + f1 * x - sg * 0.5 * exo.hip_width_m * y
        self._pelvis[2] = A_end[2] + h1 - gap
        self._pitch = pitch1
        self._stance = swing
        reward = 0.0
        if climbed:
            self._climbed += 1
            reward = 1.0 - self.placement_weight * abs(placement)
        success = sid == self._landing_id
        self._done = success
        return self._observation(), float(reward), bool(success), False, self._info(out, placement, step_info, success)

    def render(self) -> np.ndarray | None:
        if self.render_mode is None:
            gymnasium.logger.warn("render() called without a render_mode; make the env with render_mode='rgb_array'")
            return None
        if not self._ready:
            raise ExobenchError("call reset() before render()")
        import mujoco

        if self._renderer is None or self._renderer_model is not self._model:
            self._close_renderer()
            h, w = self.RENDER_SIZE
            try:
                self._renderer = mujoco.Renderer(self._model, height=h, width=w)
            except Exception as e:  # no GL context: EGL/OSMesa missing or MUJOCO_GL unset
                raise RenderError(f"cannot render off-screen ({e}); set MUJOCO_GL=egl or osmesa before mujoco is imported, or leave it unset and let exobench choose") from e
            self._renderer_model = self._model
            self._render_data = mujoco.MjData(self._model)
        d = self._render_data
        d.qpos[:] = self._motion.sample(self._model, self._t).qpos[0]
        mujoco.mj_forward(self._model, d)
        cam = mujoco.MjvCamera()
        cam.type = mujoco.mjtCamera.mjCAMERA_FREE
        cam.lookat[:] = self._pelvis + np.array([0.35, 0.0, -0.2])
        cam.distance, cam.azimuth, cam.elevation = 3.4, 60.0, -15.0
        self._renderer.update_scene(d, camera=cam)
        return self._renderer.render().copy()

    def close(self) -> None:
        self._close_renderer()
        self._close_recorder()

    # --- the simulation behind the episode (read-only) -----------------------------------------
    @property
    def rig(self) -> tuple[MountedSensor, ...]:
        """The sensors of the episode: the four calf ToF sensors with the ``tof`` config."""
        return calf_tof_rig(self.tof_config)

    @property
    def scene(self) -> Any:
        """The compiled world of the episode (``models.worlds.CompiledScene``)."""
        self._require_reset()
        return self._scene

    @property
    def motion(self) -> Motion:
        """The motion so far (from 0 to ``info["time_s"]``)."""
        self._require_reset()
        return self._motion

    @property
    def sensor_seed(self) -> int:
        """The seed of the rig's noise streams (drawn from ``np_random`` at reset)."""
        self._require_reset()
        return self._sensor_seed

    # --- internals --------------------------------------------------------------------------
    def _require_reset(self) -> None:
        if not self._ready:
            raise ExobenchError("call reset() first")

    def _close_renderer(self) -> None:
        if self._renderer is not None:
            self._renderer.close()
        self._renderer, self._renderer_model, self._render_data = None, None, None

    def _close_recorder(self) -> None:
        if self._recorder is not None:
            self._recorder.close()
        self._recorder = None

    def _heading_axes(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        c, s = np.cos(self._yaw), np.sin(self._yaw)
        return np.array([c, s, 0.0]), np.array([-s, c, 0.0]), np.array([0.0, 0.0, 1.0])

    def _sole_point(self, side: str) -> np.ndarray:
        """Sole point below the ankle of a foot (for a flat foot: straight below)."""
        f = self._feet[side]
        R = rot_yaw_pitch(np.array([self._yaw]), np.array([-f.pitch_rad]))[0]
        return f.ankle_w + R @ np.array([0.0, 0.0, -self._exo.sole_height_m])

    def _belief_terrain(self, target_sole: np.ndarray) -> Terrain:
        """The terrain the swing planner assumes (:func:`~exobench.envs.gym.stair_footing.belief_terrain`)."""
        swing = "r" if self._stance == "l" else "l"
        x, y, _ = self._heading_axes()
        sw = self._feet[swing]
        R = rot_yaw_pitch(np.array([self._yaw]), np.array([-sw.pitch_rad]))[0]
        return belief_terrain(
            self._sole_point(self._stance), x, y, sw.ankle_w + R @ self._toe_f, sw.support_z_m, float(self._toe_f[0]),
            target_sole, self._exo.heel_to_ankle_m,
        )  # fmt: skip

    def _judge(self, st: Any, swing: str) -> Outcome:
        """Safety of a swing (MotionState over the swing) on the true terrain."""
        return judge_swing(
            st, swing, self._terrain, self._surfaces, self._grid, self._toe_f, self._exo.sole_height_m,
            penetration_tol_m=self.penetration_tol_m, min_nosing_clearance_m=self.min_nosing_clearance_m,
            max_drop_m=self.max_drop_m,
        )  # fmt: skip

    def _plan(self, target_sole: np.ndarray) -> tuple[StepPlan, Any] | None:
        """The walker's step to the target, planned on the believed terrain, and its dense state
        over the swing (unit time), or None when the legs cannot make it."""
        exo = self._exo
        stance = self._stance
        swing = "r" if stance == "l" else "l"
        A = self._feet[stance].ankle_w
        sw = self._feet[swing]
        new_ankle = target_sole + np.array([0.0, 0.0, exo.sole_height_m])
        start = StepStart(
            stance, A, self._feet[stance].pitch_rad, sw.ankle_w, sw.pitch_rad, self._pelvis, self._pitch, self._yaw
        )
        rises = heel_rises(float(new_ankle[2] - A[2]), straight=True)  # the heading stays constant
        step = plan_step(
            exo, self._belief_terrain(target_sole), start, new_ankle, 0.0, self._yaw, rises=rises,
            clearance_m=self.clearance_m, shapes=SWING_SHAPES_DEEP_DIP,
        )  # fmt: skip
        if step is None:
            return None
        u = np.linspace(0.0, 1.0, int(round(self.swing_s * 1000.0)) + 1)
        try:
            st = Motion(exo, [step.segment(0.0, 1.0)]).state(u)
        except GaitError:  # between the planner's samples
            return None
        return step, st

    def _placement_error(self, st: Any, swing: str, surface_id: int) -> float:
        """Signed distance along the heading from the tread's centre line to the foot centre, m."""
        ends = st.sole_points_w(swing, np.array([[0.0, 0.0, -self._exo.sole_height_m], self._toe_f]))[-1]
        return placement_error_m(
            ends, self._surfaces.get(surface_id), self._T_world_stairs, self._stairs["tread_m"], self._heading_axes()[0]
        )

    def _sense(self) -> list[Any]:
        """The recorder's frames delivered by now (instants up to now, the motion so far); each
        kept as a point (the measured range along the beam from the true sensor pose) or invalid."""
        got = self._recorder.advance_to(self._t, self._motion)
        for reading, truth in got:
            T = truth.T_world_sensor
            ok = reading.valid
            p = T[:3, 3] + reading.range_m * T[:3, 2] if ok else np.zeros(3)
            self._readings[reading.sensor_id].append((p, ok))
        return [reading for reading, _ in got]

    def _observation(self) -> np.ndarray:
        x, y, z = self._heading_axes()
        R = np.column_stack([x, y, z])
        P = self._sole_point(self._stance)
        obs = np.zeros(self.observation_space.shape, dtype=np.float64)
        for i, sid in enumerate(TOF_IDS):
            buf = list(self._readings[sid])
            for k, (p, ok) in enumerate(buf, start=K_READINGS - len(buf)):
                if ok:
                    obs[64 * i + 4 * k : 64 * i + 4 * k + 3] = (p - P) @ R
                    obs[64 * i + 4 * k + 3] = 1.0
        obs[len(TOF_IDS) * K_READINGS * 4 :] = self._motion.state(self._t).joints[0]
        return np.clip(obs, self._obs_low, self._obs_high).astype(np.float32)

    def _info(
        self, out: Outcome | None = None, placement: float = 0.0, extra: dict[str, Any] | None = None, success: bool = False
    ) -> dict[str, Any]:
        info: dict[str, Any] = dict(self._stairs)
        info.update({
            "n_steps": self.n_steps,
            "T_world_stairs": self._T_world_stairs.copy(),
            "stance_side": self._stance,
            "stance_sole_w": self._sole_point(self._stance),
            "stance_surface_id": int(self._feet[self._stance].surface_id),
            "heading_rad": float(self._yaw),
            "time_s": float(self._t),
            "climbed": int(self._climbed),
            "frames": tuple(self._frames),
        })  # fmt: skip
        if out is not None:
            info.update({
                "safe": bool(out.safe), "failure": out.failure, "touched_surface_id": int(out.touched_surface_id),
                "penetration_m": float(out.penetration_m), "nosing_clearance_m": float(out.nosing_clearance_m),
                "drop_m": float(out.drop_m), "placement_error_m": float(placement), "is_success": bool(success),
            })  # fmt: skip
            info.update(extra or {})
        return info

