"""Kinematic gait driver: analytic leg inverse kinematics and smooth whole-body motions.

The exoskeleton has sagittal legs (hip, knee and ankle rotate about the lateral axis), so each
ankle must lie in its hip's sagittal plane. A motion is a chain of segments; in each one leg is
the *stance* leg, whose ankle is fixed in the world (or turns about the toe tip when the heel
rises, see :class:`Segment`), and the pelvis is described relative to it
in the heading frame (yaw ``theta``): ``pelvis = A + f x_theta - s (w/2) y_theta + h z`` with
``s = +1`` for a left stance, which keeps the stance ankle in its hip's plane whatever the yaw
(with sagittal legs a change of heading pivots the stance foot about its ankle). The other
(swing) ankle is ``A + a x_theta - s w y_theta`` at height ``z``; ``a`` and ``z`` follow a
parabola (``z = z0 + (z1 - z0) u + 4 H u (1 - u)``, ``a`` linear in ``u``), and every channel
moves with the same minimum-jerk progress ``u(t)``, rest to rest, so the motion is C2 in time.

The feet keep their soles parallel to the terrain under them (pitch only: flat on treads and
ground, along the slope on ramps); the pelvis is upright apart from a small forward lean.
:class:`Motion` is sampled at any time (arrays of times are vectorised) and gives MuJoCo's
``qpos``, ``qvel`` and ``qacc`` with addresses looked up by joint name. The free joint's linear
velocity is the world-frame velocity of the pelvis origin and its angular velocity is in the
pelvis frame, as MuJoCo defines them; ``qvel``/``qacc`` come from central differences of the
smooth coordinates (step ``h = 2e-4 s``), so MuJoCo's accelerometer and gyro computed from them
equal the derivatives of the motion.

World convention of :func:`climb_step`: the exoskeleton starts at the origin facing +x, both
feet flat on level ground at z = 0 (ankles below the hips, knees 5 deg flexed [A]). The
staircase must be built with :func:`exobench.envs.scenarios.staircase_params_for_case`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from exobench.core import ConfigError, ExobenchError, SceneTruth
from exobench.models.exo_spec import JOINT_RANGES_RAD, LEG_JOINTS, NECK_JOINTS, ExoSpec

from .terrain import Terrain, sole_grid_f

KNEE_MIN_RAD = np.radians(2.0)  # never straighter: no hyperextension, no singular IK [A]
KNEE_MAX_RAD = float(JOINT_RANGES_RAD["knee"][1])
STAND_KNEE_RAD = np.radians(5.0)  # relaxed standing knee flexion [A]
TARGET_KNEE_RAD = np.radians(10.0)  # least knee flexion the planner aims for at touch-down [A]
STANCE_KNEE_MAX_RAD = np.radians(75.0)  # deepest stance knee flexion a planned step may need [A]
CLIMB_LEAN_RAD = np.radians(6.0)  # forward trunk lean while stepping up [A]
DIFF_H_S = 2e-4  # central-difference step for qvel/qacc


class GaitError(ExobenchError):
    """A planned motion cannot be executed by the legs (out of reach, knee limits)."""


def min_jerk(s: np.ndarray) -> np.ndarray:
    """Minimum-jerk progress 10 s^3 - 15 s^4 + 6 s^5 of s clipped to [0, 1] (zero vel/acc at the ends)."""
    s = np.clip(s, 0.0, 1.0)
    return s * s * s * (10.0 + s * (-15.0 + 6.0 * s))


def leg_length_for_knee(exo: ExoSpec, knee_rad: float) -> float:
    """Hip-to-ankle distance of a leg whose knee is flexed by ``knee_rad``."""
    T, S = exo.thigh_m, exo.shank_m
    return float(np.sqrt(T * T + S * S + 2.0 * T * S * np.cos(knee_rad)))


def leg_ik(
    exo: ExoSpec, dx: np.ndarray, dz: np.ndarray, foot_pitch: np.ndarray, pelvis_pitch: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Joint angles (hip, knee, ankle) placing the ankle at (dx, dz) from the hip.

    ``dx`` (forward) and ``dz`` (up) are in the heading frame (yaw only), ``foot_pitch`` is the
    sole's toes-up angle in that frame and ``pelvis_pitch`` the pelvis' forward lean; signs as in
    :mod:`exobench.models.exo_spec`. The knee always flexes (the shank swings back). Raises
    :class:`GaitError` (with ``.index`` of the first bad sample) outside the knee limits.
    """
    T, S = exo.thigh_m, exo.shank_m
    D2 = dx * dx + dz * dz
    cos_k = (D2 - T * T - S * S) / (2.0 * T * S)
    bad = (cos_k > np.cos(KNEE_MIN_RAD) + 1e-12) | (cos_k < np.cos(KNEE_MAX_RAD) - 1e-12)
    if np.any(bad):
        i = int(np.argmax(bad))
        err = GaitError(
            f"leg out of reach: hip-ankle distance {np.sqrt(D2[i]):.3f} m outside "
            f"[{leg_length_for_knee(exo, KNEE_MAX_RAD):.3f}, {leg_length_for_knee(exo, KNEE_MIN_RAD):.3f}] m"
        )
        err.index = i  # type: ignore[attr-defined]
        raise err
    knee = np.arccos(np.clip(cos_k, -1.0, 1.0))
    D = np.sqrt(D2)
    gamma = np.arctan2(dx, -dz)  # hip-ankle line from the downward vertical, forward +
    delta = np.arccos(np.clip((T * T + D2 - S * S) / (2.0 * T * D), -1.0, 1.0))
    thigh = gamma + delta  # thigh ahead of the line, shank behind: the knee flexes forward
    hip = thigh + pelvis_pitch
    ankle = foot_pitch - thigh + knee
    for name, q in (("hip", hip), ("ankle", ankle)):
        lo, hi = JOINT_RANGES_RAD[name]
        bad = (q < lo - 1e-9) | (q > hi + 1e-9)
        if np.any(bad):
            i = int(np.argmax(bad))
            err = GaitError(
                f"{name} angle {np.degrees(q[i]):.1f} deg outside its range "
                f"[{np.degrees(lo):.0f}, {np.degrees(hi):.0f}] deg"
            )
            err.index = i  # type: ignore[attr-defined]
            raise err
    return hip, knee, ankle


