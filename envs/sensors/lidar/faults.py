"""Delivery faults of a LiDAR stream: duplicated sweeps, sweeps delivered out of order, clock steps.

:class:`StreamFaults` takes each simulated sweep (or None when it was lost) in sweep order and
returns what the sensor delivers for it, each frame with its truth:

- a duplicated sweep (``duplicate_prob``) is delivered twice: a second identical frame (same
  stamp, copied arrays) with a copy of its truth;
- a late sweep (``out_of_order_prob``) is delivered after the next one: its ``stamp_s`` (the
  delivery time) grows by :data:`LATE_PERIODS` sweep periods, halfway between the next two
  deliveries, so it never shares a stamp with an on-time sweep; its ``sweep_start_s`` stays.
  The sweep after a late one is the one that overtakes it, so it is on time whatever its draw:
  at probability 1 every pair of sweeps is swapped (1, 0, 3, 2, ...), never all of them
  delayed alike, which would keep their order;
- a clock step (``time_jump_prob``, ``time_jump_s``) shifts ``stamp_s`` and ``sweep_start_s`` of
  that sweep and of every later one (the offsets add up).

The truth follows its frame: ``LidarTruth.stamp_s`` is the frame's (new) stamp, and
:attr:`StreamFaults.true_starts` keeps the true start of every delivered frame (the truth
trajectory stays in true time). Random streams: one generator per fault, keyed
``"<sensor_id>/duplicate"``, ``"<sensor_id>/out_of_order"`` and ``"<sensor_id>/time_jump"``
(:func:`~exobench.envs.sensors.common.sensor_rngs`), one draw per sweep whether the sweep was
lost or not, so that turning one fault on shifts neither the noise nor another fault. With every
probability 0 nothing is drawn and every sweep is delivered unchanged.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from exobench.core import LidarScan, LidarTruth

from ..common import sensor_rngs
from .config import LidarConfig

LATE_PERIODS = 1.5
"""A late sweep's delivery delay, in sweep periods (after the next sweep, before the one after)."""

__all__ = ["LATE_PERIODS", "StreamFaults"]


class StreamFaults:
    """The delivery faults of one LiDAR; call :meth:`deliver` once per sweep, in sweep order."""

    def __init__(self, sensor_id: str, config: LidarConfig, seed: int) -> None:
        self.config = config
        self.dup_rng = sensor_rngs(seed, f"{sensor_id}/duplicate")[0]
        self.late_rng = sensor_rngs(seed, f"{sensor_id}/out_of_order")[0]
        self.jump_rng = sensor_rngs(seed, f"{sensor_id}/time_jump")[0]
        self.clock_offset_s = 0.0
        self.true_starts: list[float] = []
        self.overtaking = False  # the previous sweep is late: this one is delivered before it

    def _hit(self, rng: np.random.Generator, prob: float) -> bool:
        return bool(prob > 0.0 and rng.random() < prob)

    def deliver(self, got: tuple[LidarScan, LidarTruth] | None) -> list[tuple[LidarScan, LidarTruth]]:
        """The frames (with their truth) delivered for one sweep (``got``: the sweep, None if lost)."""
        c = self.config
        dup = self._hit(self.dup_rng, c.duplicate_prob)
        late = self._hit(self.late_rng, c.out_of_order_prob) and not self.overtaking
        if self._hit(self.jump_rng, c.time_jump_prob):
            self.clock_offset_s += c.time_jump_s
        self.overtaking = late and got is not None
        if got is None:
            return []
        scan, truth = got
        true_start = float(scan.sweep_start_s)
        shift = self.clock_offset_s
        delay = LATE_PERIODS * c.pattern.sweep_period_s if late else 0.0
        if shift or delay:
            stamp = float(scan.stamp_s) + shift + delay
            scan = dataclasses.replace(scan, stamp_s=stamp, sweep_start_s=true_start + shift)
            truth = dataclasses.replace(truth, stamp_s=stamp)
        out = [(scan, truth)]
        if dup:
            copy = {f.name: getattr(scan, f.name) for f in dataclasses.fields(scan)}
            out.append((LidarScan(**{k: v.copy() if isinstance(v, np.ndarray) else v for k, v in copy.items()}),
                        dataclasses.replace(truth)))  # fmt: skip
        self.true_starts += [true_start] * len(out)
        return out
