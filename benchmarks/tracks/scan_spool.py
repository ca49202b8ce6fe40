"""The LiDAR scans of a streamed episode with their point labels, spooled to disk as they flow.

A track whose scorer reads every point of every scan against its truth (lidar-filter: each
point's class, then KISS-ICP again on the points a filter kept) cannot keep them in memory
over a long walk: a glazed ring is ~1,700 sweeps of ~20,000 points. :class:`ScanSpool` takes
each scan with its truth as the simulation hands them out (``stream_office``'s
``lidar_sink``), writes the scan's arrays and its compact truth
(:func:`~exobench.core.compact_truth`: kind, surface, range, geoms, signal) to an anonymous
temporary file, and keeps in memory only a few numbers per scan (stamp, start, point count,
whether a pipeline uses it). :class:`ScanPairs` reads them back one scan at a time, in order,
as often as the scorer needs; nothing of the scans stays in memory between two reads.

Each scan is written as its arrays' raw bytes, each padded to 16 bytes, and read back with one
read into one buffer: the scorer reads every scan once per filter, and parsing ``.npy`` headers
(ten a scan, each an ``ast.literal_eval``) cost more than reading the bytes.

The file is unlinked when it is created, so it goes away with the process (or :meth:`ScanSpool.close`)
even when a worker is killed. On disk a scan takes its own bytes plus ~21 bytes a point.

What is spooled is what :func:`..office_walks.lidar_pairs` and :func:`~exobench.core.counters.admitted`
give a whole episode: a scan is kept with its truth when the two have the same sensor, stamp
(to 1 ns) and point count (the truth follows its frame through every delivery fault, so that
is every scan), and marked used when a pipeline reading every stream uses it (the admission
of a LiDAR scan depends on its own stream only).
"""

from __future__ import annotations

import tempfile
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from typing import Any, overload

import numpy as np

from exobench.core import LidarScan, LidarTruth, compact_truth
from exobench.core.counters import StreamCounters

_SCAN_ARRAYS = ("points_xyz", "intensity", "ring", "time_offset_s")
_TRUTH_ARRAYS = ("true_range_m", "geom_id", "surface_id", "kind", "via_geom_id", "signal")
_ALIGN = 16  # each array starts on a multiple of this in the scan's buffer: aligned for any dtype


