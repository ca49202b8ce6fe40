"""The odometry inside the simulation core: the attached camera's true optical-frame pose at each
of its instants, degraded by :func:`~exobench.envs.motion.odometry.drift_odometry`.

Truth (``SensorOutput.truth``): ``t_s`` (N,), ``T_world_odom`` (4, 4), ``distance_m`` (N,)
horizontal distance travelled, ``T_world_tracked`` (N, 4, 4) the true optical-frame poses.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from exobench.core import OdometrySample
from exobench.core.transforms import make_T

from ..adapter import BaseAdapter, MountedSensor, RecordContext, SensorOutput
from ..common import sample_times, sensor_rngs


class OdometryAdapter(BaseAdapter):
    def __init__(self, sensor: MountedSensor, ctx: RecordContext) -> None:
        import mujoco

        super().__init__(sensor, ctx)
        if sensor.attached_to is None:
            from exobench.core import ConfigError

            raise ConfigError(f"{sensor.sensor_id}.attached_to", None, "the id of the RGB-D camera it tracks")
        self.cam = mujoco.mj_name2id(ctx.model, mujoco.mjtObj.mjOBJ_CAMERA, sensor.attached_to)
        self.t = sample_times(sensor.config.rate_hz, ctx.duration_s)
        self.T = np.zeros((len(self.t), 4, 4))
        self.k = 0

    def instants(self) -> np.ndarray:
        return self.t

    def observe(self, model: Any, data: Any, t: float) -> None:
        import mujoco

        from exobench.models.exo import R_OPTICAL_MJCAMERA

        mujoco.mj_camlight(model, data)
        self.T[self.k] = make_T(data.cam_xmat[self.cam].reshape(3, 3) @ R_OPTICAL_MJCAMERA, data.cam_xpos[self.cam].copy())
        self.k += 1

    def finish(self) -> SensorOutput:
        from exobench.envs.motion.odometry import drift_odometry

        c, t, sid = self.config, self.t, self.sensor_id
        rng = sensor_rngs(self.ctx.seed, sid)[0]
        T_world_odom, T_odom_cam, v_odom, dist = drift_odometry(t, self.T, c.drift_pct, c.yaw_drift_deg_per_m, rng)
        frames = [OdometrySample(float(t[k]), sid, T_odom_cam[k].copy(), v_odom[k].copy()) for k in range(len(t))]
        return SensorOutput(frames, None, {"t_s": t, "T_world_odom": T_world_odom, "distance_m": dist, "T_world_tracked": self.T})

    @staticmethod
    def calibration_params(sensor: MountedSensor) -> dict[str, Any]:
        return {"rate_hz": sensor.config.rate_hz, "tracks": sensor.attached_to}
