"""Floor plan of the procedural office: walls, glass, doors, windows, furniture, floors, routes (numpy only).

The building is axis-aligned in the world, x along the corridors, y to the north, z up, the
floor at z = 0 and the inside of the south-west corner at the origin. From south to north:

    y = 0 .. W                south corridor (blank walls on both sides along the core:
                              the featureless corridor)
    slot of 0.12 m            south partition of the meeting room
    W + t .. W + t + D        central block: service core (x from W) and meeting room (east end)
    slot                      north partition of the meeting room
    north corridor, W wide    where the walker starts, at its west end
    slot                      corridor partitions of the offices (plaster or glass, with doors)
    offices, D deep           n_offices side by side along x = 0 .. corridor_length_m
    exterior wall             with one window per office

Cross corridors (W wide) at both ends join the two long corridors, so the corridors form a
ring around the central block (a loop for loop closure). Every interior wall stands in a 0.12 m
slot: a plaster wall fills it, a glass partition stands in its middle (panes between 50 mm
mullions). Doors are openings with an open leaf at 90 deg inside the room, hinged on the jamb
nearer the room's side wall; the clear width beside the open leaf is ``door_width_m``.
Floors and ceilings are one plane per area (corridor, room), split under the walls.

With ``facade="windows"`` the south, west and east exterior walls get a row of windows along the
corridors (bays of :data:`~exobench.models.office_params.FACADE_BAYS`, sill and head as the
offices' windows), with ``facade="curtain"`` glazing from the floor between slim mullions (a
curtain wall), of ``facade_glass``, with nothing outside: a window-lined building at night,
whose panes mirror the corridor (:mod:`exobench.models.materials`). ``partition_glass`` is the
material of the glass partitions and glass door leaves.

Glass and polished floors along the routes: of the ``round(glass_fraction * (n_offices + 2))``
glass partitions the meeting room's south one (beside the ``"corridor"`` route) is always one,
the others are drawn at random; of the ``round(polished_fraction * n_areas)`` polished floors
the south corridor's is always one. The ``"loop"`` route enters every room and walks every
corridor, so it passes all of them.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from .furniture_kinds import Candidate, room_candidates
from .office_furniture import (
    Group,
    Placed,
    Rect,
    Solid,
    find_spot,
    footprint_rect,
    rotate_xy,
)
from .office_params import (
    DOOR_HEIGHT_M,
    DOOR_JAMB_M,
    EXT_WALL_T_M,
    GLASS_LEAF_T_M,
    MULLION_M,
    WALL_T_M,
    WOOD_LEAF_T_M,
    OfficeParams,
)
from .office_walls import (
    Names,
    box,
    door_leaf,
    facade_walls,
    glass_partition,
    glazing_heights,
    plaster_wall,
    translation,
)

VISIT_M = 1.5  # how far a route walks into a room past its door
ROUTE_KEEPOUT_M = 0.5  # furniture keeps this far from a route


@dataclass
class Layout:
    """Everything that was built, in the world frame (see the module docstring)."""

    solids: list[Solid]
    objects: list[dict]
    regions: list[dict]
    routes: dict[str, list[list[float]]]
    start_w: list[float]
    featureless_x_m: list[float]
    corridor_y_m: dict[str, float]
    extent: Rect  # outside of the exterior walls
    # the furniture layer: the pieces standing (their solids are the last of ``solids``, from
    # ``n_static`` on), and the areas by each room's doors that furniture keeps clear
    furniture: list[Placed]
    n_static: int
    keepouts: dict[str, list[Rect]]

    def with_furniture(self, furniture: list[Placed]) -> Layout:
        """The same building furnished with ``furniture`` (solids and objects of the pieces last)."""
        solids, objects = list(self.solids[: self.n_static]), list(self.objects[: len(self.objects) - len(self.furniture)])
        for item in furniture:
            s, obj = item.emit()
            solids += s
            objects.append(obj)
        return replace(self, solids=solids, objects=objects, furniture=list(furniture))


def _place_groups(rng: np.random.Generator, names: Names, room: Rect, room_name: str, density: float,
                  candidates: list[Candidate], keepouts: list[Rect]) -> list[Placed]:
    placed: list[Placed] = []
    taken = list(keepouts)
    for i, (make, against_wall) in enumerate(candidates):
        group: Group = make(rng)
        if rng.random() >= density and not (i == 0 and density > 0.0):  # the first is the room's main piece
            continue
        spot = find_spot(rng, room, group.footprint, taken, against_wall=against_wall)
        if spot is None:
            continue
        k, x, y = spot
        taken.append(footprint_rect(k, x, y, *group.footprint))
        for piece, (ox, oy), km in group.members:
            dx, dy = rotate_xy(k, ox, oy)
            placed.append(Placed(names(piece.cls), piece, (k + km) % 4, x + dx, y + dy, room_name))
    return placed


def _plane(name: str, rect: Rect, z: float, up: bool, material: str, look: str, kind: str) -> Solid:
    x0, x1, y0, y1 = rect
    return Solid(name, "plane", (0.5 * (x0 + x1), 0.5 * (y0 + y1), z), (0.5 * (x1 - x0), 0.5 * (y1 - y0), 0.0),
                 material, look, kind, up)


def build_layout(p: OfficeParams) -> Layout:
    """Lay out the whole floor from validated parameters; deterministic in ``p`` (incl. its seed)."""
    rng = np.random.default_rng(p.seed)
    names = Names()
    W, X, D, C, t, te = p.corridor_width_m, p.corridor_length_m, p.room_depth_m, p.ceiling_m, WALL_T_M, EXT_WALL_T_M
    dw, n = p.door_width_m, p.n_offices
    # y of the slots and areas, south to north
    yc0 = W + t
    yc1 = yc0 + D
    yn0 = yc1 + t
    yn1 = yn0 + W
    yo0 = yn1 + t
    yo1 = yo0 + D
    yS, yN = 0.5 * W, yn0 + 0.5 * W
    xm1 = X - W - t
    xm0 = xm1 - p.meeting_room_m

    # office widths: the minimum plus a random share of what is left
    w_min = p.office_min_width_m
    spare = X - (n - 1) * t - n * w_min
    widths = w_min + spare * rng.dirichlet(np.full(n, 4.0))
    rep = p.repeated_rooms  # the first `rep` offices are one room repeated: the same width, door and partition
    if rep:
        widths[:rep] = widths[:rep].mean()
    ox = []
    x = 0.0
    for k in range(n):
        x1 = X if k == n - 1 else x + float(widths[k])
        ox.append((x, x1))
        x = x1 + t
    # which corridor partitions are glass (offices 0..n-1, then meeting north, meeting south); the
    # meeting room's south partition, the one the "corridor" route passes, is glass first
    n_glass = int(round(p.glass_fraction * (n + 2)))
    glass = set(int(i) for i in _first(rng.permutation(n + 2), n + 1)[:n_glass])
    if rep:
        glass = (glass - set(range(rep))) | (set(range(rep)) if 0 in glass else set())

    regions = [{"name": "corridor_n", "kind": "corridor", "rect": [0.0, X, yc1 + t / 2, yn1 + t / 2]},
               {"name": "corridor_s", "kind": "corridor", "rect": [0.0, X, 0.0, W + t / 2]},
               {"name": "corridor_w", "kind": "corridor", "rect": [0.0, W, W + t / 2, yc1 + t / 2]},
               {"name": "corridor_e", "kind": "corridor", "rect": [X - W, X, W + t / 2, yc1 + t / 2]},
               {"name": "meeting", "kind": "meeting", "rect": [xm0, X - W, W + t / 2, yc1 + t / 2],
                "clear": [xm0, xm1, yc0, yc1]}]
    for k, (a, b) in enumerate(ox):
        regions.append({"name": f"office{k}", "kind": "office",
                        "rect": [0.0 if k == 0 else a - t / 2, X if k == n - 1 else b + t / 2, yn1 + t / 2, yo1],
                        "clear": [a, b, yo0, yo1]})
    # polished floors: the south corridor (walked by both routes) first, then at random
    n_polished = int(round(p.polished_fraction * len(regions)))
    polished = set(int(i) for i in _first(rng.permutation(len(regions)), 1)[:n_polished])
    solids: list[Solid] = []
    for i, r in enumerate(regions):
        if i in polished:
            r["floor"], look = "polished_floor", "office_polished"
        elif r["kind"] == "corridor":
            r["floor"], look = "tiles", "world_floor"
        else:
            r["floor"], look = "carpet", "office_carpet"
        solids.append(_plane(f"floor_{r['name']}", tuple(r["rect"]), 0.0, True, r["floor"], look, "ground"))
    for r in regions:
        solids.append(_plane(f"ceiling_{r['name']}", tuple(r["rect"]), C, False, "plaster", "office_ceiling", "ceiling"))

    objects: list[dict] = []
    # exterior walls (north one with windows), service core, east wall of the meeting room
    if p.facade != "plain":
        solids += facade_walls(p, names, objects, (yn1, yo1))
    else:
        solids.append(box("wall_ext_w", (-te, -te, 0.0), (0.0, yo1 + te, C), "plaster", "world_plaster", "wall"))
        solids.append(box("wall_ext_e", (X, -te, 0.0), (X + te, yo1 + te, C), "plaster", "world_plaster", "wall"))
        solids.append(box("wall_ext_s", (0.0, -te, 0.0), (X, 0.0, C), "plaster", "world_plaster", "wall"))
    windows = []
    if p.windows:  # a curtain-walled building is glazed from the floor on the north side too
        sill, head = glazing_heights(p.facade, C)
        for a, b in ox:
            ww = min(0.6 * (b - a), 2.4)
            c = 0.5 * (a + b)
            windows.append((c - ww / 2, c + ww / 2, sill, head))
    solids += plaster_wall("wall_ext_n", 0, 0.0, X, yo1, yo1 + te, C, windows)
    for u0, u1, z0, z1 in windows:
        name = names("window")
        ym = yo1 + te / 2
        solids.append(box(name, (u0, ym - p.glass_thickness_m / 2, z0), (u1, ym + p.glass_thickness_m / 2, z1),
                           p.facade_glass, "office_glass", "glass"))
        objects.append({"name": name, "class": "window", "T_world_object": translation(0.5 * (u0 + u1), ym, z0),
                        "size_m": [u1 - u0, p.glass_thickness_m, z1 - z0], "geom_names": [name]})
    solids.append(box("core", (W, W, 0.0), (xm0, yn0, C), "plaster", "world_plaster", "wall"))
    solids.append(box("wall_meeting_e", (xm1, W, 0.0), (X - W, yn0, C), "plaster", "world_plaster", "wall"))
    for k in range(n - 1):
        solids.append(box(f"wall_side{k}", (ox[k][1], yn1, 0.0), (ox[k + 1][0], yo1, C), "plaster", "world_plaster", "wall"))

    def partition(idx: int, name: str, u0: float, u1: float, slot: tuple[float, float], clear0: float, hinge_west: bool,
                  into: int) -> tuple[list[Solid], float, float, tuple[float, float]]:
        """A corridor partition with its door; the clear passage starts at ``clear0``.
        Returns solids, the face the leaf rests on, the hinge jamb and the opening."""
        is_glass = idx in glass
        lt = GLASS_LEAF_T_M if is_glass else WOOD_LEAF_T_M
        opening = (clear0 - lt, clear0 + dw) if hinge_west else (clear0, clear0 + dw + lt)
        mid = 0.5 * (slot[0] + slot[1])
        if is_glass:
            s, panes = glass_partition(name, 0, u0, u1, mid, C, p.glass_thickness_m, opening, p.partition_glass)
            gname = names("glass_partition")
            objects.append({"name": gname, "class": "glass_partition", "T_world_object": translation(0.5 * (u0 + u1), mid, 0.0),
                            "size_m": [u1 - u0, MULLION_M, C], "geom_names": [g.name for g in s]})
            face = mid + into * MULLION_M / 2
        else:
            s = plaster_wall(name, 0, u0, u1, slot[0], slot[1], C, [(opening[0], opening[1], 0.0, DOOR_HEIGHT_M)])
            face = slot[1] if into > 0 else slot[0]
        hinge = opening[0] if hinge_west else opening[1]
        leaf, obj = door_leaf(names("door"), is_glass, hinge, 1 if hinge_west else -1, face, into, opening[1] - opening[0],
                               glass_material=p.partition_glass)
        objects.append(obj)
        return s + [leaf], face, hinge, opening

    keep: dict[str, list[Rect]] = {}
    door_x: dict[str, float] = {}
    first_west = False
    for k, (a, b) in enumerate(ox):
        west = bool(rng.random() < 0.5)
        first_west = west if k == 0 else first_west
        west = first_west if k < rep else west
        clear0 = a + DOOR_JAMB_M + WOOD_LEAF_T_M if west else b - DOOR_JAMB_M - WOOD_LEAF_T_M - dw
        s, face, hinge, opening = partition(k, f"wall_office{k}", a, b, (yn1, yo0), clear0, west, +1)
        solids += s
        dc = clear0 + dw / 2
        door_x[f"office{k}"] = dc
        ow = opening[1] - opening[0]
        swing = (hinge, hinge + ow) if west else (hinge - ow, hinge)
        visit = yo0 + min(VISIT_M, D - 0.5)
        keep[f"office{k}"] = [(swing[0], swing[1], yo0, yo0 + ow),
                              (dc - ROUTE_KEEPOUT_M, dc + ROUTE_KEEPOUT_M, yo0, visit + ROUTE_KEEPOUT_M)]
    # meeting room: a door in each partition on the same clear passage, leaves on opposite jambs
    clear0 = xm0 + DOOR_JAMB_M + WOOD_LEAF_T_M
    dm = clear0 + dw / 2
    door_x["meeting"] = dm
    s, face_n, hinge_n, op_n = partition(n, "wall_meeting_n", xm0, xm1, (yc1, yn0), clear0, True, -1)
    solids += s
    s, face_s, hinge_s, op_s = partition(n + 1, "wall_meeting_s", xm0, xm1, (W, yc0), clear0, False, +1)
    solids += s
    keep["meeting"] = [(hinge_n, hinge_n + op_n[1] - op_n[0], yc1 - (op_n[1] - op_n[0]), yc1),
                       (hinge_s - (op_s[1] - op_s[0]), hinge_s, yc0, yc0 + op_s[1] - op_s[0]),
                       (dm - ROUTE_KEEPOUT_M, dm + ROUTE_KEEPOUT_M, yc0, yc1)]

    # furniture: drawn from the layout's generator where it left off (as it always was), or from
    # its own seed, so the same building can be furnished differently
    n_static = len(solids)
    frng = rng if p.furniture_seed < 0 else np.random.default_rng(p.furniture_seed)
    furniture: list[Placed] = []
    repeated = {f"office{k}": ox[k][0] - ox[0][0] for k in range(1, rep)}
    for r in regions:
        if r["kind"] == "corridor":
            continue
        room = tuple(r["clear"])
        if r["name"] in repeated:  # office 0's pieces where they stand in it, with identities of their own
            dx = repeated[r["name"]]
            furniture += [Placed(names(q.piece.cls), q.piece, q.k, q.x + dx, q.y, r["name"])
                          for q in furniture if q.room == "office0"]  # fmt: skip
            continue
        furnish = p.furnish
        if furnish == "mixed":  # a building of offices in its west half and labs in its east half
            furnish = "lab" if room[0] + room[1] > X else "office"
        cands = room_candidates(furnish, r["kind"], room)
        furniture += _place_groups(frng, names, room, r["name"], p.furniture_density, cands, keep[r["name"]])
    for item in furniture:
        s, obj = item.emit()
        solids += s
        objects.append(obj)

    # routes: a loop round the ring visiting every office (in and out again), then a second lap
    # through the meeting room, both closing at the start; and the whole south corridor
    S, NE, SE, SW = [W / 2, yN], [X - W / 2, yN], [X - W / 2, yS], [W / 2, yS]
    loop = [S]
    for k in sorted(range(n), key=lambda k: door_x[f"office{k}"]):
        dc = door_x[f"office{k}"]
        loop += [[dc, yN], [dc, yo0 + min(VISIT_M, D - 0.5)], [dc, yN]]
    loop += [NE, SE, SW, S, [dm, yN], [dm, 0.5 * (yc0 + yc1)], [dm, yS], SW, S]
    loop = [q for i, q in enumerate(loop) if i == 0 or q != loop[i - 1]]
    routes = {"loop": loop, "ring": [S, NE, SE, SW, S], "corridor": [SW, SE]}
    return Layout(solids=solids, objects=objects, regions=regions, routes=routes, start_w=[W / 2, yN, 0.0],
                  featureless_x_m=[W, xm0], corridor_y_m={"north": yN, "south": yS},
                  extent=(-te, X + te, -te, yo1 + te), furniture=furniture, n_static=n_static, keepouts=keep)


def _first(order: np.ndarray, item: int) -> np.ndarray:
    """``order`` with ``item`` moved to the front (the other items keep their order)."""
    return np.concatenate([[item], order[order != item]])
