"""D-VIO depth and inverse-depth reprojection factors (seeds/002 eq. 8, 11-14) on constructed
landmarks: zero residual at the truth, the stated growth under perturbation, Jacobians against
finite differences."""

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

XI, PI, PJ = 0, 1, 2  # keys: inverse depth, host pose, co-visible pose
NOISE = DepthNoise()
# A camera-IMU extrinsic of a D455's size (camera about 2 cm from the IMU, slightly turned) so
# that R_IC and p_IC take part in every expression.
EXT = Extrinsics(gtsam.Rot3.RzRyRx(0.02, -0.03, 0.01).matrix(), np.array([0.0203, -0.0051, -0.0112]))


def _T(ypr, p):
    return gtsam.Pose3(gtsam.Rot3.Ypr(*ypr), np.asarray(p, dtype=float))


T_GI = _T((0.3, -0.1, 0.05), (1.0, 2.0, 1.5))
T_GJ = _T((0.45, -0.05, 0.1), (1.3, 2.2, 1.45))
T_IC = gtsam.Pose3(gtsam.Rot3(EXT.R_IC), EXT.p_IC)


def _observe(T_GI_, L):
    """Normalised bearing and depth of the world point L in the camera of IMU pose T_GI_."""
    P = (T_GI_ * T_IC).transformTo(L)
    return P[:2] / P[2], P[2]


L_G = (T_GI * T_IC).transformFrom(np.array([0.4, -0.2, 2.5]))  # 2.5 m in front of camera i
U_I, D_I = _observe(T_GI, L_G)
U_J, D_J = _observe(T_GJ, L_G)


def _values(T_i=T_GI, T_j=T_GJ, xi=1.0 / D_I):
    v = gtsam.Values()
    v.insert(PI, T_i)
    v.insert(PJ, T_j)
    v.insert(XI, np.array([xi]))
    return v


def _factors(kernel="none", d_i=D_I, d_j=D_J, u_j=U_J):
    return (reprojection_factor(PI, PJ, XI, U_I, u_j, EXT, 1.5 / 424.0, kernel),
            projection_depth_factor(PI, PJ, XI, U_I, d_j, EXT, NOISE, kernel),
            host_depth_factor(XI, d_i, NOISE, kernel))


def test_residuals_are_zero_on_an_exact_landmark():
    assert 2.0 < D_J < 3.0 and np.linalg.norm(U_J - U_I) > 0.05  # a real second view
    for f in _factors():
        assert np.allclose(f.unwhitenedError(_values()), 0.0, atol=1e-12)


def test_depth_residuals_grow_by_the_depth_error_in_metres():
    for delta in (-0.1, 0.02, 0.3):
        _, proj, host = _factors(d_i=D_I + delta, d_j=D_J + delta)
        assert proj.unwhitenedError(_values())[0] == pytest.approx(-delta, abs=1e-12)
        assert host.unwhitenedError(_values())[0] == pytest.approx(-delta, abs=1e-12)
    # A wrong inverse depth: the host residual is the depth difference (eq. 11).
    _, _, host = _factors()
    assert host.unwhitenedError(_values(xi=1.0 / (D_I + 0.25)))[0] == pytest.approx(0.25)


def test_moving_the_covisible_camera_along_and_across_its_axis():
    R_Gc = (T_GJ * T_IC).rotation().matrix()
    delta = 0.05
    forward = _T((0.45, -0.05, 0.1), T_GJ.translation() + delta * R_Gc[:, 2])
    sideways = _T((0.45, -0.05, 0.1), T_GJ.translation() + delta * R_Gc[:, 0])
    reproj, proj, _ = _factors()
    # Forward by delta: the landmark is delta nearer (eq. 12), its bearing scales by D_J/(D_J-delta).
    assert proj.unwhitenedError(_values(T_j=forward))[0] == pytest.approx(-delta, abs=1e-12)
    assert np.allclose(reproj.unwhitenedError(_values(T_j=forward)), U_J * delta / (D_J - delta), atol=1e-12)
    # Sideways (camera x) by delta: u shifts by -delta/z, the depth does not change.
    assert np.allclose(reproj.unwhitenedError(_values(T_j=sideways)), [-delta / D_J, 0.0], atol=1e-12)
    assert proj.unwhitenedError(_values(T_j=sideways))[0] == pytest.approx(0.0, abs=1e-12)


