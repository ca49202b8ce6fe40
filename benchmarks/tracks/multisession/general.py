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

from typing import Any

import numpy as np

from .episodes import parse_sessions, session_scenario

GENERAL_CASES = 4
GENERAL_REGIONS = ("corridor_s", "corridor_n", "corridor_w", "corridor_e", "meeting", "office0")
STEP_M = 0.1  # the walked points' spacing


def walked_points(scenario: dict[str, Any], plan: Any) -> np.ndarray:
    """Points (N, 3) every :data:`STEP_M` along one session's planned walk, cut at ``max_distance_m``:
    x, y and the heading of the walk there (rad)."""
    from exobench.envs.sim.scenarios.office import WorldLook, compiled_office
    from exobench.models.office_routes import region_route

    office = session_scenario(scenario, plan)
    look = WorldLook(office.surfaces, office.light_level)
    script = office.change_script()
    world: dict[str, Any] = {} if script is None else {"changes": script, "day": office.day}
    scene = compiled_office(office.office_params(), office.exo_spec(), (), None if look.is_default else look, **world)
    wps = np.asarray(office.route_polyline(region_route(scene.truth, office.regions())))
    pts = []
    for a, b in zip(wps[:-1], wps[1:]):
        n = max(1, int(np.linalg.norm(b - a) / STEP_M))
        xy = a + np.arange(n)[:, None] / n * (b - a)
        pts.append(np.column_stack([xy, np.full(n, np.arctan2(b[1] - a[1], b[0] - a[0]))]))
    return np.concatenate(pts)


def general_scenario(run_seed: int, k: int) -> dict[str, Any]:
    """Case ``k`` of the general suite, drawn from ``(run_seed, k)`` (module docstring)."""
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
    script = draw_changes(build_layout(office.office_params()), change_seed, plans[-1].day, near=near)
    return {**base, "changes": script.compact()}
