"""The host keyframe's grouped factor (mapping/odometry/dvio/grouped.py) against the sum of the
per-observation factors of factors.py (themselves checked against finite differences): the same
cost and the same Gauss-Newton system, with and without a robust kernel, near and far from the
truth, with and without the depth factors, and the m-estimators against gtsam's."""

import gtsam
import numpy as np
import pytest

from exobench.core.errors import ConfigError
from exobench.mapping.odometry.dvio.factors import (
    DepthNoise,
    Extrinsics,
    host_depth_factor,
    projection_depth_factor,
    reprojection_factor,
)
from exobench.mapping.odometry.dvio.grouped import (
    HostedLandmark,
    host_group_factor,
    kernel_loss_weight,
    sfm_landmark_factor,
)

X, L = gtsam.symbol_shorthand.X, gtsam.symbol_shorthand.L
NOISE = DepthNoise()
SIGMA = 1.5 / 424.0
EXT = Extrinsics(gtsam.Rot3.RzRyRx(0.02, -0.03, 0.01).matrix(), np.array([0.0203, -0.0051, -0.0112]))
T_IC = gtsam.Pose3(gtsam.Rot3(EXT.R_IC), EXT.p_IC)
POSES = {k: gtsam.Pose3(gtsam.Rot3.Ypr(0.3 + 0.05 * k, -0.1 + 0.02 * k, 0.05), np.array([1.0 + 0.1 * k, 2.0, 1.5]))
         for k in range(4)}  # fmt: skip


def _scene(seed=0, n=6):
    """Landmarks hosted in keyframe 0, each seen by 1-3 of keyframes 1-3, some depths missing."""
    rng = np.random.default_rng(seed)
    T0 = POSES[0] * T_IC
    lms, truth = [], {}
    for i in range(n):
        p_c = np.array([rng.uniform(-0.8, 0.8), rng.uniform(-0.5, 0.5), rng.uniform(0.8, 4.5)])
        l_G = T0.transformFrom(p_c)
        obs = []
        for k in sorted(rng.choice([1, 2, 3], size=1 + i % 3, replace=False)):
            P = (POSES[int(k)] * T_IC).transformTo(l_G)
            d = P[2] if i % 4 else float("nan")  # every fourth landmark has no depth in its views
            obs.append((X(int(k)), P[:2] / P[2] + rng.normal(0, 2e-3, 2), d + rng.normal(0, 0.02)))
        d_host = p_c[2] + rng.normal(0, 0.02) if i != 1 else 7.5  # one host depth out of range
        lms.append(HostedLandmark(L(i), p_c[:2] / p_c[2], d_host, tuple(obs)))
        truth[L(i)] = 1.0 / p_c[2]
    return lms, truth


def _values(truth, off=0.0, seed=1):
    rng = np.random.default_rng(seed)
    v = gtsam.Values()
    for k, T in POSES.items():
        v.insert(X(k), T.retract(off * rng.normal(0, 1, 6)))
    for key, xi in truth.items():
        v.insert(key, np.array([xi * (1.0 + off * rng.normal(0, 3))]))
    return v


def _per_observation(lms, kernel, depth):
    g = gtsam.NonlinearFactorGraph()
    for lm in lms:
        if depth:
            f = host_depth_factor(lm.key, lm.d_host, NOISE, kernel)
            if f is not None:
                g.add(f)
        for key, uu, d in lm.observations:
            g.add(reprojection_factor(X(0), key, lm.key, lm.u_host, uu, EXT, SIGMA, kernel))
            if depth:
                f = projection_depth_factor(X(0), key, lm.key, lm.u_host, d, EXT, NOISE, kernel)
                if f is not None:
                    g.add(f)
    return g


def _system(graph, values):
    """The Gauss-Newton Hessian and gradient of the linearised graph, in one fixed ordering."""
    order = gtsam.Ordering()
    for k in sorted(values.keys()):
        order.push_back(k)
    return graph.linearize(values).hessian(order)


@pytest.mark.parametrize("kernel", ["cauchy", "huber", "none"])
@pytest.mark.parametrize("depth", [True, False])
@pytest.mark.parametrize("off", [0.0, 0.03])
def test_the_grouped_factor_is_the_sum_of_the_per_observation_factors(kernel, depth, off):
    lms, truth = _scene()
    values = _values(truth, off)
    one = gtsam.NonlinearFactorGraph()
    one.add(host_group_factor(X(0), lms, EXT, SIGMA, NOISE if depth else None, kernel))
    each = _per_observation(lms, kernel, depth)
    assert one.error(values) == pytest.approx(each.error(values), rel=1e-9)
    (H1, g1), (H2, g2) = _system(one, values), _system(each, values)
    assert np.allclose(H1, H2, rtol=1e-7, atol=1e-6 * np.abs(H2).max())
    assert np.allclose(g1, g2, rtol=1e-7, atol=1e-6 * np.abs(g2).max())


