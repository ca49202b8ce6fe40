"""The multisession track's general suite: offices, furniture, walks and changes drawn from the run seed.

A general case must exercise what the track measures: sessions that overlap, so that place
recognition can join them, and changes that the sessions see. Each case draws a building, its
furniture and two regions A and B; sessions 0 (day 0) and 1 (day 1) walk A then B, session 2
(day 1) walks A then a third region C: from the common start to A it walks the way the others
did, the same way round, then leaves them (as the paper's sessions overlap in part). The change
script of day 1 is drawn among the places these walks pass within reach of
(:func:`~exobench.models.office_changes.draw_changes` with ``near``: the day-0 walks, cut at
``max_distance_m``), and written into the case as the ``changes`` row, so the run's records
show it. Formerly the script was drawn anywhere in the building and session 2 walked B then A:
the changes stood 1.5-15 m from every walk, out of view, and in two of the four cases of run
seed 0 session 2 shared no view with the others (docs/tracks/multisession.md, The general suite).
"""

from __future__ import annotations

import functools
from typing import Any

import numpy as np

from .episodes import parse_sessions, session_scenario

GENERAL_CASES = 4
GENERAL_REGIONS = ("corridor_s", "corridor_n", "corridor_w", "corridor_e", "meeting", "office0")
STEP_M = 0.1  # the walked points' spacing
SHARED_M = 1.0  # a stretch this long gives several keyframes (one every 0.3 m) to match
DRAW_TRIES = 8


def walked_points(scenario: dict[str, Any], plan: Any) -> np.ndarray:
    """Points (N, 3) every :data:`STEP_M` along one session's planned walk, cut at ``max_distance_m``:
    x, y and the heading of the walk there (rad)."""
    from exobench.envs.sim.scenarios.office import region_waypoints

    wps = np.asarray(region_waypoints(session_scenario(scenario, plan)))
    pts = []
    for a, b in zip(wps[:-1], wps[1:]):
        n = max(1, int(np.linalg.norm(b - a) / STEP_M))
        xy = a + np.arange(n)[:, None] / n * (b - a)
        pts.append(np.column_stack([xy, np.full(n, np.arctan2(b[1] - a[1], b[0] - a[0]))]))
    return np.concatenate(pts)


def general_scenario(run_seed: int, k: int) -> dict[str, Any]:
    """Case ``k`` of the general suite, drawn from ``(run_seed, k)`` (module docstring)."""
    return dict(_general_case(int(run_seed), int(k)))


@functools.lru_cache(maxsize=64)
def _general_case(run_seed: int, k: int) -> tuple[tuple[str, Any], ...]:
    """:func:`general_scenario`'s rows, kept per process: a draw plans every session's walk (twice
    where a script is drawn again), and the suite is listed often (plans, checks, tests)."""
    return tuple(_draw(run_seed, k).items())


def _draw(run_seed: int, k: int) -> dict[str, Any]:
    from exobench.models.office_changes import draw_changes
    from exobench.models.office_layout import build_layout

    rng = np.random.default_rng([int(run_seed), 28, k])
    a, b = (str(x) for x in rng.choice(GENERAL_REGIONS, size=2, replace=False))
    office_seed, furniture_seed = int(rng.integers(0, 1000)), int(rng.integers(0, 1000))
    change_seed = int(rng.integers(0, 1000))
    c = str(rng.choice([r for r in GENERAL_REGIONS if r not in (a, b)]))
    sessions = f"0:{a},{b};1:{a},{b};1:{a},{c}"
    base = {"office_seed": office_seed, "furniture_seed": furniture_seed, "max_distance_m": 10.0,
            "surfaces": "textured", "sessions": sessions}  # fmt: skip
    plans = parse_sessions(sessions)
    day0 = [type(p)(p.session, 0, p.regions) for p in plans]  # the walks in the office as furnished
    near = np.concatenate([walked_points(base, p) for p in day0])
    office = session_scenario(base, day0[0])
    layout = build_layout(office.office_params())
    # the day-1 walks go round what the script puts in their way: a script after which a session
    # shares no stretch with an earlier one, or no day-1 walk sees a change, is drawn again from the
    # next seed (general/2 of seed 0: a trolley across corridor_w turned both day-1 walks east)
    for attempt in range(DRAW_TRIES):
        script = draw_changes(layout, change_seed + attempt, plans[-1].day, near=near)
        case = {**base, "changes": script.compact()}
        if _overlapping_and_seen(case, plans, layout, script):
            return case
    return case


def _overlapping_and_seen(case: dict[str, Any], plans: list[Any], layout: Any, script: Any) -> bool:
    """Each session shares :data:`SHARED_M` walked the same way round with an earlier one, and a
    day-1 walk sees every changed piece (``draw_changes``' own test of view, on the day-1 walks)."""
    from exobench.models.office_changes import NEAR_M, Seen, apply_changes, changed_ids

    walks = [walked_points(case, p) for p in plans]
    for i in range(1, len(walks)):
        if not any(_shared_m(walks[i], walks[j]) >= SHARED_M for j in range(i)):
            return False
    last = plans[-1].day
    seen = Seen(layout, np.concatenate([w for w, p in zip(walks, plans) if p.day == last]), NEAR_M)
    before, after = apply_changes(layout, script, last)
    spots = {q.id: [(q.x, q.y)] for q in before}
    for q in after:
        spots.setdefault(q.id, []).append((q.x, q.y))
    changed = changed_ids(before, after)
    return bool(changed) and all(seen.sees(x, y) for oid, kind in changed.items()
                                 for x, y in (spots[oid] if kind == "moved" else spots[oid][-1:]))


def _shared_m(a: np.ndarray, b: np.ndarray) -> float:
    """Metres of walk ``a`` within 0.5 m of walk ``b`` and heading within 30 deg of it there."""
    near = np.linalg.norm(a[:, None, :2] - b[None, :, :2], axis=-1) <= 0.5
    turn = np.abs((a[:, None, 2] - b[None, :, 2] + np.pi) % (2 * np.pi) - np.pi)
    return float((near & (turn <= np.radians(30.0))).any(axis=1).sum() * STEP_M)
