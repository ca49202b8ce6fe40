"""Whole-body kinematic motions: a chain of rest-to-rest segments sampled at any time.

In each segment one leg is the *stance* leg, whose ankle is fixed in the world (or turns about
the toe tip when the heel rises, see :class:`Segment`), and the pelvis is described relative to
it in the heading frame (yaw ``theta``): ``pelvis = A + f x_theta - s (w/2) y_theta + h z`` with
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
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from exobench.core import SceneTruth
from exobench.models.exo_spec import LEG_JOINTS, NECK_JOINTS, ExoSpec

from ..terrain import Terrain
from .kinematics import GaitError, leg_ik, rot_yaw_pitch, sole_grid_f, toe_pivot

DIFF_H_S = 2e-4  # central-difference step for qvel/qacc
TRUTH_CHUNK = 10_000  # instants of the motion solved at once for its truth (10 s at 1 kHz)


def min_jerk(s: np.ndarray) -> np.ndarray:
    """Minimum-jerk progress 10 s^3 - 15 s^4 + 6 s^5 of s clipped to [0, 1] (zero vel/acc at the ends)."""
    s = np.clip(s, 0.0, 1.0)
    return s * s * s * (10.0 + s * (-15.0 + 6.0 * s))


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
        t = np.atleast_1d(np.asarray(t, dtype=float))
        worst = 0.0
        for k in range(0, len(t), TRUTH_CHUNK):  # in chunks: a long walk's soles at 1 kHz are big
            st = self.state(t[k : k + TRUTH_CHUNK])
            for side in ("l", "r"):
                p = st.sole_points_w(side, pts)
                moved = np.ones(len(p), dtype=bool)  # a foot at rest needs checking once
                moved[1:] = np.any(np.abs(np.diff(p, axis=0)) > 0.0, axis=(1, 2))
                p = p[moved].reshape(-1, 3)
                worst = max(worst, float(np.max(terrain.penetration(p), initial=0.0)))
        return worst



def check_feasible(motion: Motion, rate_hz: float = 1000.0) -> None:
    """Solve the legs over the whole motion (raises :class:`GaitError` where it fails)."""
    motion.state(np.arange(0.0, motion.duration_s + 0.5 / rate_hz, 1.0 / rate_hz))
