"""core: transforms against independent formulas, errors, plane truth helpers."""

import numpy as np
import pytest

from exobench.core import ConfigError, PlanarSurface, SceneTruth, UnknownNameError, check_range, height_at
from exobench.core.pipeline import config_from_dict
from exobench.core.transforms import (
    angle_between_deg,
    axis_angle_to_matrix,
    invert_T,
    make_T,
    matrix_to_quat_wxyz,
    quat_multiply,
    quat_wxyz_to_matrix,
    rot_x,
    rot_y,
    rot_z,
)


def test_quaternion_matrix_roundtrip_and_product():
    rng = np.random.default_rng(0)
    for _ in range(100):
        q = rng.normal(size=4)
        q /= np.linalg.norm(q)
        R = quat_wxyz_to_matrix(q)
        assert np.allclose(R @ R.T, np.eye(3), atol=1e-12)
        assert np.isclose(np.linalg.det(R), 1.0)
        q2 = matrix_to_quat_wxyz(R)
        assert np.allclose(q2, q if q[0] >= 0 else -q, atol=1e-12)
        p = rng.normal(size=4)
        p /= np.linalg.norm(p)
        assert np.allclose(quat_wxyz_to_matrix(quat_multiply(q, p)), R @ quat_wxyz_to_matrix(p), atol=1e-12)


def test_quaternion_product_of_stacks_is_the_product_row_by_row():
    """One product serves single quaternions and stacks (the IMU's errors, a trajectory's
    orientations): each row equals the single product, bit for bit, and the rotations compose."""
    rng = np.random.default_rng(1)
    a, b = rng.normal(size=(7, 4)), rng.normal(size=(7, 4))
    rows = quat_multiply(a, b)
    one = quat_multiply(a[0], b)
    assert rows.shape == one.shape == (7, 4)
    for k in range(7):
        assert np.array_equal(rows[k], quat_multiply(a[k], b[k]))
        assert np.array_equal(one[k], quat_multiply(a[0], b[k]))
        qa, qb = a[k] / np.linalg.norm(a[k]), b[k] / np.linalg.norm(b[k])
        assert np.allclose(quat_wxyz_to_matrix(rows[k]), quat_wxyz_to_matrix(qa) @ quat_wxyz_to_matrix(qb), atol=1e-12)


def test_elementary_rotations_match_rodrigues():
    for a in (-1.0, 0.3, 2.0):
        assert np.allclose(rot_x(a), axis_angle_to_matrix([1, 0, 0], a))
        assert np.allclose(rot_y(a), axis_angle_to_matrix([0, 1, 0], a))
        assert np.allclose(rot_z(a), axis_angle_to_matrix([0, 0, 1], a))
    # a quarter turn about z takes x to y
    assert np.allclose(rot_z(np.pi / 2) @ [1, 0, 0], [0, 1, 0])


def test_invert_transform():
    T = make_T(rot_z(0.4) @ rot_x(-0.2), np.array([1.0, -2.0, 0.5]))
    assert np.allclose(T @ invert_T(T), np.eye(4), atol=1e-12)


def test_angle_between_treats_normals_as_lines():
    assert angle_between_deg([0, 0, 1], [0, 0, -1]) == pytest.approx(0.0)
    assert angle_between_deg([0, 0, 1], [0, 1, 1]) == pytest.approx(45.0)
    assert angle_between_deg([0, 0, 1], [0, 0, -1], unsigned_axis=False) == pytest.approx(180.0)


@pytest.mark.parametrize("bad", [0.0, -1.0, 0.31, float("nan"), float("inf"), "x"])
def test_check_range_names_field_value_and_range(bad):
    with pytest.raises(ConfigError) as e:
        check_range("stairs.riser_m", bad, 0.0, 0.30, low_open=True)
    msg = str(e.value)
    assert "stairs.riser_m" in msg and "0.3" in msg


def test_unknown_name_lists_valid():
    err = UnknownNameError("pipeline", "rtlz", ["rtls", "batch-ransac"])
    assert "rtlz" in str(err) and "batch-ransac, rtls" in str(err)


def test_config_from_dict_converts_and_refuses_unknown():
    from dataclasses import dataclass

    @dataclass(frozen=True)
    class Cfg:
        q: int = 5
        th_z_m: float = 0.008
        htvr: bool = False

    c = config_from_dict(Cfg, {"q": "7", "th_z_m": "0.01", "htvr": "true"})
    assert (c.q, c.th_z_m, c.htvr) == (7, 0.01, True)
    with pytest.raises(UnknownNameError):
        config_from_dict(Cfg, {"qq": 1})
    with pytest.raises(ConfigError):
        config_from_dict(Cfg, {"q": "1.5"})


def _square(z, x0, x1, sid, kind="tread"):
    poly = np.array([[x0, -1, z], [x1, -1, z], [x1, 1, z], [x0, 1, z]], dtype=float)
    return PlanarSurface(sid, kind, np.array([0, 0, 1.0]), np.array([x0, 0, z]), poly, (f"g{sid}",))


def test_surface_contains_and_height_at():
    truth = SceneTruth(
        surfaces=(_square(0.0, -5, 0, 0, "ground"), _square(0.16, 0, 0.28, 2), _square(0.32, 0.28, 2, 4)),
        geom_surfaces={"g0": (0,), "g2": (2,), "g4": (4,)},
    )
    assert height_at(truth, -1.0, 0.0) == 0.0
    assert height_at(truth, 0.1, 0.5) == pytest.approx(0.16)
    assert height_at(truth, 1.0, 0.0) == pytest.approx(0.32)
    assert np.isnan(height_at(truth, 1.0, 3.0))
    assert truth.surface_of_hit("g2", np.array([0.1, 0.2, 0.16])) == 2
    assert truth.surface_of_hit("g2", np.array([0.5, 0.2, 0.16])) == -1  # outside the polygon
