"""Algorithm 1 (seeds/004, Sec. IV): branch by branch, and on synthetic beams sweeping a staircase.

The synthetic streams are generated here, independently of exobench: two beams 8 cm apart with
4 deg toe-out, carried forward and up while pitched down, hit an analytic staircase profile
(riser 0.162 m, tread 0.28 m: the paper's Case A) by ray-plane intersection; 1.5 mm noise
(the paper's static noise) is added along the beam with a fixed seed.
"""

import numpy as np
import pytest

from exobench.perception.stairs.staircase import StaircaseAlgorithm, StaircaseParams

RISER_M, TREAD_M, RISER_X_M = 0.162, 0.28, 0.30


# --- independent synthetic data -------------------------------------------------------------
def stair_hit(o, u, n_steps=3, riser=RISER_M, tread=TREAD_M, x1=RISER_X_M):
    """(range, surface id) of the first hit of the ray o + s u on the staircase profile.

    Stairs along +x: ground z = 0 for x < x1; riser k at x = x1 + (k-1) tread; tread k at
    z = k riser. Ids as in the paper: 0 ground, 2k-1 riser k, 2k tread k. (inf, -1) if no hit.
    """
    best = (np.inf, -1)
    for k in range(n_steps + 1):  # ground and treads
        if abs(u[2]) > 1e-12:
            s = (k * riser - o[2]) / u[2]
            x = o[0] + s * u[0]
            lo = -np.inf if k == 0 else x1 + (k - 1) * tread
            if s > 0 and lo <= x <= x1 + k * tread and s < best[0]:
                best = (s, 2 * k)
    for k in range(1, n_steps + 1):  # risers
        if abs(u[0]) > 1e-12:
            s = (x1 + (k - 1) * tread - o[0]) / u[0]
            z = o[2] + s * u[2]
            if s > 0 and (k - 1) * riser <= z <= k * riser and s < best[0]:
                best = (s, 2 * k - 1)
    return best


def sweep_rays(t, yaw_deg=0.0, duration_s=2.0):
    """Origins and beam directions of the two sensors ("r", "l") at time t."""
    s = t / duration_s
    h = np.radians(yaw_deg)
    fwd, left = np.array([np.cos(h), np.sin(h), 0.0]), np.array([-np.sin(h), np.cos(h), 0.0])
    centre = np.array([-0.55, 0.0, 0.22]) + 0.6 * s * fwd + np.array([0.0, 0.0, 0.25 * s])
    pitch = np.radians(35.0 - 5.0 * s)
    rays = {}
    for flag, side in (("r", -1.0), ("l", 1.0)):
        yaw = h + side * np.radians(4.0)
        u = np.array([np.cos(pitch) * np.cos(yaw), np.cos(pitch) * np.sin(yaw), -np.sin(pitch)])
        rays[flag] = (centre + side * 0.04 * left, u)
    return rays


def sweep_stream(seed=0, yaw_deg=0.0, rate_hz=50.0, duration_s=2.0, noise_m=1.5e-3):
    """[(t, flag, point, true surface id)] of both sensors, in time order."""
    rng = np.random.default_rng(seed)
    out = []
    for t in np.arange(0.0, duration_s, 1.0 / rate_hz):
        for flag, (o, u) in sweep_rays(t, yaw_deg, duration_s).items():
            r, sid = stair_hit(o, u)
            out.append((t, flag, o + (r + noise_m * rng.standard_normal()) * u, sid))
    return out


def _angle_deg(a, b):
    c = abs(np.dot(a, b)) / (np.linalg.norm(a) * np.linalg.norm(b))
    return float(np.degrees(np.arccos(min(1.0, c))))


