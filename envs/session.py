"""Recorded sessions on disk: an episode's frames, calibration and (apart) ground truth.

Layout of a session directory (format ``exobench-session``, version 2)::

    meta.json                      format, version, exobench version, scenario, seed, frame counts
    calibration.json               sensor mounts, encoder joint names, robot description (URDF text)
    frames.jsonl                   every frame, time-ordered, one JSON object per line ("kind" first)
    lidar/<sensor_id>/<k>.npz      arrays of the k-th scan of that LiDAR (k = 000000, 000001, ...)
    rgbd/<sensor_id>/<k>.npz       arrays of the k-th image pair of that RGB-D camera
    truth/episode.json             scene surfaces, estimator frame, touch-down, tracks, events,
                                   LiDAR trajectory_w, number of LiDAR truths
    truth/tof.jsonl                ground truth of each ToF frame, in ToF frame order
    truth/lidar/<k>.npz            ground truth of the k-th LiDAR scan of the episode (all sensors)
    truth/extra.npz                the numpy arrays of ``EpisodeTruth.extra`` (only when it has any)

Scalar frames (ToF, IMU, joints, contact) are written whole into their ``frames.jsonl`` line.
A ``lidar`` line carries ``stamp_s``, ``sensor_id``, ``sweep_start_s``, the point count ``n``
and a reference ``file`` (relative to the session) + ``index`` (per sensor); the file holds
``points_xyz`` (N, 3), ``intensity`` (N,), ``ring`` (N,), ``time_offset_s`` (N,). An ``rgbd``
line carries ``stamp_s``, ``sensor_id``, ``shape`` [H, W], ``file`` and ``index``; the file
holds ``rgb``, ``depth_m`` and ``K``. A LiDAR truth file holds every ``LidarTruth`` field
(``stamp_s`` and ``sensor_id`` as 0-d arrays) except ``material``, which is stored as
``material_index`` (N,) (uint8, or uint16 beyond 256 names) into ``material_names`` (the scan's
distinct names, a numpy unicode array of the field's dtype); files written before that hold
``material`` itself (a numpy unicode array) and still read. The
.npz files are zip-compressed numpy arrays (``np.savez_compressed``): dtypes and values come
back exactly, object arrays are refused. :func:`iter_frames` streams: it loads a scan's file
when its line is read.

Floats in JSON are written with Python's shortest round-trip repr, so reading a session gives
back the same float64 values bit for bit; NaN is written as ``null``. A session is written into
a temporary sibling directory and renamed into place, so a failed write leaves nothing behind.
A pipeline replayed on a session gets exactly the frames it would have had live, so it scores
identically; the truth/ folder is for the harness and can be left out when sharing real logs.

``EpisodeTruth.steps`` are written in ``episode.json`` (one object per step); the other
values of ``EpisodeTruth.extra`` (numbers, strings, lists, dicts) are written there as JSON
(tuples come back as lists, nested numpy arrays as lists); top-level numpy arrays go to
``truth/extra.npz`` and come back with their dtype and values exactly. Sessions written before
steps/extra existed read back with empty ones.

Versions: 1 had no binary files (LiDAR and RGB-D frames were refused) and no LiDAR truth;
version-1 sessions are still read (their LiDAR truth is empty). Writing always gives version 2.
"""

from __future__ import annotations

import json
import math
import os
import re
import shutil
import tempfile
import zipfile
import zlib
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np

from exobench.core import (
    Calibration,
    ContactSample,
    Episode,
    EpisodeTruth,
    Frame,
    ImuSample,
    JointState,
    LidarScan,
    OdometrySample,
    PlanarSurface,
    RgbdFrame,
    SceneTruth,
    SensorMount,
    SessionError,
    StepTruth,
    ToFReading,
    ToFTruth,
    frame_kind,
)

FORMAT = "exobench-session"
VERSION = 2
SUPPORTED_VERSIONS = (1, 2)
LIDAR_FIELDS = ("points_xyz", "intensity", "ring", "time_offset_s")
RGBD_FIELDS = ("rgb", "depth_m", "K")
LIDAR_TRUTH_FIELDS = (
    "stamp_s", "sensor_id", "true_range_m", "hit_w", "geom_id", "surface_id", "material", "kind",
    "via_geom_id", "signal", "origin_w", "dir_w",
)  # fmt: skip
_SAFE_ID = re.compile(r"[A-Za-z0-9_\-][A-Za-z0-9_.\-]*")
_NPZ_ERRORS = (OSError, ValueError, KeyError, EOFError, zipfile.BadZipFile, zlib.error)


