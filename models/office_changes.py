"""Change scripts of the office's furniture layer: what moves, comes and goes, day by day (numpy only).

A :class:`ChangeScript` is a list of :class:`Change` rows, each on a day (1, 2, ...): ``move`` an
object to a new pose, ``remove`` it, ``add`` a new piece, or put an ``obstacle`` (a trolley,
a stack of boxes: :data:`~exobench.models.furniture_kinds.OBSTACLE_CLASSES`) in a corridor.
Objects are named by their identity: the name a piece got when the office was furnished
(``chair3``; its geoms are ``chair3_seat``, ...) or the one the script gives an added piece; it
stays the same through every day whatever else is added or removed. An added piece is drawn
from its class and ``variant`` (the seed of its sizes), so a script is plain data.

A script is written as JSON (a list of objects with the fields of :class:`Change`) or in a
compact form a scenario row can carry, changes separated by ``;``::

    1 move chair3 4.20 9.10 1; 1 remove plant0; 2 add cabinet/7 cab_new 3.0 10.5 2; 2 obstacle trolley/3 cart 12.0 0.9 0

(day, kind, then ``move ID X Y TURN``, ``remove ID``, ``add CLASS/VARIANT ID X Y TURN``,
``obstacle CLASS/VARIANT ID X Y TURN``; X, Y the piece's origin, the centre of its footprint
on the floor, TURN the number of quarter turns about z.)

:func:`apply_changes` validates every change before anything is built, in order, and raises
:class:`~exobench.core.errors.ChangeScriptError` naming the day and the object for: a move or
removal of an object that does not stand there that day; an added id already taken; a piece
whose solids cut a wall, a door, a glass partition or another piece, that stands off the floor,
or in the clear space at a room's door (its leaf's swing and the way in); an obstacle outside
the corridors or one that closes a corridor to a walker (:func:`~exobench.models.office_routes.corridor_open`).
:func:`draw_changes` draws a plausible script from a seed (see its docstring).
"""

from __future__ import annotations

import json
from dataclasses import asdict, dataclass, replace

import numpy as np

from exobench.core.errors import ChangeScriptError, ConfigError, UnknownNameError

from .furniture_kinds import MAKERS, OBSTACLE_CLASSES
from .office_furniture import Placed, Solid, footprint_rect, overlaps, place_piece
from .office_layout import Layout
from .office_routes import corridor_open, floor_grid

CHANGE_KINDS = ("move", "remove", "add", "obstacle")
MAX_DAY = 365
EPS_M = 1e-9
NEAR_M = 2.5  # a drawn change a walk sees: this close to a walked point (the camera's depth reaches 6 m) ...
AHEAD_DEG = 40.0  # ... and this near the walker's heading there (the thigh camera spans 90 deg)


@dataclass(frozen=True)
class Change:
    """One change on ``day``: ``kind`` (:data:`CHANGE_KINDS`) of object ``object_id``; ``cls`` and
    ``variant`` (add, obstacle) the new piece; ``x``, ``y``, ``turn`` (move, add, obstacle) its
    new origin and quarter turns about z."""

    day: int
    kind: str
    object_id: str
    cls: str = ""
    variant: int = 0
    x: float = 0.0
    y: float = 0.0
    turn: int = 0

    def __post_init__(self) -> None:
        where = f"changes.day{self.day}.{self.object_id}"
        if isinstance(self.day, bool) or not isinstance(self.day, int) or not 1 <= self.day <= MAX_DAY:
            raise ConfigError("changes.day", self.day, f"an integer day in [1, {MAX_DAY}]")
        if self.kind not in CHANGE_KINDS:
            raise UnknownNameError("change kind", self.kind, CHANGE_KINDS)
        if not self.object_id or any(c in self.object_id for c in " ;/"):
            raise ConfigError("changes.object_id", self.object_id, "a non-empty name without spaces, ';' or '/'")
        if self.kind in ("add", "obstacle"):
            allowed = OBSTACLE_CLASSES if self.kind == "obstacle" else tuple(c for c in MAKERS if c not in OBSTACLE_CLASSES)
            if self.cls not in allowed:
                raise UnknownNameError(f"class of a piece to {self.kind}", self.cls, allowed)
        for f in ("x", "y"):
            v = float(getattr(self, f))
            if not np.isfinite(v):
                raise ConfigError(f"{where}.{f}", v, "a finite position in m")
            object.__setattr__(self, f, v)
        object.__setattr__(self, "turn", int(self.turn) % 4)
        object.__setattr__(self, "variant", int(self.variant))


