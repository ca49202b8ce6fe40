"""The furniture layer's mixed office-and-lab furnishing and repeated rooms (issue 28), and the
floors of `textured_floors`: each against what it promises, and neither changes an office that
does not ask for it (the digests of tests/models/test_office_changes.py cover that to the bit)."""

import numpy as np
import pytest

from exobench.core.errors import ConfigError
from exobench.models.furniture_kinds import LAB_CLASSES
from exobench.models.office import build_office
from exobench.models.office_layout import build_layout
from exobench.models.office_params import OfficeParams
from exobench.models.vision_look import texture_images

OFFICE_ONLY = {"desk", "chair", "couch", "plant", "meeting_table"}


def _rooms(layout):
    return {r["name"]: r for r in layout.regions if r["kind"] != "corridor"}


def test_mixed_furnishes_the_west_half_as_offices_and_the_east_half_as_labs():
    p = OfficeParams(furnish="mixed")
    layout = build_layout(p)
    rooms = _rooms(layout)
    east = {n for n, r in rooms.items() if r["clear"][0] + r["clear"][1] > p.corridor_length_m}
    assert east and east != set(rooms)
    for name in rooms:
        classes = {q.piece.cls for q in layout.furniture if q.room == name}
        if name in east:
            assert classes & set(LAB_CLASSES) and not classes & OFFICE_ONLY, (name, classes)
        else:
            assert not classes & set(LAB_CLASSES), (name, classes)
    # the same building as the office and the lab of its seed
    office = build_layout(OfficeParams())
    assert layout.solids[: layout.n_static] == office.solids[: office.n_static]


def _relative(layout, room, x0):
    return sorted((repr(q.piece), q.k, round(q.x - x0, 9), round(q.y, 9)) for q in layout.furniture if q.room == room)


def test_repeated_rooms_are_one_room_repeated():
    p = OfficeParams(seed=5, repeated_rooms=3)
    layout = build_layout(p)
    rooms = _rooms(layout)
    x0 = [rooms[f"office{k}"]["clear"][0] for k in range(4)]
    widths = [rooms[f"office{k}"]["clear"][1] - x for k, x in enumerate(x0)]
    assert widths[0] == pytest.approx(widths[1]) == pytest.approx(widths[2])
    first = _relative(layout, "office0", x0[0])
    assert first and _relative(layout, "office1", x0[1]) == first == _relative(layout, "office2", x0[2])
    assert _relative(layout, "office3", x0[3]) != first
    # each copy has identities of its own, and the partitions and doors are the same relative to the room
    ids = [q.id for q in layout.furniture]
    assert len(ids) == len(set(ids))
    solids = {s.name: s for s in layout.solids}

    def door(k):
        return [round(s.centre[0] - x0[k], 9) for n, s in solids.items() if n.startswith(f"wall_office{k}")]

    assert door(0) == door(1) == door(2)
    # the building compiles and its truth says so; without the option the truth has no such key
    assert build_office(p).truth.params["repeated_rooms"] == 3
    assert "repeated_rooms" not in build_office(OfficeParams()).truth.params


@pytest.mark.parametrize("value", [1, 7, -1])
def test_repeated_rooms_refused_outside_its_range(value):
    with pytest.raises(ConfigError, match="repeated_rooms"):
        OfficeParams(n_offices=6, repeated_rooms=value)


def test_textured_floors_carpet_the_plain_floors_and_keep_the_rest():
    plain, floors = texture_images(3, "textured"), texture_images(3, "textured_floors")
    assert set(floors) == set(plain) | {"world_floor", "office_polished"}
    for mat in plain:  # the textured look's own images are the same
        np.testing.assert_array_equal(floors[mat][0], plain[mat][0])
    img, metres = floors["world_floor"]
    assert metres == 8.0 and img.shape[0] == 2048
    # no repeat within the 8 m: the two halves of the corridor's carpet differ
    assert np.mean(img[:, :1024] != img[:, 1024:]) > 0.5