def _padded(n: int) -> int:
    return -(-n // _ALIGN) * _ALIGN


@dataclass(frozen=True)
class SpooledScan:
    """What is kept in memory of one spooled scan: its place in the file and what is matched on."""

    offset: int
    stamp_s: float
    sensor_id: str
    sweep_start_s: float
    n_points: int
    used: bool
    layout: tuple[tuple[str, str, tuple[int, ...]], ...] = ()  # (name, dtype, shape) of each array, in order
    n_bytes: int = 0


class ScanSpool:
    """Scans and their compact truth on disk, in the order they were added (module docstring)."""

    def __init__(self) -> None:
        self._file = tempfile.TemporaryFile(prefix="exobench-scans-")
        self._order = StreamCounters()
        self.entries: list[SpooledScan] = []

    def add(self, scan: LidarScan, truth: LidarTruth | None) -> None:
        """Spool one LiDAR scan with its truth (every scan of the stream, in frame order)."""
        used = self._order.admit(scan) is not None
        if (truth is None or truth.sensor_id != scan.sensor_id or round(float(truth.stamp_s), 9) != round(float(scan.stamp_s), 9)
                or len(truth.kind) != len(scan.points_xyz)):  # fmt: skip
            return  # lidar_pairs would find it no truth either
        small = compact_truth(truth)
        arrays = [(n, np.asarray(getattr(scan, n))) for n in _SCAN_ARRAYS] + [(n, np.asarray(getattr(small, n))) for n in _TRUTH_ARRAYS]
        layout, chunks, n_bytes = [], [], 0
        for name, a in arrays:
            if a.dtype.hasobject:
                raise TypeError(f"cannot spool {name} of dtype object")
            raw = np.ascontiguousarray(a).tobytes()
            chunks.append(raw + bytes(_padded(len(raw)) - len(raw)))
            layout.append((name, a.dtype.str, tuple(a.shape)))
            n_bytes += len(chunks[-1])
        f = self._file
        f.seek(0, 2)
        offset = f.tell()
        f.write(b"".join(chunks))
        self.entries.append(SpooledScan(offset, float(scan.stamp_s), scan.sensor_id, float(scan.sweep_start_s), len(scan.points_xyz),
                                        used, tuple(layout), n_bytes))  # fmt: skip

    def load(self, entry: SpooledScan) -> tuple[LidarScan, LidarTruth]:
        """The scan and its compact truth as they were added (arrays equal bit for bit)."""
        f = self._file
        f.seek(entry.offset)
        buf = bytearray(entry.n_bytes)  # writable: the arrays are views of it, as np.load's are their own
        if f.readinto(buf) != entry.n_bytes:
            raise OSError(f"the scan spool ends inside the scan at {entry.stamp_s} s")
        arrays, at = {}, 0
        for name, dtype, shape in entry.layout:
            dt = np.dtype(dtype)
            count = int(np.prod(shape, dtype=np.int64))
            arrays[name] = np.frombuffer(buf, dtype=dt, count=count, offset=at).reshape(shape)
            at += _padded(count * dt.itemsize)
        scan = {n: arrays[n] for n in _SCAN_ARRAYS}
        truth = {n: arrays[n] for n in _TRUTH_ARRAYS}
        empty3 = np.zeros((0, 3), dtype=np.float32)
        return (
            LidarScan(stamp_s=entry.stamp_s, sensor_id=entry.sensor_id, sweep_start_s=entry.sweep_start_s, **scan),
            LidarTruth(stamp_s=entry.stamp_s, sensor_id=entry.sensor_id, hit_w=empty3, material=np.zeros(0, dtype="<U1"),
                       origin_w=empty3, dir_w=empty3.copy(), **truth),
        )  # fmt: skip

    def pairs(self) -> ScanPairs:
        """Every spooled (scan, truth) pair, in order, read on demand."""
        entries = list(self.entries)
        return ScanPairs([e.stamp_s for e in entries], [e.n_points for e in entries], lambda i: self.load(entries[i]),
                         sensor_ids=[e.sensor_id for e in entries], used=[e.used for e in entries])  # fmt: skip

    def close(self) -> None:
        self._file.close()


class ScanPairs(Sequence[tuple[LidarScan, Any]]):
    """(scan, truth) pairs read on demand: ``pairs[i]`` (or iterating) loads one pair; each
    scan's stamp, point count, sensor and whether a pipeline uses it are known without loading
    any (``used``: every scan when not given)."""

    def __init__(self, stamps_s: Sequence[float], n_points: Sequence[int], load: Callable[[int], tuple[LidarScan, Any]], *,
                 sensor_ids: Sequence[str] | None = None, used: Sequence[bool] | None = None) -> None:  # fmt: skip
        self.stamps_s = [float(t) for t in stamps_s]
        self.n_points = [int(n) for n in n_points]
        self.sensor_ids = list(sensor_ids) if sensor_ids is not None else [""] * len(self.stamps_s)
        self.used = [bool(u) for u in used] if used is not None else [True] * len(self.stamps_s)
        if not len(self.n_points) == len(self.sensor_ids) == len(self.used) == len(self.stamps_s):
            raise ValueError("one stamp, point count, sensor and use flag per scan")
        self._load = load

    @classmethod
    def of(cls, pairs: Sequence[tuple[LidarScan, Any]]) -> ScanPairs:
        """Pairs already in memory (a whole episode's)."""
        pairs = list(pairs)
        return cls([s.stamp_s for s, _ in pairs], [len(s.points_xyz) for s, _ in pairs], pairs.__getitem__,
                   sensor_ids=[s.sensor_id for s, _ in pairs])  # fmt: skip

    def select(self, keep: Sequence[bool]) -> ScanPairs:
        """The pairs whose ``keep`` is true, in order (still read on demand)."""
        idx = [i for i, k in enumerate(keep) if k]
        return ScanPairs([self.stamps_s[i] for i in idx], [self.n_points[i] for i in idx], lambda j: self._load(idx[j]),
                         sensor_ids=[self.sensor_ids[i] for i in idx], used=[self.used[i] for i in idx])  # fmt: skip

    def __len__(self) -> int:
        return len(self.stamps_s)

    @overload
    def __getitem__(self, i: int) -> tuple[LidarScan, Any]: ...
    @overload
    def __getitem__(self, i: slice) -> list[tuple[LidarScan, Any]]: ...

    def __getitem__(self, i: int | slice) -> Any:
        if isinstance(i, slice):
            return [self[k] for k in range(*i.indices(len(self)))]
        if not -len(self) <= i < len(self):
            raise IndexError(i)
        return self._load(i % len(self))

    def __iter__(self) -> Iterator[tuple[LidarScan, Any]]:
        for i in range(len(self)):
            yield self._load(i)
