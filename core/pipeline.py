"""The pipeline protocol every perception or mapping estimator implements.

A pipeline is a small class constructed from its typed config (a dataclass named ``Config`` on
the class); it never reads files, owns a viewer or knows the simulator::

    pipe = RtlsPipeline(RtlsPipeline.Config(th_z_m=0.008))
    pipe.reset(calibration)
    for frame in frames:              # time-ordered
        online = pipe.process(frame)  # estimate so far, or None
    result = pipe.finalize()          # the offline result the harness scores

``process`` first calls :func:`check_frame`, which raises :class:`~.errors.PipelineStateError`
before ``reset`` and :class:`~.errors.FrameTypeError` for anything that is not a frame (a dict,
None, a string): every built-in pipeline does, and a third-party pipeline should do the same,
so that a mistake in the caller is an error and never a silently ignored input. Then it admits
the frame through :class:`~.counters.StreamCounters`, which counts it and refuses a repeated or
out-of-order one. Values inside a frame that no sensor can report are not errors: a pipeline
skips and counts them (see :mod:`exobench.core.limits` and :mod:`exobench.core.counters`).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from typing import Any, ClassVar, Protocol, runtime_checkable

from .calibration import Calibration
from .errors import ConfigError, FrameTypeError, PipelineStateError, UnknownNameError
from .frames import Frame
from .kinds import frame_classes


@runtime_checkable
class Pipeline(Protocol):
    """Protocol of an estimator.

    Class attributes:
        name: registry name, e.g. ``"rtls"``.
        track: the track whose estimate type it returns, e.g. ``"stairs"``.
        Config: dataclass of its parameters (every field has a default).
        deterministic: optional, True when absent (:func:`is_deterministic`): the same frames
            give bit-identical estimates. A pipeline that cannot promise it (ORB-SLAM3 maps in
            threads of its own) sets it False; the conformance tests then do not compare two
            runs, and the run's configuration, records and report mark it not bit-reproducible.
    """

    name: ClassVar[str]
    track: ClassVar[str]

    def reset(self, calibration: Calibration) -> None:
        """Forget all state and prepare for a new episode on this device."""

    def process(self, frame: Frame) -> Any | None:
        """Consume one frame; return the current estimate, or None when there is none yet."""

    def finalize(self) -> Any:
        """Return the final estimate of the episode."""


def is_deterministic(pipeline: object) -> bool:
    """Whether a pipeline class (or instance) promises bit-identical estimates for the same
    frames: its ``deterministic`` class attribute, True when it has none."""
    return bool(getattr(pipeline, "deterministic", True))


def check_frame(pipeline: object, frame: object, was_reset: bool) -> None:
    """Refuse a call of ``pipeline.process(frame)`` that cannot be right: before ``reset``
    (``was_reset`` False) with :class:`PipelineStateError`, and with ``frame`` not of a
    registered kind (:data:`~.kinds.KINDS`) with :class:`FrameTypeError`. Call it first in ``process``."""
    if not was_reset:
        raise PipelineStateError(getattr(pipeline, "name", "") or type(pipeline).__name__, "process()")
    classes = frame_classes()
    if not isinstance(frame, classes):
        raise FrameTypeError(frame, [c.__name__ for c in classes])


def config_from_dict(config_cls: type, values: Mapping[str, Any], *, prefix: str = "") -> Any:
    """Build a config dataclass from plain values, refusing unknown keys and wrong types.

    Values given as strings (from the command line) are converted to the field's default type.
    A field whose default is itself a config dataclass (a stage of the pipeline) takes either a
    nested mapping (``{"filter": {"kind": "threshold"}}``) or dotted keys
    (``{"filter.kind": "threshold"}``), at any depth; the values given are applied over that
    default. Unknown keys raise :class:`UnknownNameError` naming the dotted path; a plain value
    given to a whole nested config raises :class:`ConfigError`. ``prefix`` (e.g. ``"kiss-icp."``)
    only names the owner in messages.
    """
    kind = f"{prefix.rstrip('.') or config_cls.__name__} parameter"
    return _build(config_cls, None, values, kind, prefix, "")


def _field_default(f: dataclasses.Field) -> Any:
    if f.default is not dataclasses.MISSING:
        return f.default
    if f.default_factory is not dataclasses.MISSING:
        return f.default_factory()
    return None


def _build(config_cls: type, base: Any, values: Mapping[str, Any], kind: str, prefix: str, path: str) -> Any:
    """``config_cls(**values)`` (``base`` None) or ``replace(base, **values)``, nested fields built
    recursively; ``path`` is the dotted path of this config inside the top one (``""`` or ``"a.b."``)."""
    fields = {f.name: f for f in dataclasses.fields(config_cls) if f.init}
    kwargs: dict[str, Any] = {}
    nested: dict[str, dict[str, Any]] = {}
    for key, raw in values.items():
        name, dot, rest = str(key).partition(".")
        if name not in fields:
            raise UnknownNameError(kind, f"{path}{key}", [f"{path}{n}" for n in fields])
        default = base_value = getattr(base, name) if base is not None else _field_default(fields[name])
        if dataclasses.is_dataclass(default) and not isinstance(default, type):
            if dot:
                nested.setdefault(name, {})[rest] = raw
            elif isinstance(raw, Mapping):
                nested.setdefault(name, {}).update(raw)
            elif type(raw) is type(default):
                kwargs[name] = raw
            else:
                raise ConfigError(f"{prefix}{path}{name}", raw,
                                  f"a {type(default).__name__}: give its fields as {path}{name}.<field>")  # fmt: skip
        elif dot:
            raise UnknownNameError(kind, f"{path}{key}", [f"{path}{n}" for n in fields])
        else:
            kwargs[name] = coerce_like(f"{prefix}{path}{name}", raw, base_value)
    for name, sub in nested.items():
        inner = kwargs.pop(name, None)
        inner = inner if inner is not None else (getattr(base, name) if base is not None else _field_default(fields[name]))
        kwargs[name] = _build(type(inner), inner, sub, kind, prefix, f"{path}{name}.")
    try:
        return config_cls(**kwargs) if base is None else dataclasses.replace(base, **kwargs)
    except ConfigError as e:
        if not path:
            raise
        # name the field by its dotted path inside the top-level config
        raise ConfigError(f"{prefix}{path}{e.field}", e.value, e.allowed) from None


def coerce_like(field_name: str, raw: Any, default: Any) -> Any:
    """Convert ``raw`` to the type of ``default`` (bool, int, float, str, or a tuple of numbers:
    ``"0, 0.08, 0"`` from the command line, each a finite number), or raise ConfigError."""
    if isinstance(default, tuple) and default and all(_is_number(x) for x in default):
        parts = raw.strip().strip("()[]").split(",") if isinstance(raw, str) else raw
        try:
            parts = list(parts)
        except TypeError:
            parts = None
        if parts is None or len(parts) != len(default):
            raise ConfigError(field_name, raw, f"{len(default)} numbers separated by commas")
        out = tuple(coerce_like(field_name, p, d) for p, d in zip(parts, default))
        if not all(math.isfinite(x) for x in out):
            raise ConfigError(field_name, raw, f"{len(default)} finite numbers")
        return out
    if isinstance(default, bool):
        if isinstance(raw, bool):
            return raw
        s = str(raw).strip().lower()
        if s in ("1", "true", "yes", "on"):
            return True
        if s in ("0", "false", "no", "off"):
            return False
        raise ConfigError(field_name, raw, "true or false")
    if isinstance(default, int):
        try:
            f = float(raw)
        except (TypeError, ValueError):
            raise ConfigError(field_name, raw, "an integer") from None
        if not math.isfinite(f) or f != int(f):
            raise ConfigError(field_name, raw, "an integer")
        return int(f)
    if isinstance(default, float):
        try:
            return float(raw)
        except (TypeError, ValueError):
            raise ConfigError(field_name, raw, "a number") from None
    if isinstance(default, str):
        return str(raw)
    return raw


def _is_number(x: Any) -> bool:
    return isinstance(x, (int, float)) and not isinstance(x, bool)
