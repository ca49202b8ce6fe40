"""The recorder: one loop that runs a rig of sensors over a motion in a compiled MuJoCo world.

A :class:`Recorder` asks every mounted sensor's adapter (:mod:`exobench.envs.sensors.kinds`) at
which instants it needs MuJoCo's state, samples the motion at the union of those instants (all
streams run on exact multiples of their periods, so commensurate rates share instants), lets the
hooks add joint motion (a neck or chest view) and place mocap bodies (pedestrians), sets the state
(full dynamics where a sensor needs accelerations, an IMU; kinematics elsewhere) and lets each
sensor observe it. Frames are merged in time order, ties broken by the rig's order. Link poses of
``track_bodies`` are kept at ``track_rate_hz``. Same inputs, same frames bit for bit.

Two ways to run it, one loop (:meth:`Recorder.observe`):

- :func:`record`: the whole motion at once, then every adapter's frames and truth
  (:meth:`~exobench.envs.sensors.adapter.SensorAdapter.finish`): what every scenario does.
- :meth:`Recorder.advance_to`: step by step while the motion grows (the gymnasium environment).
  Each call observes the instants in ``[t_prev, t)`` and returns the frames delivered by ``t``
  (stamp <= t; later ones wait for a later call). The window is half open because a motion's
  state at a segment boundary belongs to the segment that starts there, which a caller extending
  the motion step by step has not planned yet; so a motion recorded step by step gives the frames
  :func:`record` gives over the final motion, bit for bit. Only kinds whose adapters stream
  (``streams``: their noise is drawn reading by reading in time order) can be stepped.
- :func:`stream_record`: the frames of :func:`record`, bit for bit and in its order, handed out
  as they are produced, so that a long walk is never held whole. The small streams (IMU,
  encoders, contacts: noise drawn over the whole recording) and the link tracks are recorded
  whole first; the big ones (``chunked`` adapters: LiDAR sweeps, RGB-D images) are then observed
  chunk by chunk and merged in. Each sensor's state at an instant is the motion's there whoever
  else observes it, so splitting the rig changes no frame.
"""

from __future__ import annotations

import heapq
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, field
from functools import reduce
from typing import Any

import numpy as np

from exobench.core import ConfigError, ExobenchError, Frame, SceneTruth
from exobench.models.exo_spec import ExoSpec

from ..motion import Motion
from ..sensors import imu_dynamics, sample_times
from ..sensors.adapter import MountedSensor, PoseFn, SensorOutput
from ..sensors.kinds import SENSOR_KINDS, adapter_class
from .pose import RigidPose

TRACKED_BODIES = ("pelvis", "thigh_l", "shank_l", "foot_l", "thigh_r", "shank_r", "foot_r", "head")
TRACK_RATE_HZ = 50.0
CHUNK_S = 0.5  # how much of a streamed recording's big streams is observed at once
DUE_TOL_S = 1e-12  # a frame stamped at the requested time (up to rounding) is delivered


class Hook:
    """Extra motion of a recording: override :meth:`prepare` to add joint motion to the sampled
    state at every instant, :meth:`place` to move mocap bodies before the state is set."""

    def prepare(self, model: Any, sample: Any, times_s: np.ndarray) -> None:
        """Edit ``sample`` (``qpos``/``qvel``/``qacc`` rows at ``times_s``) in place."""

    def place(self, data: Any, k: int) -> None:
        """Put mocap bodies where they are at instant ``k`` of ``times_s``."""


@dataclass
class Context:
    """What sensors read while recording (:class:`exobench.envs.sensors.adapter.RecordContext`).
    ``motion`` and ``duration_s`` grow when a stepped recording's motion is extended."""

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


