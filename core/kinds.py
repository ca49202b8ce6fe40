"""What a frame kind is, in one record, and the table of the kinds every pipeline accepts.

A frame kind is more than its dataclass: tests and users fault its frames
(:mod:`exobench.core.faults`), pipelines count its NaN and absurd values
(:mod:`exobench.core.counters`, :mod:`exobench.core.limits`) and order its stream by the time it
was measured. A :class:`FrameKind` gathers these; :data:`KINDS` holds one per kind name, and
:func:`register_kind` adds one (the shipped kinds register in :mod:`exobench.core.frame_kinds`,
a new kind in its own frame module, with one line). Everything that dispatches on a frame's
kind asks this table: :func:`exobench.core.pipeline.check_frame` accepts every registered
kind, and a frame of a type not registered is a :class:`~.errors.FrameTypeError` naming the
registered ones.

The simulation side of a kind (its adapter and its session codec) is the second table,
:mod:`exobench.envs.sensors.kinds`, which also checks that the two agree.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from .calibration import Calibration
from .errors import FrameTypeError

FrameFn = Callable[[Any], Any]


@dataclass(frozen=True)
class FrameKind:
    """Everything exobench's core knows of one frame kind.

    Attributes:
        name: the kind name (``frames.<name>.*`` counters, the ``kind`` of a session line), e.g. ``"tof"``.
        frame_type: its frozen dataclass, with ``stamp_s`` and ``sensor_id`` first.
        nan: ``frame -> frame`` with NaN in every measured value (a faulty driver), shapes kept.
        nan_values: ``frame -> int``, how many non-finite measured values it holds, counted as
            the counters count them (points and pixels one by one, else one per frame); a value
            that is not a number counts 0.
        absurd: ``(frame, variant) -> frame`` with values no such sensor can report (the
            ``variant`` picks among several forms, e.g. ToF ranges of 1e308, 0 and 1e6 m).
        absurd_values: ``calibration -> (frame -> int)``: the absurd-value rule, the limits read
            once from the calibration (``None``: fall-back limits), then per frame how many
            finite values lie beyond them (:mod:`exobench.core.limits`); NaN is not absurd.
        no_return: ``frame -> frame`` as the sensor reports a measurement that found nothing
            (ToF no target, an empty sweep, a depth image of zeros); None when the sensor has no
            such state (IMU, encoders, contacts, odometry).
        measured: the field holding the time the frame was measured, which orders its stream
            (``"sweep_start_s"`` for a LiDAR sweep, else ``"stamp_s"``).
    """

    name: str
    frame_type: type
    nan: FrameFn
    nan_values: Callable[[Any], int]
    absurd: Callable[[Any, int], Any]
    absurd_values: Callable[[Calibration | None], Callable[[Any], int]]
    no_return: FrameFn | None = None
    measured: str = "stamp_s"


KINDS: dict[str, FrameKind] = {}
"""Every registered frame kind by name (fill it with :func:`register_kind` only)."""

FRAME_TYPES: dict[str, type] = {}
"""Kind name -> frame type of every registered kind (kept by :func:`register_kind`)."""

_BY_TYPE: dict[type, FrameKind] = {}
_CLASSES: list[tuple[type, ...]] = [()]

REQUIRED = ("nan", "nan_values", "absurd", "absurd_values")
"""The parts of a record that must be functions (``no_return`` may be None)."""

_PART_NAMES = {
    "nan": "no NaN form (nan)",
    "nan_values": "no NaN-value counter (nan_values)",
    "absurd": "no absurd form (absurd)",
    "absurd_values": "no absurd-value rule (absurd_values)",
}


def record_problems(kind: FrameKind) -> list[str]:
    """What a record lacks or gets wrong, one phrase each (empty when nothing)."""
    out = [_PART_NAMES[p] for p in REQUIRED if not callable(getattr(kind, p, None))]
    if kind.no_return is not None and not callable(kind.no_return):
        out.append("no_return is neither None nor a function")
    names = getattr(kind.frame_type, "__dataclass_fields__", None)
    if not isinstance(kind.frame_type, type) or names is None:
        out.append(f"frame type {kind.frame_type!r} is not a dataclass")
    else:
        missing = [f for f in ("stamp_s", "sensor_id", kind.measured) if f not in names]
        if missing:
            out.append(
                f"frame type {kind.frame_type.__name__} has no field {', '.join(dict.fromkeys(missing))}"
            )
    return out


def register_kind(kind: FrameKind) -> FrameKind:
    """Add a kind to :data:`KINDS`. A name or frame type registered twice, or a record that
    lacks a part (:func:`record_problems`), is refused with a ``ValueError`` naming it."""
    if kind.name in KINDS or kind.frame_type in _BY_TYPE:
        raise ValueError(
            f"frame kind {kind.name!r} ({getattr(kind.frame_type, '__name__', kind.frame_type)}) is registered already"
        )
    problems = record_problems(kind)
    if problems:
        raise ValueError(f"frame kind {kind.name!r}: {'; '.join(problems)}")
    KINDS[kind.name] = kind
    _reindex()
    return kind


def unregister_kind(name: str) -> None:
    """Remove a kind (a test that registered its own kind cleans up with this)."""
    del KINDS[name]
    _reindex()


def _reindex() -> None:
    FRAME_TYPES.clear()
    FRAME_TYPES.update({k.name: k.frame_type for k in KINDS.values()})
    _BY_TYPE.clear()
    _BY_TYPE.update({k.frame_type: k for k in KINDS.values()})
    _CLASSES[0] = tuple(FRAME_TYPES.values())


def frame_classes() -> tuple[type, ...]:
    """The frame types of every registered kind."""
    return _CLASSES[0]


def kind_of(frame: Any) -> FrameKind:
    """The record of a frame's kind; :class:`FrameTypeError` for anything not a registered frame."""
    k = _BY_TYPE.get(type(frame))
    if k is not None:
        return k
    for cls, k in _BY_TYPE.items():  # a subclass of a registered frame type
        if isinstance(frame, cls):
            return k
    raise FrameTypeError(frame, [c.__name__ for c in frame_classes()])


def frame_kind(frame: Any) -> str:
    """The short kind name of a frame (the key of :data:`KINDS`)."""
    return kind_of(frame).name


# --- parts a new kind can be built from -----------------------------------------------------------
def nan_like(a: Any) -> np.ndarray:
    """An array of NaN of ``a``'s shape, in a float dtype at least as wide as ``a``'s."""
    return np.full(np.shape(a), np.nan, dtype=np.result_type(np.asarray(a).dtype, np.float32))


def nan_in(*fields: str) -> Callable[[Any], int]:
    """A NaN-value counter: one when any of ``fields`` (numbers or arrays) holds a non-finite value."""

    def count(frame: Any) -> int:
        return int(not all(np.isfinite(np.asarray(getattr(frame, f), dtype=float)).all() for f in fields))

    return count


def nan_form(*fields: str) -> FrameFn:
    """A NaN form: the frame with every value of ``fields`` NaN (a float field becomes ``nan``)."""

    def form(frame: Any) -> Any:
        values = {
            f: math.nan if np.ndim(getattr(frame, f)) == 0 else nan_like(getattr(frame, f)) for f in fields
        }
        return replace(frame, **values)

    return form