@dataclass(frozen=True)
class ChangeScript:
    """The changes of every day, in the order they apply (by day, then as given)."""

    changes: tuple[Change, ...] = ()

    def __post_init__(self) -> None:
        object.__setattr__(self, "changes", tuple(sorted(self.changes, key=lambda c: c.day)))

    @property
    def last_day(self) -> int:
        return max((c.day for c in self.changes), default=0)

    def on_day(self, day: int) -> tuple[Change, ...]:
        return tuple(c for c in self.changes if c.day == day)

    def upto(self, day: int) -> ChangeScript:
        return ChangeScript(tuple(c for c in self.changes if c.day <= day))

    def to_json(self) -> str:
        return json.dumps([asdict(c) for c in self.changes])

    def compact(self) -> str:
        """The compact form (see the module docstring); :func:`parse_changes` reads it back."""
        out = []
        for c in self.changes:
            if c.kind == "remove":
                out.append(f"{c.day} remove {c.object_id}")
            elif c.kind == "move":
                out.append(f"{c.day} move {c.object_id} {c.x!r} {c.y!r} {c.turn}")
            else:
                out.append(f"{c.day} {c.kind} {c.cls}/{c.variant} {c.object_id} {c.x!r} {c.y!r} {c.turn}")
        return "; ".join(out)


def parse_changes(text: str) -> ChangeScript:
    """A script from JSON (a list of :class:`Change` fields) or the compact form; "" is no change."""
    text = (text or "").strip()
    if not text:
        return ChangeScript()
    if text[0] in "[{":
        try:
            rows = json.loads(text)
        except json.JSONDecodeError as e:
            raise ConfigError("changes", text, f"valid JSON ({e.msg} at character {e.pos})") from None
        rows = rows.get("changes", []) if isinstance(rows, dict) else rows
        try:
            return ChangeScript(tuple(Change(**r) for r in rows))
        except TypeError as e:
            raise ConfigError("changes", text, f"objects with the fields of Change ({e})") from None
    changes = []
    for item in filter(None, (s.strip() for s in text.split(";"))):
        w = item.split()
        try:
            day, kind = int(w[0]), w[1]
            if kind == "remove" and len(w) == 3:
                changes.append(Change(day, kind, w[2]))
            elif kind == "move" and len(w) == 6:
                changes.append(Change(day, kind, w[2], x=float(w[3]), y=float(w[4]), turn=int(w[5])))
            elif kind in ("add", "obstacle") and len(w) == 7:
                cls, _, variant = w[2].partition("/")
                changes.append(Change(day, kind, w[3], cls, int(variant or 0), float(w[4]), float(w[5]), int(w[6])))
            else:
                raise ValueError(item)
        except (ValueError, IndexError):
            raise ConfigError("changes", item, "'DAY move ID X Y TURN', 'DAY remove ID', 'DAY add CLASS/VARIANT ID X Y "
                              "TURN' or 'DAY obstacle CLASS/VARIANT ID X Y TURN'") from None
    return ChangeScript(tuple(changes))


def _in_rect(r: tuple[float, float, float, float], box: tuple[float, float, float, float]) -> bool:
    return r[0] >= box[0] - EPS_M and r[1] <= box[1] + EPS_M and r[2] >= box[2] - EPS_M and r[3] <= box[3] + EPS_M


def _region_of(layout: Layout, rect: tuple[float, float, float, float]) -> dict | None:
    """The room (clear floor) or corridor that holds a footprint whole, or None."""
    for r in layout.regions:
        if _in_rect(rect, tuple(r.get("clear", r["rect"]))):
            return r
    return None


