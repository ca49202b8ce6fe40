"""The stairs track's ``general`` suite: staircases never seen, drawn from the run seed.

The paper's three staircases (Tab. III) are a narrow slice of what a user meets. This suite draws
staircases across the building codes' range, poses and users from a generator seeded by the run
seed, so that a pipeline cannot be tuned on a fixed list: ``--seeds 3`` gives three different
draws. A draw that the climbing-step planner cannot walk (a foot longer than a short tread, for
a tall user) is replaced by the next draw, so every case simulates.
"""

from __future__ import annotations

import functools

import numpy as np

from exobench.core.errors import ConfigError

from ..spec import Case

GENERAL_SEED = 14  # the issue that asked for this suite
GENERAL_EPISODES = 60
RISER_RANGE_M = (0.10, 0.22)  # building codes' range
TREAD_RANGE_M = (0.22, 0.35)
YAW_RANGE_DEG = (-30.0, 30.0)
DISTANCE_RANGE_M = (0.25, 0.50)
USER_HEIGHT_RANGE_M = (1.55, 1.95)
GROUP = "general"
MAX_DRAWS = 4 * GENERAL_EPISODES


def _draw(rng: np.random.Generator) -> dict[str, float]:
    return {
        "riser_m": round(float(rng.uniform(*RISER_RANGE_M)), 4),
        "tread_m": round(float(rng.uniform(*TREAD_RANGE_M)), 4),
        "yaw_deg": round(float(rng.uniform(*YAW_RANGE_DEG)), 2),
        "distance_m": round(float(rng.uniform(*DISTANCE_RANGE_M)), 4),
        "user_height_m": round(float(rng.uniform(*USER_HEIGHT_RANGE_M)), 3),
    }


def _walkable(values: dict[str, float]) -> bool:
    from exobench.envs.sim import StairScenario, plan_climb

    try:
        plan_climb(StairScenario.from_dict(values))
    except ConfigError:
        return False
    return True


@functools.lru_cache(maxsize=8)
def general_cases(run_seed: int, n: int = GENERAL_EPISODES) -> tuple[Case, ...]:
    """``n`` walkable draws for ``run_seed`` (deterministic; planned once per process)."""
    rng = np.random.default_rng([GENERAL_SEED, int(run_seed)])
    out: list[Case] = []
    for _ in range(MAX_DRAWS):
        values = _draw(rng)
        if _walkable(values):
            out.append(Case(f"general/{len(out):02d}", GROUP, values))
            if len(out) == n:
                return tuple(out)
    raise ConfigError("general suite", run_seed, f"a seed giving {n} walkable staircases in {MAX_DRAWS} draws")
