"""Walls, glass partitions, façade windows and door leaves of the procedural office (numpy only).

The builders :func:`~exobench.models.office_layout.build_layout` assembles: a wall spans ``u``
along an axis (0: x, 1: y) and ``w`` across it; a plaster wall is boxes around its openings, a
glass partition panes between mullions, a façade a row of windows between piers
(``facade="windows"``), a door leaf an open leaf hinged on its jamb. Each records its objects
(class, pose, size, geoms) for the scene truth.
"""

from __future__ import annotations

import math

from .office_furniture import Solid
from .office_params import (
    CURTAIN_SILL_M,
    DOOR_HEIGHT_M,
    EXT_WALL_T_M,
    FACADE_BAYS,
    GLASS_LEAF_T_M,
    MULLION_M,
    WOOD_LEAF_T_M,
    OfficeParams,
)

MAX_PANE_M = 1.2  # widest glass pane between mullions [A]
WINDOW_SILL_M, WINDOW_HEAD_M = 0.9, 2.2  # [A]


class Names:
    """Unique geom and object names: ``names("window")`` gives window0, window1, ..."""

    def __init__(self) -> None:
        self.counts: dict[str, int] = {}

    def __call__(self, prefix: str) -> str:
        k = self.counts.get(prefix, 0)
        self.counts[prefix] = k + 1
        return f"{prefix}{k}"


def box(name: str, lo: tuple[float, float, float], hi: tuple[float, float, float], material: str, look: str,
         kind: str) -> Solid:
    return Solid(name, "box", tuple(0.5 * (a + b) for a, b in zip(lo, hi)), tuple(0.5 * (b - a) for a, b in zip(lo, hi)),
                 material, look, kind)


def along(axis: int, u0: float, u1: float, w0: float, w1: float, z0: float, z1: float) -> tuple[tuple, tuple]:
    """lo, hi of a box spanning u along ``axis`` (0: x, 1: y) and w across it."""
    if axis == 0:
        return (u0, w0, z0), (u1, w1, z1)
    return (w0, u0, z0), (w1, u1, z1)


def plaster_wall(name: str, axis: int, u0: float, u1: float, w0: float, w1: float, height: float,
                 openings: list[tuple[float, float, float, float]]) -> list[Solid]:
    """A plaster wall from u0 to u1 along ``axis``, w0..w1 thick, with openings (u0, u1, z0, z1)."""
    out: list[Solid] = []
    u = u0
    parts: list[tuple[float, float, float, float]] = []
    for a, b, z0, z1 in sorted(openings):
        if a > u:
            parts.append((u, a, 0.0, height))
        if z0 > 0.0:
            parts.append((a, b, 0.0, z0))
        if z1 < height:
            parts.append((a, b, z1, height))
        u = b
    if u < u1:
        parts.append((u, u1, 0.0, height))
    for i, (a, b, z0, z1) in enumerate(parts):
        lo, hi = along(axis, a, b, w0, w1, z0, z1)
        out.append(box(f"{name}_{i}", lo, hi, "plaster", "world_plaster", "wall"))
    return out


def glass_partition(name: str, axis: int, u0: float, u1: float, w_mid: float, height: float, glass_t: float,
                    door: tuple[float, float] | None, material: str = "glass") -> tuple[list[Solid], list[str]]:
    """Glass panes between square mullions from u0 to u1, centred on w_mid; a door opening (a, b)
    gets jamb mullions, a head rail at the door height and a glass transom. Returns solids and pane names."""
    m, gh = MULLION_M, 0.5 * glass_t
    w0, w1 = w_mid - m / 2, w_mid + m / 2
    posts = [(u0, u0 + m)]
    spans: list[tuple[float, float, float]] = []  # (u0, u1, z0) of each pane
    if door is not None:
        posts += [(door[0] - m, door[0]), (door[1], door[1] + m)]
    posts.append((u1 - m, u1))
    posts.sort()
    solids: list[Solid] = []
    panes: list[str] = []
    frames: list[tuple[float, float]] = list(posts)
    for (_, a), (b, _) in zip(posts, posts[1:]):
        if door is not None and abs(a - door[0]) < 1e-12:
            continue  # the door opening itself
        if b - a < 0.2:  # too narrow for a pane: a wide aluminium profile instead
            frames.append((a, b))
            continue
        n = math.ceil((b - a) / MAX_PANE_M - 1e-9)
        pw = (b - a - (n - 1) * m) / n
        for k in range(n):
            s0 = a + k * (pw + m)
            spans.append((s0, s0 + pw, 0.0))
            if k:
                frames.append((s0 - m, s0))
    for i, (a, b) in enumerate(sorted(frames)):
        lo, hi = along(axis, a, b, w0, w1, 0.0, height)
        solids.append(box(f"{name}_mullion{i}", lo, hi, "metal", "office_metal", "frame"))
    if door is not None:
        lo, hi = along(axis, door[0], door[1], w0, w1, DOOR_HEIGHT_M, DOOR_HEIGHT_M + m)
        solids.append(box(f"{name}_head", lo, hi, "metal", "office_metal", "frame"))
        if height - DOOR_HEIGHT_M - m > 0.05:
            spans.append((door[0], door[1], DOOR_HEIGHT_M + m))
    for i, (a, b, z0) in enumerate(spans):
        lo, hi = along(axis, a, b, w_mid - gh, w_mid + gh, z0, height)
        pane = f"{name}_pane{i}"
        solids.append(box(pane, lo, hi, material, "office_glass", "glass"))
        panes.append(pane)
    return solids, panes


