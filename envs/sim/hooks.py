"""Recorder hooks: motion beyond the walker's legs and pelvis.

- :class:`ViewHook`: joints that turn a camera (the neck's ``neck_yaw``/``neck_pitch``, the chest
  rig's ``chest_yaw``/``chest_pitch``) follow a :class:`~exobench.envs.motion.view.ViewMotion`;
  their angles, rates and accelerations go into the sampled state, so rendering, IMUs and truth
  agree.
- :class:`PedestrianHook`: mocap bodies ``ped<k>`` (added by
  :func:`~exobench.envs.sim.compose.compose_rig`) walk their straight paths on the terrain.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from ..terrain import Terrain
from .recorder import Hook


def joint_addr(model: Any, name: str) -> tuple[int, int]:
    """(qpos address, dof address) of a joint."""
    import mujoco

    j = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, name)
    return int(model.jnt_qposadr[j]), int(model.jnt_dofadr[j])


class ViewHook(Hook):
    """Camera-turning joints driven by a view motion (``view.joints``, ``view.derivatives(t)``)."""

    def __init__(self, view: Any) -> None:
        self.view = view

    def prepare(self, model: Any, sample: Any, times_s: np.ndarray) -> None:
        adr = {name: joint_addr(model, name) for name in self.view.joints}
        for name, (q, qd, qdd) in self.view.derivatives(times_s).items():
            qa, va = adr[name]
            sample.qpos[:, qa], sample.qvel[:, va], sample.qacc[:, va] = q, qd, qdd


class PedestrianHook(Hook):
    """People (``PedestrianPath``: ``xy(t)``, ``yaw``) as mocap bodies ``ped<k>`` standing on the terrain."""

    def __init__(self, paths: Sequence[Any], terrain: Terrain) -> None:
        self.paths, self.terrain = list(paths), terrain

    def positions(self, times_s: np.ndarray) -> tuple[list[np.ndarray], list[np.ndarray]]:
        """(xy (N, 2), z of the feet (N,)) of every person at ``times_s``."""
        xy = [p.xy(times_s) for p in self.paths]
        return xy, [np.nan_to_num(self.terrain.height(q), nan=0.0) for q in xy]

    def prepare(self, model: Any, sample: Any, times_s: np.ndarray) -> None:
        import mujoco

        self.xy, self.z = self.positions(times_s)
        self.mocap = [int(model.body_mocapid[mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, f"ped{k}")])
                      for k in range(len(self.paths))]  # fmt: skip

    def place(self, data: Any, k: int) -> None:
        for i, p in enumerate(self.paths):
            data.mocap_pos[self.mocap[i]] = [self.xy[i][k, 0], self.xy[i][k, 1], self.z[i][k]]
            data.mocap_quat[self.mocap[i]] = [np.cos(0.5 * p.yaw), 0.0, 0.0, np.sin(0.5 * p.yaw)]

    def geom_groups(self, model: Any) -> list[list[int]]:
        """The geom ids of each person (what cameras report the image share of)."""
        import mujoco

        return [sorted({mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, f"ped{k}_{g}") for g in ("body", "head")})
                for k in range(len(self.paths))]  # fmt: skip
