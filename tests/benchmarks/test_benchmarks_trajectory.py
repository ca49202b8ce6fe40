"""Trajectory metrics against evo on the same trajectories, and against constructed cases."""

from __future__ import annotations

import math

import numpy as np
import pytest

# evo is a test dependency (pyproject's "test" extra): the reference implementation we match
from evo.core import metrics as evo_metrics  # noqa: E402
from evo.core import sync  # noqa: E402
from evo.core.trajectory import PoseTrajectory3D  # noqa: E402
from evo.tools import file_interface  # noqa: E402

from exobench.benchmarks.trajectory import (
    Trajectory,
    align,
    associate,
    ate,
    drift_per_metre,
    loop_errors,
    loop_errors_rmse,
    read_kitti,
    read_tum,
    rpe,
    time_per_scan_ms,
    umeyama_alignment,
    write_kitti,
    write_tum,
)
from exobench.core.errors import ConfigError
from exobench.core.transforms import axis_angle_to_matrix, make_T, matrix_to_quat_wxyz, rot_z


def _smooth(seed: int, n: int = 300, rate_hz: float = 20.0) -> Trajectory:
    """A smooth walk-like trajectory: sums of sinusoids in position and roll/pitch/yaw."""
    rng = np.random.default_rng(seed)
    t = np.arange(n) / rate_hz
    pos = np.zeros((n, 3))
    for k in range(3):
        a, f, ph = rng.uniform(0.3, 2.0, 3), rng.uniform(0.02, 0.3, 3), rng.uniform(0, 2 * np.pi, 3)
        pos[:, k] = (a[:, None] * np.sin(2 * np.pi * f[:, None] * t + ph[:, None])).sum(axis=0)
    pos[:, 0] += 0.8 * t  # walking forward
    yaw = 0.4 * np.sin(0.2 * t) + 0.1 * t
    pitch = 0.1 * np.sin(0.7 * t + 1.0)
    roll = 0.05 * np.sin(1.1 * t)
    quats = np.array([_quat_rpy(r, p, y) for r, p, y in zip(roll, pitch, yaw)])
    return Trajectory(t + 1000.0, pos, quats)


def _quat_rpy(roll: float, pitch: float, yaw: float) -> np.ndarray:
    R = rot_z(yaw) @ axis_angle_to_matrix([0, 1, 0], pitch) @ axis_angle_to_matrix([1, 0, 0], roll)
    return matrix_to_quat_wxyz(R)


def _perturbed(ref: Trajectory, seed: int) -> Trajectory:
    """Drift, noise, a rigid offset, jittered stamps and dropped poses."""
    rng = np.random.default_rng(seed)
    n = len(ref)
    T = ref.poses_se3()
    drift_yaw = np.linspace(0, 0.08, n)
    for i in range(n):
        R_noise = axis_angle_to_matrix(rng.normal(size=3), rng.normal(scale=0.01))
        T[i, :3, :3] = rot_z(drift_yaw[i]) @ T[i, :3, :3] @ R_noise
        T[i, :3, 3] = rot_z(drift_yaw[i]) @ T[i, :3, 3] + np.array([0.01, -0.005, 0.002]) * i / 10
        T[i, :3, 3] += rng.normal(scale=0.02, size=3)
    T_off = make_T(axis_angle_to_matrix([0.2, -0.3, 1.0], 0.7), np.array([3.0, -2.0, 0.5]))
    T = T_off @ T
    stamps = ref.stamps_s + rng.uniform(-0.004, 0.004, n)
    keep = np.sort(rng.choice(n, size=n - 25, replace=False))
    return Trajectory.from_poses(stamps, T).subset(keep)


def _to_evo(tr: Trajectory) -> PoseTrajectory3D:
    return PoseTrajectory3D(
        positions_xyz=tr.positions_xyz.copy(),
        orientations_quat_wxyz=tr.orientations_quat_wxyz.copy(),
        timestamps=tr.stamps_s.copy(),
    )


@pytest.fixture(params=[0, 1, 2])
def pair(request) -> tuple[Trajectory, Trajectory]:
    ref = _smooth(request.param)
    est = _perturbed(ref, 100 + request.param)
    if request.param == 2:  # a reference with fewer poses than the estimate: association starts from it
        ref = ref.subset(np.arange(0, len(ref), 2))
    return est, ref


def _evo_ape(est: Trajectory, ref: Trajectory, correct_scale: bool) -> dict[str, float]:
    ref_e, est_e = sync.associate_trajectories(_to_evo(ref), _to_evo(est), max_diff=0.01)
    est_e.align(ref_e, correct_scale=correct_scale)
    ape = evo_metrics.APE(evo_metrics.PoseRelation.translation_part)
    ape.process_data((ref_e, est_e))
    return ape.get_all_statistics()


