"""Office furniture as axis-aligned primitives, and its placement in a room (numpy only).

A piece of furniture is built in its own frame: origin on the floor at the centre of its
footprint, x along its width, y from its back (the side that goes against a wall) to its front,
z up. It is turned by a multiple of 90 deg about z, so every box stays axis-aligned in the
world and every face is exact. Sizes follow ``docs/sensor-reference.md`` (Buildings): desks
0.73-0.76 m high and 1.2-1.8 x 0.6-0.9 m, chair seats 0.40-0.45 m, 3-seat sofas 1.8-2.2 x
0.8-1.0 m; the rest are [A] typical catalogue sizes (cabinets 0.8 x 0.45 m, 0.75/1.2/1.9 m
tall; plant pots 0.30-0.40 m wide, 0.35 m tall; bins 0.30-0.36 m wide).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

# exact rotations by k * 90 deg about z: (cos, sin)
_CS = ((1, 0), (0, 1), (-1, 0), (0, -1))
CLASSES = ("desk", "chair", "couch", "cabinet", "plant", "bin")
GAP_M = 0.02  # furniture never touches a wall or another piece


@dataclass(frozen=True)
class Solid:
    """A world geom: ``shape`` box (half sizes), cylinder (r, r, half height), sphere (r, r, r) or
    plane (half x, half y, 0; ``up`` False faces down); axis-aligned, centred at ``centre``.

    ``material`` is its LiDAR material (:mod:`exobench.models.materials`), ``look`` its MuJoCo
    material, ``kind`` the surface kind of its faces.
    """

    name: str
    shape: str
    centre: tuple[float, float, float]
    half: tuple[float, float, float]
    material: str
    look: str
    kind: str
    up: bool = True

    @property
    def lo(self) -> np.ndarray:
        return np.asarray(self.centre) - np.asarray(self.half)

    @property
    def hi(self) -> np.ndarray:
        return np.asarray(self.centre) + np.asarray(self.half)

    def as_dict(self) -> dict:
        return {"name": self.name, "shape": self.shape, "centre": list(self.centre), "half": list(self.half),
                "material": self.material, "kind": self.kind, "up": self.up}


@dataclass(frozen=True)
class Part:
    """One primitive of a piece, in the piece's frame."""

    suffix: str
    shape: str
    centre: tuple[float, float, float]
    half: tuple[float, float, float]
    material: str
    look: str


@dataclass(frozen=True)
class Piece:
    """A piece of furniture in its own frame: class, (width, depth, height), parts."""

    cls: str
    size: tuple[float, float, float]
    parts: tuple[Part, ...]


def _box(suffix: str, x0: float, x1: float, y0: float, y1: float, z0: float, z1: float, material: str, look: str) -> Part:
    return Part(suffix, "box", (0.5 * (x0 + x1), 0.5 * (y0 + y1), 0.5 * (z0 + z1)),
                (0.5 * (x1 - x0), 0.5 * (y1 - y0), 0.5 * (z1 - z0)), material, look)


def _legs(hx: float, hy: float, side: float, z1: float, look: str = "office_metal") -> list[Part]:
    out = []
    for i, (sx, sy) in enumerate(((-1, -1), (1, -1), (1, 1), (-1, 1))):
        cx, cy = sx * (hx - side / 2), sy * (hy - side / 2)
        out.append(_box(f"leg{i}", cx - side / 2, cx + side / 2, cy - side / 2, cy + side / 2, 0.0, z1, "metal", look))
    return out


def desk(rng: np.random.Generator) -> Piece:
    """A desk: a 25 mm wooden top on four 50 mm metal legs."""
    w = float(rng.choice([1.2, 1.4, 1.6, 1.8]))
    d = float(rng.choice([0.6, 0.7, 0.8, 0.9]))
    h = float(rng.choice([0.73, 0.74, 0.75, 0.76]))
    top_t = 0.025
    parts = [_box("top", -w / 2, w / 2, -d / 2, d / 2, h - top_t, h, "wood", "office_wood")]
    parts += _legs(w / 2 - 0.03, d / 2 - 0.03, 0.05, h - top_t)
    return Piece("desk", (w, d, h), tuple(parts))


CHAIR_W_M = 0.46


def chair(rng: np.random.Generator) -> Piece:
    """A chair facing +y: fabric seat on four metal legs, a backrest along its back edge."""
    sh = float(rng.choice([0.40, 0.42, 0.43, 0.45]))
    hw, seat_t, back_t, back_h = CHAIR_W_M / 2, 0.06, 0.04, 0.42
    parts = [_box("seat", -hw, hw, -hw, hw, sh - seat_t, sh, "fabric", "office_fabric"),
             _box("back", -hw + 0.01, hw - 0.01, -hw, -hw + back_t, sh, sh + back_h, "fabric", "office_fabric")]
    parts += _legs(hw - 0.02, hw - 0.02, 0.03, sh - seat_t)
    return Piece("chair", (CHAIR_W_M, CHAIR_W_M, sh + back_h), tuple(parts))


