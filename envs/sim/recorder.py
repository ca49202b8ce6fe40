"""The recorder: one loop that runs a rig of sensors over a motion in a compiled MuJoCo world.

:func:`record` asks every mounted sensor's adapter (:mod:`exobench.envs.sensors.kinds`) at which
instants it needs MuJoCo's state, samples the motion at the union of those instants (all streams
run on exact multiples of their periods, so commensurate rates share instants), lets the hooks
add joint motion (a neck or chest view) and place mocap bodies (pedestrians), sets the state
(full dynamics where a sensor needs accelerations, an IMU; kinematics elsewhere), lets each
sensor observe it, and finally merges every sensor's frames in time order, ties broken by the
rig's order. Link poses of ``track_bodies`` are kept at ``track_rate_hz``. Same inputs, same
frames bit for bit.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from functools import reduce
from typing import Any

import numpy as np

from exobench.core import ConfigError, Frame, SceneTruth
from exobench.models.exo_spec import ExoSpec

from ..motion import Motion
from ..sensors import imu_dynamics, sample_times
from ..sensors.adapter import MountedSensor, PoseFn, SensorOutput
from ..sensors.kinds import adapter_class
from .pose import RigidPose

TRACKED_BODIES = ("pelvis", "thigh_l", "shank_l", "foot_l", "thigh_r", "shank_r", "foot_r", "head")
TRACK_RATE_HZ = 50.0


class Hook:
    """Extra motion of a recording: override :meth:`prepare` to add joint motion to the sampled
    state at every instant, :meth:`place` to move mocap bodies before the state is set."""

    def prepare(self, model: Any, sample: Any, times_s: np.ndarray) -> None:
        """Edit ``sample`` (``qpos``/``qvel``/``qacc`` rows at ``times_s``) in place."""

    def place(self, data: Any, k: int) -> None:
        """Put mocap bodies where they are at instant ``k`` of ``times_s``."""


@dataclass
class Context:
    """What sensors read while recording (:class:`exobench.envs.sensors.adapter.RecordContext`)."""

    model: Any
    scene_truth: SceneTruth
    exo: ExoSpec
    motion: Motion
    seed: int
    duration_s: float
    rig: Sequence[MountedSensor]
    watch_geoms: Sequence[Sequence[int]] = ()
    _shared: dict[str, Any] = field(default_factory=dict)

    def pose_fn(self, site: str) -> PoseFn:
        return RigidPose(self.model, self.motion, site)

    def shared(self, key: str, compute: Callable[[], Any]) -> Any:
        if key not in self._shared:
            self._shared[key] = compute()
        return self._shared[key]


@dataclass(frozen=True, eq=False)
class Recording:
    """Output of :func:`record`: ``frames`` in time order, each sensor's :class:`SensorOutput`
    (``outputs[sensor_id]``), link tracks (body -> (N, 8) rows ``[t, x, y, z, qw, qx, qy, qz]``)."""

    frames: tuple[Frame, ...]
    outputs: dict[str, SensorOutput]
    body_tracks: dict[str, np.ndarray]
    context: Context

    def frame_truth(self, sensor_ids: Sequence[str]) -> tuple[Any, ...]:
        """The per-frame truth of ``sensor_ids``' frames, in the merged frame order."""
        by_frame = {}
        for sid in sensor_ids:
            out = self.outputs[sid]
            for f, t in zip(out.frames, out.frame_truth or (), strict=True):
                by_frame[id(f)] = t
        return tuple(by_frame[id(f)] for f in self.frames if id(f) in by_frame)


def record(
    model: Any,
    truth: SceneTruth,
    exo: ExoSpec,
    motion: Motion,
    rig: Sequence[MountedSensor],
    seed: int,
    *,
    duration_s: float | None = None,
    hooks: Sequence[Hook] = (),
    track_bodies: Sequence[str] = (),
    track_rate_hz: float = TRACK_RATE_HZ,
    watch_geoms: Sequence[Sequence[int]] = (),
) -> Recording:
    """Every sensor of ``rig`` over ``motion`` (up to ``duration_s``, default the whole motion)."""

    ids = [s.sensor_id for s in rig]
    if len(set(ids)) != len(ids):
        raise ConfigError("rig", ids, "sensors with distinct ids")
    dur = float(motion.duration_s if duration_s is None else duration_s)
    ctx = Context(model, truth, exo, motion, int(seed), dur, tuple(rig), tuple(watch_geoms))
    adapters: list[Any] = []
    try:
        for s in rig:
            adapters.append(adapter_class(s.kind)(s, ctx))
        body_tracks = _step(model, motion, adapters, hooks, track_bodies, track_rate_hz, dur)
        outputs = {s.sensor_id: a.finish() for s, a in zip(rig, adapters)}
    finally:
        for a in adapters:
            a.close()
    rank = {sid: i for i, sid in enumerate(ids)}
    merged = [(f.stamp_s, rank[f.sensor_id], f) for sid in ids for f in outputs[sid].frames]
    merged.sort(key=lambda x: (x[0], x[1]))  # stable: each stream is already in time order
    return Recording(tuple(f for _, _, f in merged), outputs, body_tracks, ctx)


def _step(
    model: Any, motion: Motion, adapters: list[Any], hooks: Sequence[Hook], track_bodies: Sequence[str],
    track_rate_hz: float, dur: float,
) -> dict[str, np.ndarray]:  # fmt: skip
    """Put MuJoCo in the motion's state at every instant some sensor (or the link tracks) needs."""
    import mujoco

    inst = [np.asarray(a.instants(), dtype=float) for a in adapters]
    t_trk = sample_times(track_rate_hz, dur) if track_bodies else np.zeros(0)
    t_mj = reduce(np.union1d, [*inst, t_trk], np.zeros(0))
    tracks: dict[str, list[np.ndarray]] = {b: [] for b in track_bodies}
    if len(t_mj):
        sample = motion.sample(model, t_mj)
        for h in hooks:
            h.prepare(model, sample, t_mj)
        measures = [np.isin(t_mj, ti) for ti in inst]
        dyn = reduce(np.logical_or, [m for a, m in zip(adapters, measures) if a.needs_dynamics], np.zeros(len(t_mj), bool))
        is_trk = np.isin(t_mj, t_trk)
        body_ids = [mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, b) for b in track_bodies]
        data = mujoco.MjData(model)
        for k, t in enumerate(t_mj):
            tk = float(t)
            for h in hooks:
                h.place(data, k)
            if dyn[k]:
                imu_dynamics(model, data, sample.qpos[k], sample.qvel[k], sample.qacc[k])
            else:
                data.qpos[:] = sample.qpos[k]
                mujoco.mj_kinematics(model, data)
            for a, m in zip(adapters, measures):
                if m[k]:
                    a.observe(model, data, tk)
            if is_trk[k]:
                for b, i in zip(track_bodies, body_ids):
                    tracks[b].append(np.concatenate([[tk], data.xpos[i], data.xquat[i]]))
    return {b: np.array(v).reshape(-1, 8) for b, v in tracks.items()}