@pytest.mark.parametrize("correct_scale", [False, True])
def test_ate_equals_evo_ape_translation_part(pair, correct_scale):
    est, ref = pair
    ours = ate(est, ref, align=True, correct_scale=correct_scale)
    theirs = _evo_ape(est, ref, correct_scale)
    assert ours["rmse"] > 0.01  # the perturbation is visible after alignment
    for k in ("rmse", "mean", "median", "std", "min", "max", "sse"):
        assert ours[k] == pytest.approx(theirs[k], abs=1e-9, rel=1e-12), k


@pytest.mark.parametrize(
    ("delta", "unit", "all_pairs"),
    [(1, "frames", False), (5, "frames", False), (3, "frames", True), (1.0, "m", False), (2.0, "m", True)],
)
def test_rpe_equals_evo_rpe_translation_part(pair, delta, unit, all_pairs):
    est, ref = pair
    ours = rpe(est, ref, delta=delta, delta_unit=unit, all_pairs=all_pairs)
    ref_e, est_e = sync.associate_trajectories(_to_evo(ref), _to_evo(est), max_diff=0.01)
    est_e.align(ref_e)  # as evo_rpe -a does; RPE does not change under a rigid alignment
    evo_unit = evo_metrics.Unit.frames if unit == "frames" else evo_metrics.Unit.meters
    metric = evo_metrics.RPE(evo_metrics.PoseRelation.translation_part, delta=delta, delta_unit=evo_unit,
                             all_pairs=all_pairs)
    metric.process_data((ref_e, est_e))
    theirs = metric.get_all_statistics()
    for k in ("rmse", "mean", "median", "max", "min", "sse"):
        assert ours[k] == pytest.approx(theirs[k], abs=1e-9, rel=1e-9), k


def test_association_matches_evo(pair):
    est, ref = pair
    est_s, ref_s = associate(est, ref, 0.01)
    ref_e, est_e = sync.associate_trajectories(_to_evo(ref), _to_evo(est), max_diff=0.01)
    np.testing.assert_array_equal(est_s.stamps_s, est_e.timestamps)
    np.testing.assert_array_equal(ref_s.stamps_s, ref_e.timestamps)
    assert np.all(np.abs(est_s.stamps_s - ref_s.stamps_s) <= 0.01)
    with pytest.raises(ConfigError):
        associate(est, Trajectory(ref.stamps_s + 100.0, ref.positions_xyz, ref.orientations_quat_wxyz))


def test_ate_without_alignment_of_a_shifted_copy_is_the_shift():
    ref = _smooth(5)
    d = np.array([0.3, -0.4, 1.2])  # |d| = 1.3
    est = Trajectory(ref.stamps_s, ref.positions_xyz + d, ref.orientations_quat_wxyz)
    m = ate(est, ref, align=False)
    assert m["rmse"] == pytest.approx(1.3) and m["min"] == pytest.approx(1.3) and m["std"] == pytest.approx(0, abs=1e-12)
    assert ate(est, ref, align=True)["max"] == pytest.approx(0.0, abs=1e-9)
    assert rpe(est, ref)["max"] == pytest.approx(0.0, abs=1e-12)


@pytest.mark.parametrize("with_scale", [False, True])
def test_umeyama_recovers_a_known_transform(with_scale):
    rng = np.random.default_rng(7)
    src = rng.normal(size=(50, 3))
    R = axis_angle_to_matrix([1.0, 2.0, -0.5], 2.4)
    t, s = np.array([1.0, -3.0, 0.25]), (1.7 if with_scale else 1.0)
    dst = s * src @ R.T + t
    R_hat, t_hat, s_hat = umeyama_alignment(src, dst, with_scale=with_scale)
    np.testing.assert_allclose(R_hat, R, atol=1e-12)
    np.testing.assert_allclose(t_hat, t, atol=1e-12)
    assert s_hat == pytest.approx(s, abs=1e-12)
    assert np.linalg.det(R_hat) == pytest.approx(1.0)


def test_umeyama_refuses_collinear_points():
    line = np.outer(np.linspace(0, 1, 10), [1.0, 2.0, 3.0])
    with pytest.raises(ConfigError):
        umeyama_alignment(line, line + 1.0)


def test_align_moves_a_rigidly_moved_copy_back_onto_the_reference():
    ref = _smooth(3)
    T_off = make_T(axis_angle_to_matrix([0, 0, 1], 1.0), np.array([5.0, 1.0, 0.0]))
    est = Trajectory.from_poses(ref.stamps_s, T_off @ ref.poses_se3())
    np.testing.assert_allclose(align(est, ref).poses_se3(), ref.poses_se3(), atol=1e-10)


