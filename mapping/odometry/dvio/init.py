"""Depth-enhanced structure-from-motion initialisation of D-VIO (seeds/002 eq. 1-5) and the
visual-inertial alignment that follows it (VINS-Mono's ``LinearAlignment``).

1. SfM (:func:`depth_sfm`): the IMU poses of the window's keyframes and the landmarks' positions
   in the frame of the first keyframe's IMU, W, minimising the reprojection cost of eq. (1-2) and
   the depth cost of eq. (3-4) together (eq. 5), with a robust kernel. The start is the first
   keyframe's depths back-projected, each later keyframe placed by PnP on the landmarks known so
   far (``cv2.solvePnPRansac``) and adding its own depth landmarks. Depth makes the SfM metric, so
   unlike VINS-Mono's visual-only SfM its scale is known; the alignment still estimates one, as a
   check (close to 1 when the depth is right).
2. Alignment (:func:`align_visual_inertial`): with the preintegrations ``(alpha, beta)`` of eq. (7)
   between consecutive keyframes, the velocities ``v_k``, the gravity ``g_W`` and the scale ``s``
   solve the linear system, in W,

       R_k alpha_k = s (p_{k+1} - p_k) - v_k dt - g_W dt^2 / 2
       R_k beta_k  = v_{k+1} - v_k - g_W dt

   by least squares. Depth makes the SfM metric, so ``s`` is not needed (what the depth lets the
   initialisation skip: VINS-Mono waits for motion that makes the scale observable): it is
   reported, and checked only when ``max_scale_error`` is given; the free solution is refused when
   ``|g_W|`` is more than ``max_gravity_error_mps2`` from gravity (VINS-Mono refuses s < 0 and a
   gravity off by more than 1 m/s^2). Then ``s = 1`` and gravity at its known magnitude along the free solution's direction
   give ``v`` by least squares again (VINS-Mono refines the direction on a 2-sphere; one
   projection suffices when the direction is good, which the metric SfM makes it). Applying the
   free ``s`` instead would scale good depth-metric poses by the noise of double-differenced
   positions. The rotation that takes ``g_W`` to -z (no yaw: it is unobservable) gives the poses
   in the gravity-aligned frame G.

0. Gyroscope bias (:func:`solve_gyro_bias`, VINS-Mono's ``solveGyroscopeBias``), between SfM and
   alignment: the SfM's relative rotations ``R_k^T R_{k+1}`` are compared with the preintegrated
   ones ``gamma_k(b_g)``; the bias solves ``sum_k |Log(gamma_k(b_g)^T R_k^T R_{k+1})|^2`` by
   Gauss-Newton with gamma's bias Jacobian (VINS-Mono takes one linear step from zero; two
   steps here, so a bias guess far from the truth is also corrected). The alignment then uses
   the preintegrations corrected to that bias (gtsam's first-order bias correction, which is
   VINS-Mono's ``repropagate`` to first order; the window re-integrates the samples). Faulty observations (non-finite bearings, depths the camera
cannot measure) are left out; too few landmarks for PnP or too few keyframes give an
:class:`InitResult` with ``ok`` False and the reason, never an exception.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import cv2
import gtsam
import numpy as np

from .factors import DepthNoise, Extrinsics
from .grouped import sfm_landmark_factor
from .imu import GRAVITY_MPS2

__all__ = ["InitResult", "KeyframeObs", "align_visual_inertial", "corrected_deltas", "depth_sfm", "initialise",
           "solve_gyro_bias"]

# Landmark keys live above the pose keys (one pose per keyframe, far fewer than this).
_L0 = 1_000_000
_MIN_PNP = 6


@dataclass(frozen=True, eq=False)
class KeyframeObs:
    """One keyframe's observations: feature id -> (normalised bearing (2,), depth m or NaN)."""

    stamp_s: float
    features: Mapping[int, tuple[np.ndarray, float]]


