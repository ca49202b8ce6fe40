"""Typed errors of exobench.

Library code raises these; only the command line turns them into a one-line message and a
non-zero exit. Every error names the field, the value and what would have been allowed.
"""

from __future__ import annotations

from collections.abc import Iterable


class ExobenchError(Exception):
    """Base class of every error exobench raises on purpose."""


class ConfigError(ExobenchError, ValueError):
    """A parameter is outside its allowed range or of the wrong kind.

    Attributes:
        field: dotted name of the parameter, e.g. ``"stairs.riser_m"``.
        value: the offending value as given.
        allowed: human-readable allowed range, e.g. ``"0 < riser_m <= 0.30"``.
    """

    def __init__(self, field: str, value: object, allowed: str) -> None:
        self.field = field
        self.value = value
        self.allowed = allowed
        super().__init__(f"{field}={value!r} is invalid; allowed: {allowed}")


class UnknownNameError(ExobenchError, KeyError):
    """A name (suite, track, pipeline, parameter, sensor, ...) is not known.

    The message lists the valid names so the user can correct the call.
    """

    def __init__(self, kind: str, name: str, valid: Iterable[str]) -> None:
        self.kind = kind
        self.name = name
        self.valid = tuple(sorted(valid))
        super().__init__(name)

    def __str__(self) -> str:
        return f"unknown {self.kind} {self.name!r}; valid: {', '.join(self.valid) or '(none)'}"


class SessionError(ExobenchError):
    """A recorded session on disk is missing, malformed or of an unsupported version."""


class RenderError(ExobenchError):
    """Off-screen rendering is unavailable (neither EGL nor OSMesa could be initialised)."""


def check_range(
    field: str,
    value: float,
    low: float | None = None,
    high: float | None = None,
    *,
    low_open: bool = False,
    high_open: bool = False,
) -> float:
    """Return ``value`` as a float if it lies in the range, else raise :class:`ConfigError`.

    NaN and infinities are always rejected. ``low_open``/``high_open`` make a bound strict.
    """
    lo = "" if low is None else (f"{low} < " if low_open else f"{low} <= ")
    hi = "" if high is None else (f" < {high}" if high_open else f" <= {high}")
    allowed = f"{lo}{field.rsplit('.', 1)[-1]}{hi}" if (lo or hi) else "a finite number"
    try:
        x = float(value)
    except (TypeError, ValueError):
        raise ConfigError(field, value, allowed) from None
    if x != x or x in (float("inf"), float("-inf")):
        raise ConfigError(field, value, allowed)
    if low is not None and (x <= low if low_open else x < low):
        raise ConfigError(field, value, allowed)
    if high is not None and (x >= high if high_open else x > high):
        raise ConfigError(field, value, allowed)
    return x


def check_int(field: str, value: object, low: int | None = None, high: int | None = None) -> int:
    """Return ``value`` as an int if it is a whole number within ``[low, high]``, else raise
    :class:`ConfigError`. Booleans, NaN, infinities and fractions are refused; a bound given as
    None is open. The one integer range check of exobench: configs call it in ``__post_init__``."""
    if low is not None and high is not None:
        allowed = f"an integer in [{low}, {high}]"
    elif low is not None:
        allowed = f"an integer >= {low}"
    elif high is not None:
        allowed = f"an integer <= {high}"
    else:
        allowed = "an integer"
    if isinstance(value, bool):
        raise ConfigError(field, value, allowed)
    try:
        x = float(value)  # type: ignore[arg-type]
    except (TypeError, ValueError, OverflowError):
        raise ConfigError(field, value, allowed) from None
    if x != x or x in (float("inf"), float("-inf")) or x != int(x):
        raise ConfigError(field, value, allowed)
    n = int(x)
    if (low is not None and n < low) or (high is not None and n > high):
        raise ConfigError(field, value, allowed)
    return n
