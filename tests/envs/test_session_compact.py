"""Format 5: the compact LiDAR streams come back bit for bit, on a simulated walk and on adversarial values."""

import dataclasses

import numpy as np
import pytest

from exobench.core import LidarScan, LidarTruth
from exobench.envs.session import read_meta, read_session, write_session
from exobench.envs.session.lidar_pack import pack_scans, pack_truths, unpack_scans, unpack_truths
from exobench.envs.session.packing import residual, restore, unzigzag, zigzag
from exobench.envs.sim import OfficeScenario, simulate_office

pytestmark = pytest.mark.long(seconds=5)  # the workers take it first (tests/conftest.py); 5: the file at -n 0 in one run at load 12-15, scaled to that run's CPU


def _same(a, b) -> bool:
    a, b = np.asarray(a), np.asarray(b)
    return a.dtype == b.dtype and a.shape == b.shape and a.tobytes() == b.tobytes()


def _assert_same(xs, ys, what: str) -> None:
    assert len(xs) == len(ys), what
    for k, (x, y) in enumerate(zip(xs, ys)):
        assert type(x) is type(y), (what, k)
        for f in dataclasses.fields(x):
            u, v = getattr(x, f.name), getattr(y, f.name)
            ok = _same(u, v) if isinstance(u, np.ndarray) else (type(u) is type(v) and u == v)
            assert ok, (what, k, f.name)


def test_office_walk_roundtrips_bit_exact_and_small(tmp_path):
    ep = simulate_office(OfficeScenario.from_dict({"max_distance_m": 1.0}), 2)
    assert sum(isinstance(f, LidarScan) for f in ep.frames) > 5
    path = write_session(ep, tmp_path / "s")
    assert read_meta(path)["version"] == 5
    assert not (path / "truth" / "lidar").exists() and (path / "truth" / "lidar.npz").is_file()
    back = read_session(path)
    _assert_same(ep.frames, back.frames, "frames")
    _assert_same(ep.truth.lidar, back.truth.lidar, "lidar truth")
    old = write_session(ep, tmp_path / "s4", compact=False)

    def size(p):
        return sum(f.stat().st_size for f in p.rglob("*") if f.is_file())

    assert size(path) < 0.3 * size(old)


def _adversarial_floats(rng, n: int) -> np.ndarray:
    a = rng.normal(size=n) * 3.0
    special = [np.nan, -np.nan, np.inf, -np.inf, -0.0, 0.0, 5e-324, -5e-324, 2.2250738585072014e-308, 1e308]
    a[: len(special)] = special
    a.view(np.uint64)[len(special)] = 0x7FF8DEADBEEF0001  # NaN payloads
    a.view(np.uint64)[len(special) + 1] = 0xFFF0000000000001  # signalling NaN, sign set
    return a


def test_residual_coding_is_exact_on_any_bits():
    rng = np.random.default_rng(0)
    actual = rng.integers(0, 2**64, 5000, dtype=np.uint64, endpoint=False).view(np.float64)
    pred = rng.integers(0, 2**64, 5000, dtype=np.uint64, endpoint=False).view(np.float64)
    actual[:20], pred[20:40] = _adversarial_floats(rng, 20), _adversarial_floats(rng, 20)
    assert _same(restore(residual(actual, pred), pred), actual)
    d = np.array([0, -1, 1, -(2**63), 2**63 - 1], dtype=np.int64)
    assert _same(unzigzag(zigzag(d)), d) and zigzag(d)[:3].tolist() == [0, 1, 2]


def _scans_and_truths(rng, adversarial: bool):
    """Scans of two sensors re-firing the same rays (one ray twice in a scan), ranges in 2 mm steps,
    and (adversarial) NaN payloads, -0.0, infinities and denormals in every float field."""
    rays = rng.normal(size=(50, 3))
    rays /= np.linalg.norm(rays, axis=1)[:, None]
    t_ray = np.sort(rng.uniform(0, 0.1, 50))
    scans, truths = [], []
    for k in range(8):
        for sid in ("a", "b"):
            idx = np.sort(rng.choice(50, 30, replace=False))
            idx[1] = idx[0]  # a ray twice in one scan
            n = len(idx)
            r = np.round(rng.uniform(0.5, 9.0, n) / 0.002) * 0.002
            p = r[:, None] * rays[idx]
            t = t_ray[idx].copy()
            if adversarial:
                p.reshape(-1)[:36] = _adversarial_floats(rng, 36)
                t[:12] = _adversarial_floats(rng, 12)
                p[14] = 0.0
            ring = (idx % 16).astype(np.uint16)
            scans.append(LidarScan(0.1 * k, sid, p, rng.integers(0, 256, n).astype(np.uint8), ring, t, 0.1 * k - 0.1))
            floats = {f: rng.normal(size=(n, 3)) for f in ("hit_w", "origin_w", "dir_w")}
            floats |= {f: rng.uniform(0, 9, n) for f in ("true_range_m", "signal")}
            floats["origin_w"][3:9] = floats["origin_w"][2]
            floats["hit_w"][:20] = floats["origin_w"][:20] + floats["true_range_m"][:20, None] * floats["dir_w"][:20]
            if adversarial:
                for v in floats.values():
                    v.reshape(-1)[:12] = _adversarial_floats(rng, 12)
            truths.append(LidarTruth(
                0.1 * k, sid, geom_id=rng.integers(-1, 400, n), surface_id=rng.integers(-1, 9, n),
                material=rng.choice(np.array(["wood", "glass", "x"]), n), kind=rng.integers(0, 4, n).astype(np.int8),
                via_geom_id=np.full(n, -1), **floats,
            ))  # fmt: skip
    return scans, truths


@pytest.mark.parametrize("adversarial", [False, True])
def test_streams_are_exact_on_adversarial_values(adversarial):
    rng = np.random.default_rng(3 + adversarial)
    scans, truths = _scans_and_truths(rng, adversarial)
    for sid in ("a", "b"):
        mine = [s for s in scans if s.sensor_id == sid]
        arrays, ids = pack_scans(mine)
        if not adversarial:
            assert float(arrays["range_quantum"]) == 0.002 and len(arrays["ray_dir"]) <= 50
        for s, back in zip(mine, unpack_scans(arrays)):
            for f, v in back.items():
                assert _same(getattr(s, f), v), (sid, f)
    _, ids_a = pack_scans([s for s in scans if s.sensor_id == "a"])
    _, ids_b = pack_scans([s for s in scans if s.sensor_id == "b"])
    ray_ids = [(ids_a if t.sensor_id == "a" else ids_b)[k // 2] for k, t in enumerate(truths)]
    ray_ids[3] = None  # a truth without its scan
    for got, want in zip(unpack_truths(pack_truths(tuple(truths), ray_ids)), truths):
        for f in dataclasses.fields(want):
            u, v = getattr(want, f.name), getattr(got, f.name)
            assert (_same(u, v) if isinstance(u, np.ndarray) else u == v), f.name
