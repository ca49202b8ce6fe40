"""Heel and toe insole force pads.

Insole pads have no physics behind them (the motion is kinematic): a pad is in contact when it
is within ``contact_tol_m`` of the terrain under it (or below it), and the body weight
``M (g + a_z)`` (``a_z`` the pelvis's vertical acceleration) is shared [A] between the feet in
contact by where the pelvis projects on the line between the ankles, and within a foot between
its pads by where the pelvis projects on the foot's heel-toe line.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from exobench.core import ContactSample
from exobench.models.exo_spec import CONTACT_IDS

from ..common import sensor_rngs
from .config import ContactConfig

if TYPE_CHECKING:
    from exobench.envs.terrain import Terrain


def contact_forces(
    terrain: Terrain,
    pads_w: dict[str, np.ndarray],
    ankles_w: dict[str, np.ndarray],
    pelvis_w: np.ndarray,
    pelvis_acc_z: np.ndarray,
    total_mass_kg: float,
    contact_tol_m: float,
    gravity_m_s2: float = 9.81,
) -> dict[str, np.ndarray]:
    """True normal force under every pad (id -> (N,)), N, from geometric contact."""
    touch = {}
    for pid, p in pads_w.items():
        gap = p[:, 2] - terrain.height(p[:, :2])
        touch[pid] = np.isfinite(gap) & (gap <= contact_tol_m)
    foot_touch = {s: touch[f"contact_{s}_heel"] | touch[f"contact_{s}_toe"] for s in ("l", "r")}
    load = total_mass_kg * np.maximum(gravity_m_s2 + pelvis_acc_z, 0.0)

    def share(a: np.ndarray, b: np.ndarray) -> np.ndarray:  # fraction towards b of the pelvis along a->b
        ab = (b - a)[:, :2]
        n2 = np.einsum("ij,ij->i", ab, ab)
        lam = np.einsum("ij,ij->i", (pelvis_w - a)[:, :2], ab) / np.where(n2 > 1e-12, n2, 1.0)
        return np.where(n2 > 1e-12, np.clip(lam, 0.0, 1.0), 0.5)

    lam_r = share(ankles_w["l"], ankles_w["r"])
    both = foot_touch["l"] & foot_touch["r"]
    foot_load = {
        "l": load * np.where(both, 1.0 - lam_r, foot_touch["l"]),
        "r": load * np.where(both, lam_r, foot_touch["r"]),
    }
    out = {}
    for s in ("l", "r"):
        h, t = touch[f"contact_{s}_heel"], touch[f"contact_{s}_toe"]
        lam_t = share(pads_w[f"contact_{s}_heel"], pads_w[f"contact_{s}_toe"])
        pads = h & t
        out[f"contact_{s}_heel"] = foot_load[s] * np.where(pads, 1.0 - lam_t, h)
        out[f"contact_{s}_toe"] = foot_load[s] * np.where(pads, lam_t, t)
    return out


class ContactSensor:
    """One insole pad (sensor id in :data:`CONTACT_IDS`)."""

    def __init__(self, sensor_id: str, config: ContactConfig, seed: int) -> None:
        if sensor_id not in CONTACT_IDS:
            raise KeyError(sensor_id)
        self.sensor_id, self.config = sensor_id, config
        self.noise_rng, self.drop_rng = sensor_rngs(seed, sensor_id)

    def frames(self, t: np.ndarray, force_n: np.ndarray) -> list[ContactSample]:
        c = self.config
        f = np.maximum(force_n + self.noise_rng.standard_normal(len(t)) * c.noise_n, 0.0)
        keep = self.drop_rng.random(len(t)) >= c.dropout_prob
        return [
            ContactSample(float(t[k] + c.latency_s), self.sensor_id, float(f[k]), bool(f[k] > c.threshold_n))
            for k in np.flatnonzero(keep)
        ]
