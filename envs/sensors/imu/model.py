"""Trunk IMU: AHRS orientation, gyro and accelerometer from the kinematic motion.

The true angular velocity and specific force of the IMU site come from MuJoCo
(``mj_objectVelocity`` / ``mj_objectAcceleration`` in the site frame after
``mj_rnePostConstraint`` with the motion's ``qacc``; MuJoCo gives the world body the
acceleration -gravity, so a resting IMU reads +9.81 m/s^2 up, like the accelerometer sensor).
Noise follows kalibr: white noise ND / sqrt(dt) plus a bias random walk RW * sqrt(dt) per
sample (initial bias 0 [A]); the orientation carries a small Gauss-Markov rotation error.
With ``heel_strike_scale`` > 0 the accelerometer also carries the heel-strike transients of the
motion's footsteps (:mod:`.impact`, world vertical, rotated into the IMU frame with the true
orientation). Stamps are measurement time + ``latency_s`` + ``time_offset_s`` (the IMU clock's
offset from the camera's).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from exobench.core import ImuSample
from exobench.core.transforms import quat_multiply

from ..common import sensor_rngs
from .config import ImuConfig
from .impact import impact_accel_world


class ImuSensor:
    """The trunk IMU. Call :meth:`observe` after :func:`imu_dynamics` at each measurement time."""

    def __init__(self, sensor_id: str, config: ImuConfig, model: object, seed: int,
                 strikes: Sequence[tuple[float, str]] = ()) -> None:  # fmt: skip
        """``strikes``: (touchdown time, foot side) of every footstep, for the heel-strike transients."""
        import mujoco

        self.sensor_id, self.config = sensor_id, config
        self.site = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, sensor_id)
        if self.site < 0:
            raise KeyError(f"model has no site {sensor_id!r}")
        self.body = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_BODY, int(model.site_bodyid[self.site]))  # type: ignore[attr-defined]
        self.strikes = tuple(strikes)
        self.noise_rng, self.drop_rng = sensor_rngs(seed, sensor_id)
        self._t: list[float] = []
        self._q: list[np.ndarray] = []
        self._p: list[np.ndarray] = []
        self._gyro: list[np.ndarray] = []
        self._acc: list[np.ndarray] = []
        self._buf = np.zeros(6)

    def observe(self, model: object, data: object, t: float) -> None:
        import mujoco

        self._t.append(t)
        q = np.empty(4)
        mujoco.mju_mat2Quat(q, data.site_xmat[self.site])  # type: ignore[attr-defined]
        self._q.append(q)
        self._p.append(np.array(data.site_xpos[self.site]))  # type: ignore[attr-defined]
        mujoco.mj_objectVelocity(model, data, mujoco.mjtObj.mjOBJ_SITE, self.site, self._buf, 1)
        self._gyro.append(self._buf[:3].copy())
        mujoco.mj_objectAcceleration(model, data, mujoco.mjtObj.mjOBJ_SITE, self.site, self._buf, 1)
        self._acc.append(self._buf[3:].copy())

    def true_arrays(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """(t (N,), quat_wxyz of R_world_imu (N, 4), gyro (N, 3), accel (N, 3)) without noise."""
        return np.array(self._t), np.array(self._q).reshape(-1, 4), np.array(self._gyro), np.array(self._acc)

    def pose_rows(self) -> np.ndarray:
        """The true pose of the IMU site at each measurement time, rows ``[t, x, y, z, qw, qx, qy, qz]``
        (N, 8): 8 numbers a sample instead of a 4x4 matrix, so a long walk's IMU truth stays small."""
        t = np.asarray(self._t, dtype=float)
        return np.column_stack([t, np.asarray(self._p).reshape(-1, 3), np.asarray(self._q).reshape(-1, 4)])

    def frames(self) -> list[ImuSample]:
        c = self.config
        t, q_true, gyro, acc = self.true_arrays()
        n = len(t)
        dt = 1.0 / c.rate_hz
        rng = self.noise_rng
        s = c.noise_scale
        if c.heel_strike_scale > 0.0 and n:  # before the noise: the same draws as without it
            acc = acc + self.impact_accel(t, q_true)
        # draw every stream for every sample, in a fixed order, whatever the settings
        w_g, w_a = rng.standard_normal((n, 3)), rng.standard_normal((n, 3))
        b_g, b_a = rng.standard_normal((n, 3)), rng.standard_normal((n, 3))
        e_o = rng.standard_normal((n, 3))
        bias_g = _walk(b_g) * (s * c.gyro_random_walk * np.sqrt(dt))
        bias_a = _walk(b_a) * (s * c.accel_random_walk * np.sqrt(dt))
        gyro_m = gyro + bias_g + w_g * (s * c.gyro_noise_density / np.sqrt(dt))
        acc_m = acc + bias_a + w_a * (s * c.accel_noise_density / np.sqrt(dt))
        # orientation error: first-order Gauss-Markov rotation vector, stationary from the start
        sig = np.radians(c.orientation_rms_deg) / np.sqrt(3.0)
        phi = np.exp(-dt / c.orientation_tau_s)
        err = np.empty((n, 3))
        if n:
            err[0] = sig * e_o[0]
            for k in range(1, n):
                err[k] = phi * err[k - 1] + sig * np.sqrt(1.0 - phi * phi) * e_o[k]
        # R_measured = exp(err) R_true: the error is a small rotation in the world frame
        ang = np.linalg.norm(err, axis=1)
        axis = err / np.where(ang > 0, ang, 1.0)[:, None]
        q_err = np.column_stack([np.cos(0.5 * ang), np.sin(0.5 * ang)[:, None] * axis])
        q = quat_multiply(q_err, q_true)
        q /= np.linalg.norm(q, axis=1)[:, None]
        q *= np.where(q[:, :1] < 0, -1.0, 1.0)
        keep = self.drop_rng.random(n) >= c.dropout_prob
        return [
            ImuSample(float(t[k] + c.latency_s + c.time_offset_s), self.sensor_id, q[k].copy(), gyro_m[k].copy(), acc_m[k].copy())
            for k in np.flatnonzero(keep)
        ]

    def impact_accel(self, t: np.ndarray, q_wxyz: np.ndarray) -> np.ndarray:
        """The heel-strike transients at times ``t`` in the IMU frame (N, 3), the IMU's world
        orientation ``q_wxyz`` (N, 4) at those times."""
        a_w = impact_accel_world(t, self.strikes, self.body or "", self.config.heel_strike_scale)
        return np.einsum("nji,nj->ni", _rotations(q_wxyz), a_w)


def _rotations(q: np.ndarray) -> np.ndarray:
    """Rotation matrices (N, 3, 3) of unit quaternions wxyz (N, 4)."""
    w, x, y, z = (q / np.linalg.norm(q, axis=1)[:, None]).T
    return np.stack([
        np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], axis=-1),
        np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], axis=-1),
        np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], axis=-1),
    ], axis=1)  # fmt: skip


def _walk(steps: np.ndarray) -> np.ndarray:
    """Random walk starting at 0: value k is the sum of the first k steps."""
    out = np.zeros_like(steps)
    out[1:] = np.cumsum(steps[:-1], axis=0)
    return out


def imu_dynamics(model: object, data: object, qpos: np.ndarray, qvel: np.ndarray, qacc: np.ndarray) -> None:
    """Set the state and compute positions, velocities and accelerations (no dynamics solve)."""
    import mujoco

    data.qpos[:] = qpos  # type: ignore[attr-defined]
    data.qvel[:] = qvel  # type: ignore[attr-defined]
    mujoco.mj_kinematics(model, data)
    mujoco.mj_comPos(model, data)
    mujoco.mj_comVel(model, data)
    data.qacc[:] = qacc  # type: ignore[attr-defined]
    mujoco.mj_rnePostConstraint(model, data)