# --- the synthetic staircase ----------------------------------------------------------------
@pytest.mark.parametrize("htvr", [False, True], ids=["general", "htvr"])
@pytest.mark.parametrize("yaw_deg", [0.0, 10.0])
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_sweep_reconstructs_the_touchdown_tread(htvr, yaw_deg, seed):
    stream = sweep_stream(seed=seed, yaw_deg=yaw_deg)
    alg = StaircaseAlgorithm(StaircaseParams(htvr=htvr))
    for _, flag, p, _ in stream:
        alg.assign(p, flag)
    truth = np.array([sid for *_, sid in stream])
    got = alg.point_surfaces()
    S2 = alg.surfaces[2]
    assert S2.ok
    assert _angle_deg(S2.plane.normal, [0.0, 0.0, 1.0]) < 3.0
    assert abs(S2.plane.centroid[2] - RISER_M) < 3e-3  # distance of the centroid to the true tread
    S1 = alg.surfaces[1]
    assert S1.ok and abs(S1.plane.centroid[0] - RISER_X_M) < 3e-3
    assert _angle_deg(S1.plane.normal, [1.0, 0.0, 0.0]) < 3.0
    used = got >= 0
    # the paper discards points (Assign's "other situations", SurfUpdate's |d| > sigma_n), so
    # the accuracy is over the points that ended in a surface; a fair share must end in one
    assert used.mean() > 0.3
    assert (got[used] == truth[used]).mean() > 0.9
    assert set(got[used]) <= {0, 1, 2}
    assert alg.surfaces[0].ok


def test_counts_and_reliability_follow_the_points():
    stream = sweep_stream(seed=3)
    alg = StaircaseAlgorithm(StaircaseParams(reliable_n=5))
    for _, flag, p, _ in stream:
        alg.assign(p, flag)
    got = alg.point_surfaces()
    flags = np.array([f for _, f, _, _ in stream])
    for S in alg.surfaces:
        for f in ("r", "l"):
            assert S.n_by_flag[f] == int(np.sum((got == S.index) & (flags == f)))
        assert S.plane.n == int(np.sum(got == S.index))
        if S.plane.n >= 3:  # the plane is the batch fit of exactly the points the surface holds
            P = np.array([p for (_, _, p, _), g in zip(stream, got, strict=True) if g == S.index])
            np.testing.assert_allclose(S.plane.centroid, P.mean(axis=0), atol=1e-9)


# --- branch by branch (q = 3) ---------------------------------------------------------------
def _feed(alg, zs, flag="r", x0=0.0, dx=0.01):
    return [alg.assign(np.array([x0 + dx * i, 0.0, z]), flag) for i, z in enumerate(zs)]


def test_queue_holds_points_until_full_then_line5_assigns_only_central_points():
    alg = StaircaseAlgorithm(StaircaseParams(queue_q=3))
    ids = _feed(alg, [0.0, 0.002, -0.002])
    assert all(alg.surface_of(i) == -1 for i in ids) and alg.counts["n_assigned"] == 0
    # Q = [0, .002, -.002]: z_bar 0, sigma_z 1.63 mm < th_z; |0 - 0| < sigma_z -> S0
    ids += _feed(alg, [0.0])
    assert alg.surface_of(ids[0]) == 0
    # Q = [.002, -.002, 0]: |.002 - 0| = 2 mm >= sigma_z -> discarded
    ids += _feed(alg, [0.0])
    assert alg.surface_of(ids[1]) == -1 and alg.counts["n_discarded"] == 1
    assert alg.current_id == 0


def test_queues_are_per_sensor():
    alg = StaircaseAlgorithm(StaircaseParams(queue_q=3))
    _feed(alg, [0.0, 0.002, -0.002], flag="r")
    _feed(alg, [0.0, 0.002], flag="l")
    assert alg.counts["n_assigned"] == 0  # neither queue was full when a point arrived


@pytest.mark.parametrize("first_z,switch", [(0.02, True), (0.01, False)])
def test_line8_switches_to_the_riser_above_1p5_th_z(first_z, switch):
    alg = StaircaseAlgorithm(StaircaseParams(queue_q=3))
    ids = _feed(alg, [first_z, 0.05, 0.08, 0.10])  # sigma_z >= th_z; S0 empty: e_z = 0
    assert alg.current_id == (1 if switch else 0)
    assert alg.surface_of(ids[0]) == (1 if switch else -1)
    ids += _feed(alg, [0.12], x0=0.04)  # q_z = 0.05: switch now (line 8) or stay (line 12)
    assert alg.current_id == 1 and alg.surface_of(ids[1]) == 1


