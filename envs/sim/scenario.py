"""Scenario dataclasses generated from their parameter tables.

A scenario's parameters are listed once, in a table ``name -> ParamSpec(default, low, high, unit,
doc)`` (the command line lists it and sets values from it). :func:`scenario_base` turns the table
into a frozen dataclass whose fields are the table's rows, in order, with their defaults; values
are validated on construction (``ConfigError(field, value, allowed)``; a parameter whose default
is None also takes None; a free string parameter takes any string and is checked by the
scenario). ``from_dict`` refuses unknown names (``UnknownNameError``) and converts strings;
``as_dict`` gives the plain values (a scenario leaves out the parameters of :data:`OMIT_AT_DEFAULT`
at their neutral value, so that records of scenarios without them are unchanged).

``check_composition`` checks what can be known of an episode without building its world: the
rig it records (presets added, ids unique, sensor configs valid) calibrated on the user's
exoskeleton; a scenario extends it with its world's parameters. :func:`check_scenario` runs it
once per distinct scenario, so a run's plan checks every episode before anything simulates.
"""

from __future__ import annotations

import dataclasses
import functools
from typing import Any

from exobench.core import ConfigError
from exobench.models.world_params import ParamSpec, check_param, from_dict_checked

from .rig import preset_names, with_segmentation_truth

# parameter -> its neutral value, at which as_dict leaves it out: options added after records
# existed (a rig's extra sensors, segmentation truth, what visual-inertial odometry meets)
OMIT_AT_DEFAULT: dict[str, Any] = {
    "extra_sensors": "", "segmentation_truth": False, "heel_strike_scale": 0.0, "imu_extrinsics": "identity",
    "imu_time_offset_s": 0.0, "surfaces": "default", "light_level": 1.0, "texture_seed": 0, "exposure_s": 0.0,
    # the office's furniture layer and its change scripts (models.office_changes), region routes
    "furniture_seed": -1, "furnish": "office", "repeated_rooms": 0, "day": 0, "changes": "", "change_seed": -1, "route_regions": "",
}  # fmt: skip


def _is_free_string(spec: ParamSpec) -> bool:
    return isinstance(spec.default, str) and not spec.choices


def scenario_base(name: str, kind: str, params: dict[str, ParamSpec], base: type | None = None) -> type:
    """A frozen dataclass over ``params`` (see the module docstring); subclass it to add methods.

    With ``base`` (a scenario class) the new class extends it: ``params`` is its whole table (the
    base's rows, some perhaps with other ranges, and its own), and it keeps the base's methods.
    """

    def __post_init__(self: Any) -> None:
        for f in dataclasses.fields(self):
            spec = params.get(f.name)
            if spec is None:
                continue
            v = getattr(self, f.name)
            if v is None and spec.default is None:
                continue
            if _is_free_string(spec):
                if not isinstance(v, str):
                    raise ConfigError(f.name, v, "a string")
                if f.name == "extra_sensors":
                    preset_names(v)
                continue
            object.__setattr__(self, f.name, check_param(f.name, v, spec))

    @classmethod  # type: ignore[misc]
    def from_dict(cls: type, values: dict[str, Any]) -> Any:
        """Validated scenario from plain values (strings are converted); unknown names refused."""
        values = dict(values)
        for k, spec in params.items():
            v = values.get(k)
            if spec.default is None and isinstance(v, str) and v.strip().lower() in ("none", "null", ""):
                values[k] = None
        return from_dict_checked(cls, f"{kind} scenario", params, values)

    def as_dict(self: Any) -> dict[str, Any]:
        d = dataclasses.asdict(self)
        for k, neutral in OMIT_AT_DEFAULT.items():
            if k in d and d[k] == neutral and type(d[k]) is type(neutral):
                del d[k]
        return d

    def configured(self: Any, config: str, cls: type, **by_hand: Any) -> Any:
        """``cls`` built from the rows that feed ``config`` (``ParamSpec.feeds``) and ``by_hand``
        (the values a scenario derives itself)."""
        fed = {t.partition(".")[2]: getattr(self, n) for n, spec in params.items() for t in spec.feeds
               if t.partition(".")[0] == config}  # fmt: skip
        return cls(**fed, **by_hand)

    def check_composition(self: Any) -> None:
        """Compose the rig this scenario records and calibrate it on its user's device (no world is
        built): an impossible rig raises ``ConfigError`` here, not in the simulation."""
        from .calibration import build_calibration

        rig = self.rig()
        if getattr(self, "segmentation_truth", False):
            if not any(s.kind == "rgbd" for s in rig):  # it would be ignored
                raise ConfigError("segmentation_truth", True, "false on a rig without an RGB-D camera (add one: "
                                  "extra_sensors=rgbd_head, rgbd_chest or rgbd_thigh)")  # fmt: skip
            rig = with_segmentation_truth(rig)
        build_calibration(self.exo_spec(), rig)

    def _type(spec: ParamSpec) -> Any:
        return Any if spec.default is None else type(spec.default)

    fields = [(n, _type(s), dataclasses.field(default=s.default)) for n, s in params.items()]
    ns = {"__post_init__": __post_init__, "from_dict": from_dict, "as_dict": as_dict, "PARAMS": params,
          "configured": configured, "__doc__": f"One {kind} episode; see ``PARAMS`` for units, ranges and meaning."}  # fmt: skip
    if base is None:  # an extension keeps its base's checks (a world adds its own to this one)
        ns["check_composition"] = check_composition
    return dataclasses.make_dataclass(name, fields, bases=(base,) if base else (), frozen=True, namespace=ns)


@functools.lru_cache(maxsize=512)
def check_scenario(scenario: Any) -> None:
    """``scenario.check_composition()``, once per distinct (frozen, hashable) scenario: a suite's
    cases repeat over the run seeds, and a plan checks every episode."""
    scenario.check_composition()