class Recorder:
    """A recording under way: the rig's adapters over a motion (see the module docstring).

    Use it as a context manager or call :meth:`close`; :func:`record` is the whole-motion run.
    """

    def __init__(
        self,
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
    ) -> None:
        ids = [s.sensor_id for s in rig]
        if len(set(ids)) != len(ids):
            raise ConfigError("rig", ids, "sensors with distinct ids")
        dur = float(motion.duration_s if duration_s is None else duration_s)
        self.ctx = Context(model, truth, exo, motion, int(seed), dur, tuple(rig), tuple(watch_geoms))
        self.hooks, self.track_bodies, self.track_rate_hz = tuple(hooks), tuple(track_bodies), float(track_rate_hz)
        self._rank = {sid: i for i, sid in enumerate(ids)}
        self._adapters: list[Any] = []
        try:
            for s in rig:
                self._adapters.append(adapter_class(s.kind)(s, self.ctx))
        except BaseException:
            self.close()
            raise
        self._observed_s = -np.inf  # instants before this have been observed
        self._data: Any = None
        self._tracks: dict[str, list[np.ndarray]] = {b: [] for b in self.track_bodies}
        self._pending: list[tuple[float, int, Frame, Any]] = []
        self._stepped = False

    def __enter__(self) -> Recorder:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def close(self) -> None:
        for a in self._adapters:
            a.close()

    @property
    def observed_s(self) -> float:
        """Instants before this time have been observed (-inf before the first call)."""
        return self._observed_s

    def observe(self, until_s: float | None = None) -> None:
        """The one sensor loop: put MuJoCo in the motion's state at every instant some sensor (or
        the link tracks) needs from the last call's end up to ``until_s`` (excluded; None: every
        instant left), and let each sensor observe it there."""
        import mujoco

        model, motion, lo = self.ctx.model, self.ctx.motion, self._observed_s
        hi = np.inf if until_s is None else float(until_s)

        def window(t: np.ndarray) -> np.ndarray:
            return t[(t >= lo) & (t < hi)] if np.isfinite(lo) or np.isfinite(hi) else t

        inst = [window(np.asarray(a.instants(), dtype=float)) for a in self._adapters]
        track = bool(self.track_bodies)
        t_trk = window(sample_times(self.track_rate_hz, self.ctx.duration_s)) if track else np.zeros(0)
        t_mj = reduce(np.union1d, [*inst, t_trk], np.zeros(0))
        self._observed_s = hi
        if not len(t_mj):
            return
        sample = motion.sample(model, t_mj)
        for h in self.hooks:
            h.prepare(model, sample, t_mj)
        measures = [np.isin(t_mj, ti) for ti in inst]
        dyn = reduce(np.logical_or, [m for a, m in zip(self._adapters, measures) if a.needs_dynamics], np.zeros(len(t_mj), bool))
        is_trk = np.isin(t_mj, t_trk)
        body_ids = [mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, b) for b in self.track_bodies]
        if self._data is None:
            self._data = mujoco.MjData(model)
        data = self._data
        for k, t in enumerate(t_mj):
            tk = float(t)
            for h in self.hooks:
                h.place(data, k)
            if dyn[k]:
                imu_dynamics(model, data, sample.qpos[k], sample.qvel[k], sample.qacc[k])
            else:
                data.qpos[:] = sample.qpos[k]
                mujoco.mj_kinematics(model, data)
            for a, m in zip(self._adapters, measures):
                if m[k]:
                    a.observe(model, data, tk)
            if is_trk[k]:
                for b, i in zip(self.track_bodies, body_ids):
                    self._tracks[b].append(np.concatenate([[tk], data.xpos[i], data.xquat[i]]))

    def finish(self) -> Recording:
        """Every frame and truth of the instants observed (each adapter's ``finish``), merged."""
        if self._stepped:
            raise ExobenchError("finish() after advance_to(): the frames were delivered step by step")
        outputs = {s.sensor_id: a.finish() for s, a in zip(self.ctx.rig, self._adapters)}
        merged = [(f.stamp_s, self._rank[sid], f) for sid in self._rank for f in outputs[sid].frames]
        merged.sort(key=lambda x: (x[0], x[1]))  # stable: each stream is already in time order
        tracks = {b: np.array(v).reshape(-1, 8) for b, v in self._tracks.items()}
        return Recording(tuple(f for _, _, f in merged), outputs, tracks, self.ctx)

    def advance_to(self, t_s: float, motion: Motion | None = None) -> list[tuple[Frame, Any]]:
        """Observe the instants in ``[t_prev, t_s)`` of ``motion`` (default: the current one; a
        new motion must extend it: its first segments are the current one's) and return the
        (frame, truth or None) pairs delivered by ``t_s`` and not returned before, in time order."""
        slow = sorted({s.kind for s in self.ctx.rig if not adapter_class(s.kind).streams})
        if slow:
            streaming = sorted(k for k, sk in SENSOR_KINDS.items() if sk.adapter.streams)
            raise ConfigError("rig", slow, f"sensor kinds that can be stepped ({', '.join(streaming)})")
        if motion is not None:
            old = self.ctx.motion.segments
            if motion.segments[: len(old)] != old:
                raise ConfigError("motion", f"{len(motion.segments)} segments", "a motion whose first segments are the recorded one's")
            self.ctx.motion, self.ctx.duration_s = motion, float(motion.duration_s)
        t_s = float(t_s)
        if not (max(self._observed_s, 0.0) <= t_s <= self.ctx.duration_s):
            raise ConfigError("t_s", t_s, f"[{max(self._observed_s, 0.0)}, {self.ctx.duration_s}] s (time runs forward, within the motion)")
        self._stepped = True
        self.observe(t_s)
        for s, a in zip(self.ctx.rig, self._adapters):
            out = a.take()
            truths = out.frame_truth if out.frame_truth is not None else [None] * len(out.frames)
            self._pending += [(f.stamp_s, self._rank[s.sensor_id], f, tr) for f, tr in zip(out.frames, truths, strict=True)]
        self._pending.sort(key=lambda x: (x[0], x[1]))  # stable, as in finish
        due = [p for p in self._pending if p[0] <= t_s + DUE_TOL_S]
        self._pending = self._pending[len(due) :]
        return [(f, tr) for _, _, f, tr in due]


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
    with Recorder(
        model, truth, exo, motion, rig, seed, duration_s=duration_s, hooks=hooks, track_bodies=track_bodies,
        track_rate_hz=track_rate_hz, watch_geoms=watch_geoms,
    ) as rec:  # fmt: skip
        rec.observe()
        return rec.finish()