def _cuts(a: list[Solid], b: list[Solid]) -> str | None:
    """The name of a solid of ``b`` whose box cuts one of ``a`` (touching is allowed), or None."""
    for s in a:
        for t in b:
            if np.all(s.lo < t.hi - EPS_M) and np.all(t.lo < s.hi - EPS_M):
                return t.name
    return None


class _State:
    """The furniture on one day while a script is applied."""

    def __init__(self, layout: Layout) -> None:
        self.layout = layout
        self.static = [s for s in layout.solids[: layout.n_static] if s.shape != "plane"]
        self.items: dict[str, Placed] = {p.id: p for p in layout.furniture}
        self.solids: dict[str, list[Solid]] = {p.id: p.emit()[0] for p in layout.furniture}

    def check(self, day: int, item: Placed, obstacle: bool) -> str | None:
        """Why ``item`` cannot stand where it is, among the other pieces, or None."""
        solids = place_piece(item.piece, item.id, item.k, item.x, item.y)[0]
        rect = footprint_rect(item.k, item.x, item.y, item.piece.size[0], item.piece.size[1])
        taken = {s.name for s in self.static} | {s.name for oid, ss in self.solids.items() if oid != item.id for s in ss}
        clash = sorted({s.name for s in solids} & taken)
        if clash:
            return f"its geom {clash[0]} would have the name of one already there"
        hit = _cuts(solids, self.static)
        if hit is not None:
            return f"it would cut {hit} (walls, doors and glass stay where they are)"
        region = _region_of(self.layout, rect)
        if region is None:
            return f"its footprint {np.round(rect, 3).tolist()} is not on the floor of one room or corridor"
        if obstacle and region["kind"] != "corridor":
            return f"an obstacle goes in a corridor, not in {region['name']}"
        for oid, other in self.solids.items():
            if oid != item.id and _cuts(solids, other) is not None:
                return f"it would cut {oid}"
        for room, rects in self.layout.keepouts.items():
            if any(overlaps(rect, k) for k in rects):
                return f"it would stand in the way through the door of {room}"
        if region["kind"] == "corridor":
            others = [s for oid, ss in self.solids.items() if oid != item.id for s in ss]
            grid = floor_grid(self.static + others + solids, self.layout.regions, self.layout.extent)
            if not corridor_open(grid, region["rect"]):
                return f"it would close {region['name']} to a walker"
        return None

    def put(self, item: Placed) -> None:
        self.items[item.id] = item
        self.solids[item.id] = place_piece(item.piece, item.id, item.k, item.x, item.y)[0]

    def apply(self, c: Change) -> None:
        if c.kind in ("move", "remove") and c.object_id not in self.items:
            raise ChangeScriptError(c.day, c.object_id, f"no such object stands there on day {c.day - 1} (furniture: "
                                    f"{', '.join(sorted(self.items)[:12])}{', ...' if len(self.items) > 12 else ''})")
        if c.kind == "remove":
            del self.items[c.object_id]
            del self.solids[c.object_id]
            return
        if c.kind == "move":
            item = replace(self.items[c.object_id], k=c.turn, x=c.x, y=c.y)
        else:
            if c.object_id in self.items or c.object_id in {s.name for s in self.static}:
                raise ChangeScriptError(c.day, c.object_id, "that id is taken; an added piece needs a new one")
            item = Placed(c.object_id, MAKERS[c.cls](np.random.default_rng(c.variant)), c.turn, c.x, c.y, "")
        why = self.check(c.day, item, c.kind == "obstacle")
        if why is not None:
            raise ChangeScriptError(c.day, c.object_id, f"{c.kind} to ({c.x:.3f}, {c.y:.3f}) turn {c.turn}: {why}")
        rect = footprint_rect(item.k, item.x, item.y, item.piece.size[0], item.piece.size[1])
        self.put(replace(item, room=_region_of(self.layout, rect)["name"]))  # type: ignore[index]


