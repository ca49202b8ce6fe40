"""What every simulated sensor shares: its random streams, its sampling times, its timing checks.

Every sensor draws from its own generators, derived from
``np.random.SeedSequence([seed, stable_int_key(sensor_id)])``, so a sensor's noise does not depend
on which other sensors run, nor its dropout on its noise. Timing: a sensor measures at
``k / rate_hz`` (k = 0, 1, ...); a frame is delivered (stamped) at measurement time +
``latency_s`` and dropped with probability ``dropout_prob``. The ray-cast sensors (ToF, LiDAR)
see the geom groups :data:`WORLD_GROUP` and :data:`EXO_GROUP`.
"""

from __future__ import annotations

import zlib

import numpy as np

from exobench.core import ConfigError, check_range

WORLD_GROUP, EXO_GROUP = 0, 2
"""MuJoCo geom groups of the world and of the exoskeleton (what ray-cast sensors see)."""


def stable_int_key(name: str) -> int:
    """A stable 32-bit integer for a name (CRC-32; unlike ``hash`` it is the same in every run)."""
    return zlib.crc32(name.encode("utf-8"))


def sensor_rngs(seed: int, sensor_id: str) -> tuple[np.random.Generator, np.random.Generator]:
    """(noise, dropout) generators of one sensor for a scenario seed."""
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise ConfigError("seed", seed, "an integer >= 0")
    noise, drop = np.random.SeedSequence([int(seed), stable_int_key(sensor_id)]).spawn(2)
    return np.random.default_rng(noise), np.random.default_rng(drop)


def sample_times(rate_hz: float, duration_s: float) -> np.ndarray:
    """Measurement times ``k / rate_hz`` in [0, duration_s] (exact multiples, so streams at
    commensurate rates share time stamps exactly)."""
    n = int(np.floor(duration_s * rate_hz + 1e-9)) + 1
    return np.arange(n) / rate_hz


def check_timing(prefix: str, rate_hz: float, latency_s: float, dropout_prob: float) -> None:
    """The common checks of a sampled sensor's ``rate_hz`` (Hz), ``latency_s`` (s) and ``dropout_prob``."""
    check_range(f"{prefix}.rate_hz", rate_hz, 0.0, 10000.0, low_open=True)
    check_range(f"{prefix}.latency_s", latency_s, 0.0, 1.0)
    check_range(f"{prefix}.dropout_prob", dropout_prob, 0.0, 1.0, high_open=True)
