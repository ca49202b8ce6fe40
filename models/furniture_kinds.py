"""What furnishes a room (office or lab), lab pieces and corridor obstacles (numpy only).

:func:`room_candidates` lists, for a room of the procedural office, the groups tried in order
(the first is the room's main piece); ``furnish="office"`` is the office as it has always been
(same draws in the same order, so a layout's seed gives the same furniture), ``furnish="lab"``
re-furnishes the same building as a laboratory, the paper's mixed office-and-lab setting
(seeds/000 IV, the *Exo* set): benches along the walls with stools, steel shelving, cabinets,
and a free-standing bench island in the large room. Sizes [A: typical catalogue sizes]: lab
benches 0.90 m high (standing work), 1.5-3.0 x 0.75 m; steel shelving 0.9-1.2 x 0.45 m,
1.8-2.0 m tall with four or five shelves; lab stools 0.35 m wide, seat 0.60-0.65 m.

Corridor obstacles (the paper's Exp D: obstacles appear in a corridor and the planner goes
round): a trolley (0.9 x 0.6 m, 0.9 m high) and a stack of cardboard boxes (0.4-0.6 m each).

:data:`MAKERS` draws any class's piece from a generator: a change script names an added piece
by class and ``variant`` (the seed of its sizes), so the same script always adds the same piece.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from .office_furniture import (
    CHAIR_GAP_M,
    Group,
    Part,
    Piece,
    _box,
    _legs,
    cabinet,
    chair,
    couch,
    desk,
    meeting_table,
    plant,
    single,
    waste_bin,
    workstation,
)

FURNISHINGS = ("office", "lab", "mixed")  # mixed: resolved per room by the layout
LAB_CLASSES = ("bench", "shelf", "stool")
OBSTACLE_CLASSES = ("trolley", "boxes")
STOOL_W_M = 0.35


def bench(rng: np.random.Generator) -> Piece:
    """A lab bench: a 30 mm top on four 60 mm steel legs, a shelf rail 0.15 m above the floor."""
    w = float(rng.choice([1.5, 1.8, 2.4, 3.0]))
    d, h, top_t = 0.75, 0.90, 0.03
    parts = [_box("top", -w / 2, w / 2, -d / 2, d / 2, h - top_t, h, "wood", "office_wood"),
             _box("rail", -w / 2 + 0.06, w / 2 - 0.06, -d / 2 + 0.06, d / 2 - 0.06, 0.13, 0.15, "metal", "office_metal")]
    parts += _legs(w / 2, d / 2, 0.06, h - top_t)
    return Piece("bench", (w, d, h), tuple(parts))


def shelf(rng: np.random.Generator) -> Piece:
    """Steel shelving: four corner posts and four or five shelves, open at the front and sides."""
    w = float(rng.choice([0.9, 1.0, 1.2]))
    d, h = 0.45, float(rng.choice([1.8, 2.0]))
    n = int(rng.choice([4, 5]))
    parts = _legs(w / 2, d / 2, 0.035, h)
    for i in range(n):
        z = 0.10 + i * (h - 0.15) / (n - 1)
        parts.append(_box(f"shelf{i}", -w / 2 + 0.035, w / 2 - 0.035, -d / 2, d / 2, z, z + 0.02, "metal", "office_metal"))
    return Piece("shelf", (w, d, h), tuple(parts))


def stool(rng: np.random.Generator) -> Piece:
    """A lab stool: a round seat (cylinder) on a steel column."""
    sh = float(rng.choice([0.60, 0.62, 0.65]))
    r = STOOL_W_M / 2
    parts = (Part("seat", "cylinder", (0.0, 0.0, sh - 0.04), (r, r, 0.04), "fabric", "office_fabric"),
             Part("column", "cylinder", (0.0, 0.0, (sh - 0.08) / 2), (0.03, 0.03, (sh - 0.08) / 2), "metal", "office_metal"))
    return Piece("stool", (STOOL_W_M, STOOL_W_M, sh), parts)


def trolley(rng: np.random.Generator) -> Piece:
    """A service trolley: two steel trays on four posts, 0.9 m high."""
    w, d = float(rng.choice([0.8, 0.9])), float(rng.choice([0.5, 0.6]))
    parts = _legs(w / 2, d / 2, 0.03, 0.9)
    parts += [_box("tray0", -w / 2 + 0.03, w / 2 - 0.03, -d / 2, d / 2, 0.15, 0.18, "metal", "office_metal"),
              _box("tray1", -w / 2 + 0.03, w / 2 - 0.03, -d / 2, d / 2, 0.87, 0.90, "metal", "office_metal")]
    return Piece("trolley", (w, d, 0.9), tuple(parts))


def boxes(rng: np.random.Generator) -> Piece:
    """A stack of two or three cardboard boxes (LiDAR: as wood), each on the one below."""
    w = float(rng.choice([0.4, 0.5, 0.6]))
    d = float(rng.choice([0.4, 0.5]))
    parts, z = [], 0.0
    for i in range(int(rng.choice([2, 3]))):
        h = float(rng.choice([0.3, 0.4]))
        s = 1.0 - 0.1 * i  # each box a little smaller than the one it stands on
        parts.append(_box(f"box{i}", -s * w / 2, s * w / 2, -s * d / 2, s * d / 2, z, z + h, "wood", "office_wood"))
        z += h
    return Piece("boxes", (w, d, z), tuple(parts))


MAKERS: dict[str, Callable[[np.random.Generator], Piece]] = {
    "desk": desk, "chair": chair, "couch": couch, "cabinet": cabinet, "plant": plant, "bin": waste_bin,
    "bench": bench, "shelf": shelf, "stool": stool, "trolley": trolley, "boxes": boxes,
}  # fmt: skip


def bench_station(rng: np.random.Generator) -> Group:
    """A bench against the wall and a stool in front of it."""
    b, s = bench(rng), stool(rng)
    w, d = b.size[0], b.size[1] + CHAIR_GAP_M + STOOL_W_M
    return Group(((b, (0.0, -d / 2 + b.size[1] / 2), 0), (s, (0.0, d / 2 - STOOL_W_M / 2), 2)), (w, d))


def bench_island(rng: np.random.Generator) -> Group:
    """Two benches back to back, free-standing, with a stool on each long side."""
    a = bench(rng)
    b = Piece("bench", a.size, a.parts)
    w, dd = a.size[0], a.size[1]
    d = 2 * dd + 2 * (CHAIR_GAP_M + STOOL_W_M)
    members: list[tuple[Piece, tuple[float, float], int]] = [(a, (0.0, -dd / 2), 2), (b, (0.0, dd / 2), 0)]
    for side, k in ((1.0, 2), (-1.0, 0)):
        members.append((stool(rng), (0.0, side * (d / 2 - STOOL_W_M / 2)), k))
    return Group(tuple(members), (w, d))


Candidate = tuple[Callable[[np.random.Generator], Group], bool]


def room_candidates(furnish: str, kind: str, room: tuple[float, float, float, float]) -> list[Candidate]:
    """Groups tried in a room, in order, each with whether it goes against a wall."""
    area = (room[1] - room[0]) * (room[3] - room[2])
    if furnish == "lab":
        if kind == "office":
            cands: list[Candidate] = [(bench_station, True)]
            if room[1] - room[0] >= 3.6:
                cands.append((bench_station, True))
            cands += [(lambda g: single(shelf(g)), True), (lambda g: single(shelf(g)), True),
                      (lambda g: single(cabinet(g)), True), (lambda g: single(waste_bin(g)), True)]
            return cands
        return [(bench_island, False), (lambda g: single(shelf(g)), True), (lambda g: single(shelf(g)), True),
                (lambda g: single(shelf(g)), True), (lambda g: single(cabinet(g)), True),
                (lambda g: single(waste_bin(g)), True)]
    if kind == "office":
        cands = [(workstation, True)]
        if room[1] - room[0] >= 3.6:
            cands.append((workstation, True))
        if area >= 16.0:
            cands.append((lambda g: single(couch(g)), True))
        cands += [(lambda g: single(cabinet(g)), True), (lambda g: single(cabinet(g)), True),
                  (lambda g: single(plant(g)), True), (lambda g: single(waste_bin(g)), True)]
        return cands
    return [(meeting_table, False), (lambda g: single(couch(g)), True), (lambda g: single(cabinet(g)), True),
            (lambda g: single(plant(g)), True), (lambda g: single(plant(g)), True),
            (lambda g: single(waste_bin(g)), True)]


__all__ = ["FURNISHINGS", "LAB_CLASSES", "MAKERS", "OBSTACLE_CLASSES", "room_candidates", "bench", "shelf", "stool",
           "trolley", "boxes", "chair"]