@dataclass(frozen=True, eq=False)
class InitResult:
    """Outcome of the initialisation.

    Attributes:
        ok: False when it could not be done (``reason`` says why; the other fields may be empty).
        T_G_imu: (M, 4, 4) IMU poses of the keyframes in G (gravity -z, origin at the first).
        v_G: (M, 3) velocities in G, m/s.
        gravity_W: gravity in the first keyframe's IMU frame (W), m/s^2.
        scale: the free alignment's scale of the SfM (1 for a perfect metric SfM; a check, the
            poses are the SfM's metric ones).
        landmarks_G: feature id -> position in G.
        gyro_bias: gyroscope bias, rad/s (3,), from :func:`solve_gyro_bias` (the given guess when
            not estimated).
    """

    ok: bool
    reason: str = ""
    T_G_imu: np.ndarray = field(default_factory=lambda: np.zeros((0, 4, 4)))
    v_G: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    gravity_W: np.ndarray = field(default_factory=lambda: np.full(3, np.nan))
    scale: float = float("nan")
    landmarks_G: dict[int, np.ndarray] = field(default_factory=dict)
    gyro_bias: np.ndarray = field(default_factory=lambda: np.zeros(3))


def _cam_point(T_WI: gtsam.Pose3, l_W: np.ndarray, ext: Extrinsics) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The landmark in the camera (eq. 1's bracket) and its Jacobians wrt the pose and l."""
    R = T_WI.rotation().matrix()
    P_I = R.T @ (l_W - T_WI.translation())
    P_c = ext.R_IC.T @ (P_I - ext.p_IC)
    skew = np.array([[0.0, -P_I[2], P_I[1]], [P_I[2], 0.0, -P_I[0]], [-P_I[1], P_I[0], 0.0]])
    return P_c, ext.R_IC.T @ np.hstack([skew, -np.eye(3)]), ext.R_IC.T @ R.T


def _sfm_factor(kp: int, kl: int, u: np.ndarray | None, d: float | None, ext: Extrinsics,
                model: gtsam.noiseModel.Base) -> gtsam.CustomFactor:
    """Eq. (1) when ``u`` is given, eq. (3) when ``d`` is, one observation per factor: the
    reference :func:`.grouped.sfm_landmark_factor` (which :func:`depth_sfm` uses) is tested against."""

    def error(this: gtsam.CustomFactor, values: gtsam.Values, H: list[np.ndarray] | None) -> np.ndarray:
        P, J_pose, J_l = _cam_point(values.atPose3(kp), values.atPoint3(kl), ext)
        if u is not None:
            z = P[2]
            D = np.array([[1.0 / z, 0.0, -P[0] / z**2], [0.0, 1.0 / z, -P[1] / z**2]])
            r = P[:2] / z - u
        else:
            D = np.array([[0.0, 0.0, 1.0]])
            r = np.array([P[2] - d])
        if H is not None:
            H[0], H[1] = D @ J_pose, D @ J_l
        return r

    return gtsam.CustomFactor(model, gtsam.KeyVector([kp, kl]), error)


def _usable(obs: tuple[np.ndarray, float], noise: DepthNoise) -> tuple[np.ndarray | None, float | None]:
    u = np.asarray(obs[0], dtype=float).reshape(2)
    if not np.all(np.isfinite(u)):
        return None, None
    d = float(obs[1])
    return u, (d if noise.valid(d) else None)


def depth_sfm(frames: Sequence[KeyframeObs], ext: Extrinsics, noise: DepthNoise, pixel_sigma: float = 1.5 / 424.0,
              kernel: str = "cauchy") -> tuple[list[gtsam.Pose3], dict[int, np.ndarray]] | str:
    """IMU poses in W and landmarks in W (eq. 5), or the reason it failed."""
    T_IC = gtsam.Pose3(gtsam.Rot3(ext.R_IC), ext.p_IC)
    poses: list[gtsam.Pose3] = [gtsam.Pose3()]
    lms: dict[int, np.ndarray] = {}

    def add_depth_landmarks(k: int) -> None:
        T_WC = poses[k] * T_IC
        for fid, obs in frames[k].features.items():
            u, d = _usable(obs, noise)
            if fid not in lms and u is not None and d is not None:
                lms[fid] = T_WC.transformFrom(np.array([u[0] * d, u[1] * d, d]))

    add_depth_landmarks(0)
    for k in range(1, len(frames)):
        pairs = [(lms[f], _usable(o, noise)[0]) for f, o in frames[k].features.items() if f in lms]
        pairs = [(p, u) for p, u in pairs if u is not None]
        if len(pairs) < _MIN_PNP:
            return f"keyframe {k}: {len(pairs)} known landmarks seen, PnP needs {_MIN_PNP}"
        obj = np.array([p for p, _ in pairs], dtype=np.float64)
        img = np.array([u for _, u in pairs], dtype=np.float64)
        ok, rvec, tvec, _ = cv2.solvePnPRansac(obj, img, np.eye(3), None, reprojectionError=3.0 * pixel_sigma,
                                               flags=cv2.SOLVEPNP_ITERATIVE)
        if not ok:
            return f"keyframe {k}: PnP failed"
        T_CW = gtsam.Pose3(gtsam.Rot3(cv2.Rodrigues(rvec)[0]), tvec.ravel())
        poses.append(T_CW.inverse() * T_IC.inverse())
        add_depth_landmarks(k)

    graph = gtsam.NonlinearFactorGraph()
    values = gtsam.Values()
    for k, T in enumerate(poses):
        values.insert(k, T)
    graph.add(gtsam.PriorFactorPose3(0, gtsam.Pose3(), gtsam.noiseModel.Isotropic.Sigma(6, 1e-6)))
    ids = sorted(lms)
    for fid in ids:
        values.insert(_L0 + fid, lms[fid])
    # Eq. (1) and (3) of each landmark in every keyframe that saw it, as one factor per landmark
    # (grouped.py: one Python callback per landmark and optimiser step, not two per observation).
    seen: dict[int, list[tuple[int, np.ndarray, float]]] = {}
    for k, f in enumerate(frames):
        for fid, obs in f.features.items():
            u, d = _usable(obs, noise) if fid in lms else (None, None)
            if u is not None:
                seen.setdefault(fid, []).append((k, u, math.nan if d is None else d))
    for fid in ids:
        fac = sfm_landmark_factor(_L0 + fid, seen.get(fid, []), ext, pixel_sigma, noise, kernel)
        if fac is not None:
            graph.add(fac)
    result = gtsam.LevenbergMarquardtOptimizer(graph, values).optimize()
    return ([result.atPose3(k) for k in range(len(poses))],
            {fid: result.atPoint3(_L0 + fid) for fid in ids})


def corrected_deltas(pim: gtsam.PreintegratedCombinedMeasurements, bias: gtsam.imuBias.ConstantBias | None = None,
                     ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(gamma (3x3), alpha (3,), beta (3,))`` of eq. (7) corrected to ``bias`` (default: the
    preintegration's own). gtsam's ``predict`` from the identity at rest adds gravity's terms to
    the corrected deltas; its difference from the prediction at the preintegration's own bias is
    the correction alone (the Python binding does not expose the gravity vector)."""
    if bias is None:
        return pim.deltaRij().matrix(), np.asarray(pim.deltaPij(), float), np.asarray(pim.deltaVij(), float)
    rest = gtsam.NavState(gtsam.Pose3(), np.zeros(3))
    nav, own = pim.predict(rest, bias), pim.predict(rest, pim.biasHat())
    return (nav.attitude().matrix(), pim.deltaPij() + nav.position() - own.position(),
            pim.deltaVij() + nav.velocity() - own.velocity())


def solve_gyro_bias(poses_W: Sequence[gtsam.Pose3], pims: Sequence[gtsam.PreintegratedCombinedMeasurements],
                    iterations: int = 2) -> np.ndarray:
    """Gyroscope bias (3,), rad/s, from the SfM rotations against the preintegrated ones (step 0
    of the module docstring); ``pims[k]`` spans ``poses_W[k]`` to ``poses_W[k+1]``."""
    bg = np.array(pims[0].biasHat().gyroscope(), dtype=float) if pims else np.zeros(3)
    eps = 1e-4
    for _ in range(iterations):
        JTJ, JTr = np.zeros((3, 3)), np.zeros(3)
        for k, pim in enumerate(pims):
            acc = pim.biasHat().accelerometer()
            R_rel = gtsam.Rot3(poses_W[k].rotation().matrix().T @ poses_W[k + 1].rotation().matrix())

            def err(b: np.ndarray, pim: gtsam.PreintegratedCombinedMeasurements = pim,
                    acc: np.ndarray = acc, R_rel: gtsam.Rot3 = R_rel) -> np.ndarray:
                gamma = gtsam.Rot3(corrected_deltas(pim, gtsam.imuBias.ConstantBias(acc, b))[0])
                return gtsam.Rot3.Logmap(gamma.between(R_rel))

            r = err(bg)
            J = np.column_stack([(err(bg + eps * e) - r) / eps for e in np.eye(3)])
            JTJ += J.T @ J
            JTr += J.T @ r
        if not np.all(np.isfinite(JTJ)) or np.linalg.cond(JTJ) > 1e12:
            break
        bg = bg - np.linalg.solve(JTJ, JTr)
    return bg


def _deltas(pims: Sequence[gtsam.PreintegratedCombinedMeasurements], gyro_bias: np.ndarray | None) -> list:
    return [corrected_deltas(p, None if gyro_bias is None else
                             gtsam.imuBias.ConstantBias(p.biasHat().accelerometer(), gyro_bias)) for p in pims]


def _alignment_system(poses_W: Sequence[gtsam.Pose3], pims: Sequence[gtsam.PreintegratedCombinedMeasurements],
                      deltas: Sequence) -> tuple[np.ndarray, np.ndarray]:
    """A, b of the docstring's system; unknowns (v_0 .. v_{M-1}, g_W, s)."""
    M = len(poses_W)
    n = 3 * M + 4
    rows, rhs = [], []
    for k in range(M - 1):
        dt = pims[k].deltaTij()
        R = poses_W[k].rotation().matrix()
        dp = poses_W[k + 1].translation() - poses_W[k].translation()
        A = np.zeros((6, n))
        A[:3, 3 * k:3 * k + 3] = -dt * np.eye(3)
        A[:3, 3 * M:3 * M + 3] = -0.5 * dt * dt * np.eye(3)
        A[:3, 3 * M + 3] = dp
        A[3:, 3 * k:3 * k + 3] = -np.eye(3)
        A[3:, 3 * k + 3:3 * k + 6] = np.eye(3)
        A[3:, 3 * M:3 * M + 3] = -dt * np.eye(3)
        rows.append(A)
        rhs.append(np.concatenate([R @ deltas[k][1], R @ deltas[k][2]]))
    return np.vstack(rows), np.concatenate(rhs)


def align_visual_inertial(poses_W: Sequence[gtsam.Pose3], pims: Sequence[gtsam.PreintegratedCombinedMeasurements],
                          gravity_mps2: float = GRAVITY_MPS2, gyro_bias: np.ndarray | None = None,
                          gravity_dir_W: np.ndarray | None = None,
                          ) -> tuple[np.ndarray, np.ndarray, float, np.ndarray, np.ndarray]:
    """The linear system of the docstring: the free solution's scale and gravity in W, then the
    velocities (M, 3) and gravity in W with the scale 1 and gravity's magnitude imposed, along
    ``gravity_dir_W`` when given (else along the free solution's). With ``gyro_bias`` the
    preintegrations are taken corrected to it (accelerometer bias as held)."""
    M = len(poses_W)
    A0, b0 = _alignment_system(poses_W, pims, _deltas(pims, gyro_bias))

    def solve(g_fixed: np.ndarray | None, s_fixed: float | None = None) -> np.ndarray:
        A, b = A0, b0
        if s_fixed is not None:
            b = b - A[:, 3 * M + 3] * s_fixed
            A = A[:, :3 * M + 3]
        if g_fixed is not None:
            b = b - A[:, 3 * M:3 * M + 3] @ g_fixed
            A = np.delete(A, np.s_[3 * M:3 * M + 3], axis=1)
            x = np.linalg.lstsq(A, b, rcond=None)[0]
            return np.concatenate([x[:3 * M], g_fixed, x[3 * M:], [s_fixed] if s_fixed is not None else []])
        return np.linalg.lstsq(A, b, rcond=None)[0]

    free = solve(None)
    g_free, s_free = free[3 * M:3 * M + 3], float(free[3 * M + 3])
    direction = g_free if gravity_dir_W is None else np.asarray(gravity_dir_W, dtype=float).reshape(3)
    g = gravity_mps2 * direction / max(np.linalg.norm(direction), 1e-9)
    x = solve(g, 1.0)
    return x[:3 * M].reshape(M, 3), g, s_free, g_free, x


def _rotation_to_down(g_W: np.ndarray) -> np.ndarray:
    """R_GW with R_GW g_W along -z, the smallest such rotation (no yaw added)."""
    a = g_W / np.linalg.norm(g_W)
    b = np.array([0.0, 0.0, -1.0])
    axis = np.cross(a, b)
    s, c = np.linalg.norm(axis), float(a @ b)
    if s < 1e-12:
        return np.eye(3) if c > 0 else np.diag([1.0, -1.0, -1.0])
    return gtsam.Rot3.Rodrigues(axis / s * np.arctan2(s, c)).matrix()


def initialise(frames: Sequence[KeyframeObs], pims: Sequence[gtsam.PreintegratedCombinedMeasurements],
               ext: Extrinsics, noise: DepthNoise, pixel_sigma: float = 1.5 / 424.0,
               gravity_mps2: float = GRAVITY_MPS2, max_scale_error: float | None = None,
               max_gravity_error_mps2: float = 1.0, estimate_gyro_bias: bool = True,
               gravity_dir_W: np.ndarray | None = None) -> InitResult:
    """SfM, gyroscope bias (unless ``estimate_gyro_bias`` is False: the preintegrations' own),
    then alignment over a window; ``pims[k]`` spans keyframes k to k+1.

    ``gravity_dir_W``: gravity's direction in the first keyframe's IMU frame when it is known
    from elsewhere (the window after a short loss: its last good attitude propagated by the
    gyroscope). The velocities are then solved, and the poses put in G, with it instead of the
    free solution's direction, which over the second of keyframes of a slow walk in a bare
    corridor came out 14-18 deg off (docs/dvio.md "The MH01-like walk"); the free solution's
    gravity magnitude is still checked."""
    if len(frames) < 3 or len(pims) != len(frames) - 1:
        return InitResult(False, f"{len(frames)} keyframes and {len(pims)} preintegrations; "
                                 "at least 3 keyframes and one preintegration between each pair")
    sfm = depth_sfm(frames, ext, noise, pixel_sigma)
    if isinstance(sfm, str):
        return InitResult(False, sfm)
    poses_W, lms_W = sfm
    bg = solve_gyro_bias(poses_W, pims) if estimate_gyro_bias else np.array(pims[0].biasHat().gyroscope(), float)
    v_W, g_W, s, g_free, _ = align_visual_inertial(poses_W, pims, gravity_mps2, bg, gravity_dir_W=gravity_dir_W)
    # The depth makes the SfM metric, so D-VIO need not observe the scale from the IMU, which is
    # what VINS-Mono waits for (enough excitation): on a slow walk the free scale is biased far
    # from 1 (0.2-0.9 on the vio smoke walk, standard error about 0.1) while gravity is right
    # (9.7-9.9 m/s^2). ``max_scale_error`` (None: not checked) refuses a free scale that far off.
    scale_bad = max_scale_error is not None and not abs(s - 1.0) <= max_scale_error
    if not (np.all(np.isfinite(v_W)) and np.isfinite(s)) or scale_bad:
        return InitResult(False, f"visual-inertial alignment: scale {s:.3f} of the depth SfM, "
                                 f"allowed 1 +- {max_scale_error}", scale=s)
    if not abs(np.linalg.norm(g_free) - gravity_mps2) <= max_gravity_error_mps2:
        return InitResult(False, f"visual-inertial alignment: gravity {np.linalg.norm(g_free):.2f} m/s^2, "
                                 f"allowed {gravity_mps2} +- {max_gravity_error_mps2}", scale=s)
    R_GW = _rotation_to_down(g_W)
    p0 = poses_W[0].translation()
    T = np.zeros((len(poses_W), 4, 4))
    for k, P in enumerate(poses_W):
        T[k, :3, :3] = R_GW @ P.rotation().matrix()
        T[k, :3, 3] = R_GW @ (P.translation() - p0)
        T[k, 3, 3] = 1.0
    lms_G = {f: R_GW @ (p - p0) for f, p in lms_W.items()}
    return InitResult(True, "", T, v_W @ R_GW.T, g_W, s, lms_G, bg)
