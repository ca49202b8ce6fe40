"""Typed errors of exobench.

Library code raises these; only the command line turns them into a one-line message and a
non-zero exit. Every error names the field, the value and what would have been allowed, in at
most a line or two: a long value is cut (:data:`MAX_VALUE_CHARS`), and of many valid names the
closest to the one given come first and at most :data:`MAX_NAMES_SHOWN` are listed, with a count.
"""

from __future__ import annotations

import difflib
from collections.abc import Iterable

MAX_VALUE_CHARS = 80
MAX_NAMES_SHOWN = 10


def short_text(text: str, limit: int = MAX_VALUE_CHARS) -> str:
    """``text`` cut to ``limit`` characters with "..." and its full length when longer."""
    return text if len(text) <= limit else f"{text[: limit - 3]}... ({len(text)} chars)"


def short_repr(value: object, limit: int = MAX_VALUE_CHARS) -> str:
    """``repr(value)`` cut as :func:`short_text` does."""
    return short_text(repr(value), limit)


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
        super().__init__(f"{field}={short_repr(value)} is invalid; allowed: {short_text(str(allowed), 300)}")


class ChangeScriptError(ConfigError):
    """A world's change script cannot be applied: an object moved into a wall or another object,
    one removed or moved that does not exist, an obstacle that closes a corridor. Refused before
    anything runs; ``day`` and ``object_id`` name the change, ``field`` is
    ``"changes.day<d>.<object_id>"``."""

    def __init__(self, day: int, object_id: str, problem: str) -> None:
        self.day = int(day)
        self.object_id = str(object_id)
        self.problem = problem
        ExobenchError.__init__(self, f"change script, day {self.day}, object {short_repr(self.object_id)}: {short_text(problem, 300)}")
        self.field = f"changes.day{self.day}.{self.object_id}"
        self.value = self.object_id
        self.allowed = problem


class UnknownNameError(ExobenchError, KeyError):
    """A name (suite, track, pipeline, parameter, sensor, ...) is not known.

    The message lists the valid names so the user can correct the call; of more than
    :data:`MAX_NAMES_SHOWN`, the closest to ``name`` come first and the list is cut with a count
    (``valid`` keeps them all).
    """

    def __init__(self, kind: str, name: str, valid: Iterable[str]) -> None:
        self.kind = kind
        self.name = name
        self.valid = tuple(sorted(str(v) for v in valid))
        super().__init__(name)

    def __str__(self) -> str:
        shown = list(self.valid)
        if len(shown) > MAX_NAMES_SHOWN:
            close = difflib.get_close_matches(str(self.name), shown, n=3)
            shown = (close + [v for v in shown if v not in close])[:MAX_NAMES_SHOWN]
        listed = ", ".join(short_text(v, 40) for v in shown) or "(none)"
        more = f", ... ({len(self.valid)} in all)" if len(self.valid) > len(shown) else ""
        return f"unknown {self.kind} {short_repr(self.name)}; valid: {listed}{more}"


class FrameTypeError(ExobenchError, TypeError):
    """A pipeline was given something that is not a sensor frame.

    Attributes:
        received: name of the type received, e.g. ``"dict"``.
        accepted: names of the frame types a pipeline accepts.
    """

    def __init__(self, received: object, accepted: Iterable[str]) -> None:
        self.received = type(received).__name__
        self.accepted = tuple(accepted)
        super().__init__(f"process() takes a sensor frame, got {self.received}; accepted: {', '.join(self.accepted)}")


class PipelineStateError(ExobenchError, RuntimeError):
    """A pipeline method was called out of order (``process`` or ``finalize`` before ``reset``)."""

    def __init__(self, pipeline: str, method: str, needs: str = "reset()") -> None:
        self.pipeline = pipeline
        self.method = method
        super().__init__(f"{pipeline}: {method} called before {needs}")


class SessionError(ExobenchError):
    """A recorded session on disk is missing, malformed or of an unsupported version."""


class FolderError(ExobenchError):
    """A folder exobench writes or reads back (a run folder, a session being recorded) is
    damaged, in use by another exobench process, or cannot be written (read-only, disk full).
    The message starts with the path of the file or folder at fault."""


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
