"""The vio track's ``general`` suite: sequences nobody has seen, drawn from the run seed.

Each run seed draws :data:`GENERAL_EPISODES` sequences from a generator seeded by
(:data:`GENERAL_SEED`, run seed): the world (an office of its own seed, size, glazing and floors,
a route, a length, sometimes there and back; or a stair or ramp course), the mount, the user
(1.65-1.88 m), the pace, the surfaces (textured, as built, now and then featureless), the texture
seed and the light level (a dim room to a bright one). So ``--seeds 3`` gives three sets of
sequences. Courses are drawn only among the geometries the walker walks for every pattern and
user height (:mod:`exobench.envs.sim.scenarios.course`: 0.15/0.20 m risers with 0.30 m treads,
11.8-17.8 deg ramps), so every draw simulates.
"""

from __future__ import annotations

import functools
from typing import Any

import numpy as np

from ..spec import Case
from .paper import MOUNTS, PACES, STAIRWELL

GENERAL_SEED = 27  # the issue that asked for this suite
GENERAL_EPISODES = 8
USER_RANGE_M = (1.65, 1.88)
LENGTH_RANGE_M = (20.0, 60.0)
LIGHT_RANGE = (0.3, 1.5)
SURFACES = ("textured", "textured", "textured", "default", "featureless")
ROUTES = ("loop", "ring", "corridor")
GROUP = "general"


def _draw(rng: np.random.Generator) -> dict[str, Any]:
    common: dict[str, Any] = {
        "mount": str(rng.choice(MOUNTS)),
        "user_height_m": round(float(rng.uniform(*USER_RANGE_M)), 3),
        "surfaces": str(rng.choice(SURFACES)),
        "light_level": round(float(rng.uniform(*LIGHT_RANGE)), 2),
    }
    pace = str(rng.choice(tuple(PACES)))
    if rng.uniform() < 0.6:
        step, swing = PACES[pace]
        return {"world": "office", "office_seed": int(rng.integers(0, 2**31 - 1)), "n_offices": int(rng.integers(2, 7)),
                "glass_fraction": round(float(rng.uniform(0.0, 0.8)), 2),
                "polished_fraction": round(float(rng.uniform(0.0, 0.8)), 2), "route": str(rng.choice(ROUTES)),
                "max_distance_m": round(float(rng.uniform(*LENGTH_RANGE_M)), 1), "out_and_back": bool(rng.uniform() < 0.3),
                "step_length_m": step, "swing_s": swing, **common}  # fmt: skip
    terrain = str(rng.choice(("stairs", "ramp")))
    geometry = ({"riser_m": float(rng.choice((0.15, 0.20))), "tread_m": 0.30, "n_steps": int(rng.integers(3, 6))}
                if terrain == "stairs" else {"slope_deg": float(rng.choice((11.8, 15.8, 17.8)))})  # fmt: skip
    return {"world": "course", "terrain": terrain, **geometry, "pattern": pace,
            "texture_seed": int(rng.integers(0, 2**31 - 1)), **STAIRWELL, **common}  # fmt: skip


@functools.lru_cache(maxsize=8)
def general_cases(run_seed: int, n: int = GENERAL_EPISODES) -> tuple[Case, ...]:
    """``n`` sequences for ``run_seed`` (deterministic)."""
    from exobench.envs.sim.scenario import OMIT_AT_DEFAULT

    rng = np.random.default_rng([GENERAL_SEED, int(run_seed)])
    draws = [_draw(rng) for _ in range(n)]
    # a value at its neutral default is left out, as a validated scenario leaves it out
    draws = [{k: v for k, v in d.items() if not (k in OMIT_AT_DEFAULT and v == OMIT_AT_DEFAULT[k])} for d in draws]
    return tuple(Case(f"general/{i:02d}", GROUP, d, figure=True) for i, d in enumerate(draws))
