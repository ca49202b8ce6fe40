"""Routes through chosen regions of an office, round whatever stands there that day (numpy, scipy).

The fixed office routes (``loop``, ``ring``, ``corridor``: :func:`exobench.models.office.office_route`)
are polylines drawn with the building and know nothing of furniture moved or obstacles put in a
corridor. :func:`region_route` plans on the day's floor instead: a 5 cm grid of the floor where
every solid standing between the floor and :data:`WALKER_HEIGHT_M` blocks the cells its
footprint touches (cylinders and spheres by their bounding squares), kept only where the nearest
blocked cell is farther than the walker's clearance; a shortest 8-connected path (Dijkstra,
``scipy.sparse.csgraph``) from the start to a point of each region in turn, cut into straight
segments that keep the clearance. The result has the format of the office routes: waypoints
(x, y), straight walking between consecutive ones free.

The walker's size is the paper's: a box 0.5 x 0.5 x 1.8 m approximates the exoskeleton with its
user for planning (seeds/000 IV-D), so its half-width is 0.25 m; routes keep
:data:`ROUTE_CLEARANCE_M` = 0.30 m from everything (5 cm for the sway of the walk).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from exobench.core.errors import ConfigError, UnknownNameError

from .office_furniture import Solid

WALKER_HALF_WIDTH_M = 0.25
WALKER_HEIGHT_M = 1.8
ROUTE_CLEARANCE_M = 0.30
CELL_M = 0.05
CENTRE_M, CENTRE_WEIGHT = 0.9, 2.0  # see region_route
SHORT_SEGMENT_M = 0.3  # the walk drops shorter segments (envs.sim.scenarios.office.MIN_SEGMENT_M)


@dataclass(frozen=True)
class FloorGrid:
    """Which cells of the floor are blocked: cell (i, j) covers [x0 + i c, x0 + (i + 1) c] x
    [y0 + j c, ...]; cells outside every region are blocked."""

    x0: float
    y0: float
    cell_m: float
    blocked: np.ndarray  # (nx, ny) bool

    def centre(self, ij: np.ndarray) -> np.ndarray:
        return np.array([self.x0, self.y0]) + (np.asarray(ij, dtype=float) + 0.5) * self.cell_m

    def index(self, xy: Sequence[float]) -> tuple[int, int]:
        return (int(math.floor((xy[0] - self.x0) / self.cell_m)), int(math.floor((xy[1] - self.y0) / self.cell_m)))

    def free(self, clearance_m: float) -> np.ndarray:
        """Cells whose centre is at least ``clearance_m`` from anything blocked, with a cell to spare
        for the cells' own size (a free cell's centre is that far from every solid)."""
        from scipy.ndimage import distance_transform_edt

        if not self.blocked.any():
            return np.ones_like(self.blocked)
        return distance_transform_edt(~self.blocked) * self.cell_m >= clearance_m + self.cell_m

    def cells_in(self, rect: Sequence[float]) -> tuple[slice, slice]:
        """The cells whose centres lie in ``rect`` (x0, x1, y0, y1)."""
        c = self.cell_m
        i0, i1 = math.ceil((rect[0] - self.x0) / c - 0.5), math.floor((rect[1] - self.x0) / c - 0.5)
        j0, j1 = math.ceil((rect[2] - self.y0) / c - 0.5), math.floor((rect[3] - self.y0) / c - 0.5)
        nx, ny = self.blocked.shape
        return slice(max(i0, 0), min(i1 + 1, nx)), slice(max(j0, 0), min(j1 + 1, ny))


def standing(solids: Sequence[Solid], height_m: float = WALKER_HEIGHT_M) -> list[Solid]:
    """The solids a walker of ``height_m`` cannot pass over or under (no floors and ceilings)."""
    return [s for s in solids if s.shape != "plane" and s.lo[2] < height_m and s.hi[2] > 1e-6]


def floor_grid(solids: Sequence[Solid], regions: Sequence[dict], extent: Sequence[float], cell_m: float = CELL_M) -> FloorGrid:
    """The blocked cells of a floor (see :class:`FloorGrid`)."""
    x0, x1, y0, y1 = extent
    nx, ny = math.ceil((x1 - x0) / cell_m), math.ceil((y1 - y0) / cell_m)
    grid = FloorGrid(x0, y0, cell_m, np.ones((nx, ny), dtype=bool))
    on_floor = np.zeros((nx, ny), dtype=bool)
    for r in regions:
        on_floor[_touched(grid, r["rect"], inside=True)] = True
    blocked = ~on_floor
    for s in standing(solids):
        blocked[_touched(grid, (s.lo[0], s.hi[0], s.lo[1], s.hi[1]))] = True
    return FloorGrid(x0, y0, cell_m, blocked)


def _touched(grid: FloorGrid, rect: Sequence[float], inside: bool = False) -> tuple[slice, slice]:
    """Cells that ``rect`` touches (or, ``inside``, whose centres it holds)."""
    if inside:
        return grid.cells_in(rect)
    c = grid.cell_m
    nx, ny = grid.blocked.shape
    i0, i1 = math.floor((rect[0] - grid.x0) / c), math.ceil((rect[1] - grid.x0) / c)
    j0, j1 = math.floor((rect[2] - grid.y0) / c), math.ceil((rect[3] - grid.y0) / c)
    return slice(max(i0, 0), min(i1, nx)), slice(max(j0, 0), min(j1, ny))


def corridor_open(grid: FloorGrid, rect: Sequence[float], clearance_m: float = ROUTE_CLEARANCE_M) -> bool:
    """Whether a walker can still get from one end of a corridor (``rect``, its long side the
    corridor's axis) to the other within it: a free path joins the squares at its two ends."""
    from scipy.ndimage import label

    si, sj = grid.cells_in(rect)
    free = grid.free(clearance_m)[si, sj]
    if rect[1] - rect[0] < rect[3] - rect[2]:
        free = free.T
    labels, _ = label(free, structure=np.ones((3, 3)))
    # the ends: a square of the corridor's width at each end (where it meets the cross
    # corridor, or the wall it ends at)
    n = min(free.shape[1], free.shape[0] // 2)
    a, b = labels[:n], labels[-n:]
    return bool(set(a[a > 0].tolist()) & set(b[b > 0].tolist()))


def _pair(d: int, n: int) -> tuple[slice, slice]:
    """Index ranges of the cells and of their neighbours ``d`` further on, along one axis."""
    return slice(max(0, -d), n - max(0, d)), slice(max(0, d), n - max(0, -d))


def _graph(free: np.ndarray, cost: np.ndarray) -> object:
    """The free cells as a graph (scipy CSR): 8-connected, a step of 1 or sqrt(2) cells times the
    mean ``cost`` of its two cells."""
    from scipy.sparse import coo_matrix

    nx, ny = free.shape
    idx = np.arange(nx * ny).reshape(nx, ny)
    rows, cols, w = [], [], []
    for di, dj in ((1, 0), (0, 1), (1, 1), (1, -1)):
        (ai, bi), (aj, bj) = _pair(di, nx), _pair(dj, ny)
        ok = free[ai, aj] & free[bi, bj]
        if di and dj:  # a diagonal step only where both straight steps are free too
            ok &= free[bi, aj] & free[ai, bj]
        ia, ib = idx[ai, aj][ok], idx[bi, bj][ok]
        rows += [ia, ib]
        cols += [ib, ia]
        step = math.hypot(di, dj) * 0.5 * (cost.ravel()[ia] + cost.ravel()[ib])
        w += [step, step]
    r, c, v = np.concatenate(rows), np.concatenate(cols), np.concatenate(w)
    return coo_matrix((v, (r, c)), shape=(nx * ny, nx * ny)).tocsr()


def _visible(grid: FloorGrid, free: np.ndarray, a: np.ndarray, b: np.ndarray) -> bool:
    n = max(2, math.ceil(np.linalg.norm(b - a) / (grid.cell_m / 4)) + 1)
    pts = a + np.linspace(0.0, 1.0, n)[:, None] * (b - a)
    ij = np.floor((pts - [grid.x0, grid.y0]) / grid.cell_m).astype(int)
    return bool(free[ij[:, 0], ij[:, 1]].all())


def _simplify(grid: FloorGrid, free: np.ndarray, pts: np.ndarray) -> list[np.ndarray]:
    """Few straight segments along a path of cells: each as long as it keeps the clearance, then
    the corners that the next and previous ones can skip dropped (the walk's route drops
    segments shorter than 0.3 m itself, so few short ones are left for it to cut)."""
    out, i = [pts[0]], 0
    while i < len(pts) - 1:
        j = i + 1
        while j + 1 < len(pts) and _visible(grid, free, pts[i], pts[j + 1]):
            j += 1
        out.append(pts[j])
        i = j
    k = 1
    while k < len(out) - 1:
        if _visible(grid, free, out[k - 1], out[k + 1]):
            del out[k]
        else:
            k += 1
    k = 1
    while k < len(out) - 2:  # two corners closer than a short segment: one between them, if it keeps clear
        m = 0.5 * (out[k] + out[k + 1])
        if np.linalg.norm(out[k + 1] - out[k]) < SHORT_SEGMENT_M and _visible(grid, free, out[k - 1], m) \
                and _visible(grid, free, m, out[k + 2]):
            out[k:k + 2] = [m]
        else:
            k += 1
    return out


def region_route(truth: object, regions: Sequence[str], clearance_m: float = ROUTE_CLEARANCE_M,
                 cell_m: float = CELL_M) -> list[tuple[float, float]]:
    """Waypoints (x, y) from the office's start through a point of each named region in turn,
    keeping ``clearance_m`` from every solid standing that day (see the module docstring).

    A region's point is the free cell nearest its centre that can be reached; a region with
    none (closed off, or too full that day) raises ``ConfigError``; an unknown name
    ``UnknownNameError``.
    """
    from scipy.sparse.csgraph import dijkstra

    from .office_truth import solids_from_truth

    params = truth.params  # type: ignore[attr-defined]
    by_name = {r["name"]: r for r in params["regions"]}
    for name in regions:
        if name not in by_name:
            raise UnknownNameError("office region", name, by_name)
    if not regions:
        raise ConfigError("route_regions", "", "at least one region name")
    grid = floor_grid(solids_from_truth(truth), params["regions"], params["extent_m"], cell_m)
    free = grid.free(clearance_m)
    # keep to the middle of corridors and doors where there is room: a step costs up to
    # (1 + CENTRE_WEIGHT) times more the nearer it comes to anything than CENTRE_M
    from scipy.ndimage import distance_transform_edt

    near = np.clip((CENTRE_M - distance_transform_edt(~grid.blocked) * cell_m) / CENTRE_M, 0.0, 1.0)
    cost = 1.0 + CENTRE_WEIGHT * near
    start = np.asarray(params["start_w"][:2], dtype=float)
    s = grid.index(start)
    if not free[s]:
        raise ConfigError("route_regions", ",".join(regions), f"a start at {start.tolist()} with {clearance_m} m clear")
    g = _graph(free, cost)
    ny = free.shape[1]
    path: list[np.ndarray] = [start]
    here = s[0] * ny + s[1]
    for name in regions:
        dist, pred = dijkstra(g, indices=here, return_predecessors=True)
        dist = dist.reshape(free.shape)
        r = by_name[name]
        si, sj = grid.cells_in(r.get("clear", r["rect"]))
        reach = np.zeros_like(free)
        reach[si, sj] = np.isfinite(dist[si, sj])
        if not reach.any():
            raise ConfigError("route_regions", name, f"a region the walker can reach with {clearance_m} m clear that day")
        cand = np.argwhere(reach)
        centre = np.array([0.5 * (r["rect"][0] + r["rect"][1]), 0.5 * (r["rect"][2] + r["rect"][3])])
        ti, tj = cand[int(np.argmin(np.linalg.norm(grid.centre(cand) - centre, axis=1)))]
        goal = int(ti) * ny + int(tj)
        cells = [goal]
        while cells[-1] != here:
            cells.append(int(pred[cells[-1]]))
        leg = grid.centre(np.array([divmod(c, ny) for c in cells[::-1]]))
        leg[0] = path[-1]  # the leg starts where the last one ended (the start: exactly)
        path += _simplify(grid, free, leg)[1:]
        here = goal
    return [(float(p[0]), float(p[1])) for p in path]


@dataclass(frozen=True)
class _Floor:
    """What :func:`region_route` reads of an office's truth: its ``params``."""

    params: dict


def layout_route(layout: object, regions: Sequence[str], start_w: Sequence[float] | None = None,
                 clearance_m: float = ROUTE_CLEARANCE_M, cell_m: float = CELL_M) -> list[tuple[float, float]]:
    """:func:`region_route` on a layout (``models.office_layout.Layout``, furnished for the day)
    standing at ``start_w`` (None: the layout's start), instead of on a built office's truth:
    ``build_office`` writes these very regions, extent, start and solids into its truth, so the
    waypoints are the same, without building the office (its model and surfaces; with a look,
    its textures too: planning a general multisession case's walks took 4/5 of their time there)."""
    params = {"regions": layout.regions, "extent_m": list(layout.extent),  # type: ignore[attr-defined]
              "start_w": list(layout.start_w if start_w is None else start_w),  # type: ignore[attr-defined]
              "solids": [s.as_dict() for s in layout.solids]}  # type: ignore[attr-defined]  # fmt: skip
    return region_route(_Floor(params), regions, clearance_m, cell_m)


__all__ = ["CELL_M", "ROUTE_CLEARANCE_M", "WALKER_HALF_WIDTH_M", "WALKER_HEIGHT_M", "FloorGrid", "corridor_open",
           "floor_grid", "layout_route", "region_route", "standing"]
