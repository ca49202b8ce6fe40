"""Leg joint encoders: the motion's joint angles with a constant offset, white noise and quantisation."""

from __future__ import annotations

import numpy as np

from exobench.core import JointState
from exobench.models.exo_spec import LEG_JOINTS

from ..common import sensor_rngs
from .config import EncoderConfig

ENCODER_ID = "encoders"


class EncoderSensor:
    """Leg joint encoders (``JointState`` in :data:`LEG_JOINTS` order)."""

    def __init__(self, config: EncoderConfig, seed: int) -> None:
        self.config = config
        self.noise_rng, self.drop_rng = sensor_rngs(seed, ENCODER_ID)
        self.offset_rad = self.noise_rng.standard_normal(len(LEG_JOINTS)) * config.offset_std_rad

    def frames(self, t: np.ndarray, joints: np.ndarray) -> list[JointState]:
        """Frames for true joint angles ``joints`` (N, 6) measured at times ``t`` (N,)."""
        c = self.config
        q = joints + self.offset_rad + self.noise_rng.standard_normal(joints.shape) * c.noise_rad
        if c.resolution_bits > 0:
            lsb = 2.0 * np.pi / (1 << c.resolution_bits)
            q = np.round(q / lsb) * lsb
        keep = self.drop_rng.random(len(t)) >= c.dropout_prob
        return [JointState(float(t[k] + c.latency_s), ENCODER_ID, LEG_JOINTS, q[k].copy()) for k in np.flatnonzero(keep)]
