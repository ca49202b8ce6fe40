"""The pipeline protocol every perception or mapping estimator implements.

A pipeline is a small class constructed from its typed config (a dataclass named ``Config`` on
the class); it never reads files, owns a viewer or knows the simulator::

    pipe = RtlsPipeline(RtlsPipeline.Config(th_z_m=0.008))
    pipe.reset(calibration)
    for frame in frames:              # time-ordered
        online = pipe.process(frame)  # estimate so far, or None
    result = pipe.finalize()          # the offline result the harness scores
"""

from __future__ import annotations

import dataclasses
from typing import Any, ClassVar, Protocol, runtime_checkable

from .calibration import Calibration
from .errors import ConfigError, UnknownNameError
from .frames import Frame


@runtime_checkable
class Pipeline(Protocol):
    """Protocol of an estimator.

    Class attributes:
        name: registry name, e.g. ``"rtls"``.
        track: the track whose estimate type it returns, e.g. ``"stairs"``.
        Config: dataclass of its parameters (every field has a default).
    """

    name: ClassVar[str]
    track: ClassVar[str]

    def reset(self, calibration: Calibration) -> None:
        """Forget all state and prepare for a new episode on this device."""

    def process(self, frame: Frame) -> Any | None:
        """Consume one frame; return the current estimate, or None when there is none yet."""

    def finalize(self) -> Any:
        """Return the final estimate of the episode."""


def config_from_dict(config_cls: type, values: dict[str, Any], *, prefix: str = "") -> Any:
    """Build a config dataclass from plain values, refusing unknown keys and wrong types.

    Values given as strings (from the command line) are converted to the field's default type.
    """
    fields = {f.name: f for f in dataclasses.fields(config_cls)}
    kwargs: dict[str, Any] = {}
    for key, raw in values.items():
        if key not in fields:
            raise UnknownNameError(f"{prefix or config_cls.__name__} parameter", key, fields)
        default = fields[key].default
        kwargs[key] = coerce_like(f"{prefix}{key}" if prefix else key, raw, default)
    return config_cls(**kwargs)


def coerce_like(field_name: str, raw: Any, default: Any) -> Any:
    """Convert ``raw`` to the type of ``default`` (bool, int, float, str), or raise ConfigError."""
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
        if f != int(f):
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