def apply_changes(layout: Layout, script: ChangeScript, day: int) -> list[list[Placed]]:
    """The furniture standing on each day 0..``day`` (day 0: as furnished), after validating
    every change of the script (all its days, not only those up to ``day``: a script is refused
    whole, before anything runs). Pieces keep their order; added ones come last."""
    state = _State(layout)
    days: list[list[Placed]] = [list(layout.furniture)]
    for d in range(1, max(day, script.last_day) + 1):
        for c in script.on_day(d):
            state.apply(c)
        if d <= day:
            days.append(list(state.items.values()))
    return days


def draw_changes(layout: Layout, seed: int, n_days: int, tries: int = 60, near: np.ndarray | None = None,
                 near_m: float = NEAR_M) -> ChangeScript:
    """A plausible script of ``n_days`` days drawn from ``seed``.

    What the paper's office saw between days (seeds/000 IV-B, IV-D): object-level changes in
    rooms (chairs moved, objects added and taken away) and obstacles appearing in a corridor and
    going again. Each day draws 2-5 changes: moves (half of them, chairs three times as likely
    as other pieces, 0.3-1.5 m within their room, a random quarter turn), removals (1/6), added
    pieces (1/6: a chair, bin, plant or cabinet in a room) and corridor obstacles (1/6: a trolley
    or boxes); an obstacle of an earlier day is taken away again with probability 0.5. A change
    that the validation refuses is drawn again (up to ``tries`` times, then left out). Day d
    draws from ``(seed, d)``, so the first days of a longer script are the same.

    With ``near`` (walked points (N, 3): x, y and the walker's heading in rad), every change is
    one those walks see: a moved or removed piece, an added one and an obstacle stand (before and
    after) within ``near_m`` of a walked point, within :data:`AHEAD_DEG` of the heading there and
    in the same room or corridor (not behind a wall); a day
    that would draw none of them gets an obstacle. Without it, the script is drawn anywhere in
    the building, as before (the same draws to the bit).
    """
    if n_days < 0:
        raise ConfigError("change_days", n_days, ">= 0")
    state = _State(layout)
    out: list[Change] = []
    regions = {r["name"]: r for r in layout.regions}
    corridors = [r for r in layout.regions if r["kind"] == "corridor"]
    rooms = [r for r in layout.regions if r["kind"] != "corridor"]
    seen = None if near is None else Seen(layout, np.asarray(near, dtype=float).reshape(-1, 3), near_m)
    if seen is not None:  # draw only among what the walks see
        corridors = [r for r in corridors if r["name"] in seen.regions]
        rooms = [r for r in rooms if r["name"] in seen.regions]
    added = 0
    for d in range(1, n_days + 1):
        rng = np.random.default_rng([seed, d])
        todo = [str(k) for k in rng.choice(["move", "move", "move", "remove", "add", "obstacle"], int(rng.integers(2, 6)))]
        for oid in [i for i, p in state.items.items() if p.piece.cls in OBSTACLE_CLASSES]:
            if rng.random() < 0.5:
                todo.insert(0, f"clear:{oid}")
        n_before = len(out)
        if seen is not None:
            todo.append("obstacle?")  # drawn only if the day has no change yet
        for kind in todo:
            if kind == "obstacle?":
                if len(out) > n_before:
                    break
                kind = "obstacle"
            for _ in range(tries):
                c = _draw_one(rng, state, kind, d, added, regions, corridors, rooms, seen)
                if c is None:
                    break
                if seen is not None and (c.kind != "remove" and not seen.sees(c.x, c.y)
                                         or any(o.object_id == c.object_id for o in out[n_before:])):
                    continue  # unseen, or a piece already changed that day (its change would be one)
                try:
                    state.apply(c)
                except ChangeScriptError:
                    continue
                out.append(c)
                added += c.kind in ("add", "obstacle")
                break
    return ChangeScript(tuple(out))


