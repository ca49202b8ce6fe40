"""Faulty sensor data on demand: frames with no return, with NaN, and streams with gaps.

Real logs contain what a simulation rarely does: a ToF that sees nothing, a LiDAR sweep that
came back empty, a depth image of zeros, a driver that wrote NaN, a frame that never arrived,
a frame delivered twice or late. These functions make such frames from good ones, so that tests
(and users checking their own pipelines) can feed every pipeline the faults it must survive and
count (:mod:`exobench.core.counters`). They change values only: stamps, sensor ids and array
shapes stay as they were, except an empty sweep; :func:`inject_stream_faults` also repeats and
reorders frames.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace

import numpy as np

from .frame_kinds import ABSURD_DEPTH_M, ABSURD_POINT_M, ABSURD_RANGES_M, ABSURD_VALUE  # noqa: F401  (the values absurd() writes)
from .frames import Frame, LidarScan
from .kinds import kind_of


def no_return(frame: Frame) -> Frame:
    """The frame as its sensor reports a measurement that found nothing (its kind's
    ``no_return``: ToF NaN range with status NO_TARGET; LiDAR an empty sweep; RGB-D depth 0
    everywhere, the invalid value). Kinds without such a state (IMU, encoders, contacts,
    odometry) return the frame unchanged. A frame of no registered kind is a FrameTypeError."""
    fn = kind_of(frame).no_return
    return frame if fn is None else fn(frame)


def with_nan(frame: Frame) -> Frame:
    """The frame with NaN in every measured value (a faulty driver), shapes kept (its kind's ``nan``)."""
    return kind_of(frame).nan(frame)


def inject_faults(
    frames: Sequence[Frame], at: tuple[float, float, float] = (0.25, 0.5, 0.75)
) -> tuple[Frame, ...]:
    """Every sensor stream of ``frames`` with three faults: at the fractions ``at`` of each
    stream's length, one frame with no return, one with NaN, and one dropped. Deterministic;
    a stream of fewer than four frames is left as it is. Time order is kept."""
    by_sensor: dict[str, list[int]] = {}
    for i, f in enumerate(frames):
        by_sensor.setdefault(f.sensor_id, []).append(i)
    replaced: dict[int, Frame | None] = {}
    for idx in by_sensor.values():
        if len(idx) < 4:
            continue
        k_none, k_nan, k_drop = (idx[min(len(idx) - 1, int(a * len(idx)))] for a in at)
        replaced[k_none] = no_return(frames[k_none])
        replaced[k_nan] = with_nan(frames[k_nan])
        replaced[k_drop] = None
    out = (replaced.get(i, f) for i, f in enumerate(frames))
    return tuple(f for f in out if f is not None)


def n_absurd_points(scan: LidarScan) -> int:
    """How many points :func:`absurd` makes absurd in a scan: every other one (1e6 m, origin)."""
    return (len(np.asarray(scan.points_xyz).reshape(-1, 3)) + 1) // 2


def absurd(frame: Frame, variant: int = 0) -> Frame:
    """The frame with values its sensor cannot have measured (a broken driver or unit error), its
    kind's ``absurd`` form. The shipped kinds (:mod:`exobench.core.frame_kinds`):

    - ToF: status VALID with range ``ABSURD_RANGES_M[variant % 3]`` (1e308, 0 or 1e6 m);
    - LiDAR: every other point absurd, alternately at 1e6 m along its ray and at the origin
      (:func:`n_absurd_points` says how many);
    - RGB-D: depth 1e6 m everywhere; IMU: 1e308 in the quaternion, rate and force;
    - encoders: 1e308 rad; contact: 1e308 N; odometry: a translation of 1e308 m.
    """
    return kind_of(frame).absurd(frame, variant)


def inject_absurd(
    frames: Sequence[Frame], at: tuple[float, ...] = (0.2, 0.4, 0.6)
) -> tuple[tuple[Frame, ...], tuple[int, ...]]:
    """Every sensor stream of ``frames`` with absurd values (:func:`absurd`) in the frames at the
    fractions ``at`` of its length, the k-th with variant k (a ToF stream gets 1e308, 0 and 1e6);
    streams of fewer than ``len(at) + 1`` frames are left as they are. Returns the frames (none
    dropped, order kept) and the indices of the frames made absurd."""
    by_sensor: dict[str, list[int]] = {}
    for i, f in enumerate(frames):
        by_sensor.setdefault(f.sensor_id, []).append(i)
    replaced: dict[int, Frame] = {}
    for idx in by_sensor.values():
        if len(idx) <= len(at):
            continue
        for variant, a in enumerate(at):
            k = idx[min(len(idx) - 1, int(a * len(idx)))]
            replaced[k] = absurd(frames[k], variant)
    return tuple(replaced.get(i, f) for i, f in enumerate(frames)), tuple(sorted(replaced))


STREAM_FAULTS = ("dropped", "nan", "absurd", "repeated", "out_of_order")
"""The faults :func:`inject_stream_faults` puts in every stream, named as their counters."""


def inject_stream_faults(
    frames: Sequence[Frame], at: tuple[float, float, float, float, float] = (0.1, 0.25, 0.45, 0.65, 0.85)
) -> tuple[tuple[Frame, ...], dict[str, dict[str, tuple[Frame, ...]]]]:
    """Every sensor stream of ``frames`` with one frame of each of :data:`STREAM_FAULTS`, at the
    fractions ``at`` of its length (in that order): one removed, one with NaN (:func:`with_nan`),
    one absurd (:func:`absurd`), one delivered twice in a row (an identical copy) and one
    delivered after the next frame of its stream (its stamps kept). A stream of fewer than 10
    frames is left as it is. Returns the frames and, per sensor id of a changed stream and per
    fault, the frames concerned (the removed one, the NaN one, the absurd one, the copy, the
    late one)."""
    by_sensor: dict[str, list[int]] = {}
    for i, f in enumerate(frames):
        by_sensor.setdefault(f.sensor_id, []).append(i)
    changed: dict[int, Frame] = {}
    drop: set[int] = set()
    copies: dict[int, Frame] = {}
    late: dict[int, int] = {}  # index of a late frame -> index of the frame it follows
    injected: dict[str, dict[str, tuple[Frame, ...]]] = {}
    for sid, idx in by_sensor.items():
        if len(idx) < 10:
            continue
        k_drop, k_nan, k_abs, k_rep, k_late = (idx[int(a * len(idx))] for a in at)
        drop.add(k_drop)
        changed[k_nan] = with_nan(frames[k_nan])
        changed[k_abs] = absurd(frames[k_abs])
        copies[k_rep] = replace(frames[k_rep])
        late[k_late] = idx[idx.index(k_late) + 1]
        injected[sid] = {"dropped": (frames[k_drop],), "nan": (changed[k_nan],), "absurd": (changed[k_abs],),
                         "repeated": (copies[k_rep],), "out_of_order": (frames[k_late],)}  # fmt: skip
    after: dict[int, int] = {nxt: k for k, nxt in late.items()}
    out: list[Frame] = []
    for i, f in enumerate(frames):
        if i in drop or i in late:
            continue
        out.append(changed.get(i, f))
        if i in copies:
            out.append(copies[i])
        if i in after:
            out.append(frames[after[i]])
    return tuple(out), injected


def swap_place_labels(frames: Sequence[Frame], fraction: float, seed: int,
                      labels: Sequence[str] | None = None) -> tuple[Frame, ...]:
    """The frames with ``round(fraction * n)`` of their ``n`` place labels wrong: those labels,
    drawn with ``seed``, are each replaced by another of ``labels`` (default: the labels of the
    stream) drawn uniformly, as a user or a room classifier that mistakes the room. Nothing else
    changes. With fewer than two labels to choose from there is nothing to swap to: the frames
    are returned as they are."""
    from .errors import check_range
    from .frames import PlaceLabel

    check_range("place_label_error_fraction", fraction, 0.0, 1.0)
    at = [i for i, f in enumerate(frames) if isinstance(f, PlaceLabel)]
    pool = sorted(set(labels) if labels is not None else {frames[i].label for i in at})  # type: ignore[union-attr]
    if len(pool) < 2 or not at:
        return tuple(frames)
    rng = np.random.default_rng([int(seed), 0x1AB])
    wrong = rng.choice(len(at), size=int(round(fraction * len(at))), replace=False)
    out = list(frames)
    for k in wrong:
        f = out[at[k]]
        others = [lab for lab in pool if lab != f.label]  # type: ignore[union-attr]
        out[at[k]] = replace(f, label=others[int(rng.integers(len(others)))])  # type: ignore[type-var]
    return tuple(out)