def couch(rng: np.random.Generator) -> Piece:
    """A three-seat sofa: back, two arms and a seat block, all fabric."""
    w = float(rng.choice([1.8, 1.9, 2.0, 2.2]))
    d = float(rng.choice([0.8, 0.9, 1.0]))
    back_d, arm_w, arm_h, seat_h, back_h = 0.2, 0.15, 0.6, 0.42, 0.8
    y0 = -d / 2 + back_d
    parts = (_box("back", -w / 2, w / 2, -d / 2, y0, 0.0, back_h, "fabric", "office_fabric"),
             _box("arm0", -w / 2, -w / 2 + arm_w, y0, d / 2, 0.0, arm_h, "fabric", "office_fabric"),
             _box("arm1", w / 2 - arm_w, w / 2, y0, d / 2, 0.0, arm_h, "fabric", "office_fabric"),
             _box("seat", -w / 2 + arm_w, w / 2 - arm_w, y0, d / 2, 0.0, seat_h, "fabric", "office_fabric"))
    return Piece("couch", (w, d, back_h), parts)


def cabinet(rng: np.random.Generator) -> Piece:
    """A closed wooden cabinet, low, medium or tall."""
    w, d, h = 0.8, 0.45, float(rng.choice([0.75, 1.2, 1.9]))
    return Piece("cabinet", (w, d, h), (_box("body", -w / 2, w / 2, -d / 2, d / 2, 0.0, h, "wood", "office_wood"),))


def plant(rng: np.random.Generator) -> Piece:
    """A potted plant: a ceramic cylinder pot and a sphere of foliage resting in it."""
    r_pot, h_pot = float(rng.choice([0.15, 0.175, 0.2])), 0.35
    r_leaf = float(rng.choice([0.25, 0.3, 0.35]))
    z_leaf = h_pot + 0.8 * r_leaf
    parts = (Part("pot", "cylinder", (0.0, 0.0, h_pot / 2), (r_pot, r_pot, h_pot / 2), "concrete", "world_concrete"),
             Part("foliage", "sphere", (0.0, 0.0, z_leaf), (r_leaf, r_leaf, r_leaf), "plant", "office_plant"))
    return Piece("plant", (2 * r_leaf, 2 * r_leaf, z_leaf + r_leaf), parts)


def waste_bin(rng: np.random.Generator) -> Piece:
    """A metal waste-paper bin (cylinder)."""
    r, h = float(rng.choice([0.15, 0.165, 0.18])), float(rng.choice([0.35, 0.4, 0.45]))
    return Piece("bin", (2 * r, 2 * r, h), (Part("body", "cylinder", (0.0, 0.0, h / 2), (r, r, h / 2), "metal", "office_metal"),))


@dataclass(frozen=True)
class Group:
    """Pieces placed together (a desk and its chair): each with its offset (x, y) and turn k * 90 deg
    in the group's frame, and the group's footprint (width, depth)."""

    members: tuple[tuple[Piece, tuple[float, float], int], ...]
    footprint: tuple[float, float]


CHAIR_GAP_M = 0.15  # chair pulled out this far from the desk edge


def workstation(rng: np.random.Generator) -> Group:
    """A desk against the wall and its chair in front of it, facing the desk."""
    dk, ch = desk(rng), chair(rng)
    w, d = dk.size[0], dk.size[1] + CHAIR_GAP_M + CHAIR_W_M
    return Group(((dk, (0.0, -d / 2 + dk.size[1] / 2), 0), (ch, (0.0, d / 2 - CHAIR_W_M / 2), 2)), (w, d))


def meeting_table(rng: np.random.Generator) -> Group:
    """Two desks back to back with chairs along both long sides (free-standing)."""
    a = desk(rng)
    b = Piece("desk", a.size, a.parts)  # same model twice, as in a real meeting room
    w, dd = a.size[0], a.size[1]
    d = 2 * dd + 2 * (CHAIR_GAP_M + CHAIR_W_M)
    members: list[tuple[Piece, tuple[float, float], int]] = [(a, (0.0, -dd / 2), 2), (b, (0.0, dd / 2), 0)]
    xs = (-w / 4, w / 4) if w >= 1.4 else (0.0,)
    for side, k in ((1.0, 2), (-1.0, 0)):
        for x in xs:
            members.append((chair(rng), (x, side * (d / 2 - CHAIR_W_M / 2)), k))
    return Group(tuple(members), (w, d))


def single(piece: Piece) -> Group:
    return Group(((piece, (0.0, 0.0), 0),), (piece.size[0], piece.size[1]))


