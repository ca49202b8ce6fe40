"""D-VIO IMU preintegration against a closed-form trajectory (issue 27, "Tests")."""

import gtsam
import numpy as np
import pytest

from exobench.core.errors import ConfigError
from exobench.core.transforms import rot_x, rot_z
from exobench.mapping.odometry.dvio.imu import GRAVITY_MPS2, ImuNoise, ImuPreintegrator

G = np.array([0.0, 0.0, -GRAVITY_MPS2])
R_H, W_H, VZ, AZ, OMZ, ROLL = 1.5, 1.2, 0.3, 0.05, 7.0, 0.3  # helix radius, yaw rate, climb, bob


def truth(t):
    """Helix with a vertical bob (heel-strike-like 7 rad/s) and a constant tilt: position,
    velocity, acceleration, rotation, body rate, all closed form."""
    p = np.array([R_H * np.cos(W_H * t), R_H * np.sin(W_H * t), VZ * t + AZ * np.sin(OMZ * t)])
    v = np.array([-R_H * W_H * np.sin(W_H * t), R_H * W_H * np.cos(W_H * t), VZ + AZ * OMZ * np.cos(OMZ * t)])
    a = np.array([-R_H * W_H**2 * np.cos(W_H * t), -R_H * W_H**2 * np.sin(W_H * t),
                  -AZ * OMZ**2 * np.sin(OMZ * t)])
    R = rot_z(W_H * t) @ rot_x(ROLL)  # yaw at W_H about world z, then a fixed roll
    w_body = rot_x(ROLL).T @ np.array([0.0, 0.0, W_H])
    return p, v, a, R, w_body


def imu_samples(rate_hz, t_end, bias_acc=(0.0, 0.0, 0.0), bias_gyr=(0.0, 0.0, 0.0)):
    for t in np.arange(0.0, t_end + 1e-12, 1.0 / rate_hz):
        _, _, a, R, w = truth(t)
        yield t, R.T @ (a - G) + np.asarray(bias_acc), w + np.asarray(bias_gyr)


def closed_form(t0, t1):
    p0, v0, _, R0, _ = truth(t0)
    p1, v1, _, R1, _ = truth(t1)
    T = t1 - t0
    return (R0.T @ (p1 - p0 - v0 * T - 0.5 * G * T**2), R0.T @ (v1 - v0 - G * T), R0.T @ R1)


def _integrate(rate_hz, t_end=1.0, **kw):
    pre = ImuPreintegrator(ImuNoise(), kw.pop("bias", None))
    for t, a, w in imu_samples(rate_hz, t_end, **kw):
        pre.add(t, a, w)
    return pre


def _errors(pim, t_end=1.0):
    alpha, beta, R = closed_form(0.0, t_end)
    dR = pim.deltaRij().matrix()
    rot = np.linalg.norm(gtsam.Rot3(R.T @ dR).ypr())
    return np.linalg.norm(pim.deltaPij() - alpha), np.linalg.norm(pim.deltaVij() - beta), rot


def test_preintegration_matches_the_helix_closed_form():
    pre = _integrate(400.0)
    assert pre.pim.deltaTij() == pytest.approx(1.0, abs=1e-9)
    ep, ev, er = _errors(pre.pim)
    # The deltas are metres (|alpha| ~ 5 m with gravity) and m/s; the rule is second order.
    assert ep < 2e-5 and ev < 1e-5 and er < 1e-9


def test_midpoint_error_is_second_order_in_the_sample_interval():
    e100 = _errors(_integrate(100.0).pim)
    e400 = _errors(_integrate(400.0).pim)
    # Four times the rate: a first-order rule gains 4x, a second-order one about 16x.
    assert e100[0] / e400[0] > 10.0 and e100[1] / e400[1] > 10.0


def test_predict_reaches_the_true_state_from_the_true_start():
    pre = _integrate(400.0, t_end=2.0)
    p0, v0, _, R0, _ = truth(0.0)
    p1, v1, _, R1, _ = truth(2.0)
    nav = pre.predict(gtsam.NavState(gtsam.Rot3(R0), p0, v0))
    assert np.linalg.norm(nav.position() - p1) < 2e-3
    assert np.linalg.norm(nav.velocity() - v1) < 2e-3
    assert np.allclose(nav.attitude().matrix(), R1, atol=1e-8)


def test_known_bias_is_removed_and_a_bias_update_is_first_order_corrected():
    ba, bg = np.array([0.08, -0.05, 0.12]), np.array([0.004, -0.003, 0.002])
    biased = gtsam.imuBias.ConstantBias(ba, bg)
    pre = _integrate(400.0, bias_acc=ba, bias_gyr=bg, bias=biased)
    assert max(_errors(pre.pim)[:2]) < 5e-5
    # Integrated with a zero bias, the deltas are off; gtsam's first-order bias correction
    # (what the window uses when it moves the bias) brings them back close to the truth.
    raw = _integrate(400.0, bias_acc=ba, bias_gyr=bg)
    assert _errors(raw.pim)[0] > 0.03
    p0, v0, _, R0, _ = truth(0.0)
    p1, v1, _, _, _ = truth(1.0)
    start = gtsam.NavState(gtsam.Rot3(R0), p0, v0)
    assert np.linalg.norm(raw.predict(start).position() - p1) > 0.03
    corrected = raw.predict(start, biased)
    assert np.linalg.norm(corrected.position() - p1) < 2e-3
    assert np.linalg.norm(corrected.velocity() - v1) < 2e-3


def test_faulty_samples_are_skipped_and_counted_not_raised():
    clean = _integrate(400.0)
    pre = ImuPreintegrator(ImuNoise())
    for i, (t, a, w) in enumerate(imu_samples(400.0, 1.0)):
        pre.add(t, a, w)
        if i % 50 == 7:
            pre.add(t, a + 100.0, w)  # repeated stamp with a wrong value: must not count
            pre.add(t - 0.01, a, w)  # out of order
            pre.add(t + 1e-4, np.array([np.nan, 0.0, 0.0]), w)
    assert pre.skipped == 3 * 8
    assert np.allclose(pre.pim.deltaPij(), clean.pim.deltaPij(), atol=1e-12)


def test_integrate_to_splits_an_interval_at_a_frame_time_and_reset_restarts_there():
    pre = _integrate(200.0, t_end=0.5)
    pre.integrate_to(0.5025)
    assert pre.pim.deltaTij() == pytest.approx(0.5025, abs=1e-12)
    pre.reset()
    assert pre.start_s == pytest.approx(0.5025) and pre.pim.deltaTij() == 0.0
    for t, a, w in imu_samples(200.0, 1.0):
        if t > 0.5025:
            pre.add(t, a, w)
    ep, ev, _ = (np.linalg.norm(x) for x in (pre.pim.deltaPij() - closed_form(0.5025, 1.0)[0],
                                             pre.pim.deltaVij() - closed_form(0.5025, 1.0)[1], [0]))
    assert ep < 2e-3 and ev < 5e-3


def test_noise_comes_from_the_mount_params_and_bad_values_are_refused():
    n = ImuNoise.from_params({"gyro_noise_density": 2.054e-4, "accel_random_walk": 4.13e-4, "rate_hz": 400})
    cov = n.gtsam_params().getGyroscopeCovariance()
    assert cov[0, 0] == pytest.approx(2.054e-4**2)
    assert n.gtsam_params().getBiasAccCovariance()[2, 2] == pytest.approx(4.13e-4**2)
    with pytest.raises(ConfigError, match="accel_noise_density"):
        ImuNoise(accel_noise_density=-1.0)
