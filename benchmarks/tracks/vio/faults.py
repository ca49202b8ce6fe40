"""Delivery faults of the vio track's streams: frames without depth, repeated and late frames.

The sensors' own faults act in the simulation (``frame_dropout``: RGB-D frames lost;
``imu_dropout``: IMU samples lost, :class:`~exobench.envs.sensors.ImuConfig`); these act on
delivery, on the frames as they leave the simulation, in both worlds (:class:`DeliveryFaults`):

- ``depth_missing``: an RGB-D frame arrives with no depth at all (every pixel 0, the camera's
  invalid value; :func:`exobench.core.faults.no_return`), its colour kept;
- ``repeated_frames``: a frame (RGB-D or IMU) is delivered twice, the same frame again;
- ``late_frames``: a frame is delivered after the next frame of its stream (its stamp kept, so
  its stream steps back in time there: out of order); the frame after a late one is on time.

Each fault draws from its own generator (``sensor_rngs(seed, "vio/<fault>")``), one draw per
frame of the streams it applies to whether it hits or not, so that one fault does not move the
draws of another; with every probability 0 nothing is drawn and the stream is unchanged. The
truth is untouched: the camera's and the IMU's true poses are at their measurement instants.
"""

from __future__ import annotations

from collections.abc import Iterable, Iterator, Mapping
from typing import Any

from exobench.core.faults import no_return
from exobench.core.frames import ImuSample, RgbdFrame
from exobench.models.world_params import ParamSpec

FAULT_ROWS: dict[str, ParamSpec] = {
    "depth_missing": ParamSpec(0.0, 0.0, 1.0, "", "probability an RGB-D frame arrives without depth (every pixel 0)"),
    "repeated_frames": ParamSpec(0.0, 0.0, 1.0, "", "probability an RGB-D frame or IMU sample is delivered twice"),
    "late_frames": ParamSpec(0.0, 0.0, 1.0, "", "probability an RGB-D frame or IMU sample is delivered after the "
                             "next one of its stream (out of order)"),
}  # fmt: skip


def fault_settings(scenario: Mapping[str, Any]) -> dict[str, float]:
    return {k: float(scenario.get(k, spec.default)) for k, spec in FAULT_ROWS.items()}


class DeliveryFaults:
    """The delivery faults of one episode (module docstring)."""

    def __init__(self, settings: Mapping[str, float], seed: int) -> None:
        from exobench.envs.sensors import sensor_rngs

        self.p = dict(settings)
        self.rng = {k: sensor_rngs(seed, f"vio/{k}")[0] for k in FAULT_ROWS}

    @property
    def active(self) -> bool:
        return any(v > 0.0 for v in self.p.values())

    def _hit(self, fault: str) -> bool:
        p = self.p[fault]
        return bool(p > 0.0 and self.rng[fault].random() < p)

    def apply(self, frames: Iterable[Any]) -> Iterator[Any]:
        """The frames as delivered, lazily (a stream stays a stream)."""
        if not self.active:
            yield from frames
            return
        held: dict[str, Any] = {}  # sensor -> its late frame, delivered after that sensor's next one
        for f in frames:
            if not isinstance(f, (RgbdFrame, ImuSample)):
                yield f
                continue
            if isinstance(f, RgbdFrame) and self._hit("depth_missing"):
                f = no_return(f)
            late = self._hit("late_frames")
            twice = self._hit("repeated_frames")
            out = [f, f] if twice else [f]
            if f.sensor_id in held:  # this one overtakes the late one, which follows it
                yield from out
                yield held.pop(f.sensor_id)
                continue
            if late:
                held[f.sensor_id] = f
                if twice:
                    yield f
                continue
            yield from out
        yield from held.values()
