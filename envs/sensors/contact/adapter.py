"""The insole pads inside the simulation core: the load of every pad of the rig, shared out once."""

from __future__ import annotations

from typing import Any

import numpy as np

from exobench.models.exo_spec import CONTACT_PADS

from ..adapter import BaseAdapter, MountedSensor, SensorOutput
from ..common import sample_times
from .model import ContactSensor, contact_forces


class ContactAdapter(BaseAdapter):
    calibration_shared = True

    def finish(self) -> SensorOutput:
        t, forces = self.ctx.shared("contact_forces", self._forces)
        return SensorOutput(list(ContactSensor(self.sensor_id, self.config, self.ctx.seed).frames(t, forces[self.sensor_id])))

    def _forces(self) -> tuple[np.ndarray, dict[str, np.ndarray]]:
        """Forces of every pad of the rig (they share the body's load), at this pad's rate."""
        import mujoco

        from exobench.envs.terrain import Terrain

        ctx, cfg = self.ctx, self.config
        model, motion, exo = ctx.model, ctx.motion, ctx.exo
        t = sample_times(cfg.rate_hz, ctx.duration_s)
        st = motion.state(t)
        rv = int(model.jnt_dofadr[mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, "root")])
        acc_z = motion.sample(model, t).qacc[:, rv + 2]
        pads = {}
        for s in ctx.rig:
            if s.kind == "contact":
                _, T = exo.contact_mount(s.sensor_id)
                pads[s.sensor_id] = st.sole_points_w(CONTACT_PADS[s.sensor_id][0], T[:3, 3][None, :])[:, 0]
        g = float(-model.opt.gravity[2])
        forces = contact_forces(
            Terrain(ctx.scene_truth), pads, st.ankle_w, st.pelvis_w, acc_z, exo.user_mass_kg + exo.exo_mass_kg,
            cfg.contact_tol_m, g,
        )  # fmt: skip
        return t, forces

    @staticmethod
    def calibration_params(sensor: MountedSensor) -> dict[str, Any]:
        c = sensor.config
        return {"rate_hz": c.rate_hz, "threshold_n": c.threshold_n, "latency_s": c.latency_s}