class Seen:
    """What walks through ``points`` (x, y, heading) see: a spot within ``near_m`` of a walked
    point, ahead of the walker there and in the region the point lies in (a room's furniture
    seen from the corridor only through its door is left out)."""

    def __init__(self, layout: Layout, points: np.ndarray, near_m: float) -> None:
        self.points, self.near_m, self.layout = points, float(near_m), layout
        self.regions = {r["name"] for r in layout.regions if _holds(r["rect"], points).any()}

    def sees(self, x: float, y: float) -> bool:
        r = next((r for r in self.layout.regions if _holds(r["rect"], np.array([[x, y]]))[0]), None)
        if r is None or r["name"] not in self.regions:
            return False
        p = self.points[_holds(r["rect"], self.points)]
        off = np.abs((np.arctan2(y - p[:, 1], x - p[:, 0]) - p[:, 2] + np.pi) % (2 * np.pi) - np.pi)
        return bool(np.any((np.hypot(p[:, 0] - x, p[:, 1] - y) <= self.near_m) & (off <= np.radians(AHEAD_DEG))))


def _holds(rect: tuple[float, float, float, float], points: np.ndarray) -> np.ndarray:
    x0, x1, y0, y1 = rect
    return (points[:, 0] >= x0) & (points[:, 0] <= x1) & (points[:, 1] >= y0) & (points[:, 1] <= y1)


def _draw_one(rng: np.random.Generator, state: _State, kind: str, day: int, added: int, regions: dict,
              corridors: list[dict], rooms: list[dict], seen: Seen | None = None) -> Change | None:
    items = list(state.items.values())
    if kind.startswith("clear:"):
        return Change(day, "remove", kind.partition(":")[2])
    if kind in ("move", "remove"):
        pool = [p for p in items if p.piece.cls not in OBSTACLE_CLASSES and (seen is None or seen.sees(p.x, p.y))]
        if not pool:
            return None
        w = np.array([3.0 if p.piece.cls == "chair" else 1.0 for p in pool])
        p = pool[int(rng.choice(len(pool), p=w / w.sum()))]
        if kind == "remove":
            return Change(day, "remove", p.id)
        r, a = rng.uniform(0.3, 1.5), rng.uniform(0, 2 * np.pi)
        return Change(day, "move", p.id, x=round(p.x + r * np.cos(a), 3), y=round(p.y + r * np.sin(a), 3),
                      turn=int(rng.integers(4)))
    if kind == "add":
        if not rooms:
            return None
        room = rooms[int(rng.integers(len(rooms)))]
        x0, x1, y0, y1 = room["clear"]
        cls = str(rng.choice(["chair", "bin", "plant", "cabinet"]))
        return Change(day, "add", f"{cls}_d{day}_{added}", cls, int(rng.integers(2**31)),
                      round(float(rng.uniform(x0, x1)), 3), round(float(rng.uniform(y0, y1)), 3), int(rng.integers(4)))
    if not corridors:
        return None
    cor = corridors[int(rng.integers(len(corridors)))]
    x0, x1, y0, y1 = cor["rect"]
    cls = str(rng.choice(list(OBSTACLE_CLASSES)))
    return Change(day, "obstacle", f"{cls}_d{day}_{added}", cls, int(rng.integers(2**31)),
                  round(float(rng.uniform(x0, x1)), 3), round(float(rng.uniform(y0, y1)), 3), int(rng.integers(4)))


def script_from(layout: Layout, changes: str = "", change_seed: int = -1, days: int = 0) -> ChangeScript:
    """The script a scenario row gives: ``changes`` as written, or drawn from ``change_seed``
    for ``days`` days; not both."""
    if changes.strip() and change_seed >= 0:
        raise ConfigError("change_seed", change_seed, "-1 when changes is given (a script is written or drawn, not both)")
    return draw_changes(layout, change_seed, days) if change_seed >= 0 else parse_changes(changes)


def changed_ids(before: list[Placed], after: list[Placed]) -> dict[str, str]:
    """``id -> "moved" | "added" | "removed"`` between two days' furniture."""
    a, b = {p.id: p for p in before}, {p.id: p for p in after}
    out: dict[str, str] = {}
    for i, p in a.items():
        if i not in b:
            out[i] = "removed"
        elif (b[i].k, b[i].x, b[i].y) != (p.k, p.x, p.y):
            out[i] = "moved"
    out.update({i: "added" for i in b if i not in a})
    return out


__all__ = ["CHANGE_KINDS", "Change", "ChangeScript", "apply_changes", "changed_ids", "draw_changes", "parse_changes",
           "script_from"]

