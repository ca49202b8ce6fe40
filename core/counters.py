"""Counters of the frames a pipeline met: one vocabulary for every pipeline and every track.

Every built-in pipeline counts its input per frame kind (the keys of
:data:`~exobench.core.kinds.KINDS`) in a :class:`FrameCounts` and returns them on its
estimate as ``estimate.counts`` (kind -> :class:`FrameCounts`); the runner writes them into each
record as flat metrics ``frames.<kind>.<counter>`` (:func:`count_metrics`), for every kind the
track streams, the same way in every track. The counters of one kind:

- ``seen``: frames of the kind given to ``process``;
- ``ignored``: frames of a kind or a sensor the pipeline does not read (the other leg's ToF, a
  second LiDAR); nothing else is counted of them;
- ``repeated``: a frame measured at the same time as the last one of its stream (same sensor id),
  whatever its content: a sensor measures once per instant, so a second frame of that instant
  is a driver re-sending or a log merged twice, never a new measurement. It is not used: using
  it would weigh one instant twice;
- ``out_of_order``: a frame measured before the last one of its stream (or at a non-finite
  time). It is not used: an online estimator has moved past that instant (a stale encoder state
  must not replace a newer one, a sweep cannot be registered before the map it predates), which
  is what real drivers and message filters do with late messages;
- ``dropped``: frames missing from a stream whose rate the calibration gives (the mount's
  ``rate_hz``; for the encoder state ``extra["encoders"]["rate_hz"]``): a gap of more than 1.5
  periods between two frames of the stream counts ``round(gap / period) - 1`` (at least 1).
  A late frame leaves such a gap when its successor arrives, so it counts as dropped as well as
  out of order (it was never used in its place). Streams without a known rate count none;
- ``nan`` / ``absurd``: frames holding a non-finite value / a value no sensor of that mount can
  report (:mod:`exobench.core.limits`); ``nan_values`` / ``absurd_values`` count the values
  themselves (LiDAR points, depth pixels; one per frame for the other kinds). A ToF reading
  with no target (status not VALID) is a measurement, not NaN;
- ``used``: frames the pipeline took into its estimate (not ignored, repeated or out of order,
  and not refused for their content: what a frame with NaN or absurd values leaves usable is
  each pipeline's documented choice).

The time a frame was measured orders its stream: ``sweep_start_s`` for a LiDAR sweep (a sweep
delivered late has a later ``stamp_s`` but an older start), ``stamp_s`` (delivery time, a fixed
latency after the measurement) for the other kinds.

In ``process``, after :func:`exobench.core.pipeline.check_frame`::

    c = self._counters.admit(frame, consumed=frame.sensor_id in self._sensors)
    if c is None:   # ignored, repeated or out of order: counted, not to be used
        return None
    ...             # c.nan / c.absurd / c.used (or c.add_nan(n), c.add_absurd(n)) as found

Per frame this is a few dictionary look-ups (O(1) Python).
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from typing import Any

from .calibration import Calibration
from .frames import Frame
from .kinds import kind_of

COUNTERS: tuple[str, ...] = (
    "seen", "used", "ignored", "repeated", "out_of_order", "dropped", "nan", "absurd", "nan_values", "absurd_values",
)  # fmt: skip
"""The counters of :class:`FrameCounts`, in the order they are reported."""


@dataclass(slots=True)
class FrameCounts:
    """The counters of one frame kind (see the module docstring for each).

    ``sensors`` holds the ids of the streams of the kind the pipeline read (not ignored); it is
    not a counter and not reported as a metric.
    """

    seen: int = 0
    used: int = 0
    ignored: int = 0
    repeated: int = 0
    out_of_order: int = 0
    dropped: int = 0
    nan: int = 0
    absurd: int = 0
    nan_values: int = 0
    absurd_values: int = 0
    sensors: tuple[str, ...] = ()

    def add_nan(self, n_values: int = 1) -> None:
        """Count one frame holding ``n_values`` non-finite values (nothing when 0)."""
        if n_values:
            self.nan += 1
            self.nan_values += int(n_values)

    def add_absurd(self, n_values: int = 1) -> None:
        """Count one frame holding ``n_values`` absurd values (nothing when 0)."""
        if n_values:
            self.absurd += 1
            self.absurd_values += int(n_values)

    def judge(self, frame: Frame, bad: bool) -> bool:
        """Count a whole frame: used when not ``bad``, else NaN when it holds a non-finite value
        (:func:`nan_values`) and absurd otherwise. Returns whether the frame may be used."""
        if not bad:
            self.used += 1
            return True
        if nan_values(frame):
            self.add_nan()
        else:
            self.add_absurd()
        return False

    def as_dict(self) -> dict[str, int]:
        """The counters by name (:data:`COUNTERS`), ``sensors`` left out."""
        return {name: getattr(self, name) for name in COUNTERS}


def measured_s(frame: Frame) -> float:
    """The time the frame was measured, which orders its stream (its kind's ``measured`` field)."""
    return float(getattr(frame, kind_of(frame).measured))


def stream_rates(calibration: Calibration | None) -> dict[str, float]:
    """Sensor id -> rate (Hz) of the streams whose rate the calibration gives (module docstring)."""
    if calibration is None:
        return {}
    out: dict[str, float] = {}
    for m in calibration.mounts:
        rate = _rate(m.params.get("rate_hz"))
        if rate:
            out[m.sensor_id] = rate
    encoders = calibration.extra.get("encoders")
    rate = _rate(encoders.get("rate_hz")) if isinstance(encoders, Mapping) else None
    if rate:
        out["encoders"] = rate
    return out


def _rate(value: Any) -> float | None:
    try:
        rate = float(value)
    except (TypeError, ValueError):
        return None
    return rate if math.isfinite(rate) and rate > 0 else None


class StreamCounters:
    """The counters of one pipeline run, per kind, and the stream state that decides repeats,
    order and gaps (the last measurement time of each stream)."""

    def __init__(self, rates: Mapping[str, float] | None = None) -> None:
        self._period = {sid: 1.0 / r for sid, r in (rates or {}).items() if r > 0}
        self._counts: dict[str, FrameCounts] = {}
        self._last: dict[str, float] = {}
        self._sensors: dict[str, dict[str, None]] = {}  # kind -> sensor ids read, in order

    @classmethod
    def of(cls, calibration: Calibration | None) -> StreamCounters:
        """Counters that know the stream rates of ``calibration`` (:func:`stream_rates`)."""
        return cls(stream_rates(calibration))

    def kind(self, kind: str) -> FrameCounts:
        """The counters of ``kind`` (created at zero)."""
        c = self._counts.get(kind)
        if c is None:
            c = self._counts[kind] = FrameCounts()
        return c

    def admit(self, frame: Frame, consumed: bool = True) -> FrameCounts | None:
        """Count ``frame`` as seen; return its kind's counters when the pipeline is to use it,
        or None when it is ignored (``consumed`` False), repeated or out of order (counted)."""
        record = kind_of(frame)
        kind = record.name
        c = self._counts.get(kind) or self.kind(kind)
        c.seen += 1
        if not consumed:
            c.ignored += 1
            return None
        sid = frame.sensor_id
        try:
            t = float(getattr(frame, record.measured))
        except (TypeError, ValueError):  # a time that is not a number orders nothing
            t = math.nan
        last = self._last.get(sid)
        if last is not None and t == last:
            c.repeated += 1
            return None
        if not math.isfinite(t) or (last is not None and t < last):
            c.out_of_order += 1
            return None
        period = self._period.get(sid)
        if period is not None and last is not None and t - last > 1.5 * period:
            c.dropped += max(1, round((t - last) / period) - 1)
        self._last[sid] = t
        self._sensors.setdefault(kind, {})[sid] = None
        return c

    def restart(self) -> None:
        """Forget each stream's last measurement time: a new session of a multi-session episode
        starts, and the gap before its first frames is no drop, nor are its frames late."""
        self._last.clear()

    def snapshot(self) -> dict[str, FrameCounts]:
        """A copy of the counters by kind (for an estimate: later frames do not change it)."""
        sensors = self._sensors
        return {  # field by field: an online estimate takes a copy per update, so this is kept cheap
            kind: FrameCounts(
                c.seen,
                c.used,
                c.ignored,
                c.repeated,
                c.out_of_order,
                c.dropped,
                c.nan,
                c.absurd,
                c.nan_values,
                c.absurd_values,
                tuple(sensors[kind]) if kind in sensors else (),
            )
            for kind, c in self._counts.items()
        }


def admitted(frames: Iterable[Frame]) -> list[bool]:
    """Per frame, whether a pipeline reading every stream uses it by the rules above (not
    repeated, not out of order): what a scorer compares with the truth, each instant once."""
    order = StreamCounters()
    return [order.admit(f) is not None for f in frames]


def count_metrics(counts: Mapping[str, Any] | None, kinds: Iterable[str] = ()) -> dict[str, int]:
    """Flat metrics ``frames.<kind>.<counter>`` of ``counts`` (kind -> :class:`FrameCounts`), with
    every kind of ``kinds`` present (zeros when the pipeline saw none), so that every record of a
    track has the same keys."""
    out: dict[str, int] = {}
    counts = counts if isinstance(counts, Mapping) else {}
    for kind in dict.fromkeys([*kinds, *counts]):
        c = counts.get(kind)
        values = c.as_dict() if isinstance(c, FrameCounts) else {}
        for name in COUNTERS:
            out[f"frames.{kind}.{name}"] = int(values.get(name, 0))
    return out


def nan_values(frame: Frame) -> int:
    """How many non-finite values ``frame`` holds where it carries a measurement (its kind's
    ``nan_values``): LiDAR points and depth pixels one by one, one for any other frame with a
    non-finite value (a ToF reading only when its status is VALID: no target is a measurement).
    0 for values that are not numbers."""
    return kind_of(frame).nan_values(frame)