@pytest.mark.parametrize("policy", ["assign", "discard"])
@pytest.mark.parametrize("level_z,to_tread", [(0.20, True), (0.10, False)])
def test_lines_14_to_17_flat_queue_on_a_riser(policy, level_z, to_tread):
    alg = StaircaseAlgorithm(StaircaseParams(queue_q=3, riser_flat_low=policy))
    a = 0.002
    ids = _feed(alg, [0.02, 0.05, 0.08, level_z, level_z + a, level_z - a, level_z])
    assert [alg.surface_of(i) for i in ids[:3]] == [1, 1, 1]
    flat = ids[3]  # decided on Q = [level, level + a, level - a]: sigma_z < th_z
    if to_tread:  # q_z > S0.e_z + th_pl
        assert alg.current_id == 2 and alg.surface_of(flat) == 2
    else:
        assert alg.current_id == 1
        assert alg.surface_of(flat) == (1 if policy == "assign" else -1)


@pytest.mark.parametrize("riser_exit,top_on_tread", [("paper", True), ("travel", False)])
def test_a_riser_top_point_under_a_flat_queue_does_not_start_the_tread(riser_exit, top_on_tread):
    """The point from the top of a riser, 15 mm below the tread that fills the rest of its queue
    (flat: sigma_z 6 mm), has moved on with the beam: the paper's exit puts it on the tread;
    ``travel`` asks it to pass line 5's test too, so it is discarded and the tread starts on the
    next point."""
    alg = StaircaseAlgorithm(StaircaseParams(th_pl_m=0.08, riser_exit=riser_exit, sensor_ids="per_sensor"))
    ids = _feed(alg, [0.03, 0.06, 0.09, 0.12, 0.15], x0=0.5, dx=0.0)  # up the riser at x = 0.5
    top = _feed(alg, [0.165], x0=0.5, dx=0.0)[0]
    tread = _feed(alg, [0.18, 0.1805, 0.1795, 0.18, 0.1802, 0.1798, 0.18], x0=0.51, dx=0.01)
    assert all(alg.surface_of(i) == 1 for i in ids[:4])
    assert alg.surface_of(top) == (2 if top_on_tread else -1)
    assert alg.current_id == 2 and alg.surface_of(tread[0]) == 2


@pytest.mark.parametrize("tread_travel", [False, True])
def test_a_beam_resting_on_one_spot_adds_to_a_tread_only_without_tread_travel(tread_travel):
    """A beam at rest (the calf stopping at the end of the swing, possibly on the riser above the
    tread under investigation) gives a flat queue of one spot: line 5 takes it as tread; with
    ``tread_travel`` it needs the beam to sweep."""
    alg = StaircaseAlgorithm(StaircaseParams(tread_travel=tread_travel))
    sweep = _feed(alg, [0.0, 0.001, -0.001, 0.0, 0.0005, -0.0005, 0.0, 0.0003])  # a sweep of the ground
    assert alg.surface_of(sweep[0]) == 0
    rest = _feed(alg, [0.0, 0.0005, -0.0005, 0.0, 0.0002, -0.0002, 0.0, 0.0], x0=0.5, dx=0.0)
    on_s0 = [alg.surface_of(i) == 0 for i in rest[:3]]
    assert any(on_s0) != tread_travel


def test_stops_after_the_last_surface():
    a = 0.002
    zs = []
    for k in range(4):  # flat level k, then a riser up to level k + 1
        zs += [0.16 * k + d for d in (0.0, a, -a) * 3]
        zs += list(0.16 * k + np.linspace(0.02, 0.16, 8))
    alg = StaircaseAlgorithm(StaircaseParams(queue_q=3))
    _feed(alg, zs)
    assert alg.finished and alg.counts["n_beyond_last"] > 0
    got = alg.point_surfaces()
    assert got.max() == 4 and set(got[got >= 0]) == {0, 1, 2, 3, 4}
    n = alg.counts["n_assigned"]
    _feed(alg, [0.8, 0.9, 1.0, 0.9], x0=5.0)
    assert alg.counts["n_assigned"] == n


