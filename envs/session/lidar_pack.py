"""The compact LiDAR streams of format 5: all scans of a sensor in one file, all LiDAR truths in one.

Scans (``lidar/<sensor_id>.npz``): a sensor fires the same rays sweep after sweep, so each ray,
identified by its ``(time_offset_s, ring)``, is listed once in a ray table (``ray_time_offset_s``,
``ray_ring``, ``ray_dir``: a unit direction estimated from the first point seen on it) and each
point stores its ray (``ray_id_delta``), its range and the residual of ``points_xyz`` against
``range * ray_dir`` (:mod:`.packing`: zero where the prediction is exact). Ranges are stored as
integer multiples ``range_k`` of the range quantum (the sensor's range resolution, read from the
points) when the points have one, else as float64 ``range_m``. ``time_offset_s`` and ``ring``
come back from the ray table, ``intensity`` is stored as it is.

Truths (``truth/lidar.npz``): the points of every LiDAR truth in episode order, with the ray of
each point (taken from its scan) so that ``dir_w``, ``true_range_m`` and ``signal`` are stored as
residuals against the value of the same ray in the latest earlier truth of its sensor (the same
bits while the sensor keeps its orientation or pose), ``origin_w`` as the XOR with the row before
(one origin per firing block), ``hit_w`` as the residual against ``origin_w + true_range_m *
dir_w``, integer fields in their smallest integer dtype (the original dtype is in ``layout``),
``material`` as indices into a name table.

Every value comes back bit for bit; scans or truths whose dtypes or shapes do not fit this layout
are written in the per-scan files of format 4 instead.
"""

from __future__ import annotations

import json
from typing import Any

import numpy as np

from exobench.core import LidarScan, LidarTruth

from .packing import (
    by_last_seen,
    by_previous_row,
    delta,
    from_last_seen,
    from_previous_row,
    narrow,
    residual,
    restore,
    undelta,
    widen,
)

SCAN_DTYPES = {"points_xyz": np.float64, "intensity": np.uint8, "ring": np.uint16, "time_offset_s": np.float64}
SCAN_SHUFFLED = ("ray_id_delta", "points_res", "range_k")
TRUTH_FLOATS = ("true_range_m", "hit_w", "signal", "origin_w", "dir_w")
TRUTH_INTS = ("geom_id", "surface_id", "kind", "via_geom_id")
TRUTH_STREAM_NAMES = (
    "layout", "stamp_s", "sensor_names", "sensor_index", "truth_n", "n_rays", "ray_id_delta", "material_names",
    "material_index", "dir_w_res", "true_range_m_res", "signal_res", "origin_w_xor", "hit_w_res", *TRUTH_INTS,
)  # fmt: skip
TRUTH_SHUFFLED = ("ray_id_delta", "dir_w_res", "true_range_m_res", "signal_res", "origin_w_xor", "hit_w_res")


# --- scans -------------------------------------------------------------------------------------
def packable_scan(frame: LidarScan) -> bool:
    """Whether a scan has the dtypes and shapes of the compact stream (the simulated LiDAR's)."""
    a = {n: np.asarray(getattr(frame, n)) for n in SCAN_DTYPES}
    n = len(a["points_xyz"])
    return all(a[k].dtype == dt for k, dt in SCAN_DTYPES.items()) and a["points_xyz"].shape == (n, 3) and all(
        a[k].shape == (n,) for k in ("intensity", "ring", "time_offset_s")
    )


def range_quantum(r: np.ndarray) -> float:
    """The step the ranges ``r`` are multiples of (a sensor's range resolution), 0.0 if none:
    the smallest gap between distinct ranges, rounded to 4 significant digits, kept if it
    explains at least half the ranges."""
    u = np.unique(r[np.isfinite(r) & (r > 0.0)])
    gaps = np.diff(u)
    gaps = gaps[gaps > 1e-9 * u[1:]] if len(u) > 1 else gaps
    if len(gaps) == 0:
        return 0.0
    q = float(f"{float(gaps.min()):.4g}")
    with np.errstate(invalid="ignore"):
        k = np.rint(r / q)
        fits = np.abs(k * q - r) <= 1e-9 * np.maximum(np.abs(r), 1.0)
    return q if np.count_nonzero(fits) >= 0.5 * len(r) else 0.0