def test_depth_factors_are_weighted_by_the_stereo_noise_model():
    # docs/sensor-reference.md: about 8 mm at 2 m and 32 mm at 4 m for the D455 at 848x480.
    assert NOISE.sigma_m(2.0) == pytest.approx(0.0079, abs=2e-4)
    assert NOISE.sigma_m(4.0) == pytest.approx(0.0318, abs=5e-4)
    _, proj, host = _factors(d_i=D_I + 0.01, d_j=D_J + 0.01)
    assert host.error(_values()) == pytest.approx(0.5 * (0.01 / NOISE.sigma_m(D_I + 0.01)) ** 2)
    assert proj.error(_values()) == pytest.approx(0.5 * (0.01 / NOISE.sigma_m(D_J + 0.01)) ** 2)


def test_a_robust_kernel_bounds_the_cost_of_a_gross_depth_outlier():
    _, gauss, _ = _factors(d_j=D_J + 1.0)
    _, cauchy, _ = _factors(kernel="cauchy", d_j=D_J + 1.0)
    assert cauchy.error(_values()) < 0.05 * gauss.error(_values())


def _numeric_jacobians(f, values, eps=1e-6):
    cols = []
    for key in f.keys():
        dim = 1 if key == XI else 6
        J = np.zeros((f.dim(), dim))
        for k in range(dim):
            step = np.zeros(dim)
            step[k] = eps
            vp, vm = gtsam.Values(values), gtsam.Values(values)
            vp.update(key, values.atPose3(key).retract(step) if dim == 6 else values.atVector(key) + step)
            vm.update(key, values.atPose3(key).retract(-step) if dim == 6 else values.atVector(key) - step)
            J[:, k] = (f.unwhitenedError(vp) - f.unwhitenedError(vm)) / (2 * eps)
        cols.append(J)
    return np.hstack(cols)


@pytest.mark.parametrize("which", [0, 1, 2])
def test_analytic_jacobians_match_finite_differences(which):
    # Away from the truth as well, where the residuals are not zero.
    for values in (_values(), _values(T_i=T_GI.retract(np.array([0.02, -0.01, 0.03, 0.05, 0.1, -0.04])),
                                      T_j=T_GJ.retract(np.array([-0.03, 0.02, 0.0, 0.1, 0.0, 0.07])),
                                      xi=0.3)):
        f = _factors()[which]
        A, _ = f.linearize(values).jacobian()
        sigma = f.noiseModel().sigmas()[0]
        assert np.allclose(A * sigma, _numeric_jacobians(f, values), atol=1e-6)


def test_a_depth_the_camera_cannot_measure_gives_no_factor():
    for bad in (float("nan"), 0.0, -1.0, 0.2, 7.0, float("inf")):
        assert projection_depth_factor(PI, PJ, XI, U_I, bad, EXT, NOISE) is None
        assert host_depth_factor(XI, bad, NOISE) is None
    assert reprojection_factor(PI, PJ, XI, U_I, np.array([np.nan, 0.1]), EXT, 0.01) is None


def test_invalid_noise_and_kernel_are_refused_with_the_field():
    with pytest.raises(ConfigError, match="baseline_m"):
        DepthNoise(baseline_m=0.0)
    with pytest.raises(ConfigError, match="kernel"):
        host_depth_factor(XI, 2.0, NOISE, kernel="tukey")
    with pytest.raises(ConfigError, match="T_imu_camera"):
        Extrinsics.from_T_imu_camera(np.eye(3))


def test_a_window_recovers_the_inverse_depth_from_a_wrong_start():
    """Two fixed poses, the three factors: Levenberg-Marquardt brings xi from 1/5 m to the truth."""
    graph = gtsam.NonlinearFactorGraph()
    for f in _factors(kernel="cauchy"):
        graph.add(f)
    graph.add(gtsam.PriorFactorPose3(PI, T_GI, gtsam.noiseModel.Isotropic.Sigma(6, 1e-6)))
    graph.add(gtsam.PriorFactorPose3(PJ, T_GJ, gtsam.noiseModel.Isotropic.Sigma(6, 1e-6)))
    result = gtsam.LevenbergMarquardtOptimizer(graph, _values(xi=0.2)).optimize()
    assert 1.0 / result.atVector(XI)[0] == pytest.approx(D_I, abs=1e-6)


def test_a_landmark_behind_the_camera_or_a_negative_inverse_depth_stays_finite():
    behind = _values(xi=-0.5)  # the optimiser stepped xi through zero
    back = _T((0.45 + np.pi, -0.05, 0.1), T_GJ.translation())  # camera j turned away
    for values in (behind, _values(T_j=back)):
        for f in _factors(kernel="cauchy"):
            err = f.unwhitenedError(values)
            A, b = f.linearize(values).jacobian()
            assert np.all(np.isfinite(err)) and np.all(np.isfinite(A)) and np.all(np.isfinite(b))
    _, _, host = _factors()
    assert host.unwhitenedError(behind)[0] == pytest.approx(1e3 - D_I)