def test_tum_round_trip_and_evo_reads_our_file(tmp_path):
    tr = _perturbed(_smooth(4), 9)
    path = tmp_path / "est.tum"
    write_tum(tr, path)
    back = read_tum(path)
    np.testing.assert_array_equal(back.stamps_s, tr.stamps_s)
    np.testing.assert_array_equal(back.positions_xyz, tr.positions_xyz)
    np.testing.assert_array_equal(back.orientations_quat_wxyz, tr.orientations_quat_wxyz)
    first = path.read_text().splitlines()[1].split()
    assert [float(v) for v in first[4:]] == list(tr.orientations_quat_wxyz[0, [1, 2, 3, 0]])  # xyzw in the file
    evo_tr = file_interface.read_tum_trajectory_file(str(path))
    np.testing.assert_array_equal(evo_tr.timestamps, tr.stamps_s)
    np.testing.assert_allclose(np.array(evo_tr.poses_se3), tr.poses_se3(), atol=1e-12)


def test_kitti_round_trip_and_evo_reads_our_file(tmp_path):
    tr = _smooth(6, n=40)
    path = tmp_path / "est.txt"
    write_kitti(tr, path)
    lines = path.read_text().splitlines()
    assert len(lines) == 40 and all(len(line.split()) == 12 for line in lines)
    back = read_kitti(path, stamps_s=tr.stamps_s)
    np.testing.assert_allclose(back.poses_se3(), tr.poses_se3(), atol=1e-12)
    np.testing.assert_array_equal(back.stamps_s, tr.stamps_s)
    evo_poses = np.array(file_interface.read_kitti_poses_file(str(path)).poses_se3)
    np.testing.assert_array_equal(evo_poses, tr.poses_se3())


def _circle_loop(n: int = 200, radius: float = 3.0) -> np.ndarray:
    """Poses walking once around a circle, facing along it; last pose equals the first."""
    a = np.linspace(0.0, 2 * np.pi, n)
    return np.array([make_T(rot_z(ai + np.pi / 2), [radius * np.cos(ai), radius * np.sin(ai), 0.0]) for ai in a])


def test_loop_errors_of_a_perfect_loop_are_zero():
    T = _circle_loop()
    m = loop_errors(Trajectory.from_poses(np.arange(len(T)) * 0.1, T))
    for k, v in m.items():
        assert v == pytest.approx(0.0, abs=1e-12), k


def test_loop_errors_of_a_known_end_offset():
    T = _circle_loop()
    d = np.array([0.3, -0.2, 0.05])
    axis, angle = np.array([0.2, 0.1, 1.0]), 0.12
    T[-1, :3, 3] += d
    T[-1, :3, :3] = T[-1, :3, :3] @ axis_angle_to_matrix(axis, angle)
    m = loop_errors(Trajectory.from_poses(np.arange(len(T)) * 0.1, T))
    assert m["te_m"] == pytest.approx(np.linalg.norm(d), abs=1e-12)
    assert [m["tve_x_m"], m["tve_y_m"], m["tve_z_m"]] == pytest.approx(list(d), abs=1e-12)
    assert m["oe_rad"] == pytest.approx(angle, abs=1e-12)
    # in the first pose's axes (facing +y at the start), x and y of the offset swap roles
    s = loop_errors(Trajectory.from_poses(np.arange(len(T)) * 0.1, T), in_start_frame=True)
    assert [s["tve_x_m"], s["tve_y_m"], s["tve_z_m"]] == pytest.approx([d[1], -d[0], d[2]], abs=1e-12)
    r = loop_errors_rmse([m, {k: -v for k, v in m.items()}, {k: 0.0 for k in m}])
    assert r["te_m"] == pytest.approx(np.linalg.norm(d) * math.sqrt(2 / 3))


def test_drift_per_metre_of_a_known_end_error():
    n, length = 101, 10.0
    pos = np.column_stack([np.linspace(0, length, n), np.zeros(n), np.zeros(n)])
    quats = np.tile([1.0, 0, 0, 0], (n, 1))
    ref = Trajectory(np.arange(n) * 0.1, pos, quats)
    est_pos = pos.copy()
    est_pos[-1] += [0.0, 0.3, 0.4]  # 0.5 m off at the end
    est_local = Trajectory(ref.stamps_s, est_pos, quats)
    T_off = make_T(rot_z(0.9), np.array([2.0, -1.0, 0.3]))  # the estimate's own odometry frame
    est = Trajectory.from_poses(ref.stamps_s, T_off @ est_local.poses_se3())
    assert drift_per_metre(est, ref) == pytest.approx(0.5 / length, abs=1e-12)


def test_time_per_scan_is_the_median_in_ms():
    assert time_per_scan_ms([0.010, 0.030, 0.020, float("nan")]) == pytest.approx(20.0)
    assert math.isnan(time_per_scan_ms([]))


def test_bad_shapes_are_config_errors():
    with pytest.raises(ConfigError):
        Trajectory(np.zeros(3), np.zeros((2, 3)), np.tile([1.0, 0, 0, 0], (3, 1)))
    with pytest.raises(ConfigError):
        rpe(_smooth(0, n=10), _smooth(0, n=10), delta=1, delta_unit="s")