def rotate_xy(k: int, x: float, y: float) -> tuple[float, float]:
    c, s = _CS[k % 4]
    return c * x - s * y, s * x + c * y


def T_world(k: int, x: float, y: float) -> list[list[float]]:
    """4x4 pose (nested lists) of a frame turned by k * 90 deg about z, at (x, y, 0)."""
    c, s = _CS[k % 4]
    return [[float(c), float(-s), 0.0, x], [float(s), float(c), 0.0, y], [0.0, 0.0, 1.0, 0.0], [0.0, 0.0, 0.0, 1.0]]


def place_piece(piece: Piece, name: str, k: int, x: float, y: float, kind: str = "furniture") -> tuple[list[Solid], dict]:
    """World solids and the truth object of ``piece`` turned by k * 90 deg with its origin at (x, y)."""
    solids = []
    for p in piece.parts:
        dx, dy = rotate_xy(k, p.centre[0], p.centre[1])
        hx, hy, hz = p.half
        if k % 2:
            hx, hy = hy, hx
        solids.append(Solid(f"{name}_{p.suffix}", p.shape, (x + dx, y + dy, p.centre[2]), (hx, hy, hz), p.material, p.look, kind))
    obj = {"name": name, "class": piece.cls, "T_world_object": T_world(k, x, y), "size_m": list(piece.size),
           "geom_names": [s.name for s in solids]}
    return solids, obj


Rect = tuple[float, float, float, float]  # x0, x1, y0, y1


@dataclass(frozen=True)
class Placed:
    """A piece of furniture standing in the office: its identity ``id`` (the name it got when the
    office was furnished, or the one a change script gave it; its geoms are ``<id>_<part>``), the
    piece, its turn k * 90 deg and origin (x, y), and the region it stands in."""

    id: str
    piece: Piece
    k: int
    x: float
    y: float
    room: str

    def emit(self) -> tuple[list[Solid], dict]:
        solids, obj = place_piece(self.piece, self.id, self.k, self.x, self.y)
        obj["room"] = self.room
        return solids, obj


def overlaps(a: Rect, b: Rect, margin: float = 0.0) -> bool:
    return a[0] < b[1] + margin and b[0] < a[1] + margin and a[2] < b[3] + margin and b[2] < a[3] + margin


def _wall_pose(room: Rect, side: str, w: float, d: float, along: float) -> tuple[int, float, float]:
    """Turn and centre of a footprint (w along the wall, d deep) backed against ``side`` of the room."""
    x0, x1, y0, y1 = room
    if side == "S":
        return 0, along, y0 + GAP_M + d / 2
    if side == "N":
        return 2, along, y1 - GAP_M - d / 2
    if side == "W":
        return 3, x0 + GAP_M + d / 2, along
    return 1, x1 - GAP_M - d / 2, along


def footprint_rect(k: int, x: float, y: float, w: float, d: float) -> Rect:
    hx, hy = (d / 2, w / 2) if k % 2 else (w / 2, d / 2)
    return (x - hx, x + hx, y - hy, y + hy)


def find_spot(rng: np.random.Generator, room: Rect, footprint: tuple[float, float], taken: list[Rect], *,
              against_wall: bool, clearance: float = 0.1, tries: int = 40) -> tuple[int, float, float] | None:
    """A free pose (k, x, y) for a footprint in ``room``: backed against a random wall, or free-standing
    with 0.6 m all round; ``None`` when nothing fits after ``tries`` draws."""
    w, d = footprint
    x0, x1, y0, y1 = room
    for _ in range(tries):
        if against_wall:
            side = str(rng.choice(["S", "N", "W", "E"]))
            lo, hi = (x0, x1) if side in "SN" else (y0, y1)
            if hi - lo < w + 2 * GAP_M:
                continue
            along = float(rng.uniform(lo + GAP_M + w / 2, hi - GAP_M - w / 2))
            k, x, y = _wall_pose(room, side, w, d, along)
        else:
            k = int(rng.choice([0, 1]))
            hx, hy = (d / 2, w / 2) if k % 2 else (w / 2, d / 2)
            m = 0.6
            if x1 - x0 < 2 * (hx + m) or y1 - y0 < 2 * (hy + m):
                continue
            x, y = float(rng.uniform(x0 + hx + m, x1 - hx - m)), float(rng.uniform(y0 + hy + m, y1 - hy - m))
        r = footprint_rect(k, x, y, w, d)
        if r[0] < x0 + GAP_M - 1e-9 or r[1] > x1 - GAP_M + 1e-9 or r[2] < y0 + GAP_M - 1e-9 or r[3] > y1 - GAP_M + 1e-9:
            continue
        if any(overlaps(r, t, clearance) for t in taken):
            continue
        return k, x, y
    return None
