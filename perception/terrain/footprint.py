"""Walking information: gait division by heel strike and next-footprint prediction (seeds/002, II-D).

At each heel strike (an insole's heel pad starts to press) the odometry position p_i and velocity
v_i of the tracked body (camera/IMU) are recorded. Then

- eq. 16, step size between adjacent divisions: delta_i = ||p_i - p_{i-1}||;
- eq. 17, next step size, first order: delta_nxt = 2 delta_n - delta_{n-1};
- eq. 18, predicted position: p_pd = p_n + v_n / ||v_n|| * delta_nxt;

and the footprint of the foot that strikes next (the other foot than at the last strike) is p_pd
plus that foot's offset. The paper only says "specific offsets"; here an offset is a vector in
the heading frame at p_pd (x forward along the horizontal part of v_n, y to the left, z up), by
default +-``half_step_width_m`` sideways [A: 0.08 m], nothing forward or down (projecting the
footprint on the terrain is left to the terrain model). Pure numpy; positions in metres in any
gravity-aligned frame (z up).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from exobench.core import ConfigError, check_int

SIDES = ("l", "r")


@dataclass(frozen=True)
class HeelStrike:
    """One gait division: time, foot and the odometry state recorded at that instant."""

    stamp_s: float
    side: str
    p_world: np.ndarray
    v_world: np.ndarray


def step_sizes(positions_m: np.ndarray) -> np.ndarray:
    """Eq. 16: delta_i = ||p_i - p_{i-1}|| for consecutive division positions (n, 3) -> (n-1,)."""
    p = np.asarray(positions_m, dtype=float)
    return np.linalg.norm(np.diff(p, axis=0), axis=1)


def next_step_size(deltas_m: np.ndarray) -> float:
    """Eq. 17: delta_nxt = 2 delta_n - delta_{n-1} from the last two step sizes (may be < 0)."""
    d = np.asarray(deltas_m, dtype=float)
    if d.size < 2:
        raise ValueError(f"eq. 17 needs the last two step sizes, got {d.size}")
    return float(2.0 * d[-1] - d[-2])


STEP_ESTIMATES = ("eq17", "eq17_clamped", "eq17_capped", "median")


def robust_next_step_size(deltas_m: np.ndarray, method: str = "eq17_clamped", n_recent: int = 3) -> float:
    """Next step size from the recent ones, by ``method``:

    - ``"eq17"``: eq. 17 as published (first-order extrapolation of the last two);
    - ``"eq17_clamped"`` [deviation]: eq. 17 clamped to the range of the last ``n_recent`` step
      sizes. A stop-and-go (exoskeleton) walker makes very uneven steps near transitions (a
      0.1 m shuffle to stop before a stair, a full step after it): unclamped, eq. 17 then predicts
      a step backwards or a step longer than any seen, far off the terrain ahead;
    - ``"eq17_capped"`` [deviation]: eq. 17 bounded by 0 and the longest of the last ``n_recent``
      step sizes (a slowing walker keeps eq. 17's shorter step, no step backwards or longer
      than any seen);
    - ``"median"`` [deviation]: the median of the last ``n_recent`` step sizes.
    """
    d = np.asarray(deltas_m, dtype=float)
    if method not in STEP_ESTIMATES:
        raise ValueError(f"method must be one of {STEP_ESTIMATES}, got {method!r}")
    if d.size < 2:
        raise ValueError(f"the next step size needs at least two step sizes, got {d.size}")
    recent = d[-max(2, int(n_recent)):]
    if method == "median":
        return float(np.median(recent))
    delta = next_step_size(d)
    if method == "eq17_clamped":
        delta = float(np.clip(delta, recent.min(), recent.max()))
    elif method == "eq17_capped":
        delta = float(np.clip(delta, 0.0, recent.max()))
    return delta


def predict_position(p_last_m: np.ndarray, v_last_m_s: np.ndarray, delta_next_m: float) -> np.ndarray:
    """Eq. 18: p_pd = p_n + v_n / ||v_n|| * delta_nxt."""
    v = np.asarray(v_last_m_s, dtype=float)
    speed = float(np.linalg.norm(v))
    if speed <= 0.0:
        raise ValueError("eq. 18 needs a non-zero velocity at the last heel strike")
    return np.asarray(p_last_m, dtype=float) + v / speed * delta_next_m


def heading_frame(v_m_s: np.ndarray) -> np.ndarray:
    """3x3 rotation world <- heading (x = horizontal direction of v, y left, z up)."""
    x = np.array([v_m_s[0], v_m_s[1], 0.0], dtype=float)
    n = np.linalg.norm(x)
    if n <= 1e-9:
        raise ValueError("the walking direction is undefined: horizontal velocity is zero")
    x /= n
    z = np.array([0.0, 0.0, 1.0])
    return np.column_stack([x, np.cross(z, x), z])


@dataclass(frozen=True)
class FootprintConfig:
    """Offsets of the left and right footprint from p_pd in the heading frame, m.

    ``min_step_m``: lower bound of delta_nxt (None = eq. 17 unchanged, as in the paper, where a
    slowing walker can get a negative next step). ``step_estimate``, ``n_recent``: how delta_nxt
    is found (:func:`robust_next_step_size`; ``"eq17"`` is the paper's eq. 17).
    """

    offset_l_m: tuple[float, float, float] = (0.0, 0.08, 0.0)
    offset_r_m: tuple[float, float, float] = (0.0, -0.08, 0.0)
    min_step_m: float | None = None
    step_estimate: str = "eq17"
    n_recent: int = 3

    def __post_init__(self) -> None:
        if self.step_estimate not in STEP_ESTIMATES:
            raise ConfigError("footprint.step_estimate", self.step_estimate, list(STEP_ESTIMATES))
        object.__setattr__(self, "n_recent", check_int("footprint.n_recent", self.n_recent, 2))


@dataclass(frozen=True)
class FootprintPrediction:
    """The prediction after the last heel strike."""

    side: str  # foot expected to strike next
    step_sizes_m: np.ndarray  # eq. 16, all adjacent divisions
    delta_next_m: float  # eq. 17
    direction_world: np.ndarray  # v_n / ||v_n||
    p_pred_world: np.ndarray  # eq. 18
    footprint_world: np.ndarray  # p_pred + the foot's offset


def predict_footprint(strikes: list[HeelStrike], config: FootprintConfig | None = None) -> FootprintPrediction:
    """Eq. 16-18 on the recorded heel strikes (at least three) and the next foot's offset."""
    c = config or FootprintConfig()
    if len(strikes) < 3:
        raise ValueError(f"eq. 16-18 need at least three heel strikes, got {len(strikes)}")
    last = strikes[-1]
    if last.side not in SIDES:
        raise ValueError(f"heel strike side must be one of {SIDES}, got {last.side!r}")
    deltas = step_sizes(np.array([s.p_world for s in strikes]))
    delta = robust_next_step_size(deltas, c.step_estimate, c.n_recent)
    if c.min_step_m is not None:
        delta = max(delta, c.min_step_m)
    p_pd = predict_position(last.p_world, last.v_world, delta)
    side = "r" if last.side == "l" else "l"
    offset = np.asarray(c.offset_l_m if side == "l" else c.offset_r_m, dtype=float)
    v = np.asarray(last.v_world, dtype=float)
    footprint = p_pd + heading_frame(v) @ offset
    return FootprintPrediction(side, deltas, delta, v / np.linalg.norm(v), p_pd, footprint)


@dataclass
class GaitDivider:
    """Records a :class:`HeelStrike` on each rising edge of a heel contact signal that follows at
    least ``min_off_s`` without contact (a swing). Shorter gaps are contact chatter, not steps: a
    heel rocking on the pad's threshold while the foot shuffles or the weight shifts (the usual
    debounce of insole gait-event detection; 0 counts every rising edge)."""

    strikes: list[HeelStrike] = field(default_factory=list)
    min_off_s: float = 0.1
    _in_contact: dict[str, bool] = field(default_factory=lambda: {s: False for s in SIDES})
    _off_since: dict[str, float] = field(default_factory=lambda: {s: -np.inf for s in SIDES})
    n_chatter: int = 0

    def update(self, stamp_s: float, side: str, heel_in_contact: bool, p_world: np.ndarray,
               v_world: np.ndarray) -> HeelStrike | None:
        """Feed one heel contact sample with the odometry state at its time; returns the new
        division on a heel strike (contact after at least ``min_off_s`` without), else None."""
        if side not in SIDES:
            raise ValueError(f"side must be one of {SIDES}, got {side!r}")
        was = self._in_contact[side]
        self._in_contact[side] = bool(heel_in_contact)
        if was and not heel_in_contact:
            self._off_since[side] = float(stamp_s)
        if heel_in_contact and not was:
            if float(stamp_s) - self._off_since[side] < self.min_off_s:
                self.n_chatter += 1
                return None
            strike = HeelStrike(stamp_s, side, np.array(p_world, dtype=float), np.array(v_world, dtype=float))
            self.strikes.append(strike)
            return strike
        return None