def _f(x: float) -> float | None:
    x = float(x)
    return None if math.isnan(x) else x


def _arr(a: np.ndarray) -> list:
    return [_arr(r) for r in a] if np.ndim(a) > 1 else [_f(v) for v in np.asarray(a, dtype=float)]


def _unarr(v: list) -> np.ndarray:
    return np.array(v, dtype=float)  # None (written for NaN) becomes NaN


def _unf(x: float | None) -> float:
    return float("nan") if x is None else float(x)


def _plain(value: Any) -> Any:
    """JSON-ready copy of scenario/params values (numpy scalars and tuples included)."""
    if isinstance(value, dict):
        return {str(k): _plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    if isinstance(value, np.ndarray):
        return _arr(value)
    if isinstance(value, (np.floating, float)):
        return _f(value)
    if isinstance(value, np.integer):
        return int(value)
    return value


# --- binary arrays ------------------------------------------------------------------------
def _save_npz(path: Path, arrays: dict[str, np.ndarray]) -> None:
    for name, a in arrays.items():
        if a.dtype.hasobject:
            raise SessionError(f"{path.name}: array {name!r} has dtype object; sessions store plain numpy dtypes only")
    path.parent.mkdir(parents=True, exist_ok=True)
    with open(path, "wb") as fh:
        np.savez_compressed(fh, **arrays)


def _load_npz(root: Path, rel: str, names: tuple[str, ...]) -> dict[str, np.ndarray]:
    """The named arrays of ``root/rel``; SessionError naming the file if it is missing or corrupt."""
    if not isinstance(rel, str) or rel.startswith("/") or ".." in Path(rel).parts:
        raise SessionError(f"{root}: binary reference {rel!r} is not a relative path inside the session")
    path = root / rel
    try:
        with np.load(path, allow_pickle=False) as z:
            missing = [n for n in names if n not in z.files]
            if missing:
                raise SessionError(f"{path}: arrays {missing} missing; present: {sorted(z.files)}")
            return {n: z[n] for n in names}
    except FileNotFoundError:
        raise SessionError(f"{path}: binary file missing") from None
    except _NPZ_ERRORS as e:
        raise SessionError(f"{path}: corrupt binary file ({type(e).__name__}: {e})") from None


def _check_id(sensor_id: str) -> str:
    if not isinstance(sensor_id, str) or not _SAFE_ID.fullmatch(sensor_id):
        raise SessionError(f"sensor id {sensor_id!r} cannot name a session folder; use letters, digits, '_', '-', '.'")
    return sensor_id


class _BinaryStore:
    """Writes the per-frame .npz files of one session and numbers them per sensor."""

    def __init__(self, root: Path) -> None:
        self.root = root
        self.count: dict[tuple[str, str], int] = {}

    def put(self, kind: str, sensor_id: str, arrays: dict[str, np.ndarray]) -> tuple[str, int]:
        key = (kind, _check_id(sensor_id))
        k = self.count.get(key, 0)
        self.count[key] = k + 1
        rel = f"{kind}/{sensor_id}/{k:06d}.npz"
        _save_npz(self.root / rel, arrays)
        return rel, k


# --- frames ---------------------------------------------------------------------------------
def frame_to_dict(frame: Frame, store: _BinaryStore | None = None) -> dict[str, Any]:
    """The ``frames.jsonl`` object of a frame; LiDAR and RGB-D arrays go to ``store``'s files."""
    kind = frame_kind(frame)
    d: dict[str, Any] = {"kind": kind, "stamp_s": frame.stamp_s, "sensor_id": frame.sensor_id}
    if isinstance(frame, ToFReading):
        d.update(range_m=_f(frame.range_m), status=int(frame.status))
    elif isinstance(frame, ImuSample):
        d.update(quat_wxyz=_arr(frame.quat_wxyz), gyro_rad_s=_arr(frame.gyro_rad_s), accel_m_s2=_arr(frame.accel_m_s2))
    elif isinstance(frame, JointState):
        d.update(names=list(frame.names), position_rad=_arr(frame.position_rad))
    elif isinstance(frame, ContactSample):
        d.update(force_n=_f(frame.force_n), in_contact=bool(frame.in_contact))
    elif isinstance(frame, OdometrySample):
        d.update(T_odom_body=_arr(frame.T_odom_body), v_odom_m_s=_arr(frame.v_odom_m_s))
    elif store is None:
        raise SessionError(f"{kind!r} frames are stored in binary files; write them with write_session")
    elif isinstance(frame, LidarScan):
        arrays = {n: np.asarray(getattr(frame, n)) for n in LIDAR_FIELDS}
        n = len(arrays["points_xyz"])
        if arrays["points_xyz"].shape != (n, 3) or any(arrays[f].shape != (n,) for f in LIDAR_FIELDS[1:]):
            raise SessionError(f"LiDAR scan of {frame.sensor_id!r} at {frame.stamp_s} s: array shapes disagree")
        rel, k = store.put("lidar", frame.sensor_id, arrays)
        d.update(sweep_start_s=_f(frame.sweep_start_s), n=n, file=rel, index=k)
    elif isinstance(frame, RgbdFrame):
        arrays = {n: np.asarray(getattr(frame, n)) for n in RGBD_FIELDS}
        rel, k = store.put("rgbd", frame.sensor_id, arrays)
        d.update(shape=list(arrays["depth_m"].shape[:2]), file=rel, index=k)
    return d


def frame_from_dict(d: dict[str, Any], root: str | os.PathLike | None = None) -> Frame:
    """A frame from its ``frames.jsonl`` object; ``root`` (the session) resolves binary files."""
    kind, stamp, sid = d["kind"], float(d["stamp_s"]), d["sensor_id"]
    if kind == "tof":
        return ToFReading(stamp, sid, _unf(d["range_m"]), int(d["status"]))
    if kind == "imu":
        return ImuSample(stamp, sid, _unarr(d["quat_wxyz"]), _unarr(d["gyro_rad_s"]), _unarr(d["accel_m_s2"]))
    if kind == "joints":
        return JointState(stamp, sid, tuple(d["names"]), _unarr(d["position_rad"]))
    if kind == "contact":
        return ContactSample(stamp, sid, _unf(d["force_n"]), bool(d["in_contact"]))
    if kind == "odometry":
        return OdometrySample(stamp, sid, _unarr(d["T_odom_body"]), _unarr(d["v_odom_m_s"]))
    if kind in ("lidar", "rgbd"):
        if root is None:
            raise SessionError(f"{kind!r} frame at {stamp} s refers to {d['file']!r}; pass the session root")
        root = Path(root)
        if kind == "lidar":
            a = _load_npz(root, d["file"], LIDAR_FIELDS)
            n = int(d["n"])
            if a["points_xyz"].shape != (n, 3) or any(a[f].shape != (n,) for f in LIDAR_FIELDS[1:]):
                raise SessionError(f"{root / d['file']}: array shapes do not match the {n} points of its frames.jsonl line")
            return LidarScan(stamp, sid, a["points_xyz"], a["intensity"], a["ring"], a["time_offset_s"], _unf(d["sweep_start_s"]))
        a = _load_npz(root, d["file"], RGBD_FIELDS)
        if list(a["depth_m"].shape[:2]) != list(d["shape"]):
            raise SessionError(f"{root / d['file']}: depth shape {a['depth_m'].shape} does not match {d['shape']}")
        return RgbdFrame(stamp, sid, a["rgb"], a["depth_m"], a["K"])
    raise SessionError(f"frames.jsonl: unknown frame kind {kind!r}; valid: tof, imu, joints, contact, odometry, lidar, rgbd")


# --- calibration ------------------------------------------------------------------------------
def calibration_to_dict(c: Calibration) -> dict[str, Any]:
    return {
        "robot_urdf": c.robot_urdf,
        "base_link": c.base_link,
        "joint_names": list(c.joint_names),
        "sole_height_m": c.sole_height_m,
        "foot_length_m": c.foot_length_m,
        "heel_to_ankle_m": c.heel_to_ankle_m,
        "extra": _plain(c.extra),
        "mounts": [
            {
                "sensor_id": m.sensor_id,
                "kind": m.kind,
                "parent_link": m.parent_link,
                "T_parent_sensor": _arr(m.T_parent_sensor),
                "params": _plain(m.params),
            }
            for m in c.mounts
        ],
    }


def calibration_from_dict(d: dict[str, Any]) -> Calibration:
    mounts = tuple(
        SensorMount(m["sensor_id"], m["kind"], m["parent_link"], _unarr(m["T_parent_sensor"]), dict(m["params"]))
        for m in d["mounts"]
    )
    return Calibration(
        robot_urdf=d["robot_urdf"],
        base_link=d["base_link"],
        joint_names=tuple(d["joint_names"]),
        mounts=mounts,
        sole_height_m=float(d["sole_height_m"]),
        foot_length_m=float(d["foot_length_m"]),
        heel_to_ankle_m=float(d["heel_to_ankle_m"]),
        extra=dict(d.get("extra", {})),
    )


# --- truth ------------------------------------------------------------------------------------
def _surface_to_dict(s: PlanarSurface) -> dict[str, Any]:
    return {
        "surface_id": s.surface_id,
        "kind": s.kind,
        "normal_w": _arr(s.normal_w),
        "point_w": _arr(s.point_w),
        "polygon_w": _arr(s.polygon_w),
        "geom_names": list(s.geom_names),
    }


def _surface_from_dict(d: dict[str, Any]) -> PlanarSurface:
    return PlanarSurface(
        int(d["surface_id"]), d["kind"], _unarr(d["normal_w"]), _unarr(d["point_w"]),
        _unarr(d["polygon_w"]), tuple(d["geom_names"]),
    )


def truth_to_dict(t: EpisodeTruth) -> dict[str, Any]:
    return {
        "scene": {
            "kind": t.scene.kind,
            "params": _plain(t.scene.params),
            "surfaces": [_surface_to_dict(s) for s in t.scene.surfaces],
            "geom_surfaces": {k: list(v) for k, v in t.scene.geom_surfaces.items()},
            "geom_materials": dict(t.scene.geom_materials),
            "objects": _plain(list(t.scene.objects)),
        },
        "T_world_estimator": _arr(t.T_world_estimator),
        "stance_side": t.stance_side,
        "touchdown_w": _arr(t.touchdown_w),
        "foot_track_w": _arr(t.foot_track_w),
        "body_tracks": {k: _arr(v) for k, v in t.body_tracks.items()},
        "max_penetration_m": _f(t.max_penetration_m),
        "events": {k: _f(v) for k, v in t.events.items()},
        "trajectory_w": _arr(np.asarray(t.trajectory_w)),
        "n_lidar": len(t.lidar),
        "steps": [_step_to_dict(s) for s in t.steps],
        "extra": {str(k): _plain(v) for k, v in t.extra.items() if not isinstance(v, np.ndarray)},
        "extra_arrays": sorted(str(k) for k, v in t.extra.items() if isinstance(v, np.ndarray)),
    }


def _step_to_dict(s: StepTruth) -> dict[str, Any]:
    return {
        "index": int(s.index), "side": s.side, "liftoff_s": _f(s.liftoff_s), "heel_strike_s": _f(s.heel_strike_s),
        "footprint_w": _arr(s.footprint_w), "terrain": s.terrain, "mode": s.mode,
    }  # fmt: skip


def _step_from_dict(d: dict[str, Any]) -> StepTruth:
    return StepTruth(
        index=int(d["index"]), side=d["side"], liftoff_s=_unf(d["liftoff_s"]), heel_strike_s=_unf(d["heel_strike_s"]),
        footprint_w=_unarr(d["footprint_w"]), terrain=d["terrain"], mode=d["mode"],
    )  # fmt: skip


def _tof_truth_to_dict(t: ToFTruth) -> dict[str, Any]:
    return {
        "stamp_s": t.stamp_s,
        "sensor_id": t.sensor_id,
        "true_range_m": _f(t.true_range_m),
        "hit_w": _arr(t.hit_w),
        "surface_id": int(t.surface_id),
        "T_world_sensor": _arr(t.T_world_sensor),
    }


def _tof_truth_from_dict(d: dict[str, Any]) -> ToFTruth:
    return ToFTruth(
        float(d["stamp_s"]), d["sensor_id"], _unf(d["true_range_m"]), _unarr(d["hit_w"]),
        int(d["surface_id"]), _unarr(d["T_world_sensor"]),
    )


def _lidar_truth_arrays(t: Any) -> dict[str, np.ndarray]:
    """The arrays of a LiDAR truth file: every field, ``material`` as indices into a name table."""
    arrays = {n: np.asarray(getattr(t, n)) for n in LIDAR_TRUTH_FIELDS if n != "material"}
    names, index = np.unique(np.asarray(t.material).reshape(-1), return_inverse=True)
    arrays["material_names"] = names  # sorted distinct names, same dtype as the field
    arrays["material_index"] = index.astype(np.uint8 if len(names) <= 256 else np.uint16)
    return arrays


def _load_lidar_truth(root: Path, rel: str) -> dict[str, np.ndarray]:
    """A LiDAR truth file's fields, ``material`` rebuilt from its name table (or read as written
    by sessions before the table)."""
    fields = tuple(n for n in LIDAR_TRUTH_FIELDS if n != "material")
    try:
        with np.load(root / rel, allow_pickle=False) as z:
            indexed = "material_index" in z.files
    except FileNotFoundError:
        raise SessionError(f"{root / rel}: binary file missing") from None
    except _NPZ_ERRORS as e:
        raise SessionError(f"{root / rel}: corrupt binary file ({type(e).__name__}: {e})") from None
    if not indexed:
        return _load_npz(root, rel, LIDAR_TRUTH_FIELDS)
    a = _load_npz(root, rel, fields + ("material_index", "material_names"))
    index, names = a.pop("material_index"), a.pop("material_names")
    if index.ndim != 1 or names.ndim != 1 or (len(index) and int(index.max()) >= len(names)):
        raise SessionError(f"{root / rel}: material_index does not fit its {len(names)} material_names")
    a["material"] = names[index]
    return a


def _lidar_truth_from_arrays(a: dict[str, np.ndarray]) -> Any:
    from exobench.envs.lidar import LidarTruth

    fields = {n: a[n] for n in LIDAR_TRUTH_FIELDS[2:]}
    return LidarTruth(stamp_s=float(a["stamp_s"]), sensor_id=str(a["sensor_id"]), **fields)


def truth_from_dict(
    d: dict[str, Any], tof: tuple[ToFTruth, ...], lidar: tuple[Any, ...] = (), extra_arrays: dict[str, np.ndarray] | None = None
) -> EpisodeTruth:
    sc = d["scene"]
    scene = SceneTruth(
        surfaces=tuple(_surface_from_dict(s) for s in sc["surfaces"]),
        geom_surfaces={k: tuple(v) for k, v in sc["geom_surfaces"].items()},
        params=dict(sc["params"]),
        kind=sc["kind"],
        geom_materials=dict(sc.get("geom_materials", {})),
        objects=tuple(sc.get("objects", ())),
    )
    return EpisodeTruth(
        scene=scene,
        tof=tof,
        T_world_estimator=_unarr(d["T_world_estimator"]),
        stance_side=d["stance_side"],
        touchdown_w=_unarr(d["touchdown_w"]),
        foot_track_w=_unarr(d["foot_track_w"]).reshape(-1, 4),
        body_tracks={k: _unarr(v).reshape(-1, 8) for k, v in d["body_tracks"].items()},
        max_penetration_m=_unf(d["max_penetration_m"]),
        events={k: _unf(v) for k, v in d["events"].items()},
        lidar=lidar,
        trajectory_w=_unarr(d.get("trajectory_w", [])).reshape(-1, 8),
        steps=tuple(_step_from_dict(s) for s in d.get("steps", ())),
        extra={**dict(d.get("extra", {})), **dict(extra_arrays or {})},
    )


# --- directory I/O ----------------------------------------------------------------------------
def _dump(obj: Any) -> str:
    return json.dumps(obj, separators=(",", ":"), allow_nan=False)


def write_session(episode: Episode, path: str | os.PathLike, *, include_truth: bool = True) -> Path:
    """Write ``episode`` as a session directory at ``path`` (which must not exist yet)."""
    from exobench import __version__

    final = Path(path)
    if final.exists():
        raise SessionError(f"session path {str(final)!r} exists already; choose a new directory")
    final.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{final.name}.", dir=final.parent))
    try:
        counts: dict[str, int] = {}
        store = _BinaryStore(tmp)
        with open(tmp / "frames.jsonl", "w") as fh:
            for fr in episode.frames:
                d = frame_to_dict(fr, store)
                counts[d["kind"]] = counts.get(d["kind"], 0) + 1
                fh.write(_dump(d) + "\n")
        meta = {
            "format": FORMAT,
            "version": VERSION,
            "exobench_version": __version__,
            "scenario": _plain(episode.scenario),
            "seed": int(episode.seed),
            "frame_counts": counts,
            "has_truth": include_truth,
        }
        (tmp / "meta.json").write_text(json.dumps(meta, indent=1, allow_nan=False))
        (tmp / "calibration.json").write_text(json.dumps(calibration_to_dict(episode.calibration), allow_nan=False))
        if include_truth:
            (tmp / "truth").mkdir()
            (tmp / "truth" / "episode.json").write_text(_dump(truth_to_dict(episode.truth)))
            with open(tmp / "truth" / "tof.jsonl", "w") as fh:
                for t in episode.truth.tof:
                    fh.write(_dump(_tof_truth_to_dict(t)) + "\n")
            for k, lt in enumerate(episode.truth.lidar):
                arrays = _lidar_truth_arrays(lt)
                arrays["stamp_s"] = np.asarray(float(lt.stamp_s))
                arrays["sensor_id"] = np.asarray(str(lt.sensor_id))
                _save_npz(tmp / "truth" / "lidar" / f"{k:06d}.npz", arrays)
            extra_arrays = {str(k): v for k, v in episode.truth.extra.items() if isinstance(v, np.ndarray)}
            if extra_arrays:
                _save_npz(tmp / "truth" / "extra.npz", extra_arrays)
        os.rename(tmp, final)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    return final


def read_meta(path: str | os.PathLike) -> dict[str, Any]:
    p = Path(path)
    try:
        meta = json.loads((p / "meta.json").read_text())
    except FileNotFoundError:
        raise SessionError(f"{str(p)!r} is not a session: meta.json missing") from None
    except json.JSONDecodeError as e:
        raise SessionError(f"{p / 'meta.json'}: malformed JSON ({e})") from None
    if meta.get("format") != FORMAT:
        raise SessionError(f"{p / 'meta.json'}: format {meta.get('format')!r}, expected {FORMAT!r}")
    if meta.get("version") not in SUPPORTED_VERSIONS:
        raise SessionError(
            f"{p / 'meta.json'}: version {meta.get('version')!r} unsupported; supported: {list(SUPPORTED_VERSIONS)}"
        )
    return meta


def iter_frames(path: str | os.PathLike) -> Iterator[Frame]:
    """Stream the frames of a session without loading them all (a scan's file is read with its line)."""
    root = Path(path)
    with open(root / "frames.jsonl") as fh:
        for n, line in enumerate(fh, 1):
            if not line.strip():
                continue
            try:
                yield frame_from_dict(json.loads(line), root)
            except (json.JSONDecodeError, KeyError, TypeError, ValueError) as e:
                raise SessionError(f"frames.jsonl line {n}: malformed frame ({e})") from None


def read_session(path: str | os.PathLike) -> Episode:
    """Read a whole session back into an :class:`Episode` (truth required)."""
    p = Path(path)
    meta = read_meta(p)
    if not meta.get("has_truth", False):
        raise SessionError(f"{str(p)!r} has no truth/ folder; it can be replayed but not scored")
    calib = calibration_from_dict(json.loads((p / "calibration.json").read_text()))
    frames = tuple(iter_frames(p))
    with open(p / "truth" / "tof.jsonl") as fh:
        tof = tuple(_tof_truth_from_dict(json.loads(line)) for line in fh if line.strip())
    td = json.loads((p / "truth" / "episode.json").read_text())
    lidar = tuple(
        _lidar_truth_from_arrays(_load_lidar_truth(p, f"truth/lidar/{k:06d}.npz"))
        for k in range(int(td.get("n_lidar", 0)))
    )
    names = tuple(td.get("extra_arrays", ()))
    extra_arrays = _load_npz(p, "truth/extra.npz", names) if names else {}
    truth = truth_from_dict(td, tof, lidar, extra_arrays)
    return Episode(scenario=meta["scenario"], seed=meta["seed"], calibration=calib, frames=frames, truth=truth)