def leg_fk(
    exo: ExoSpec, hip: np.ndarray, knee: np.ndarray, ankle: np.ndarray, pelvis_pitch: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Inverse of :func:`leg_ik`: ankle (dx, dz) from the hip and the foot pitch, heading frame."""
    thigh = hip - pelvis_pitch
    shank = thigh - knee
    dx = exo.thigh_m * np.sin(thigh) + exo.shank_m * np.sin(shank)
    dz = -exo.thigh_m * np.cos(thigh) - exo.shank_m * np.cos(shank)
    return dx, dz, ankle + thigh - knee


def rot_yaw_pitch(yaw: np.ndarray, pitch: np.ndarray) -> np.ndarray:
    """Rotations Rz(yaw) Ry(pitch), shape (N, 3, 3)."""
    cy, sy, cp, sp = np.cos(yaw), np.sin(yaw), np.cos(pitch), np.sin(pitch)
    R = np.empty((len(yaw), 3, 3))
    R[:, 0] = np.stack([cy * cp, -sy, cy * sp], axis=-1)
    R[:, 1] = np.stack([sy * cp, cy, sy * sp], axis=-1)
    R[:, 2] = np.stack([-sp, np.zeros_like(sp), cp], axis=-1)
    return R


def toe_pivot(exo: ExoSpec, ankle0: np.ndarray, x_h: np.ndarray, pitch0: np.ndarray, pitch: np.ndarray) -> np.ndarray:
    """Ankle (N, 3) of a foot turned about its toe tip from pitch ``pitch0`` to ``pitch``.

    ``ankle0`` is the ankle at ``pitch0``; ``x_h`` the heading's forward unit vectors (N, 3).
    """
    toe_x, sole_h = exo.foot_m - exo.heel_to_ankle_m, exo.sole_height_m
    z = np.array([0.0, 0.0, 1.0])

    def offset(b: np.ndarray) -> np.ndarray:  # ankle -> toe tip at pitch b
        b = np.atleast_1d(b)[:, None]
        return toe_x * (np.cos(b) * x_h + np.sin(b) * z) - sole_h * (-np.sin(b) * x_h + np.cos(b) * z)

    return ankle0 + offset(pitch0) - offset(pitch)


@dataclass(frozen=True)
class Segment:
    """One rest-to-rest piece of a motion (see the module docstring for the parametrisation).

    ``stance`` is ``"l"`` or ``"r"``; ``ankle_w`` the stance ankle at ``t0`` (world); angles in
    rad; ``a``/``z`` of the swing ankle (``z`` absolute world height), ``apex_m`` the parabola's
    extra height ``H``; foot pitches are toes-up sole angles in the heading frame.
    ``swing_lag`` (0..0.3) delays the swing foot's forward motion: ``a`` follows
    ``min_jerk((u - lag) / (1 - 2 lag))`` instead of ``u``, so the foot first rises and last
    descends nearly vertically (0: the plain parabola of the staircase paper); ``swing_dip``
    (rad) points the toes down mid-swing by ``dip * 4 u (1 - u)``, as feet do after toe-off. When the
    stance pitch changes (a heel rise, only with a constant yaw) the stance foot pivots about
    its toe tip and the stance ankle moves with it. ``swing_pivot`` (a segment whose swing foot
    rests on the ground, ``a`` and ``z`` constant, yaw constant): the other foot turns about its
    toe tip from ``swing_pitch[0]`` to ``swing_pitch[1]`` (the heel lowering after a forefoot
    landing) and its ankle follows that rotation exactly.
    """

    t0: float
    t1: float
    stance: str
    ankle_w: tuple[float, float, float]
    stance_pitch: tuple[float, float]
    yaw: tuple[float, float]
    pitch: tuple[float, float]
    f: tuple[float, float]
    h: tuple[float, float]
    a: tuple[float, float]
    z: tuple[float, float]
    apex_m: float
    swing_pitch: tuple[float, float]
    swing_lag: float = 0.0
    swing_dip: float = 0.0
    swing_pivot: bool = False


@dataclass(frozen=True)
class Footstep:
    """A step of the swing foot: times, where its sole point (below the ankle) landed, yaw."""

    side: str
    liftoff_s: float
    touchdown_s: float
    sole_w: np.ndarray
    yaw_rad: float
    surface_id: int


@dataclass(frozen=True, eq=False)
class MotionState:
    """Coordinates of the motion at times ``t`` (N,): pelvis pose, joints, feet (world)."""

    t: np.ndarray
    pelvis_w: np.ndarray  # (N, 3)
    yaw: np.ndarray  # (N,)
    pitch: np.ndarray  # (N,)
    joints: np.ndarray  # (N, 6) in LEG_JOINTS order
    ankle_w: dict[str, np.ndarray]  # side -> (N, 3)
    foot_pitch: dict[str, np.ndarray]  # side -> (N,)

    def foot_R(self, side: str) -> np.ndarray:
        """World orientation of a foot, (N, 3, 3): heading yaw, toes-up pitch."""
        return rot_yaw_pitch(self.yaw, -self.foot_pitch[side])

    def sole_points_w(self, side: str, points_f: np.ndarray) -> np.ndarray:
        """Foot-frame points (K, 3) in the world at every time, (N, K, 3)."""
        return self.ankle_w[side][:, None, :] + np.einsum("nij,kj->nki", self.foot_R(side), points_f)


@dataclass(frozen=True, eq=False)
class MotionSample:
    """MuJoCo state at times ``t`` (N,): ``qpos`` (N, nq), ``qvel`` and ``qacc`` (N, nv)."""

    t: np.ndarray
    qpos: np.ndarray
    qvel: np.ndarray
    qacc: np.ndarray


class Motion:
    """A whole-body kinematic motion built from :class:`Segment` pieces; sample it at any time."""

    def __init__(
        self,
        exo: ExoSpec,
        segments: list[Segment],
        *,
        events: dict[str, float] | None = None,
        footsteps: tuple[Footstep, ...] = (),
        stance_side: str = "l",
    ) -> None:
        if not segments:
            raise GaitError("a motion needs at least one segment")
        self.exo = exo
        self.segments = tuple(segments)
        self.events = dict(events or {})
        self.footsteps = footsteps
        self.stance_side = stance_side
        self.duration_s = float(segments[-1].t1)
        S = self.segments
        self._t0 = np.array([s.t0 for s in S])
        self._t1 = np.array([s.t1 for s in S])
        self._sg = np.array([1.0 if s.stance == "l" else -1.0 for s in S])
        self._A = np.array([s.ankle_w for s in S], dtype=float)
        self._pairs = {
            k: np.array([getattr(s, k) for s in S], dtype=float)
            for k in ("yaw", "pitch", "f", "h", "a", "z", "swing_pitch", "stance_pitch")
        }
        self._apex = np.array([s.apex_m for s in S])
        self._lag = np.array([s.swing_lag for s in S])
        self._dip = np.array([s.swing_dip for s in S])
        self._pivot = np.array([s.swing_pivot for s in S], dtype=bool)
        self._addr_cache: dict[int, tuple[object, np.ndarray, int, int]] = {}

    # --- coordinates -------------------------------------------------------------------------
    def state(self, t: np.ndarray | float, *, solve_legs: bool = True) -> MotionState:
        """Pelvis pose, joint angles and feet at times ``t`` (clamped to [0, duration]).

        With ``solve_legs=False`` the joints are NaN (planning before the legs are checked).
        """
        t = np.atleast_1d(np.asarray(t, dtype=float))
        tc = np.clip(t, 0.0, self.duration_s)
        i = np.clip(np.searchsorted(self._t0, tc, side="right") - 1, 0, len(self.segments) - 1)
        span = self._t1[i] - self._t0[i]
        u = min_jerk(np.where(span > 0, (tc - self._t0[i]) / np.where(span > 0, span, 1.0), 1.0))

        def lerp(k: str) -> np.ndarray:
            p = self._pairs[k][i]
            return p[:, 0] + (p[:, 1] - p[:, 0]) * u

        yaw, pitch, f, h = lerp("yaw"), lerp("pitch"), lerp("f"), lerp("h")
        lag = self._lag[i]
        ua = np.where(lag > 0, min_jerk((u - lag) / np.maximum(1.0 - 2.0 * lag, 1e-9)), u)
        pa = self._pairs["a"][i]
        a = pa[:, 0] + (pa[:, 1] - pa[:, 0]) * ua
        zz = self._pairs["z"][i]
        z_sw = zz[:, 0] + (zz[:, 1] - zz[:, 0]) * u + 4.0 * self._apex[i] * u * (1.0 - u)
        sg = self._sg[i]
        w = self.exo.hip_width_m
        xh = np.column_stack([np.cos(yaw), np.sin(yaw), np.zeros_like(yaw)])
        yh = np.column_stack([-np.sin(yaw), np.cos(yaw), np.zeros_like(yaw)])
        st_pitch = lerp("stance_pitch")
        sp0 = self._pairs["stance_pitch"][i][:, 0]
        A = np.where(
            (st_pitch != sp0)[:, None], toe_pivot(self.exo, self._A[i], xh, sp0, st_pitch), self._A[i]
        )
        pelvis = A + f[:, None] * xh - (sg * 0.5 * w)[:, None] * yh
        pelvis[:, 2] = A[:, 2] + h
        swing = A + a[:, None] * xh - (sg * w)[:, None] * yh
        swing[:, 2] = z_sw
        sw_pitch = lerp("swing_pitch") - self._dip[i] * 4.0 * u * (1.0 - u)
        piv = self._pivot[i]
        if np.any(piv):  # a resting foot turning about its toe tip (see Segment)
            swp0 = self._pairs["swing_pitch"][i][:, 0]
            swing = np.where(piv[:, None], toe_pivot(self.exo, swing, xh, swp0, sw_pitch), swing)
        left = sg > 0
        ankle = {"l": np.where(left[:, None], A, swing), "r": np.where(left[:, None], swing, A)}
        fpitch = {"l": np.where(left, st_pitch, sw_pitch), "r": np.where(left, sw_pitch, st_pitch)}
        joints = np.full((len(t), 6), np.nan)
        for k, side in enumerate(("l", "r") if solve_legs else ()):
            hip = pelvis + (0.5 * w if side == "l" else -0.5 * w) * yh
            d = ankle[side] - hip
            lateral = np.einsum("ij,ij->i", d, yh)
            if np.any(np.abs(lateral) > 1e-9):
                j = int(np.argmax(np.abs(lateral) > 1e-9))
                raise GaitError(f"ankle_{side} leaves its hip's sagittal plane by {lateral[j]:.3g} m at t={t[j]:.3f} s")
            try:
                q = leg_ik(self.exo, np.einsum("ij,ij->i", d, xh), d[:, 2], fpitch[side], pitch)
            except GaitError as e:
                j = getattr(e, "index", 0)
                raise GaitError(f"{side} leg at t={t[j]:.3f} s: {e}") from None
            joints[:, 3 * k : 3 * k + 3] = np.column_stack(q)
        return MotionState(t, pelvis, yaw, pitch, joints, ankle, fpitch)

    def _coords(self, t: np.ndarray) -> np.ndarray:
        s = self.state(t)
        return np.column_stack([s.pelvis_w, s.yaw, s.pitch, s.joints])

    # --- MuJoCo state ------------------------------------------------------------------------
    def _addresses(self, model: object) -> tuple[np.ndarray, int, int]:
        import mujoco

        hit = self._addr_cache.get(id(model))
        if hit is not None and hit[0] is model:
            return hit[1], hit[2], hit[3]
        jid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, "root")
        if jid < 0:
            raise GaitError("the model has no free joint named 'root'")
        root_q, root_v = int(model.jnt_qposadr[jid]), int(model.jnt_dofadr[jid])
        adr = []
        for name in LEG_JOINTS:
            j = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, name)
            if j < 0:
                raise GaitError(f"the model has no joint named {name!r}")
            adr.append((int(model.jnt_qposadr[j]), int(model.jnt_dofadr[j])))
        arr = np.array(adr, dtype=int)
        self._addr_cache[id(model)] = (model, arr, root_q, root_v)
        return arr, root_q, root_v

    @staticmethod
    def _joint_qposadr(model: object, name: str) -> list[int]:
        import mujoco

        j = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, name)
        return [] if j < 0 else [int(model.jnt_qposadr[j])]  # type: ignore[attr-defined]

    def sample(self, model: object, t: np.ndarray | float) -> MotionSample:
        """``qpos``, ``qvel``, ``qacc`` of ``model`` at times ``t`` (other joints, e.g. the neck, at 0)."""
        t = np.atleast_1d(np.asarray(t, dtype=float))
        adr, rq, rv = self._addresses(model)
        h = DIFF_H_S
        c0, cm, cp = self._coords(t), self._coords(t - h), self._coords(t + h)
        vel = (cp - cm) / (2.0 * h)
        acc = (cp - 2.0 * c0 + cm) / (h * h)
        n = len(t)
        qpos = np.tile(np.asarray(model.qpos0, dtype=float), (n, 1))  # type: ignore[attr-defined]
        for name in NECK_JOINTS:  # the head looks straight ahead
            qpos[:, self._joint_qposadr(model, name)] = 0.0
        nv = int(model.nv)  # type: ignore[attr-defined]
        qvel, qacc = np.zeros((n, nv)), np.zeros((n, nv))
        yaw, pitch = c0[:, 3], c0[:, 4]
        qpos[:, rq : rq + 3] = c0[:, :3]
        cy, sy, cp_, sp_ = np.cos(yaw / 2), np.sin(yaw / 2), np.cos(pitch / 2), np.sin(pitch / 2)
        qpos[:, rq + 3 : rq + 7] = np.column_stack([cy * cp_, -sy * sp_, cy * sp_, sy * cp_])
        qvel[:, rv : rv + 3] = vel[:, :3]
        qacc[:, rv : rv + 3] = acc[:, :3]
        dyaw, dpitch, ddyaw, ddpitch = vel[:, 3], vel[:, 4], acc[:, 3], acc[:, 4]
        s, c = np.sin(pitch), np.cos(pitch)
        # body-frame angular velocity of Rz(yaw) Ry(pitch) and its time derivative
        qvel[:, rv + 3 : rv + 6] = np.column_stack([-s * dyaw, dpitch, c * dyaw])
        qacc[:, rv + 3 : rv + 6] = np.column_stack(
            [-c * dpitch * dyaw - s * ddyaw, ddpitch, -s * dpitch * dyaw + c * ddyaw]
        )
        qpos[:, adr[:, 0]] = c0[:, 5:]
        qvel[:, adr[:, 1]] = vel[:, 5:]
        qacc[:, adr[:, 1]] = acc[:, 5:]
        return MotionSample(t, qpos, qvel, qacc)

    # --- ground truth ------------------------------------------------------------------------
    def sole_point_w(self, side: str, t: np.ndarray | float) -> np.ndarray:
        """The sole point right below a foot's ankle, world, (N, 3)."""
        st = self.state(t)
        return st.sole_points_w(side, np.array([[0.0, 0.0, -self.exo.sole_height_m]]))[:, 0]

    def max_penetration_m(self, truth: SceneTruth, t: np.ndarray, sole_f: np.ndarray | None = None) -> float:
        """Deepest point of either sole below the terrain under it over the times ``t``, m."""
        terrain = Terrain(truth)
        pts = sole_grid_f(self.exo) if sole_f is None else sole_f
        st = self.state(t)
        worst = 0.0
        for side in ("l", "r"):
            p = st.sole_points_w(side, pts)
            moved = np.ones(len(p), dtype=bool)  # a foot at rest needs checking once
            moved[1:] = np.any(np.abs(np.diff(p, axis=0)) > 0.0, axis=(1, 2))
            p = p[moved].reshape(-1, 3)
            worst = max(worst, float(np.max(terrain.penetration(p), initial=0.0)))
        return worst


# ----------------------------------------------------------------------------------------------
# planning helpers shared by climb_step and walk


@dataclass
class _SwingPlan:
    """Everything a swing segment needs apart from its apex height."""

    stance: str
    A: np.ndarray
    stance_pitch: tuple[float, float]
    yaw: tuple[float, float]
    pitch: tuple[float, float]
    f: tuple[float, float]
    h: tuple[float, float]
    a: tuple[float, float]
    z: tuple[float, float]
    swing_pitch: tuple[float, float]
    lag: float = 0.0
    dip: float = 0.0

    def segment(self, t0: float, t1: float, apex_m: float) -> Segment:
        return Segment(
            t0, t1, self.stance, tuple(float(v) for v in self.A), self.stance_pitch,
            self.yaw, self.pitch, self.f, self.h, self.a, self.z, float(apex_m), self.swing_pitch,
            float(self.lag), float(self.dip),
        )  # fmt: skip


def still_segment(exo: ExoSpec, plan: _SwingPlan, t0: float, t1: float, *, at_end: bool) -> Segment:
    """A segment holding the pose at the start (``at_end=False``) or end of a swing plan."""
    k = 1 if at_end else 0

    def hold(p: tuple[float, float]) -> tuple[float, float]:
        return (p[k], p[k])

    A = np.asarray(plan.A, dtype=float)
    if at_end and plan.stance_pitch[1] != plan.stance_pitch[0]:
        x_h = np.array([[np.cos(plan.yaw[1]), np.sin(plan.yaw[1]), 0.0]])
        A = toe_pivot(exo, A, x_h, np.array([plan.stance_pitch[0]]), np.array([plan.stance_pitch[1]]))[0]
    return Segment(
        t0, t1, plan.stance, tuple(float(v) for v in A), hold(plan.stance_pitch),
        hold(plan.yaw), hold(plan.pitch), hold(plan.f), hold(plan.h), hold(plan.a), hold(plan.z),
        0.0, hold(plan.swing_pitch),
    )  # fmt: skip


def heel_drop_segment(
    exo: ExoSpec, plan: _SwingPlan, t0: float, t1: float, *, to_pitch: float, f: float, h: float
) -> Segment:
    """The double support after a forefoot landing: both feet stay, the landed foot turns about
    its toe tip from the swing plan's end pitch to ``to_pitch`` (its heel lowers onto the
    support; a ``swing_pivot`` segment) and the pelvis moves from the plan's end pose to
    ``(f, h)`` over the stance ankle (it comes down as the leading leg takes the body)."""
    seg = still_segment(exo, plan, t0, t1, at_end=True)
    return Segment(
        seg.t0, seg.t1, seg.stance, seg.ankle_w, seg.stance_pitch, seg.yaw, seg.pitch, (seg.f[0], float(f)),
        (seg.h[0], float(h)), seg.a, seg.z, 0.0, (seg.swing_pitch[0], float(to_pitch)), swing_pivot=True,
    )  # fmt: skip


def swing_apex_m(
    exo: ExoSpec,
    terrain: Terrain,
    plan: _SwingPlan,
    *,
    clearance_m: float,
    min_apex_m: float = 0.03,
    ramp: float = 0.2,
    n: int = 241,
    exact_progress: bool = False,
) -> float:
    """Least parabola height ``H`` keeping the swing sole ``clearance_m`` above the terrain.

    The clearance asked for grows linearly from 0 at lift-off and touch-down to its full value
    at a fraction ``ramp`` of the path, so the foot can leave and reach its support. The path is
    sampled uniformly in progress ``u``. ``exact_progress=True`` (the walk planner) inverts the
    minimum-jerk profile exactly; the default keeps the original Newton inversion, which sends
    the first and last 5 % of ``u`` to the rest poses (harmless for a flat foot; the staircase
    track's climbing step and its reference results use it), but misses a toe pitched down near
    lift-off or touch-down.
    """
    seg = plan.segment(0.0, 1.0, 0.0)
    m = Motion(exo, [seg])
    u = np.linspace(0.0, 1.0, n)[1:-1]  # uniform in path progress, not in time
    t = _inverse_min_jerk_exact(u) if exact_progress else _inverse_min_jerk(u)
    st = m.state(t, solve_legs=False)
    swing = "r" if plan.stance == "l" else "l"
    pts = st.sole_points_w(swing, sole_grid_f(exo, nx=13, ny=3))
    ground = terrain.height(pts.reshape(-1, 3)[:, :2]).reshape(pts.shape[:2])
    need = np.minimum(1.0, np.minimum(u, 1.0 - u) / ramp) * clearance_m
    deficit = np.nanmax(ground - pts[:, :, 2], axis=1, initial=-np.inf) + need
    H = np.max(deficit / (4.0 * u * (1.0 - u)))
    return float(max(H, min_apex_m))


# swing shapes (lag, toe-down dip) the walk planner tries, plainest first
SWING_SHAPES = tuple((lag, np.radians(dip)) for dip in (0.0, 15.0, 30.0) for lag in (0.0, 0.15, 0.3))


def _inverse_min_jerk_exact(u: np.ndarray) -> np.ndarray:
    """Times s in [0, 1] with min_jerk(s) = u (bisection; min_jerk is increasing on [0, 1])."""
    lo, hi = np.zeros_like(u), np.ones_like(u)
    for _ in range(52):
        mid = 0.5 * (lo + hi)
        below = min_jerk(mid) < u
        lo, hi = np.where(below, mid, lo), np.where(below, hi, mid)
    return 0.5 * (lo + hi)


def _inverse_min_jerk(u: np.ndarray) -> np.ndarray:
    s = u.copy()
    for _ in range(30):  # Newton on 10s^3-15s^4+6s^5 = u, monotone on [0, 1]
        f = min_jerk(s) - u
        df = 30.0 * s * s * (1.0 - s) ** 2
        s = np.clip(s - f / np.maximum(df, 1e-9), 0.0, 1.0)
    return s


def pelvis_height(exo: ExoSpec, f: float, swing_a: float, swing_dz: float, knee_rad: float) -> float:
    """Highest pelvis (above the stance ankle) with both knees flexed at least ``knee_rad``.

    ``f`` is the pelvis ahead of the stance ankle; the other ankle is ``swing_a`` ahead and
    ``swing_dz`` above the stance ankle; capped at the relaxed standing height.
    """
    D = leg_length_for_knee(exo, knee_rad)
    h = leg_length_for_knee(exo, STAND_KNEE_RAD)
    for dx, dz in ((f, 0.0), (swing_a - f, swing_dz)):
        if abs(dx) >= D:
            return float("nan")
        h = min(h, dz + np.sqrt(D * D - dx * dx))
    return float(h)


def end_pelvis(
    exo: ExoSpec,
    swing_a: float,
    swing_dz: float,
    pitch: float,
    foot_pitch: tuple[float, float] = (0.0, 0.0),
    max_knee_rad: float = STANCE_KNEE_MAX_RAD,
) -> tuple[float, float]:
    """The preferred of :func:`end_pelvis_options`, or (nan, nan) when there is none."""
    opts = end_pelvis_options(exo, swing_a, swing_dz, pitch, foot_pitch, max_knee_rad)
    return opts[0] if opts else (float("nan"), float("nan"))


def end_pelvis_options(
    exo: ExoSpec,
    swing_a: float,
    swing_dz: float,
    pitch: float,
    foot_pitch: tuple[float, float] = (0.0, 0.0),
    max_knee_rad: float = STANCE_KNEE_MAX_RAD,
) -> list[tuple[float, float]]:
    """Pelvis positions (f, h) over the stance ankle for a double stance, best first.

    The other ankle is ``swing_a`` ahead and ``swing_dz`` above the stance ankle. The pelvis
    stands at the highest height :func:`pelvis_height` allows; positions keeping every joint
    8 deg inside its range come first, nearest to 45 % of the way to the other foot, then the
    others by decreasing margin. Empty when no position keeps the knees below
    ``max_knee_rad`` and the joints in range.
    """
    D_deep = leg_length_for_knee(exo, max_knee_rad)
    cands = []
    for lam in np.linspace(0.15, 0.85, 57):
        f = lam * swing_a
        h = pelvis_height(exo, f, swing_a, swing_dz, TARGET_KNEE_RAD)
        if not np.isfinite(h) or np.hypot(f, h) < D_deep or np.hypot(swing_a - f, h - swing_dz) < D_deep:
            continue
        margin = np.inf
        for dx, dz, fp in ((-f, -h, foot_pitch[0]), (swing_a - f, swing_dz - h, foot_pitch[1])):
            try:
                q = leg_ik(exo, np.array([dx]), np.array([dz]), np.array([fp]), np.array([pitch]))
            except GaitError:
                margin = -np.inf
                break
            for name, v in zip(("hip", "knee", "ankle"), q):
                lo, hi = JOINT_RANGES_RAD[name]
                margin = min(margin, float(v[0] - lo), float(hi - v[0]))
        if margin > -np.inf:
            cands.append((lam, f, h, margin))
    good = sorted((c for c in cands if c[3] >= np.radians(8.0)), key=lambda c: abs(c[0] - 0.45))
    rest = sorted((c for c in cands if c[3] < np.radians(8.0)), key=lambda c: -c[3])
    return [(float(c[1]), float(c[2])) for c in good + rest]


def check_feasible(motion: Motion, rate_hz: float = 1000.0) -> None:
    """Solve the legs over the whole motion (raises :class:`GaitError` where it fails)."""
    motion.state(np.arange(0.0, motion.duration_s + 0.5 / rate_hz, 1.0 / rate_hz))


# ----------------------------------------------------------------------------------------------
# the paper's protocol


def _riser_and_tread(truth: SceneTruth) -> tuple[object, object, object | None]:
    try:
        riser, tread = truth.surface(1), truth.surface(2)
    except KeyError:
        raise ConfigError("truth", truth.kind, "a staircase with surfaces 1 (riser) and 2 (tread)") from None
    if riser.kind != "riser" or tread.kind not in ("tread", "landing"):
        raise ConfigError("truth", truth.kind, "an ascending staircase (surface 1 a riser, 2 a tread)")
    nxt = None
    for s in truth.surfaces:
        if s.surface_id == 3 and s.kind == "riser":
            nxt = s
    return riser, tread, nxt


def climb_step(
    exo: ExoSpec,
    truth: SceneTruth,
    *,
    distance_m: float,
    yaw_deg: float,
    duration_s: float = 2.0,
    side: str = "r",
    still_s: float = 0.3,
    settle_s: float = 0.3,
    clearance_m: float = 0.04,
) -> Motion:
    """One climbing step of the staircase paper (section V-A), not updated by perception.

    The exoskeleton stands at the origin facing +x, feet flat on the ground; the staircase in
    ``truth`` must have its first riser at perpendicular distance ``distance_m`` from the swing
    foot's toe tip and be yawed by ``-yaw_deg`` (the exoskeleton turned by ``yaw_deg``
    counter-clockwise relative to the stairs), as
    :func:`exobench.envs.scenarios.staircase_params_for_case` builds it. After ``still_s`` of
    standing, the ``side`` foot lifts off and follows a parabola (flat sole, minimum-jerk
    progress) to the first tread: the footprint is centred on the tread along the walking
    direction (toe 1 cm short of the next riser when the foot is longer than the tread), the
    apex is the lowest giving ``clearance_m`` over the terrain; the pelvis moves forward, down
    as needed and leans 6 deg. Touch-down is ``settle_s`` before the end.

    Events: ``liftoff_s``, ``touchdown_s``. Raises :class:`ConfigError` when the first tread is
    out of one step's reach or the staircase does not match ``distance_m``/``yaw_deg``.
    """
    if side not in ("l", "r"):
        raise ConfigError("side", side, "'l' or 'r'")
    if duration_s - still_s - settle_s < 0.5:
        raise ConfigError("duration_s", duration_s, f">= {still_s + settle_s + 0.5} s (still, swing >= 0.5 s, settle)")
    stance = "l" if side == "r" else "r"
    sg = 1.0 if stance == "l" else -1.0
    w = exo.hip_width_m
    sole_h = exo.sole_height_m
    toe_x = exo.foot_m - exo.heel_to_ankle_m
    y_sw = -sg * 0.5 * w
    toe = np.array([toe_x, y_sw, 0.0])
    riser, tread, nxt = _riser_and_tread(truth)
    d = -riser.normal_w  # up the stairs, horizontal
    dist = float((riser.point_w - toe) @ d)
    if abs(dist - distance_m) > 1e-6:
        raise ConfigError("distance_m", distance_m, f"the staircase's first riser is {dist:.4f} m from the toe tip")
    yaw_st = np.degrees(np.arctan2(d[1], d[0]))
    if abs(((yaw_st + yaw_deg) + 180.0) % 360.0 - 180.0) > 1e-6:
        raise ConfigError("yaw_deg", yaw_deg, f"the staircase is yawed {yaw_st:.3f} deg, i.e. yaw_deg={-yaw_st:.3f}")
    cpsi = float(d[0])
    if cpsi < 0.2:
        raise ConfigError("yaw_deg", yaw_deg, "|yaw_deg| < 78 (the stairs must lie ahead)")
    terrain = Terrain(truth)
    grid = sole_grid_f(exo)
    for s_side, y in (("l", 0.5 * w), ("r", -0.5 * w)):
        z, ids = terrain.query(grid[:, :2] + [0.0, y])
        if np.any(ids != 0) or np.any(np.abs(z) > 1e-9):
            raise ConfigError(
                "distance_m", distance_m, f"both feet must start on the level ground before the stairs (foot_{s_side} is not)"
            )

    # touch-down: footprint centred on the tread along d (toe short of the next riser)
    proj_t = (tread.polygon_w - riser.point_w) @ d
    lo, hi = float(proj_t.min()), float(proj_t.max())
    if nxt is not None:
        hi = min(hi, float((nxt.point_w - riser.point_w) @ d))
    spread = grid[:, :2] @ np.array([d[0], d[1]])  # footprint along d at yaw 0 (foot along +x)
    half = 0.5 * float(spread.max() - spread.min())
    centre_f = 0.5 * float(spread.max() + spread.min())
    target = 0.5 * (lo + hi)
    if 2.0 * half > hi - lo:  # the foot is longer than the tread: toe 1 cm short of the next riser
        target = hi - 0.01 - half
    start_c = float((np.array([0.0, y_sw, 0.0]) - riser.point_w) @ d) + centre_f
    shift = (target - start_c) / cpsi  # ankle travel along +x
    z_tread = float(truth.surface(tread.surface_id).point_w[2])
    A = np.array([0.0, sg * 0.5 * w, sole_h])
    a1, z1 = shift, z_tread + sole_h
    z_td, ids = terrain.query(grid[:, :2] + [a1, y_sw])
    front = grid[:, 0] >= 0.0  # ankle to toe must rest on the tread; a heel may overhang
    above = np.isfinite(z_td) & (z_td > z_tread + 1e-9)
    if np.any(ids[front] != tread.surface_id) or np.any(above):
        raise ConfigError("tread_m", tread.surface_id, "a tread that holds the foot from the ankle to the toe")

    h_stand = leg_length_for_knee(exo, STAND_KNEE_RAD)
    options = end_pelvis_options(exo, a1, z_tread, CLIMB_LEAN_RAD)
    if not options:
        raise ConfigError(
            "distance_m", distance_m, f"a first tread within one step's reach (ankle travel {a1:.3f} m at yaw {yaw_deg} deg is too long)"
        )
    t_lift, t_td = still_s, duration_s - settle_s
    sole_td = np.array([a1, y_sw, z_tread])
    fs = Footstep(side, t_lift, t_td, sole_td, 0.0, int(tread.surface_id))
    last = ""
    # the paper's parabola (no lag); the toes may point down mid-swing when a flat foot would
    # need more ankle dorsiflexion than the device allows
    for dip in np.radians([0.0, 15.0, 30.0]):
        plan = _SwingPlan(
            stance=stance, A=A, stance_pitch=(0.0, 0.0), yaw=(0.0, 0.0), pitch=(0.0, CLIMB_LEAN_RAD),
            f=(0.0, 0.0), h=(h_stand, h_stand), a=(0.0, a1), z=(sole_h, z1), swing_pitch=(0.0, 0.0), dip=float(dip),
        )  # fmt: skip
        apex = swing_apex_m(exo, terrain, plan, clearance_m=clearance_m)
        for f1, h1 in options[:12]:  # the preferred end pose whose whole swing the legs can follow
            plan.f, plan.h = (0.0, f1), (h_stand, h1)
            segs = [
                still_segment(exo, plan, 0.0, t_lift, at_end=False),
                plan.segment(t_lift, t_td, apex),
                still_segment(exo, plan, t_td, duration_s, at_end=True),
            ]
            motion = Motion(
                exo, segs, events={"liftoff_s": t_lift, "touchdown_s": t_td}, footsteps=(fs,), stance_side=stance
            )
            try:
                check_feasible(motion)
            except GaitError as e:
                last = str(e)
                continue
            return motion
    raise ConfigError(
        "distance_m", distance_m, f"a first tread the {side} leg can step onto at yaw {yaw_deg} deg ({last})"
    )


def walk(exo: ExoSpec, truth: SceneTruth, route: object) -> Motion:
    """Footsteps along a route; see :func:`exobench.envs.walk.plan_walk` and :class:`exobench.envs.walk.Route`."""
    from .walk import plan_walk

    return plan_walk(exo, truth, route)  # type: ignore[arg-type]
