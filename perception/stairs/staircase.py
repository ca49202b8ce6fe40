"""Algorithm 1 of the staircase paper (seeds/004, Sec. IV): assign ToF points to surfaces S0..S4.

Points arrive one at a time from two ranging sensors, flagged ``"r"`` and ``"l"`` (the paper's
right and left sensor). :meth:`StaircaseAlgorithm.assign` is the paper's ``Assign(p, Q, S, f, id)``
and the private ``_surf_update`` its ``SurfUpdate(q, S_id, f)`` (:meth:`StaircaseAlgorithm.surf_update`
runs it on a new point directly):

- Each sensor has a FIFO ``Q`` of ``q`` points. Nothing is assigned until ``Q`` is full; then
  ``z_bar`` and ``sigma_z`` (population standard deviation, 1/q) are computed over ``Q``, the
  oldest point ``q`` is extracted, tested with lines 5-17, and the new point is inserted.
  The surface index ``id`` is shared by both sensors.
- Lines 5-17: even ``id`` (tread/ground): flat queue and ``|q_z - z_bar| < sigma_z`` -> S_id;
  non-flat queue and ``q_z > S_id.e_z + 1.5 th_z`` -> ``id += 1`` and S_id. Odd ``id`` (riser):
  non-flat -> S_id; flat -> ``id += 1`` first if ``q_z > S_{id-1}.e_z + th_pl``, then S_id.
  Every other case discards ``q``.
- ``SurfUpdate``: when the surface's FIFO ``B`` (``b`` points) is full its oldest point ``r`` is
  extracted and removed from the plane (eq. 17-18) if not ``|d| <= sigma_n``; ``q`` enters ``B``
  and the plane (eq. 15-16); the surface becomes reliable (``ok``) once it holds ``N`` points of
  each sensor; when S_id is reliable, ``Shift(S_{id-1}, S_id)`` runs.

Choices where the paper is silent or ambiguous (each is a :class:`StaircaseParams` field or
documented here):
- ``q``, ``b`` and ``N`` are not given in the paper. Defaults: ``q = 5`` (0.1 s of one sensor at
  50 Hz: short enough to span at most two adjacent surfaces, as Sec. IV-A requires, long enough
  for a meaningful ``sigma_z``), ``b = 10`` (each point is checked against a plane fitted with
  the 10 points after it) and ``N = 5`` (five points per sensor, the two segments Sec. II needs).
- Lines 14-17 (odd ``id``, flat queue, ``q_z`` not above ``S_{id-1}.e_z + th_pl``): the listing
  indents line 17 (``SurfUpdate``) outside the inner ``if``, so ``q`` is assigned to the riser;
  the prose of Sec. IV-A calls "any other situation" a discard. ``riser_flat_low="assign"``
  follows the listing (default), ``"discard"`` the prose.
- An empty surface has ``e_z = 0``: the structure starts zeroed, which in the paper's frame on
  the supporting foot (``stance_ground``) is the ground height, so line 8 works for S0.
- ``RemoveFromSurf`` decrements the count of the sensor that produced ``r`` (the flag is kept
  with each point in ``B``), not the flag of the point being added.
- ``Shift(S_{id-1}, S_id)`` moves the points still held in ``S_{id-1}.B`` whose distance to S_id
  is smaller than to S_{id-1} (the device keeps only ``B``, not the whole cloud). Distances are
  taken to the planes before any move; moved points leave ``S_{id-1}.B`` and enter the plane of
  S_id (eq. 15-16) but not its ``B``: they have just been checked against S_id.
- ``ok`` never goes back to false (the listing only ever sets it).
- The normal and ``sigma_n`` of a plane are computed once per change, when first needed, and at
  the latest at the end of the ``SurfUpdate`` that changed it (Sec. IV-B: ``AddToSurf`` computes
  ``n*``), so the eigen-decomposition is part of the work of the point that caused it and a
  later read-out of the planes costs no decomposition.
- The test ``|d| <= sigma_n`` allows 1e-12 m of round-off: for exactly coplanar points both
  sides are ~1e-17 m and the bare comparison would drop points at random.
- Options beyond the listing, each off by default here (the paper's Algorithm 1) and on in the
  ``rtls``/``rtls-htvr`` pipelines, which must read staircases across the building codes' range
  (risers 0.10-0.22 m) from any approach within +-30 deg:
  - ``sensor_ids="per_sensor"``: the paper's calling program keeps one ``id``; turned towards the
    stairs, the two beams cross each riser at different times (Sec. V-A notes it), so with one
    ``id`` the later beam's riser points are discarded and its last ground points go to the
    riser. Per sensor, each beam walks S0..S4 on its own; the surfaces stay shared.
  - ``riser_exit="travel"``: lines 14-16 read a flat queue as the next tread, but a beam that
    climbs a riser slowly or rests on it (the calf at the end of the swing) is flat too. The
    switch then also needs the queue to have moved horizontally by at least ``th_z`` and more
    than vertically, and ``q`` itself to pass line 5's test ``|q_z - z_bar| < sigma_z`` (a
    point from the top of the riser, a centimetre or two below a tread that fills the rest of
    the queue, leaves the queue flat but is not on the tread: joined to a tread a few
    centimetres long it tilts it by tens of degrees); otherwise ``q`` is discarded.
  - ``tread_travel``: likewise a beam resting on the next riser (the calf slowing at the end of
    the swing) gives a flat queue that line 5 reads as tread; with this option a tread point
    also needs the queue to have travelled (as ``riser_exit="travel"``). For general planes,
    where a few such points tilt the last tread; HTVR's horizontal treads only lose points by
    it.
  - ``tread_gate_m``: line 5 adds a point of a flat queue to the current tread; a beam resting
    on the riser above it (or on the riser below, seen past S4) passes that test. With a
    reliable tread the point must also lie within ``tread_gate_m`` of its plane.
  - ``reliable_n_riser``: at 50 Hz a beam crosses a riser in 4-8 samples, of which the queue
    test keeps a few; ``N = 5`` per sensor leaves S1 or S3 unreliable in two episodes of three,
    and the tread depth unread. Two points of each sensor already give the two segments of
    Sec. II.
- Only ``n_surfaces`` (5) surfaces exist: a switch beyond S4 stops the algorithm, and every later
  point is discarded.

Expect many discards: with Gaussian noise about a third of the tread points fail line 5's
``|q_z - z_bar| < sigma_z`` and about a third of the points leaving ``B`` lie beyond
``sigma_n``; on synthetic sweeps with 1.5 mm noise about 40-45 % of the points end in a surface.

The algorithm keeps, for every point it received, the surface it is in now (-1: discarded,
removed, or still waiting in ``Q``), so a harness can score the assignment.
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass, field

import numpy as np

from exobench.core.errors import ConfigError, check_int, check_range

from .rtls import PlaneFit, make_plane

__all__ = ["FLAGS", "StaircaseAlgorithm", "StaircaseParams", "Surface"]

FLAGS = ("r", "l")
# numerical guard of the test |d| <= sigma_n: exactly coplanar points give d and sigma_n of ~1e-17
_ROUNDOFF_M = 1e-12


@dataclass(frozen=True)
class StaircaseParams:
    """Parameters of Algorithm 1.

    Attributes:
        th_z_m: flatness threshold on ``sigma_z`` of the queue, m (paper: 8e-3).
        th_pl_m: minimum riser height before switching to the next tread, m (paper: 0.13).
        queue_q: length ``q`` of each sensor's FIFO ``Q`` (not in the paper; default 5).
        buffer_b: length ``b`` of each surface's FIFO ``B`` (not in the paper; default 10).
        reliable_n: points ``N`` needed from each sensor for ``ok`` (not in the paper; default 5).
        n_surfaces: number of surfaces S0..S_{n-1} (paper: 5).
        htvr: horizontal treads and vertical risers (Sec. V-B): even ids use a 1-D horizontal
            plane, odd ids a 2-D vertical one; otherwise every surface is a general plane.
        riser_flat_low: ``"assign"`` (listing of Algorithm 1) or ``"discard"`` (prose), see the
            module docstring.
        reliable_n_riser: ``N`` for the risers (odd ids); 0 (default) uses ``reliable_n`` for
            every surface as the paper does.
        tread_gate_m: a point that line 5 would add to a reliable tread must also lie within this
            distance of its plane; 0 (default) adds it as the paper does.
        sensor_ids: ``"shared"`` (one ``id`` for both sensors, the paper's calling program) or
            ``"per_sensor"`` (each sensor's ``Assign`` advances its own ``id``), see the module
            docstring.
        riser_exit: ``"paper"`` (lines 14-16: a flat queue above ``S_{id-1}.e_z + th_pl`` leaves
            the riser) or ``"travel"`` (it must also have moved horizontally), see the module
            docstring.
        tread_travel: a tread point (line 5) also needs the queue to have moved horizontally
            (default False: the paper's line 5), see the module docstring.
    """

    th_z_m: float = 8e-3
    th_pl_m: float = 0.13
    queue_q: int = 5
    buffer_b: int = 10
    reliable_n: int = 5
    n_surfaces: int = 5
    htvr: bool = False
    riser_flat_low: str = "assign"
    reliable_n_riser: int = 0
    tread_gate_m: float = 0.0
    sensor_ids: str = "shared"
    riser_exit: str = "paper"
    tread_travel: bool = False

    def __post_init__(self) -> None:
        check_range("th_z_m", self.th_z_m, 0.0, 1.0, low_open=True)
        check_range("th_pl_m", self.th_pl_m, 0.0, 2.0)
        check_range("tread_gate_m", self.tread_gate_m, 0.0, 1.0)
        for name, low in (("queue_q", 2), ("buffer_b", 1), ("reliable_n", 1), ("n_surfaces", 1), ("reliable_n_riser", 0)):
            object.__setattr__(self, name, check_int(name, getattr(self, name), low, 100_000))
        if self.riser_flat_low not in ("assign", "discard"):
            raise ConfigError("riser_flat_low", self.riser_flat_low, "'assign' or 'discard'")
        if self.sensor_ids not in ("shared", "per_sensor"):
            raise ConfigError("sensor_ids", self.sensor_ids, "'shared' or 'per_sensor'")
        if not isinstance(self.tread_travel, bool):
            raise ConfigError("tread_travel", self.tread_travel, "true or false")
        if self.riser_exit not in ("paper", "travel"):
            raise ConfigError("riser_exit", self.riser_exit, "'paper' or 'travel'")


@dataclass
class Surface:
    """The paper's structure ``S_id = {n, B, V, e, n*, sigma, ok}``.

    ``plane`` holds ``V``, ``e``, the normal and ``sigma_n``; ``buffer`` is ``B`` as point ids;
    ``n_by_flag`` is ``n = [n_r, n_l]``; ``reliable_uid`` is the id of the point whose ``Assign``
    call made the surface reliable.
    """

    index: int
    plane: PlaneFit
    buffer: deque = field(default_factory=deque)
    n_by_flag: dict[str, int] = field(default_factory=lambda: {f: 0 for f in FLAGS})
    ok: bool = False
    reliable_uid: int | None = None

    @property
    def e_z(self) -> float:
        """Height of the centroid; 0 for an empty surface (the zeroed structure)."""
        return self.plane.centroid_z() if self.plane.n else 0.0


class StaircaseAlgorithm:
    """Algorithm 1 on a stream of points, general or HTVR (see the module docstring).

    Points are kept as tuples of floats: the work per point is a few dozen scalar operations,
    which plain Python does faster than numpy calls on 3-vectors.
    """

    def __init__(self, params: StaircaseParams | None = None) -> None:
        self.params = params or StaircaseParams()
        self.reset()

    def reset(self) -> None:
        p = self.params
        kinds = [("horizontal" if i % 2 == 0 else "vertical") if p.htvr else "general" for i in range(p.n_surfaces)]
        self.surfaces: tuple[Surface, ...] = tuple(Surface(i, make_plane(k)) for i, k in enumerate(kinds))
        self._ids = {f: 0 for f in FLAGS}  # the surface under investigation, per sensor or shared
        self._queues: dict[str, deque[int]] = {f: deque() for f in FLAGS}
        self._points: list[tuple[float, float, float]] = []
        self._flags: list[str] = []
        self._where: list[int] = []
        self._call_uid = -1
        self.counts = {"n_assigned": 0, "n_discarded": 0, "n_removed": 0, "n_shifted": 0, "n_beyond_last": 0}

    # --- public read-out ---
    @property
    def current_id(self) -> int:
        """The surface under investigation (with ``per_sensor`` ids, the furthest of the two)."""
        return max(self._ids.values())

    @property
    def finished(self) -> bool:
        """True once a switch beyond the last surface happened (for every sensor)."""
        return min(self._ids.values()) >= self.params.n_surfaces

    def surface_of(self, uid: int) -> int:
        """Surface the point ``uid`` is in now, -1 if none."""
        return self._where[uid]

    def point_surfaces(self) -> np.ndarray:
        """Surface of every point received so far, in arrival order (-1: none)."""
        return np.array(self._where, dtype=int)

    def points(self) -> np.ndarray:
        """Every point received so far, shape (N, 3)."""
        return np.array(self._points, dtype=float).reshape(-1, 3)

    # --- Algorithm 1 ---
    def _register(self, p: np.ndarray | tuple[float, float, float], flag: str) -> int:
        if flag not in FLAGS:
            raise ConfigError("flag", flag, "'r' or 'l'")
        if type(p) is not tuple:
            p = np.asarray(p, dtype=float).reshape(3).tolist()
        x, y, z = p
        uid = len(self._points)
        self._points.append((float(x), float(y), float(z)))
        self._flags.append(flag)
        self._where.append(-1)
        self._call_uid = uid
        return uid

    def assign(self, p: np.ndarray | tuple[float, float, float], flag: str) -> int:
        """``Assign(p, Q_f, S, f, id)``; returns the id given to ``p`` (its arrival index).

        ``p`` is a point (3,), as an array or a tuple of floats.
        """
        uid = self._register(p, flag)
        Q = self._queues[flag]
        if len(Q) >= self.params.queue_q:
            pts = self._points
            zs = [pts[u][2] for u in Q]
            n = len(zs)
            z_bar = sum(zs) / n
            sigma_z = math.sqrt(sum([(z - z_bar) ** 2 for z in zs]) / n)
            qu = Q.popleft()
            self._decide(qu, pts[qu][2], z_bar, sigma_z, flag, Q)
        Q.append(uid)
        return uid

    def _travelled(self, qu: int, Q: deque[int]) -> bool:
        """Whether the queue (``qu`` and the points after it) moved horizontally by at least
        ``th_z`` and more than vertically: the beam sweeps a tread, not a riser or one spot."""
        pts = self._points
        x0, y0, z0 = pts[qu]
        x1, y1, z1 = pts[Q[-1]]
        h = math.hypot(x1 - x0, y1 - y0)
        return h >= self.params.th_z_m and h > abs(z1 - z0)

    def _decide(self, qu: int, q_z: float, z_bar: float, sigma_z: float, flag: str, Q: deque[int]) -> None:
        """Lines 5-17 for the extracted point ``qu`` of sensor ``flag`` (``Q``: the rest of its queue)."""
        p = self.params
        i = self._ids[flag]
        target = None
        if i >= p.n_surfaces:
            self.counts["n_beyond_last"] += 1
        elif i % 2 == 0:
            if sigma_z < p.th_z_m and abs(q_z - z_bar) < sigma_z and (not p.tread_travel or self._travelled(qu, Q)):
                S = self.surfaces[i]
                if not (p.tread_gate_m and S.ok and abs(S.plane.distance3(*self._points[qu])) > p.tread_gate_m):
                    target = i
            elif sigma_z >= p.th_z_m and q_z > self.surfaces[i].e_z + 1.5 * p.th_z_m:
                target = i + 1
        elif sigma_z >= p.th_z_m:
            target = i
        elif q_z > self.surfaces[i - 1].e_z + p.th_pl_m:
            if p.riser_exit == "paper" or (self._travelled(qu, Q) and abs(q_z - z_bar) < sigma_z):
                target = i + 1
        elif p.riser_flat_low == "assign":
            target = i
        if target is None:
            self.counts["n_discarded"] += 1
            return
        if p.sensor_ids == "shared":
            self._ids["r"] = self._ids["l"] = target
        else:
            self._ids[flag] = target
        if target >= p.n_surfaces:
            self.counts["n_beyond_last"] += 1
            return
        self._surf_update(qu, self.surfaces[target])

    def surf_update(self, p: np.ndarray | tuple[float, float, float], flag: str, index: int) -> int:
        """``SurfUpdate(p, S_index, f)`` on a new point, bypassing ``Assign``; returns its id.

        For callers that assign points by other means, and for testing the update on its own.
        """
        if not 0 <= index < self.params.n_surfaces:
            raise ConfigError("index", index, f"0 <= index < {self.params.n_surfaces}")
        uid = self._register(p, flag)
        self._surf_update(uid, self.surfaces[index])
        return uid

    def _surf_update(self, qu: int, S: Surface) -> None:
        """``SurfUpdate(q, S_id, f)`` (lines 19-30)."""
        p = self.params
        counts = self.counts
        counts["n_assigned"] += 1
        plane, B = S.plane, S.buffer
        if len(B) >= p.buffer_b:
            r = B.popleft()
            x, y, z = self._points[r]
            if not (abs(plane.distance3(x, y, z)) <= plane.fit3()[3] + _ROUNDOFF_M):
                self._remove_from_surf(r, S)
                counts["n_removed"] += 1
        B.append(qu)
        self._add_to_surf(qu, S)
        if not S.ok:
            nb, need = S.n_by_flag, p.reliable_n
            if S.index % 2 and p.reliable_n_riser:
                need = p.reliable_n_riser
            if nb["r"] >= need and nb["l"] >= need:  # N points of each sensor (FLAGS)
                S.ok = True
                S.reliable_uid = self._call_uid
        if S.ok and S.index > 0:
            self._shift(self.surfaces[S.index - 1], S)
        S.plane.fit3()  # AddToSurf computes n* (Sec. IV-B): the fit is part of this update

    def _add_to_surf(self, u: int, S: Surface) -> None:
        x, y, z = self._points[u]
        S.plane.add3(x, y, z)
        S.n_by_flag[self._flags[u]] += 1
        self._where[u] = S.index

    def _remove_from_surf(self, u: int, S: Surface) -> None:
        x, y, z = self._points[u]
        S.plane.remove3(x, y, z)
        S.n_by_flag[self._flags[u]] -= 1
        self._where[u] = -1

    def _shift(self, prev: Surface, cur: Surface) -> None:
        """``Shift(S_{id-1}, S_id)``: move points of ``prev.B`` that are closer to ``cur``."""
        if not prev.buffer:
            return
        # distances to both planes as they are before any move
        pnx, pny, pnz, _ = prev.plane.fit3()
        pex, pey, pez = prev.plane.centroid3()
        cnx, cny, cnz, _ = cur.plane.fit3()
        cex, cey, cez = cur.plane.centroid3()
        pts = self._points
        move = []
        for u in prev.buffer:
            x, y, z = pts[u]
            d_prev = abs((x - pex) * pnx + (y - pey) * pny + (z - pez) * pnz)
            d_cur = abs((x - cex) * cnx + (y - cey) * cny + (z - cez) * cnz)
            if d_cur < d_prev:
                move.append(u)
        for u in move:
            prev.buffer.remove(u)
            self._remove_from_surf(u, prev)
            self._add_to_surf(u, cur)
        if move:
            prev.plane.fit3()
        self.counts["n_shifted"] += len(move)
