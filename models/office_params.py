"""Validated parameters of the procedural office (:func:`exobench.models.office.build_office`).

:data:`OFFICE_PARAMS` lists every parameter as ``ParamSpec(default, low, high, unit, doc)`` for
the command line; :class:`OfficeParams` checks each value against its range and then the
combinations a building cannot have (offices narrower than their door, a meeting room longer
than the corridor, ...), raising ``ConfigError`` naming the field, the value and what fits.
Sizes follow ``docs/sensor-reference.md`` (Buildings): clear door >= 0.81 m, corridor >= 1.12 m,
glass panes 8-12 mm and 2.4-3.0 m tall. ``facade``, ``facade_glass`` and ``partition_glass``
build the thesis' window-lined setting (seeds/003 section 5.2.2; materials in
:mod:`exobench.models.materials`); their defaults build the plain office.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from typing import Any

from exobench.core.errors import ConfigError

from .world_params import ParamSpec, from_dict_checked, validate_fields

# fixed building dimensions [A: typical office construction]
WALL_T_M = 0.12  # interior partition slot (plaster stud wall; glass partitions stand in its middle)
EXT_WALL_T_M = 0.25  # exterior wall
DOOR_HEIGHT_M = 2.1  # door openings and leaves
DOOR_JAMB_M = 0.15  # wall between a door opening and the room's side wall
WOOD_LEAF_T_M = 0.04  # door leaf thickness; the open leaf narrows the opening to the clear width
GLASS_LEAF_T_M = 0.012
MULLION_M = 0.05  # aluminium profiles of glass partitions, square section
OFFICE_MIN_WIDTH_M = 2.4  # narrowest cellular office [A: a desk, a chair and a door side by side]
ROOM_DEPTH_SPARE_M = 0.6  # room depth beyond the open door leaf, to step past it

FACADES = ("plain", "windows", "curtain")
FACADE_GLASSES = ("glass", "float_glass", "lowe_glass", "igu_float", "igu_lowe")
# façade bays (bay, pier): ``windows`` are windows 1.2 m wide between 0.3 m plaster piers [A: typical
# ribbon glazing]; ``curtain`` is glazing from CURTAIN_SILL_M between slim mullions, 60 mm face width
# at 1.35 m centres (stick curtain walls: Schüco FW 50+ / FW 60+ face widths 50 / 60 mm; modules
# 1.2-1.5 m [A])
FACADE_BAYS = {"windows": (1.5, 0.3), "curtain": (1.35, 0.06)}
CURTAIN_SILL_M = 0.05

OFFICE_PARAMS: dict[str, ParamSpec] = {
    "seed": ParamSpec(0, 0, 2**31 - 1, "", "random seed of the layout (office widths, door sides, glass, floors, furniture)"),
    "n_offices": ParamSpec(6, 1, 24, "", "cellular offices along the north corridor"),
    "corridor_width_m": ParamSpec(1.8, 1.12, 4.0, "m", "clear width of every corridor (IBC 1020.2: >= 1.12 m)"),
    "corridor_length_m": ParamSpec(24.0, 8.0, 80.0, "m", "inside length of the building = length of the two long corridors"),
    "room_depth_m": ParamSpec(4.0, 1.5, 10.0, "m", "clear depth of the offices and of the meeting room"),
    "meeting_room_m": ParamSpec(6.0, 1.5, 30.0, "m", "clear length of the meeting room along the corridors"),
    "ceiling_m": ParamSpec(2.7, 2.4, 3.0, "m", "floor to ceiling; glass partitions are this tall (2.4-3.0 m)"),
    "door_width_m": ParamSpec(0.9, 0.81, 1.2, "m", "clear width of every door with its leaf open (ADA 404.2.3: >= 0.81 m)"),
    "glass_fraction": ParamSpec(0.4, 0.0, 1.0, "", "share of corridor partitions (offices and meeting room) that are glass"),
    "glass_thickness_m": ParamSpec(0.010, 0.008, 0.012, "m", "thickness of glass panes (8-12 mm)"),
    "polished_fraction": ParamSpec(0.3, 0.0, 1.0, "", "share of floor areas (rooms and corridors) with a polished floor"),
    "furniture_density": ParamSpec(0.8, 0.0, 1.0, "", "probability that each optional piece of furniture is placed (a room's desk or meeting table is there whenever > 0)"),
    "furniture_seed": ParamSpec(-1, -1, 2**31 - 1, "", "random seed of the furniture layer (-1: drawn from the "
                                "layout's seed, as the office has always been furnished)"),
    "furnish": ParamSpec("office", None, None, "", "how the rooms are furnished: office (desks, chairs, couches, "
                         "cabinets, plants, bins), lab (benches with stools, steel shelving, cabinets, a bench "
                         "island in the large room) or mixed (the rooms of the west half offices, those of the east "
                         "half labs; models.furniture_kinds)", choices=("office", "lab", "mixed")),
    "repeated_rooms": ParamSpec(0, 0, 24, "", "the first this-many offices are the same room (width, door, "
                                "partition and furniture; perceptual aliasing); 0: none, else 2..n_offices"),
    "windows": ParamSpec(True, None, None, "", "one window per office in the north facade", choices=(False, True)),
    "facade": ParamSpec("plain", None, None, "", "exterior walls along the corridors: plain; windows (a row of "
                        "windows along the south, west and east walls, as in a window-lined building); or curtain "
                        "(glazed from the floor between slim mullions, a curtain wall)",
                        choices=FACADES),
    "facade_glass": ParamSpec("glass", None, None, "", "material of the exterior windows (models.materials: glass, "
                              "float_glass: Fresnel float glass, lowe_glass: coated low-e glazing; igu_float, igu_lowe: "
                              "double-glazed units of them and a float pane)",
                              choices=FACADE_GLASSES),
    "partition_glass": ParamSpec("glass", None, None, "", "material of the glass partitions and glass door leaves "
                                 "(as facade_glass)", choices=FACADE_GLASSES),
}


@dataclass(frozen=True)
class OfficeParams:
    """An office floor: offices, two long corridors joined at both ends, a meeting room; see :data:`OFFICE_PARAMS`."""

    seed: int = OFFICE_PARAMS["seed"].default
    n_offices: int = OFFICE_PARAMS["n_offices"].default
    corridor_width_m: float = OFFICE_PARAMS["corridor_width_m"].default
    corridor_length_m: float = OFFICE_PARAMS["corridor_length_m"].default
    room_depth_m: float = OFFICE_PARAMS["room_depth_m"].default
    meeting_room_m: float = OFFICE_PARAMS["meeting_room_m"].default
    ceiling_m: float = OFFICE_PARAMS["ceiling_m"].default
    door_width_m: float = OFFICE_PARAMS["door_width_m"].default
    glass_fraction: float = OFFICE_PARAMS["glass_fraction"].default
    glass_thickness_m: float = OFFICE_PARAMS["glass_thickness_m"].default
    polished_fraction: float = OFFICE_PARAMS["polished_fraction"].default
    furniture_density: float = OFFICE_PARAMS["furniture_density"].default
    furniture_seed: int = OFFICE_PARAMS["furniture_seed"].default
    furnish: str = OFFICE_PARAMS["furnish"].default
    repeated_rooms: int = OFFICE_PARAMS["repeated_rooms"].default
    windows: bool = OFFICE_PARAMS["windows"].default
    facade: str = OFFICE_PARAMS["facade"].default
    facade_glass: str = OFFICE_PARAMS["facade_glass"].default
    partition_glass: str = OFFICE_PARAMS["partition_glass"].default

    def __post_init__(self) -> None:
        validate_fields(self, OFFICE_PARAMS, "office")
        self._check_fit()

    @property
    def door_opening_m(self) -> float:
        """Width of a door opening: the clear width plus the thickest (wooden) open leaf."""
        return self.door_width_m + WOOD_LEAF_T_M

    @property
    def office_min_width_m(self) -> float:
        return max(OFFICE_MIN_WIDTH_M, self.door_opening_m + 2 * DOOR_JAMB_M)

    def _check_fit(self) -> None:
        W, X, n = self.corridor_width_m, self.corridor_length_m, self.n_offices
        swing = self.door_opening_m + ROOM_DEPTH_SPARE_M
        if self.room_depth_m < swing:
            raise ConfigError("office.door_width_m", self.door_width_m,
                              f"<= {self.room_depth_m - ROOM_DEPTH_SPARE_M - WOOD_LEAF_T_M:.3f} m: the open leaf "
                              f"({self.door_opening_m:.3f} m) plus {ROOM_DEPTH_SPARE_M} m must fit in room_depth_m = {self.room_depth_m} m")
        need_m = 2 * DOOR_JAMB_M + self.door_opening_m + WOOD_LEAF_T_M
        if self.meeting_room_m < need_m:
            raise ConfigError("office.meeting_room_m", self.meeting_room_m,
                              f">= {need_m:.3f} m (its two doors, hinged on opposite jambs, and {DOOR_JAMB_M} m of wall "
                              f"each side)")
        need_x = n * self.office_min_width_m + (n - 1) * WALL_T_M
        if X < need_x:
            raise ConfigError("office.corridor_length_m", X,
                              f">= {need_x:.3f} m for {n} offices at least {self.office_min_width_m:.2f} m wide "
                              f"with {WALL_T_M} m walls between them")
        if self.repeated_rooms and not 2 <= self.repeated_rooms <= n:
            raise ConfigError("office.repeated_rooms", self.repeated_rooms, f"0 or 2..n_offices ({n})")
        max_meeting = X - 2 * W - 2 * WALL_T_M
        if self.meeting_room_m > max_meeting:
            raise ConfigError("office.meeting_room_m", self.meeting_room_m,
                              f"<= {max_meeting:.3f} m (corridor_length_m - 2 corridor_width_m - 2 walls: the "
                              f"meeting room and the core sit between the two cross corridors)")

    @classmethod
    def from_dict(cls, values: dict[str, Any]) -> OfficeParams:
        return from_dict_checked(cls, "office", OFFICE_PARAMS, values)

    def as_dict(self) -> dict[str, Any]:
        # left out at 0, so the scene truth of every office without repeated rooms stays as it was
        out = asdict(self)
        if not self.repeated_rooms:
            del out["repeated_rooms"]
        return out

