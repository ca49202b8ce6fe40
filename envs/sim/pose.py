"""Exact sensor poses between the recorder's instants: sites rigid with the pelvis, and pose rows."""

from __future__ import annotations

from typing import Any

import numpy as np

from exobench.core import ConfigError
from exobench.core.transforms import invert_T, make_T, matrix_to_quat_wxyz

from ..motion import Motion, rot_yaw_pitch


class RigidPose:
    """``T_world_sensor`` of a site rigid with the pelvis, at any time of a motion (a ``PoseFn``):
    ``T_world_pelvis(t) @ T_pelvis_sensor`` with the pelvis pose from the motion's coordinates
    (no kinematics call per time)."""

    def __init__(self, model: Any, motion: Motion, site: str) -> None:
        import mujoco

        sid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, site)
        pelvis = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, "pelvis")
        if sid < 0 or int(model.site_bodyid[sid]) != pelvis:
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


def site_pose(model: Any, data: Any, site: str) -> np.ndarray:
    """``T_world_site`` of a named site in ``data``'s current (computed) state."""
    import mujoco

    sid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, site)
    if sid < 0:
        raise ConfigError("site", site, "a site of the model")
    return make_T(np.asarray(data.site_xmat[sid]).reshape(3, 3), data.site_xpos[sid])


def pose_rows(t: np.ndarray, T: np.ndarray) -> np.ndarray:
    """Rows ``[t, x, y, z, qw, qx, qy, qz]`` of poses ``T`` (N, 4, 4) at times ``t`` (N,)."""
    q = np.array([matrix_to_quat_wxyz(R) for R in T[:, :3, :3]]).reshape(-1, 4)
    return np.column_stack([t, T[:, :3, 3], q])
