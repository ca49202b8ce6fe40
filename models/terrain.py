"""Terrain profiles: solid boxes and their exposed faces, for stairs, ramps and courses (numpy only).

Every world is a *profile* along a local x axis (the walking direction): flats at a height,
joined by risers (vertical steps, up or down) and slopes (ramps). :func:`build_profile` turns a
profile into MuJoCo-ready boxes and into the exact list of faces a ray can see, each a convex
polygon with its outward normal and the boxes whose faces make it up. Local frame: x forward
along the route, y to the left, z up, the floor at z = 0.

Solids: an elevated flat is a ``block`` from the floor up to ``z - t`` topped by a ``slab`` of
thickness ``t`` (concrete under wood); the slab overhangs a riser below it by the nosing. A slope
is one box tilted about y whose top face is the ramp, thick enough to reach the height of its low
end at its high end (it pokes h*sin*cos into the flat there), over a ``fill`` box from the
floor to the low end (left out between walls, where it cannot be seen). The floor is one plane.

Surface ids: the items of the profile in walking order get 0, 1, 2, ...; the other faces
(nosings, lateral sides, ends, floor strips that are not walked on, walls) follow.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from exobench.core.errors import ConfigError

SLAB_MAX_M = 0.04  # wooden tread / concrete floor slab thickness [A]
WALL_THICKNESS_M = 0.15
WALL_CLEARANCE_M = 2.4  # walls rise this far above the highest walking surface [A]


@dataclass(frozen=True)
class Flat:
    """A horizontal walking surface from ``x0`` to ``x1`` at height ``z`` (``z == 0``: the floor).

    ``kind`` is its surface kind (ground, tread or landing); ``field`` names the parameter that
    sets its length, for error messages.
    """

    x0: float
    x1: float
    z: float
    kind: str
    field: str = ""


@dataclass(frozen=True)
class Riser:
    """A vertical step at ``x`` between the flats on either side, with its nosing overhang."""

    x: float
    nosing_m: float = 0.0


@dataclass(frozen=True)
class Slope:
    """A ramp from (x0, z0) to (x1, z1), straight in x-z."""

    x0: float
    x1: float
    z0: float
    z1: float


Item = Flat | Riser | Slope


@dataclass(frozen=True)
class Box:
    """A box in the local frame: centre, half sizes, pitch about local y (rad), material."""

    name: str
    centre: np.ndarray
    half: np.ndarray
    pitch_rad: float
    material: str


@dataclass
class Face:
    """An exposed planar face: kind, outward unit normal, convex polygon (K, 3), box names."""

    kind: str
    normal: np.ndarray
    polygon: np.ndarray
    geoms: tuple[str, ...]
    item: int | None = None  # index of the profile item it is the walking surface of


@dataclass
class Terrain:
    """A built profile in the local frame. Faces are ordered by surface id."""

    boxes: list[Box]
    faces: list[Face]
    floor_x: tuple[float, float]
    floor_half_y: float
    items: list[Item]
    heights: list[tuple[float, float]] = field(default_factory=list)  # (z at start, z at end) per item

    @property
    def top_z(self) -> float:
        return max(max(h) for h in self.heights)


def _rect_x(x: float, y0: float, y1: float, z0: float, z1: float, sign: float) -> np.ndarray:
    """Rectangle in the plane x = const, counter-clockwise seen from the side ``sign * x``."""
    pts = [(x, y0, z0), (x, y1, z0), (x, y1, z1), (x, y0, z1)]  # ccw seen from +x
    return np.array(pts if sign > 0 else pts[::-1], dtype=float)


def _rect_y(y: float, x0: float, x1: float, z0: float, z1: float, sign: float) -> np.ndarray:
    pts = [(x0, y, z0), (x1, y, z0), (x1, y, z1), (x0, y, z1)]  # ccw seen from -y
    return np.array(pts if sign < 0 else pts[::-1], dtype=float)


def _rect_z(z: float, x0: float, x1: float, y0: float, y1: float, sign: float) -> np.ndarray:
    pts = [(x0, y0, z), (x1, y0, z), (x1, y1, z), (x0, y1, z)]
    return np.array(pts if sign > 0 else pts[::-1], dtype=float)


def _side_polygon(xz: list[tuple[float, float]], y: float, sign: float) -> np.ndarray:
    """Polygon in the plane y = const from (x, z) vertices listed counter-clockwise in x-z."""
    pts = [(x, y, z) for x, z in xz]  # ccw in (x, z) is ccw seen from -y
    return np.array(pts[::-1] if sign > 0 else pts, dtype=float)


def _box(name: str, x0: float, x1: float, y0: float, y1: float, z0: float, z1: float, material: str) -> Box:
    lo, hi = np.array([x0, y0, z0]), np.array([x1, y1, z1])
    return Box(name, 0.5 * (lo + hi), 0.5 * (hi - lo), 0.0, material)


def _heights(items: list[Item]) -> list[tuple[float, float]]:
    out = []
    for i, it in enumerate(items):
        if isinstance(it, Flat):
            out.append((it.z, it.z))
        elif isinstance(it, Slope):
            out.append((it.z0, it.z1))
        else:
            out.append((items[i - 1].z, items[i + 1].z))  # risers sit between flats
    return out


def check_profile(items: list[Item]) -> None:
    """Structural checks: flats at both ends and around every riser and slope, contiguous x."""
    if not items or not isinstance(items[0], Flat) or not isinstance(items[-1], Flat):
        raise ValueError("a profile starts and ends with a flat")
    for i, it in enumerate(items):
        if isinstance(it, (Riser, Slope)):
            if not (isinstance(items[i - 1], Flat) and isinstance(items[i + 1], Flat)):
                raise ValueError(f"item {i} ({type(it).__name__}) needs flats on both sides")
        if i and isinstance(it, Flat) and isinstance(items[i - 1], Flat):
            raise ValueError(f"consecutive flats at item {i}; merge them")


def build_profile(items: list[Item], width_m: float, *, walls: bool = False, floor_margin_m: float = 3.0,
                  floor_x: tuple[float, float] | None = None, floor_half_y: float | None = None) -> Terrain:
    """Boxes and exposed faces of a profile of ``width_m`` centred on local y = 0.

    Raises ConfigError (naming the flat's ``field``) when the flat at the high end of a slope is
    too short to hold the end of the ramp box.
    """
    check_profile(items)
    W = 0.5 * width_m
    heights = _heights(items)
    boxes: list[Box] = []
    walk: list[Face] = []
    extra: list[Face] = []

    def flat_slab_t(i: int) -> float:
        z = items[i].z
        t = min(SLAB_MAX_M, 0.4 * z)
        for j in (i - 1, i + 1):
            if 0 <= j < len(items) and isinstance(items[j], Riser):
                lo, hi = heights[j]
                t = min(t, 0.4 * abs(hi - lo))
        return t

    slab_t = {i: flat_slab_t(i) for i, it in enumerate(items) if isinstance(it, Flat) and it.z > 0}
    # a ramp box pokes into the flat at its high end, flush with that flat's lateral faces
    side_geoms: dict[int, tuple[str, ...]] = {}
    for i, it in enumerate(items):
        if isinstance(it, Slope):
            hi = i + 1 if it.z1 > it.z0 else i - 1
            side_geoms[hi] = side_geoms.get(hi, ()) + (f"ramp{i}",)

    # overhang of each elevated flat's slab beyond its block: in front (a riser up before it)
    # and behind (a riser down after it)
    def overhang(i: int) -> tuple[float, float]:
        front = back = 0.0
        if i > 0 and isinstance(items[i - 1], Riser) and items[i - 2].z < items[i].z:
            front = items[i - 1].nosing_m
        if i + 1 < len(items) and isinstance(items[i + 1], Riser) and items[i + 2].z < items[i].z:
            back = items[i + 1].nosing_m
        return front, back

    for i, it in enumerate(items):
        if isinstance(it, Flat):
            nf, nb = overhang(i) if it.z > 0 else (0.0, 0.0)
            x0, x1 = it.x0, it.x1
            if it.z == 0.0:
                walk.append(Face(it.kind, np.array([0.0, 0.0, 1.0]), np.zeros((0, 3)), ("floor",), i))
                continue
            t = slab_t[i]
            blk, slb = f"block{i}", f"slab{i}"
            boxes.append(_box(blk, x0, x1, -W, W, 0.0, it.z - t, "riser"))
            boxes.append(_box(slb, x0 - nf, x1 + nb, -W, W, it.z - t, it.z, "tread"))
            walk.append(Face(it.kind, np.array([0.0, 0.0, 1.0]), _rect_z(it.z, x0 - nf, x1 + nb, -W, W, 1.0), (slb,), i))
            for x, n, sgn in ((x0 - nf, nf, -1.0), (x1 + nb, nb, 1.0)):
                if n > 0:  # nosing front and underside
                    extra.append(Face("side", np.array([sgn, 0.0, 0.0]), _rect_x(x, -W, W, it.z - t, it.z, sgn), (slb,)))
                    xa, xb = (x, x + n) if sgn < 0 else (x - n, x)
                    extra.append(Face("side", np.array([0.0, 0.0, -1.0]), _rect_z(it.z - t, xa, xb, -W, W, -1.0), (slb,)))
            if not walls:
                for y, sgn in ((W, 1.0), (-W, -1.0)):
                    extra.append(Face("side", np.array([0.0, sgn, 0.0]), _rect_y(y, x0, x1, 0.0, it.z, sgn),
                                      (blk, slb, *side_geoms.get(i, ()))))
                    if nf > 0:
                        extra.append(Face("side", np.array([0.0, sgn, 0.0]), _rect_y(y, x0 - nf, x0, it.z - t, it.z, sgn), (slb,)))
                    if nb > 0:
                        extra.append(Face("side", np.array([0.0, sgn, 0.0]), _rect_y(y, x1, x1 + nb, it.z - t, it.z, sgn), (slb,)))
            for end, x, sgn in ((0, x0, -1.0), (len(items) - 1, x1, 1.0)):
                if i == end:  # the elevated start or end of the route: its end face is exposed
                    extra.append(Face("side", np.array([sgn, 0.0, 0.0]), _rect_x(x, -W, W, 0.0, it.z, sgn), (blk, slb)))
        elif isinstance(it, Riser):
            za, zb = heights[i]
            hi_i = i + 1 if zb > za else i - 1
            sgn = -1.0 if zb > za else 1.0  # the face looks back down the route for a riser up
            lo, hi = min(za, zb), max(za, zb)
            t = slab_t[hi_i]
            geoms = (f"block{hi_i}",) if it.nosing_m > 0 else (f"block{hi_i}", f"slab{hi_i}")
            top = hi - t if it.nosing_m > 0 else hi
            walk.append(Face("riser", np.array([sgn, 0.0, 0.0]), _rect_x(it.x, -W, W, lo, top, sgn), geoms, i))
        else:
            rise = it.z1 - it.z0
            run = it.x1 - it.x0
            a = np.arctan2(abs(rise), run)
            up = rise > 0
            z_lo = min(it.z0, it.z1)
            # thickness reaching z_lo below the high end; the box pokes h*sin*cos past it
            d = abs(rise) * np.cos(a)
            hi_i = i + 1 if up else i - 1
            poke = abs(rise) * np.sin(a) * np.cos(a)
            need = poke + 1e-3
            hi_flat = items[hi_i]
            if hi_flat.x1 - hi_flat.x0 < need:
                raise ConfigError(hi_flat.field or "length_m", hi_flat.x1 - hi_flat.x0,
                                  f">= {need:.3f} m (to hold the high end of the ramp before it)")
            pitch = -a if up else a
            n_top = np.array([-np.sin(a) if up else np.sin(a), 0.0, np.cos(a)])
            mid = np.array([0.5 * (it.x0 + it.x1), 0.0, 0.5 * (it.z0 + it.z1)])
            name, fill = f"ramp{i}", f"ramp{i}_fill"
            boxes.append(Box(name, mid - 0.5 * d * n_top, np.array([0.5 * np.hypot(run, rise), W, 0.5 * d]), pitch, "ramp"))
            geoms = (name,)
            if z_lo > 0 and not walls:  # between walls the gap under the ramp box is out of sight
                boxes.append(_box(fill, it.x0, it.x1, -W, W, 0.0, z_lo, "riser"))
                geoms = (name, fill)
            poly = np.array([(it.x0, -W, it.z0), (it.x1, -W, it.z1), (it.x1, W, it.z1), (it.x0, W, it.z0)])
            walk.append(Face("ramp", n_top, poly, (name,), i))
            if not walls:
                xz = [(it.x0, 0.0), (it.x1, 0.0), (it.x1, it.z1), (it.x0, it.z0)]
                xz = [p for k, p in enumerate(xz) if not (k == 0 and it.z0 == 0.0) and not (k == 1 and it.z1 == 0.0)]
                for y, sgn in ((W, 1.0), (-W, -1.0)):
                    extra.append(Face("side", np.array([0.0, sgn, 0.0]), _side_polygon(xz, y, sgn), geoms))

    # floor: strips across the whole floor width, the walked-on ones first
    fx0 = items[0].x0 - floor_margin_m if floor_x is None else floor_x[0]
    fx1 = items[-1].x1 + floor_margin_m if floor_x is None else floor_x[1]
    FY = W + floor_margin_m + (WALL_THICKNESS_M if walls else 0.0) if floor_half_y is None else floor_half_y
    claimed: list[tuple[float, float]] = []
    for f in walk:
        if f.geoms == ("floor",):
            it = items[f.item]
            x0 = fx0 if f.item == 0 else it.x0
            x1 = fx1 if f.item == len(items) - 1 else it.x1
            f.polygon = _rect_z(0.0, x0, x1, -FY, FY, 1.0)
            claimed.append((x0, x1))
    claimed.sort()
    gaps, x = [], fx0
    for a, b in claimed:
        if a > x:
            gaps.append((x, a))
        x = max(x, b)
    if x < fx1:
        gaps.append((x, fx1))
    for a, b in gaps:
        extra.append(Face("ground", np.array([0.0, 0.0, 1.0]), _rect_z(0.0, a, b, -FY, FY, 1.0), ("floor",)))

    if walls:
        zw = max(max(h) for h in heights) + WALL_CLEARANCE_M
        xs, xe = items[0].x0, items[-1].x1
        for side, sgn in (("l", 1.0), ("r", -1.0)):
            yi, yo = sgn * W, sgn * (W + WALL_THICKNESS_M)
            name = f"wall_{side}"
            boxes.append(_box(name, xs, xe, min(yi, yo), max(yi, yo), 0.0, zw, "wall"))
            extra.append(Face("wall", np.array([0.0, -sgn, 0.0]), _rect_y(yi, xs, xe, 0.0, zw, -sgn), (name,)))
            extra.append(Face("wall", np.array([0.0, sgn, 0.0]), _rect_y(yo, xs, xe, 0.0, zw, sgn), (name,)))
            ylo, yhi = min(yi, yo), max(yi, yo)
            extra.append(Face("wall", np.array([0.0, 0.0, 1.0]), _rect_z(zw, xs, xe, ylo, yhi, 1.0), (name,)))
            extra.append(Face("wall", np.array([-1.0, 0.0, 0.0]), _rect_x(xs, ylo, yhi, 0.0, zw, -1.0), (name,)))
            extra.append(Face("wall", np.array([1.0, 0.0, 0.0]), _rect_x(xe, ylo, yhi, 0.0, zw, 1.0), (name,)))

    return Terrain(boxes=boxes, faces=walk + extra, floor_x=(fx0, fx1), floor_half_y=FY, items=list(items), heights=heights)