def pack_scans(scans: list[LidarScan]) -> tuple[dict[str, np.ndarray], list[np.ndarray]]:
    """The stream arrays of a sensor's scans, and the ray id of every point of each scan."""
    counts = np.array([len(s.points_xyz) for s in scans], dtype=np.int64)
    p = np.concatenate([s.points_xyz for s in scans]).reshape(-1, 3)
    ring = np.concatenate([s.ring for s in scans])
    t = np.concatenate([s.time_offset_s for s in scans])
    times, t_id = np.unique(t.view(np.uint64), return_inverse=True)
    keys, ids = np.unique(t_id.reshape(-1).astype(np.int64) * 65536 + ring, return_inverse=True)
    ids = ids.reshape(-1)
    with np.errstate(invalid="ignore", over="ignore", divide="ignore"):
        nrm = np.sqrt(np.einsum("ij,ij->i", p, p))
        q = range_quantum(nrm)
        if q > 0.0:
            k = np.rint(nrm / q)
            k = np.where(np.isfinite(k) & (k >= 0) & (k < 2**32), k, 0).astype(np.uint32)
            r = k * q
        else:
            r = nrm
        ok = np.isfinite(r) & (r > 0.0) & np.all(np.isfinite(p), axis=1)
        # the first point of each ray (assigned in reverse: the earliest write stays); any point would do
        first = np.full(len(keys), -1)
        seen = np.flatnonzero(ok)
        first[ids[seen[::-1]]] = seen[::-1]
        have = first >= 0
        ray_dir = np.zeros((len(keys), 3))
        ray_dir[have] = p[first[have]] / r[first[have], None]
        pred = r[:, None] * ray_dir[ids]
    arrays = {
        "scan_n": counts,
        "ray_time_offset_s": times[keys // 65536].view(np.float64),
        "ray_ring": (keys % 65536).astype(np.uint16),
        "ray_dir": ray_dir,
        "ray_id_delta": delta(ids),
        "range_quantum": np.asarray(q),
        "points_res": residual(p, pred),
        "intensity": np.concatenate([s.intensity for s in scans]),
    }
    if q > 0.0:
        arrays["range_k"] = narrow(k)
    else:
        arrays["range_m"] = r
    return arrays, np.split(ids, np.cumsum(counts)[:-1])


def unpack_scans(a: dict[str, np.ndarray]) -> list[dict[str, np.ndarray]]:
    """The arrays of every scan of a stream (``points_xyz``, ``intensity``, ``ring``, ``time_offset_s``)."""
    counts = a["scan_n"].astype(np.int64)
    ids = undelta(a["ray_id_delta"])
    n, n_rays = int(counts.sum()), len(a["ray_ring"])
    if len(ids) != n or (n and (ids.min() < 0 or ids.max() >= n_rays)):
        raise ValueError(f"{n} points, {len(ids)} ray ids for {n_rays} rays")
    q = float(a["range_quantum"])
    r = a["range_k"].astype(np.float64) * q if "range_k" in a else a["range_m"]
    with np.errstate(invalid="ignore", over="ignore"):
        p = restore(a["points_res"], r[:, None] * a["ray_dir"][ids])
    ring, t = a["ray_ring"][ids], a["ray_time_offset_s"][ids]
    cut = np.cumsum(counts)[:-1]
    return [
        {"points_xyz": pp, "intensity": ii, "ring": rr, "time_offset_s": tt}
        for pp, ii, rr, tt in zip(np.split(p, cut), np.split(a["intensity"], cut), np.split(ring, cut), np.split(t, cut))
    ]


# --- truths ------------------------------------------------------------------------------------
def packable_truths(truths: tuple[LidarTruth, ...]) -> bool:
    """Whether the LiDAR truths fit the compact stream: float64 fields, integer ids, string
    materials, shapes agreeing within each truth and dtypes agreeing across them."""
    if not truths:
        return False
    dtypes = None
    for t in truths:
        a = {n: np.asarray(getattr(t, n)) for n in (*TRUTH_FLOATS, *TRUTH_INTS, "material")}
        n = len(a["true_range_m"])
        if any(a[f].dtype != np.float64 for f in TRUTH_FLOATS) or any(a[f].dtype.kind not in "iu" for f in TRUTH_INTS):
            return False
        if a["material"].dtype.kind != "U":
            return False
        if any(a[f].shape != (n, 3) for f in ("hit_w", "origin_w", "dir_w")) or any(
            a[f].shape != (n,) for f in ("true_range_m", "signal", "material", *TRUTH_INTS)
        ):
            return False
        d = {f: a[f].dtype.str for f in (*TRUTH_INTS, "material")}
        if dtypes is not None and d != dtypes:
            return False
        dtypes = d
    return True


def pack_truths(truths: tuple[LidarTruth, ...], ray_ids: list[np.ndarray | None]) -> dict[str, np.ndarray]:
    """The stream arrays of the episode's LiDAR truths; ``ray_ids[k]``: the ray of each point of
    truth k (from its scan), or None (then its points are predicted from nothing)."""
    counts = np.array([len(t.true_range_m) for t in truths], dtype=np.int64)
    names = sorted({t.sensor_id for t in truths})
    ids, n_ids = [], 0
    offset = {s: 0 for s in names}
    width = {s: 1 + max((int(i.max()) for t, i in zip(truths, ray_ids) if i is not None and len(i) and t.sensor_id == s), default=-1) for s in names}
    for s in names:
        offset[s], n_ids = n_ids, n_ids + width[s]
    for t, i in zip(truths, ray_ids):
        if i is None:
            ids.append(n_ids + np.arange(len(t.true_range_m)))
            n_ids += len(t.true_range_m)
        else:
            ids.append(offset[t.sensor_id] + i.astype(np.int64))
    ids_all = np.concatenate(ids)

    def cat(f: str) -> np.ndarray:
        return np.concatenate([np.asarray(getattr(t, f)) for t in truths])

    rng, sig = cat("true_range_m")[:, None], cat("signal")[:, None]
    origin, direction, hit = cat("origin_w"), cat("dir_w"), cat("hit_w")
    mat_names, mat_index = np.unique(cat("material"), return_inverse=True)
    layout = {f: np.asarray(getattr(truths[0], f)).dtype.str for f in (*TRUTH_INTS, "material")}
    with np.errstate(invalid="ignore", over="ignore"):
        hit_pred = origin + rng * direction
    arrays = {
        "layout": np.asarray(json.dumps(layout)),
        "stamp_s": np.array([float(t.stamp_s) for t in truths]),
        "sensor_names": np.array(names, dtype=str),
        "sensor_index": np.array([names.index(t.sensor_id) for t in truths], dtype=np.int64),
        "truth_n": counts,
        "n_rays": np.asarray(n_ids),
        "ray_id_delta": delta(ids_all),
        "material_names": mat_names.astype(layout["material"]),
        "material_index": narrow(mat_index.reshape(-1)),
        "dir_w_res": by_last_seen(direction, ids_all, counts, n_ids),
        "true_range_m_res": by_last_seen(rng, ids_all, counts, n_ids)[:, 0],
        "signal_res": by_last_seen(sig, ids_all, counts, n_ids)[:, 0],
        "origin_w_xor": by_previous_row(origin),
        "hit_w_res": residual(hit, hit_pred),
    }
    for f in TRUTH_INTS:
        arrays[f] = narrow(cat(f))
    return arrays


def unpack_truths(a: dict[str, Any]) -> list[LidarTruth]:
    """The LiDAR truths of a stream written by :func:`pack_truths`."""
    layout = json.loads(str(a["layout"]))
    counts = a["truth_n"].astype(np.int64)
    n, n_ids = int(counts.sum()), int(a["n_rays"])
    ids = undelta(a["ray_id_delta"])
    if len(ids) != n or (n and (ids.min() < 0 or ids.max() >= n_ids)):
        raise ValueError(f"{n} points, {len(ids)} ray ids for {n_ids} rays")
    direction = from_last_seen(a["dir_w_res"], ids, counts, n_ids)
    rng = from_last_seen(a["true_range_m_res"][:, None], ids, counts, n_ids)
    sig = from_last_seen(a["signal_res"][:, None], ids, counts, n_ids)[:, 0]
    origin = from_previous_row(a["origin_w_xor"])
    with np.errstate(invalid="ignore", over="ignore"):
        hit = restore(a["hit_w_res"], origin + rng * direction)
    names, index = a["material_names"], a["material_index"]
    if len(index) and int(index.max()) >= len(names):
        raise ValueError(f"material_index does not fit its {len(names)} material_names")
    material = names.astype(layout["material"])[index]
    ints = {f: widen(a[f], layout[f]) for f in TRUTH_INTS}
    cut = np.cumsum(counts)[:-1]
    parts = {
        "true_range_m": np.split(rng[:, 0], cut), "hit_w": np.split(hit, cut), "signal": np.split(sig, cut),
        "origin_w": np.split(origin, cut), "dir_w": np.split(direction, cut), "material": np.split(material, cut),
        **{f: np.split(v, cut) for f, v in ints.items()},
    }  # fmt: skip
    sensors = a["sensor_names"]
    return [
        LidarTruth(
            stamp_s=float(a["stamp_s"][k]), sensor_id=str(sensors[int(a["sensor_index"][k])]),
            **{f: np.ascontiguousarray(parts[f][k]) for f in parts},
        )  # fmt: skip
        for k in range(len(counts))
    ]