def test_bounds_on_depth_and_inverse_depth_are_the_per_observation_factors():
    lms, truth = _scene()
    values = _values({k: (-0.3 if k == L(2) else xi) for k, xi in truth.items()})  # one xi through zero
    behind = gtsam.Values(values)
    behind.update(X(2), gtsam.Pose3(gtsam.Rot3.Ypr(0.4 + np.pi, -0.06, 0.05), POSES[2].translation()))
    for v in (values, behind):
        one = gtsam.NonlinearFactorGraph()
        one.add(host_group_factor(X(0), lms, EXT, SIGMA, NOISE))
        each = _per_observation(lms, "cauchy", True)
        assert one.error(v) == pytest.approx(each.error(v), rel=1e-9)
        (H1, g1), (H2, g2) = _system(one, v), _system(each, v)
        assert np.all(np.isfinite(H1)) and np.allclose(H1, H2, rtol=1e-7, atol=1e-9 * np.abs(H2).max())
        assert np.allclose(g1, g2, rtol=1e-7, atol=1e-9 * np.abs(g2).max())


@pytest.mark.parametrize("kernel", ["cauchy", "huber"])
def test_kernel_loss_and_weight_are_gtsams(kernel):
    est = (gtsam.noiseModel.mEstimator.Cauchy if kernel == "cauchy" else gtsam.noiseModel.mEstimator.Huber).Create(1.3)
    r = np.array([0.0, 0.2, 1.29, 1.31, 4.0, 40.0])
    rho, w = kernel_loss_weight(kernel, 1.3, r)
    assert np.allclose(rho, [est.loss(x) for x in r]) and np.allclose(w, [est.weight(x) for x in r])


def test_bad_input_is_refused_naming_the_field():
    lms, _ = _scene()
    with pytest.raises(ConfigError, match="kernel"):
        host_group_factor(X(0), lms, EXT, SIGMA, NOISE, kernel="tukey")
    with pytest.raises(ConfigError, match="observation key"):
        host_group_factor(X(1), lms, EXT, SIGMA, NOISE)
    assert host_group_factor(X(0), [HostedLandmark(L(0), np.zeros(2), 1.0, ())], EXT, SIGMA, NOISE) is None


@pytest.mark.parametrize("off", [0.0, 0.03])
def test_the_sfm_landmark_factor_is_the_sum_of_the_per_observation_sfm_factors(off):
    from exobench.mapping.odometry.dvio.factors import robust
    from exobench.mapping.odometry.dvio.init import _sfm_factor

    rng = np.random.default_rng(3)
    l_G = (POSES[0] * T_IC).transformFrom(np.array([0.3, -0.2, 2.2]))
    obs = []
    for k in range(4):
        P = (POSES[k] * T_IC).transformTo(l_G)
        d = P[2] + rng.normal(0, 0.02) if k != 2 else float("nan")
        obs.append((X(k), P[:2] / P[2] + rng.normal(0, 3e-3, 2), d))
    values = _values({}, off)
    values.insert(L(0), l_G + off * rng.normal(0, 1, 3))
    one = gtsam.NonlinearFactorGraph()
    one.add(sfm_landmark_factor(L(0), obs, EXT, SIGMA, NOISE))
    each = gtsam.NonlinearFactorGraph()
    for key, uu, d in obs:
        each.add(_sfm_factor(key, L(0), uu, None, EXT, robust(gtsam.noiseModel.Isotropic.Sigma(2, SIGMA), "cauchy", 1.0)))
        if NOISE.valid(d):
            each.add(_sfm_factor(key, L(0), None, d, EXT,
                                 robust(gtsam.noiseModel.Isotropic.Sigma(1, NOISE.sigma_m(d)), "cauchy", 1.0)))
    assert one.error(values) == pytest.approx(each.error(values), rel=1e-9)
    (H1, g1), (H2, g2) = _system(one, values), _system(each, values)
    assert np.allclose(H1, H2, rtol=1e-7, atol=1e-9 * np.abs(H2).max())
    assert np.allclose(g1, g2, rtol=1e-7, atol=1e-9 * np.abs(g2).max())
