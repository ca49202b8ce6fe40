"""The scan spool (benchmarks.tracks.scan_spool) on hand-made scans: what is read back is what was
added, bit for bit and of the same dtypes and shapes, and a scan is read in one read of the file.

Oracle: the arrays given to :meth:`ScanSpool.add` (and :func:`exobench.core.compact_truth` of the
truth given, for the truth's labels)."""

from __future__ import annotations

import numpy as np

from exobench.benchmarks.tracks.scan_spool import ScanSpool
from exobench.core import LidarScan, LidarTruth, compact_truth


def _scan_and_truth(n: int, stamp: float, rng: np.random.Generator) -> tuple[LidarScan, LidarTruth]:
    pts = rng.normal(size=(n, 3)).astype(np.float32)
    if n:
        pts[0] = np.nan  # a NaN point survives as NaN
    scan = LidarScan(stamp_s=stamp, sensor_id="lidar_trunk", points_xyz=pts, intensity=rng.integers(0, 256, n).astype(np.uint8),
                     ring=rng.integers(0, 16, n).astype(np.int16), time_offset_s=rng.uniform(0, 0.1, n),
                     sweep_start_s=stamp - 0.1)  # fmt: skip
    truth = LidarTruth(stamp_s=stamp, sensor_id="lidar_trunk", true_range_m=rng.uniform(0, 30, n), hit_w=rng.normal(size=(n, 3)),
                       geom_id=rng.integers(-1, 500, n), surface_id=rng.integers(-1, 90, n), material=np.array(["glass"] * n),
                       kind=rng.integers(0, 5, n), via_geom_id=rng.integers(-1, 500, n), signal=rng.uniform(0, 300, n),
                       origin_w=rng.normal(size=(n, 3)), dir_w=rng.normal(size=(n, 3)))  # fmt: skip
    return scan, truth


def test_spooled_scans_read_back_bit_for_bit_with_their_dtypes_and_shapes():
    rng = np.random.default_rng(0)
    given = [_scan_and_truth(n, 0.1 * (i + 1), rng) for i, n in enumerate((7, 0, 1, 333))]  # odd sizes: padding
    spool = ScanSpool()
    for s, t in given:
        spool.add(s, t)
    pairs = spool.pairs()
    assert pairs.n_points == [7, 0, 1, 333]
    for _ in range(2):  # read as often as the scorer needs
        for (s, t), (s1, t1) in zip(given, pairs, strict=True):
            small = compact_truth(t)
            for name in ("points_xyz", "intensity", "ring", "time_offset_s"):
                a, b = np.asarray(getattr(s, name)), getattr(s1, name)
                assert (b.dtype, b.shape, b.tobytes()) == (a.dtype, a.shape, a.tobytes()), name
            for name in ("true_range_m", "geom_id", "surface_id", "kind", "via_geom_id", "signal"):
                a, b = getattr(small, name), getattr(t1, name)
                assert (b.dtype, b.shape, b.tobytes()) == (a.dtype, a.shape, a.tobytes()), name
            assert (s1.stamp_s, s1.sweep_start_s, s1.sensor_id) == (s.stamp_s, s.sweep_start_s, s.sensor_id)
    _, t1 = pairs[3]
    t1.kind[0] = 9  # the arrays read are the caller's own, as np.load's are
    assert pairs[3][1].kind[0] == compact_truth(given[3][1]).kind[0]
    spool.close()


class _CountingFile:
    def __init__(self, f):
        self.f, self.reads = f, 0

    def __getattr__(self, name):
        attr = getattr(self.f, name)
        if name in ("read", "readinto"):
            def counted(*a, **k):
                self.reads += 1
                return attr(*a, **k)
            return counted
        return attr


def test_a_spooled_scan_is_read_in_one_read_of_the_file():
    # the scorer reads every scan of a walk once per filter: ten .npy headers per scan (each
    # parsed with ast.literal_eval) cost more than the scan's bytes
    rng = np.random.default_rng(1)
    spool = ScanSpool()
    for i in range(3):
        spool.add(*_scan_and_truth(2000, 0.1 * (i + 1), rng))
    spool._file = counting = _CountingFile(spool._file)
    list(spool.pairs())
    assert counting.reads == 3