# --- SurfUpdate -----------------------------------------------------------------------------
def _batch(P):
    e = P.mean(axis=0)
    _, _, Vt = np.linalg.svd(P - e)
    n = Vt[-1]
    return n, e, float(np.sqrt(np.mean(((P - e) @ n) ** 2)))


def test_surf_update_removes_the_oldest_point_of_a_full_buffer_when_beyond_sigma():
    b = 3
    alg = StaircaseAlgorithm(StaircaseParams(buffer_b=b, reliable_n=1))
    rng = np.random.default_rng(0)
    P = [np.array([x, y, 0.0]) for x, y in ((0, 0), (0.4, 0), (0, 0.4), (0.4, 0.4))]
    P += [np.array([0.2, 0.2, 0.02])]  # an outlier
    P += [np.array([rng.uniform(0, 0.4), rng.uniform(0, 0.4), rng.normal(0, 1e-3)]) for _ in range(6)]
    # independent replay of lines 20-26: B of b points, the oldest leaves and is tested
    kept, B, expect_removed = [], [], []
    for i in range(len(P)):
        if len(B) == b:
            r = B.pop(0)
            n, e, sigma = _batch(np.array([P[k] for k in kept]))
            if abs(np.dot(P[r] - e, n)) > sigma + 1e-12:
                kept.remove(r)
                expect_removed.append(r)
        B.append(i)
        kept.append(i)
    for p in P:
        alg.surf_update(p, "r", 0)
    assert 4 in expect_removed  # the outlier is removed when it leaves B
    got = alg.point_surfaces()
    assert [i for i in range(len(P)) if got[i] == -1] == expect_removed
    n, e, sigma = _batch(np.array([P[k] for k in kept]))
    S0 = alg.surfaces[0]
    np.testing.assert_allclose(S0.plane.centroid, e, atol=1e-12)
    assert abs(abs(np.dot(S0.plane.normal, n)) - 1.0) < 1e-9
    assert S0.n_by_flag["r"] == len(kept) and alg.counts["n_removed"] == len(expect_removed)


def test_reliable_after_n_points_of_each_sensor_then_shift_moves_closer_points():
    N = 3
    alg = StaircaseAlgorithm(StaircaseParams(buffer_b=10, reliable_n=N))
    ground = [np.array([0.05 * i, 0.03 * (i % 3), 0.0]) for i in range(6)]
    wrong = [np.array([0.5, 0.05, 0.06]), np.array([0.5, -0.05, 0.10])]  # on the riser x = 0.5
    ids0 = [alg.surf_update(p, "r" if i % 2 else "l", 0) for i, p in enumerate(ground + wrong)]
    riser = [np.array([0.5, y, z]) for y, z in ((-0.1, 0.02), (0.1, 0.05), (0.0, 0.12), (0.05, 0.03), (-0.05, 0.14), (0.1, 0.09))]
    flags = ["r", "r", "r", "l", "l"]
    ids1 = [alg.surf_update(p, f, 1) for p, f in zip(riser[:5], flags, strict=True)]
    S0, S1 = alg.surfaces[0], alg.surfaces[1]
    assert not S1.ok and all(alg.surface_of(i) == 0 for i in ids0)
    last = alg.surf_update(riser[5], "l", 1)  # third "l" point: N of each sensor
    assert S1.ok and S1.reliable_uid == last
    # Shift(S0, S1): the two riser points held in S0.B are closer to S1 and move there
    assert [alg.surface_of(i) for i in ids0] == [0] * 6 + [1, 1]
    assert all(alg.surface_of(i) == 1 for i in ids1 + [last])
    assert S0.plane.n == 6 and S1.plane.n == 8
    assert S0.n_by_flag == {"r": 3, "l": 3} and S1.n_by_flag == {"r": 4, "l": 4}
    np.testing.assert_allclose(S0.plane.centroid, np.mean(ground, axis=0), atol=1e-12)
    np.testing.assert_allclose(S1.plane.centroid, np.mean(riser + wrong, axis=0), atol=1e-12)
    assert abs(abs(S1.plane.normal[0]) - 1.0) < 1e-9
    assert alg.counts["n_shifted"] == 2
