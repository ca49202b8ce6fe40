"""Walking information (seeds/002 eq. 16-18) on constructed heel strikes, against hand computation."""

import numpy as np
import pytest

from exobench.core import ConfigError
from exobench.perception.terrain.footprint import (
    FootprintConfig,
    GaitDivider,
    HeelStrike,
    heading_frame,
    next_step_size,
    predict_footprint,
    predict_position,
    robust_next_step_size,
    step_sizes,
)


def _strikes(points, velocities, first_side="l"):
    sides = ["l", "r"] if first_side == "l" else ["r", "l"]
    return [HeelStrike(0.5 * i, sides[i % 2], np.array(p, float), np.array(v, float))
            for i, (p, v) in enumerate(zip(points, velocities))]


def test_straight_walk():
    # strikes at x = 0, 0.60, 1.25 (steps 0.60 and 0.65), walking along +x at 1.2 m/s
    s = _strikes([(0, 0, 1), (0.6, 0, 1), (1.25, 0, 1)], [(1.2, 0, 0)] * 3)  # l, r, l
    pred = predict_footprint(s)
    np.testing.assert_allclose(pred.step_sizes_m, [0.60, 0.65])  # eq. 16
    assert pred.delta_next_m == pytest.approx(0.70)  # eq. 17: 2 * 0.65 - 0.60
    np.testing.assert_allclose(pred.p_pred_world, [1.95, 0, 1])  # eq. 18
    assert pred.side == "r"  # the last strike was the left heel
    np.testing.assert_allclose(pred.footprint_world, [1.95, -0.08, 1])


def test_step_sizes_include_height_on_stairs():
    # each step 0.3 forward and 0.16 up: |(0.3, 0, 0.16)| = 0.34
    p = np.array([(0.3 * i, 0, 0.16 * i) for i in range(4)])
    np.testing.assert_allclose(step_sizes(p), [0.34] * 3)
    assert next_step_size(step_sizes(p)) == pytest.approx(0.34)


def test_turning_walk_uses_the_last_velocity_and_heading_frame():
    # last velocity along +y, climbing a little: v = (0, 1, 0.5)
    s = _strikes([(0, 0, 0), (0.5, 0.1, 0), (0.8, 0.5, 0)], [(1, 0, 0), (1, 1, 0), (0, 1, 0.5)], first_side="r")
    d1, d2 = np.hypot(0.5, 0.1), np.hypot(0.3, 0.4)  # 0.5099, 0.5
    pred = predict_footprint(s)
    assert pred.delta_next_m == pytest.approx(2 * d2 - d1)
    unit = np.array([0, 1, 0.5]) / np.sqrt(1.25)
    np.testing.assert_allclose(pred.direction_world, unit)
    p_pd = np.array([0.8, 0.5, 0]) + unit * (2 * d2 - d1)
    np.testing.assert_allclose(pred.p_pred_world, p_pd)
    # last strike r -> next foot l; heading x = +y, so "left" is -x
    assert pred.side == "l"
    np.testing.assert_allclose(pred.footprint_world, p_pd + [-0.08, 0, 0])
    R = heading_frame(np.array([0, 1, 0.5]))
    np.testing.assert_allclose(R, [[0, -1, 0], [1, 0, 0], [0, 0, 1]], atol=1e-12)


def test_left_right_alternation_and_custom_offsets():
    cfg = FootprintConfig(offset_l_m=(0.05, 0.1, -0.9), offset_r_m=(0.05, -0.1, -0.9))
    pts = [(0.6 * i, 0, 0.9) for i in range(5)]
    vel = [(1, 0, 0)] * 5
    sides = []
    for n in (3, 4, 5):
        pred = predict_footprint(_strikes(pts[:n], vel[:n]), cfg)
        sides.append(pred.side)
        x_pd = 0.6 * (n - 1) + 0.6
        y = 0.1 if pred.side == "l" else -0.1
        np.testing.assert_allclose(pred.footprint_world, [x_pd + 0.05, y, 0.0], atol=1e-12)
    assert sides == ["r", "l", "r"]