def glazing_heights(facade: str, ceiling: float) -> tuple[float, float]:
    """Sill and head of every window: the offices' windows', or from the floor in a curtain wall."""
    if facade == "curtain":
        return CURTAIN_SILL_M, ceiling - 0.25
    return WINDOW_SILL_M, min(WINDOW_HEAD_M, ceiling - 0.25)


def window_bays(u0: float, u1: float, facade: str) -> list[tuple[float, float]]:
    """Window openings (a, b) of a row of façade bays from u0 to u1, a pier at both ends."""
    bay, pier = FACADE_BAYS[facade]
    n = int((u1 - u0 - pier) // bay)
    if n < 1:
        return []
    w = (u1 - u0 - (n + 1) * pier) / n
    return [(u0 + pier + k * (w + pier), u0 + (k + 1) * (w + pier)) for k in range(n)]


def facade_walls(p: OfficeParams, names: Names, objects: list[dict], office_y: tuple[float, float]) -> list[Solid]:
    """South, west and east exterior walls with a row of windows (``facade="windows"``: sill and
    head as the offices' windows, between plaster piers; ``"curtain"``: from the floor to the
    head, between mullions the wall's depth) along the corridors, of ``p.facade_glass``, nothing
    outside (a dark outside). The west and east walls keep no windows along the
    offices (``office_y``: y from the north corridor's partition to the exterior wall)."""
    X, C, te, t = p.corridor_length_m, p.ceiling_m, EXT_WALL_T_M, p.glass_thickness_m
    sill, head = glazing_heights(p.facade, C)
    out: list[Solid] = []
    # (name, axis, wall from u0 to u1, w0..w1 thick, glazed from g0 to g1, yaw of the window frames:
    # x along the window, y outwards as the north windows')
    walls = [("wall_ext_s", 0, 0.0, X, -te, 0.0, 0.0, X, math.pi),
             ("wall_ext_w", 1, -te, office_y[1] + te, -te, 0.0, 0.0, office_y[0], 0.5 * math.pi),
             ("wall_ext_e", 1, -te, office_y[1] + te, X, X + te, 0.0, office_y[0], -0.5 * math.pi)]
    for wname, axis, u0, u1, w0, w1, g0, g1, yaw in walls:
        bays = window_bays(g0, g1, p.facade)
        out += plaster_wall(wname, axis, u0, u1, w0, w1, C, [(a, b, sill, head) for a, b in bays])
        wm = 0.5 * (w0 + w1)
        for a, b in bays:
            name = names("window")
            lo, hi = along(axis, a, b, wm - t / 2, wm + t / 2, sill, head)
            out.append(box(name, lo, hi, p.facade_glass, "office_glass", "glass"))
            c = 0.5 * (a + b)
            T = translation(c, wm, sill) if axis == 0 else translation(wm, c, sill)
            cy, sy = round(math.cos(yaw), 12) + 0.0, round(math.sin(yaw), 12) + 0.0
            T[0][:2], T[1][:2] = [cy, 0.0 - sy], [sy, cy]
            objects.append({"name": name, "class": "window", "T_world_object": T, "size_m": [b - a, t, head - sill],
                            "geom_names": [name]})
    return out


def door_leaf(name: str, glass: bool, hinge_u: float, leaf_dir: int, face_w: float, into: int, opening: float,
               axis: int = 0, glass_material: str = "glass") -> tuple[Solid, dict]:
    """An open leaf hinged at ``hinge_u`` (the jamb), lying across the wall into the room.

    ``leaf_dir`` (+1/-1): the side of the hinge the leaf thickness lies on (into the opening);
    ``into`` (+1/-1): the direction from the wall face ``face_w`` into the room.
    """
    t = GLASS_LEAF_T_M if glass else WOOD_LEAF_T_M
    ua, ub = sorted((hinge_u, hinge_u + leaf_dir * t))
    wa, wb = sorted((face_w, face_w + into * opening))
    lo, hi = along(axis, ua, ub, wa, wb, 0.0, DOOR_HEIGHT_M - 0.01)
    mat, look, kind = (glass_material, "office_glass", "glass") if glass else ("wood", "office_wood", "door")
    s = box(name, lo, hi, mat, look, kind)
    # object frame: x along the leaf (into the room), y its normal, origin at the bottom centre
    c = s.centre
    R = [[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]] if into > 0 else [[0.0, 1.0, 0.0], [-1.0, 0.0, 0.0], [0.0, 0.0, 1.0]]
    T = [R[0] + [c[0]], R[1] + [c[1]], R[2] + [0.0], [0.0, 0.0, 0.0, 1.0]]
    obj = {"name": name, "class": "door", "T_world_object": T, "size_m": [opening, t, DOOR_HEIGHT_M - 0.01],
           "geom_names": [name], "glass": glass}
    return s, obj


def translation(x: float, y: float, z: float) -> list[list[float]]:
    return [[1.0, 0.0, 0.0, x], [0.0, 1.0, 0.0, y], [0.0, 0.0, 1.0, z], [0.0, 0.0, 0.0, 1.0]]
