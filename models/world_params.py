"""Validated parameters of the world builders, with tables the command line can list.

Each builder has a frozen dataclass checked on construction (``ConfigError`` naming the field,
the value and the allowed range) and a table ``name -> ParamSpec(default, low, high, unit, doc)``
in :data:`PARAMS`; the dataclass defaults come from the table. ``from_dict`` builds one from
plain values and refuses unknown names with ``UnknownNameError``.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, fields
from typing import Any, NamedTuple

from exobench.core.errors import ConfigError, UnknownNameError, check_range
from exobench.core.pipeline import coerce_like


class ParamSpec(NamedTuple):
    """One parameter: default, bounds (None if not numeric), unit, description.

    ``low_open`` makes the low bound strict; ``choices`` lists the allowed values of a name;
    ``feeds`` names the config fields the value is handed to as it is, ``"<config>.<field>"``
    (``"lidar.range_noise_m"``), so that a scenario builds its configs from its table
    (``envs.sim.scenario``) instead of mapping each value by hand.
    """

    default: Any
    low: float | None
    high: float | None
    unit: str
    doc: str
    low_open: bool = False
    choices: tuple = ()
    feeds: tuple[str, ...] = ()


DIRECTIONS = ("up", "down")
_POS = ParamSpec((0.0, 0.0), -50.0, 50.0, "m", "")
_YAW = ParamSpec(0.0, -90.0, 90.0, "deg", "rotation of the route about the vertical (+ turns it to the left)")
_DIR = ParamSpec("up", None, None, "", "", choices=DIRECTIONS)
_WALLS = ParamSpec(False, None, None, "", "plaster walls along both sides of the route", choices=(False, True))

STAIRCASE_PARAMS: dict[str, ParamSpec] = {
    "riser_m": ParamSpec(0.162, 0.0, 0.30, "m", "riser height (rise of one step)", low_open=True),
    "tread_m": ParamSpec(0.28, 0.15, 0.60, "m", "tread depth from riser to riser (going)"),
    "n_steps": ParamSpec(4, 1, 30, "", "number of risers; the n-th tread is the landing (up) or the floor (down)"),
    "width_m": ParamSpec(1.2, 0.5, 5.0, "m", "width of the flight"),
    "nosing_m": ParamSpec(0.0, 0.0, 0.05, "m", "overhang of each tread over the riser below it"),
    "yaw_deg": _YAW,
    "position_m": _POS._replace(doc="(x, y) of the centre of the bottom edge of the first riser walked past"),
    "direction": _DIR._replace(doc="'up': start on the floor and climb; 'down': start on the top landing"),
    "landing_m": ParamSpec(1.2, 0.3, 5.0, "m", "depth of the top landing (where 'down' starts)"),
    "walls": _WALLS,
}

RAMP_PARAMS: dict[str, ParamSpec] = {
    "slope_deg": ParamSpec(4.8, 0.5, 25.0, "deg", "inclination (ADA maximum 1:12 = 4.8 deg)"),
    "length_m": ParamSpec(3.0, 0.5, 10.0, "m", "horizontal run of the ramp"),
    "width_m": ParamSpec(1.5, 0.5, 5.0, "m", "width of the ramp"),
    "yaw_deg": _YAW,
    "position_m": _POS._replace(doc="(x, y) of the centre of the edge where the ramp starts (bottom for up, top for down)"),
    "direction": _DIR._replace(doc="'up': start on the floor; 'down': start on the top landing"),
    "landing_m": ParamSpec(1.5, 0.3, 5.0, "m", "depth of the top landing (ADA: >= 1.5 m)"),
    "walls": _WALLS,
}

LEVEL_PARAMS: dict[str, ParamSpec] = {
    "size_m": ParamSpec(20.0, 2.0, 200.0, "m", "side of the square floor"),
}

# course segments: kind -> parameter table
SEGMENT_PARAMS: dict[str, dict[str, ParamSpec]] = {
    "level": {"length_m": ParamSpec(2.0, 0.2, 50.0, "m", "length of level walking")},
    "stairs": {
        "direction": _DIR._replace(doc="'up' or 'down'"),
        "n_steps": STAIRCASE_PARAMS["n_steps"]._replace(doc="number of risers"),
        "riser_m": STAIRCASE_PARAMS["riser_m"],
        "tread_m": STAIRCASE_PARAMS["tread_m"],
        "nosing_m": STAIRCASE_PARAMS["nosing_m"],
    },
    "ramp": {
        "direction": _DIR._replace(doc="'up' or 'down'"),
        "slope_deg": RAMP_PARAMS["slope_deg"],
        "length_m": RAMP_PARAMS["length_m"],
    },
}

# level -> stairs up -> level -> stairs down -> level -> ramp up -> level -> ramp down -> level
# (the locomotion-mode protocol of seeds/002: LG SA LG SD LG, LG RA LG RD LG)
DEFAULT_SEGMENTS: tuple[tuple[str, dict[str, Any]], ...] = (
    ("level", {"length_m": 1.0}),
    ("stairs", {"direction": "up", "n_steps": 4, "riser_m": 0.15, "tread_m": 0.30, "nosing_m": 0.02}),
    ("level", {"length_m": 2.0}),
    ("stairs", {"direction": "down", "n_steps": 4, "riser_m": 0.15, "tread_m": 0.30, "nosing_m": 0.02}),
    ("level", {"length_m": 2.0}),
    ("ramp", {"direction": "up", "slope_deg": 6.0, "length_m": 3.0}),
    ("level", {"length_m": 2.0}),
    ("ramp", {"direction": "down", "slope_deg": 6.0, "length_m": 3.0}),
    ("level", {"length_m": 1.0}),
)

COURSE_PARAMS: dict[str, ParamSpec] = {
    "segments": ParamSpec(DEFAULT_SEGMENTS, None, None, "",
                          "sequence of (kind, params): kinds " + ", ".join(SEGMENT_PARAMS) + "; heights accumulate"),
    "width_m": ParamSpec(1.5, 0.5, 5.0, "m", "width of the course"),
    "yaw_deg": _YAW,
    "position_m": _POS._replace(doc="(x, y) where the first segment starts (on the floor)"),
    "approach_m": ParamSpec(2.0, 0.5, 20.0, "m", "level floor before the first segment"),
    "exit_m": ParamSpec(2.0, 0.5, 20.0, "m", "level walking after the last segment"),
    "walls": _WALLS,
}


def check_param(field: str, value: Any, spec: ParamSpec) -> Any:
    """Validate and normalise one value against its spec (strings from the CLI are converted)."""
    if spec.choices:
        # the command line gives every value as a string: convert it to the type of the choices
        # (booleans in any spelling coerce_like knows) before comparing
        if isinstance(spec.default, bool) or (isinstance(value, str) and not isinstance(spec.default, str)):
            value = coerce_like(field, value, spec.default)
        if value not in spec.choices or isinstance(value, bool) != isinstance(spec.default, bool):
            raise ConfigError(field, value, "one of " + ", ".join(map(str, spec.choices)))
        return value
    if isinstance(spec.default, tuple):
        try:
            vals = tuple(value)
        except TypeError:
            raise ConfigError(field, value, f"({spec.low}..{spec.high}, {spec.low}..{spec.high})") from None
        if len(vals) != len(spec.default):
            raise ConfigError(field, value, f"{len(spec.default)} numbers")
        return tuple(check_range(field, v, spec.low, spec.high) for v in vals)
    if isinstance(value, bool):
        raise ConfigError(field, value, "a number")
    if isinstance(value, str):
        try:
            value = float(value.strip())
        except ValueError:
            raise ConfigError(field, value, "a number") from None
    x = check_range(field, value, spec.low, spec.high, low_open=spec.low_open)
    if isinstance(spec.default, int):
        if x != math.floor(x):
            raise ConfigError(field, value, f"an integer {spec.low}..{spec.high}")
        return int(x)
    return x


def validate_fields(obj: Any, table: dict[str, ParamSpec], prefix: str = "") -> None:
    """Check every field of a frozen dataclass that has a row in ``table``, in place."""
    for f in fields(obj):
        if f.name in table and f.name != "segments":
            name = f"{prefix}.{f.name}" if prefix else f.name
            object.__setattr__(obj, f.name, check_param(name, getattr(obj, f.name), table[f.name]))


def from_dict_checked(cls: type, kind: str, table: dict[str, ParamSpec], values: dict[str, Any]) -> Any:
    """``cls(**values)`` after refusing names that ``table`` does not know."""
    for k in values:
        if k not in table:
            raise UnknownNameError(f"{kind} parameter", str(k), table)
    return cls(**values)


@dataclass(frozen=True)
class StaircaseParams:
    """A straight flight of stairs; see :data:`STAIRCASE_PARAMS` for meaning, units and ranges."""

    riser_m: float = STAIRCASE_PARAMS["riser_m"].default
    tread_m: float = STAIRCASE_PARAMS["tread_m"].default
    n_steps: int = STAIRCASE_PARAMS["n_steps"].default
    width_m: float = STAIRCASE_PARAMS["width_m"].default
    nosing_m: float = STAIRCASE_PARAMS["nosing_m"].default
    yaw_deg: float = STAIRCASE_PARAMS["yaw_deg"].default
    position_m: tuple[float, float] = STAIRCASE_PARAMS["position_m"].default
    direction: str = STAIRCASE_PARAMS["direction"].default
    landing_m: float = STAIRCASE_PARAMS["landing_m"].default
    walls: bool = STAIRCASE_PARAMS["walls"].default

    def __post_init__(self) -> None:
        validate_fields(self, STAIRCASE_PARAMS, "stairs")

    @classmethod
    def from_dict(cls, values: dict[str, Any]) -> StaircaseParams:
        return from_dict_checked(cls, "staircase", STAIRCASE_PARAMS, values)

    def as_dict(self) -> dict[str, Any]:
        return asdict(self)


@dataclass(frozen=True)
class RampParams:
    """A straight ramp with a top landing; see :data:`RAMP_PARAMS`."""

    slope_deg: float = RAMP_PARAMS["slope_deg"].default
    length_m: float = RAMP_PARAMS["length_m"].default
    width_m: float = RAMP_PARAMS["width_m"].default
    yaw_deg: float = RAMP_PARAMS["yaw_deg"].default
    position_m: tuple[float, float] = RAMP_PARAMS["position_m"].default
    direction: str = RAMP_PARAMS["direction"].default
    landing_m: float = RAMP_PARAMS["landing_m"].default
    walls: bool = RAMP_PARAMS["walls"].default

    def __post_init__(self) -> None:
        validate_fields(self, RAMP_PARAMS, "ramp")

    @property
    def rise_m(self) -> float:
        return self.length_m * math.tan(math.radians(self.slope_deg))

    @classmethod
    def from_dict(cls, values: dict[str, Any]) -> RampParams:
        return from_dict_checked(cls, "ramp", RAMP_PARAMS, values)

    def as_dict(self) -> dict[str, Any]:
        return asdict(self)


@dataclass(frozen=True)
class LevelParams:
    """A level square floor; see :data:`LEVEL_PARAMS`."""

    size_m: float = LEVEL_PARAMS["size_m"].default

    def __post_init__(self) -> None:
        validate_fields(self, LEVEL_PARAMS, "level")

    @classmethod
    def from_dict(cls, values: dict[str, Any]) -> LevelParams:
        return from_dict_checked(cls, "level", LEVEL_PARAMS, values)

    def as_dict(self) -> dict[str, Any]:
        return asdict(self)


def normalise_segments(segments: Any) -> tuple[tuple[str, dict[str, Any]], ...]:
    """Validate course segments: each ``(kind, {param: value})``, missing params take defaults."""
    out = []
    try:
        items = list(segments)
    except TypeError:
        raise ConfigError("course.segments", segments, "a sequence of (kind, params) pairs") from None
    if not items:
        raise ConfigError("course.segments", segments, "at least one segment")
    for i, seg in enumerate(items):
        field = f"course.segments[{i}]"
        try:
            kind, values = seg
            values = dict(values)
        except (TypeError, ValueError):
            raise ConfigError(field, seg, "a (kind, params) pair") from None
        if kind not in SEGMENT_PARAMS:
            raise UnknownNameError("course segment kind", str(kind), SEGMENT_PARAMS)
        table = SEGMENT_PARAMS[kind]
        for k in values:
            if k not in table:
                raise UnknownNameError(f"{kind} segment parameter", k, table)
        clean = {k: check_param(f"{field}.{k}", values.get(k, s.default), s) for k, s in table.items()}
        out.append((kind, clean))
    return tuple(out)


@dataclass(frozen=True)
class CourseParams:
    """A course of level, stairs and ramp segments along +x; see :data:`COURSE_PARAMS`."""

    segments: tuple[tuple[str, dict[str, Any]], ...] = DEFAULT_SEGMENTS
    width_m: float = COURSE_PARAMS["width_m"].default
    yaw_deg: float = COURSE_PARAMS["yaw_deg"].default
    position_m: tuple[float, float] = COURSE_PARAMS["position_m"].default
    approach_m: float = COURSE_PARAMS["approach_m"].default
    exit_m: float = COURSE_PARAMS["exit_m"].default
    walls: bool = COURSE_PARAMS["walls"].default

    def __post_init__(self) -> None:
        validate_fields(self, COURSE_PARAMS, "course")
        object.__setattr__(self, "segments", normalise_segments(self.segments))

    @classmethod
    def from_dict(cls, values: dict[str, Any]) -> CourseParams:
        return from_dict_checked(cls, "course", COURSE_PARAMS, values)

    def as_dict(self) -> dict[str, Any]:
        d = asdict(self)
        d["segments"] = [[k, dict(v)] for k, v in self.segments]
        return d


PARAMS: dict[str, dict[str, ParamSpec]] = {
    "staircase": STAIRCASE_PARAMS,
    "ramp": RAMP_PARAMS,
    "course": COURSE_PARAMS,
    "level": LEVEL_PARAMS,
}
PARAM_CLASSES: dict[str, type] = {
    "staircase": StaircaseParams,
    "ramp": RampParams,
    "course": CourseParams,
    "level": LevelParams,
}