def test_slowing_down_can_predict_backwards_unless_bounded():
    s = _strikes([(0, 0, 0), (0.6, 0, 0), (0.8, 0, 0)], [(1, 0, 0)] * 3)
    assert predict_footprint(s).delta_next_m == pytest.approx(2 * 0.2 - 0.6)  # -0.2, as eq. 17 says
    bounded = predict_footprint(s, FootprintConfig(min_step_m=0.0))
    assert bounded.delta_next_m == 0.0
    np.testing.assert_allclose(bounded.p_pred_world, [0.8, 0, 0])


def test_gait_divider_records_rising_edges_only():
    div = GaitDivider()
    seq = [("l", True), ("l", True), ("r", False), ("l", False), ("r", True), ("r", True), ("l", True), ("r", False)]
    events = []
    for k, (side, contact) in enumerate(seq):
        e = div.update(0.1 * k, side, contact, np.array([k, 0.0, 0.0]), np.array([1.0, 0, 0]))
        if e is not None:
            events.append((e.side, e.stamp_s, e.p_world[0]))
    assert events == [("l", 0.0, 0.0), ("r", pytest.approx(0.4), 4.0), ("l", pytest.approx(0.6), 6.0)]
    assert len(div.strikes) == 3


def test_gait_divider_ignores_contact_chatter_shorter_than_a_swing():
    div = GaitDivider(min_off_s=0.1)
    # r heel: on, off at 0.37, chatter on/off every 0.02-0.04 s, off 0.53, real strike at 0.87
    seq = [(0.0, True), (0.37, False), (0.41, True), (0.43, False), (0.44, True), (0.46, False), (0.48, True),
           (0.53, False), (0.87, True)]
    events = [e for t, c in seq if (e := div.update(t, "r", c, np.array([t, 0.0, 0.0]), np.ones(3))) is not None]
    assert [e.stamp_s for e in events] == [0.0, 0.87]
    assert div.n_chatter == 3
    every = GaitDivider(min_off_s=0.0)
    assert sum(every.update(t, "r", c, np.zeros(3), np.ones(3)) is not None for t, c in seq) == 5


def test_errors():
    s = _strikes([(0, 0, 0), (0.6, 0, 0)], [(1, 0, 0)] * 2)
    with pytest.raises(ValueError):
        predict_footprint(s)
    with pytest.raises(ValueError):
        predict_position(np.zeros(3), np.zeros(3), 0.5)
    with pytest.raises(ValueError):
        GaitDivider().update(0.0, "x", True, np.zeros(3), np.zeros(3))


def test_robust_next_step_sizes_of_a_stop_and_go_walker():
    """Steps 0.40, 0.42, 0.27 then a 0.08 m shuffle (stopping before a stair): eq. 17 predicts
    2 x 0.08 - 0.27 < 0; clamped to the last three it is the shortest of them, capped it is 0,
    the median the middle one."""
    d = np.array([0.40, 0.42, 0.27, 0.08])
    assert robust_next_step_size(d, "eq17") == pytest.approx(2 * 0.08 - 0.27)
    assert robust_next_step_size(d, "eq17_clamped") == pytest.approx(0.08)
    assert robust_next_step_size(d, "eq17_capped") == pytest.approx(0.0)
    assert robust_next_step_size(d, "median") == pytest.approx(0.27)
    up = np.array([0.30, 0.35, 0.45])  # speeding up: eq. 17 gives 0.55, more than any step seen
    assert robust_next_step_size(up, "eq17_clamped") == pytest.approx(0.45)
    assert robust_next_step_size(up, "eq17_capped") == pytest.approx(0.45)
    assert robust_next_step_size(np.array([0.3, 0.4]), "eq17_capped", n_recent=5) == pytest.approx(0.4)
    s = [HeelStrike(float(i), "lr"[i % 2], np.array([x, 0.0, 1.0]), np.array([0.5, 0.0, 0.0]))
         for i, x in enumerate(np.cumsum([0.0, *d]))]
    pred = predict_footprint(s, FootprintConfig(step_estimate="eq17_capped"))
    assert pred.delta_next_m == pytest.approx(0.0)
    with pytest.raises(ConfigError):
        FootprintConfig(step_estimate="mean")
    with pytest.raises(ConfigError):
        FootprintConfig(n_recent=1)
