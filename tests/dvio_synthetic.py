"""A synthetic visual-inertial sequence for D-VIO's back end: a camera on a helix looking out at
points between two cylinders (a room's walls and furniture at 0.7-4.5 m), the IMU from the
trajectory's closed-form derivatives, features projected with pixel noise and depths with the
stereo depth noise model. Feature ids are the landmark indices (ideal tracking: the KLT front end
is bypassed)."""

import numpy as np

from exobench.benchmarks.trajectory import umeyama_alignment
from exobench.core.transforms import rot_x, rot_z
from exobench.mapping.odometry.dvio.factors import DepthNoise, Extrinsics
from exobench.mapping.odometry.dvio.imu import GRAVITY_MPS2

G = np.array([0.0, 0.0, -GRAVITY_MPS2])
RH, WH, VZ, AZ, OMZ, ROLL = 1.5, 0.8, 0.1, 0.05, 7.0, 0.3
F = 424.0
NOISE = DepthNoise()
# The camera looks along the body's +x (radially out of the helix): camera z = body x.
EXT = Extrinsics(np.array([[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]]), np.array([0.02, -0.005, -0.011]))
T_IC = np.eye(4)
T_IC[:3, :3], T_IC[:3, 3] = EXT.R_IC, EXT.p_IC


def truth(t):
    """Position, velocity, acceleration, attitude R_GI and body rate of the IMU at t."""
    p = np.array([RH * np.cos(WH * t), RH * np.sin(WH * t), VZ * t + AZ * np.sin(OMZ * t)])
    v = np.array([-RH * WH * np.sin(WH * t), RH * WH * np.cos(WH * t), VZ + AZ * OMZ * np.cos(OMZ * t)])
    a = np.array([-RH * WH**2 * np.cos(WH * t), -RH * WH**2 * np.sin(WH * t), -AZ * OMZ**2 * np.sin(OMZ * t)])
    return p, v, a, rot_z(WH * t) @ rot_x(ROLL), rot_x(ROLL).T @ np.array([0.0, 0.0, WH])


def camera_pose(t):
    p, _, _, R, _ = truth(t)
    T = np.eye(4)
    T[:3, :3], T[:3, 3] = R, p
    return T @ T_IC


def landmarks(rng, n=4000, r_min=2.2, r_max=6.0):
    ang = rng.uniform(0, 2 * np.pi, n)
    r = rng.uniform(r_min, r_max, n)
    return np.column_stack([r * np.cos(ang), r * np.sin(ang), rng.uniform(-1.0, 2.0, n)])


def observe(L, t, rng, max_features=100, pixel_noise_px=0.5, depth_noise=1.0):
    """(ids, u (N, 2) normalised, depth (N,)) of the landmarks in view at t."""
    T = camera_pose(t)
    P = (L - T[:3, 3]) @ T[:3, :3]
    z = P[:, 2]
    ok = z > NOISE.min_depth_m
    u = P[:, :2] / np.where(ok, z, 1.0)[:, None]
    ok &= (np.abs(u[:, 0]) < 200 / F) & (np.abs(u[:, 1]) < 110 / F) & (z < NOISE.max_depth_m)
    ids = np.flatnonzero(ok)[:max_features]  # lowest ids first: a feature stays while in view
    uu = u[ids] + rng.normal(0, pixel_noise_px / F, (len(ids), 2))
    sig = np.array([NOISE.sigma_m(d) for d in z[ids]])
    d = z[ids] + depth_noise * rng.normal(0, 1, len(ids)) * sig
    return ids, uu, d


def imu_samples(t0, t1, rate_hz=200.0, gyro_bias=(0.0, 0.0, 0.0)):
    gyro_bias = np.asarray(gyro_bias, dtype=float)
    for ts in np.arange(t0, t1 + 1e-9, 1.0 / rate_hz):
        _, _, a, R, w = truth(ts)
        yield float(ts), R.T @ (a - G), w + gyro_bias


def ate_m(stamps, poses):
    """APE RMSE of the camera positions after an SE(3) Umeyama alignment (evo's ``ate``)."""
    est = np.array([P[:3, 3] for P in poses])
    ref = np.array([camera_pose(t)[:3, 3] for t in stamps])
    R, t, _ = umeyama_alignment(est, ref)
    return float(np.sqrt(np.mean(np.sum((est @ R.T + t - ref) ** 2, axis=1))))