@dataclass(eq=False)
class StreamedRecording:
    """Output of :func:`stream_record`: :meth:`items` yields ``(frame, truth or None)`` in
    :func:`record`'s order (once); when it is exhausted ``outputs`` holds each sensor's
    :class:`SensorOutput` with its truth (a chunked sensor's ``frames`` and ``frame_truth`` are
    then empty: they were handed out), ``body_tracks`` and ``context`` as in :class:`Recording`."""

    small: Recording
    recorder: Recorder
    rank: dict[str, int]
    chunk_s: float
    outputs: dict[str, SensorOutput] = field(default_factory=dict)

    @property
    def body_tracks(self) -> dict[str, np.ndarray]:
        return self.small.body_tracks

    @property
    def context(self) -> Context:
        return self.small.context

    def _small_items(self) -> Iterator[tuple[float, int, Frame, Any]]:
        truths = {id(f): t for out in self.small.outputs.values() if out.frame_truth is not None
                  for f, t in zip(out.frames, out.frame_truth, strict=True)}  # fmt: skip
        for f in self.small.frames:
            yield (f.stamp_s, self.rank[f.sensor_id], f, truths.get(id(f)))

    def _big_items(self) -> Iterator[tuple[float, int, Frame, Any]]:
        rec, pending = self.recorder, []
        with rec:
            ends = np.arange(self.chunk_s, rec.ctx.duration_s, self.chunk_s)
            for hi in [*ends.tolist(), None]:
                rec.observe(hi)
                for s, a in zip(rec.ctx.rig, rec._adapters):
                    out = a.take() if hi is not None else a.finish()
                    truths = out.frame_truth if out.frame_truth is not None else [None] * len(out.frames)
                    pending += [(f.stamp_s, self.rank[s.sensor_id], f, tr) for f, tr in zip(out.frames, truths, strict=True)]
                    if hi is None:
                        self.outputs[s.sensor_id] = SensorOutput([], None, out.truth)
                pending.sort(key=lambda x: (x[0], x[1]))  # stable, as in Recorder.finish
                # an instant not yet observed gives stamps at or after it (chunked kinds never stamp back)
                due = len(pending) if hi is None else sum(1 for p in pending if p[0] < hi)
                yield from pending[:due]
                pending = pending[due:]

    def items(self) -> Iterator[tuple[Frame, Any]]:
        self.outputs.update(self.small.outputs)
        merged = heapq.merge(self._small_items(), self._big_items(), key=lambda x: (x[0], x[1]))
        for _, _, f, tr in merged:
            yield f, tr


def stream_record(
    model: Any,
    truth: SceneTruth,
    exo: ExoSpec,
    motion: Motion,
    rig: Sequence[MountedSensor],
    seed: int,
    *,
    track_bodies: Sequence[str] = (),
    track_rate_hz: float = TRACK_RATE_HZ,
    chunk_s: float = CHUNK_S,
    duration_s: float | None = None,
    hooks: Sequence[Hook] = (),
    watch_geoms: Sequence[Sequence[int]] = (),
) -> StreamedRecording:
    """:func:`record` of ``rig`` over ``motion`` (up to ``duration_s``) as a stream (see the
    module docstring). The small streams are recorded here; the big ones as
    :meth:`StreamedRecording.items` is iterated. Their kinds must never stamp a frame before the
    instant it was observed at (a LiDAR clock stepping back cannot stream). ``hooks`` act on both
    recordings: the small one is run to its end before the big one starts, so a hook that keeps
    what :meth:`Hook.prepare` computed for :meth:`Hook.place` (pedestrians) sees one recording
    at a time; ``watch_geoms`` are the cameras' (big)."""
    ids = [s.sensor_id for s in rig]
    if len(set(ids)) != len(ids):
        raise ConfigError("rig", ids, "sensors with distinct ids")
    big = [s for s in rig if adapter_class(s.kind).chunked]
    small = record(model, truth, exo, motion, [s for s in rig if not adapter_class(s.kind).chunked], seed, track_bodies=track_bodies,
                   track_rate_hz=track_rate_hz, duration_s=duration_s, hooks=hooks)  # fmt: skip
    rec = Recorder(model, truth, exo, motion, big, seed, duration_s=duration_s, hooks=hooks, watch_geoms=watch_geoms)
    return StreamedRecording(small, rec, {sid: i for i, sid in enumerate(ids)}, float(chunk_s))
