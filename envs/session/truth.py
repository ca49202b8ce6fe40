"""The ground truth of a session (``truth/``), kept apart from the frames for the harness.

``truth/episode.json`` holds the scene surfaces, the estimator frame, tracks, events, the
climbing step's part (``stairs``: stance side, touch-down, foot track; null without one),
``trajectory_w``, the number of LiDAR truths, the steps (one object per step) and the
plain values of ``EpisodeTruth.extra`` (numbers, strings, lists, dicts; tuples come back as lists,
nested numpy arrays as lists); the top-level numpy arrays of ``extra`` go to ``truth/extra.npz``
and come back with their dtype and values exactly. ``truth/tof.jsonl`` holds the truth of each
ToF frame, in ToF frame order (the ``tof`` of the stairs part). ``truth/lidar/<k>.npz`` holds the truth of the k-th LiDAR scan of
the episode (all sensors): every :class:`~exobench.core.LidarTruth` field (``stamp_s`` and
``sensor_id`` as 0-d arrays) except ``material``, which is stored as ``material_index`` (N,)
(uint8, or uint16 beyond 256 names) into ``material_names`` (the scan's distinct names, a numpy
unicode array of the field's dtype); files written before that hold ``material`` itself (a numpy
unicode array) and still read. From version 4, a float64 ``hit_w`` is stored as ``hit_w_xor``, the
XOR of its bits with ``origin_w + true_range_m * dir_w`` (zero for points seen directly), and
rebuilt bit for bit. Sessions written before steps/extra existed read back with empty
ones. Per-pixel segmentation truth: :mod:`.segmentation` (``truth/segmentation/<camera>.npz``).
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np

from exobench.core import (
    EpisodeTruth,
    LidarTruth,
    PlanarSurface,
    SceneTruth,
    SegmentationTruth,
    SessionError,
    StairTruth,
    StepTruth,
    ToFTruth,
)

from .lidar_pack import TRUTH_SHUFFLED, TRUTH_STREAM_NAMES, pack_truths, packable_truths, unpack_truths
from .segmentation import read_segmentation, write_segmentation
from .store import (
    dec_array,
    dec_float,
    dumps,
    enc_array,
    enc_float,
    load_json,
    load_npz,
    npz_names,
    plain,
    save_npz,
)

LIDAR_STREAM = "truth/lidar.npz"  # format 5: all LiDAR truths in one file (lidar_pack)
LIDAR_TRUTH_FIELDS = (
    "stamp_s", "sensor_id", "true_range_m", "hit_w", "geom_id", "surface_id", "material", "kind",
    "via_geom_id", "signal", "origin_w", "dir_w",
)  # fmt: skip


def _surface_to_dict(s: PlanarSurface) -> dict[str, Any]:
    return {
        "surface_id": s.surface_id,
        "kind": s.kind,
        "normal_w": enc_array(s.normal_w),
        "point_w": enc_array(s.point_w),
        "polygon_w": enc_array(s.polygon_w),
        "geom_names": list(s.geom_names),
    }


def _surface_from_dict(d: dict[str, Any]) -> PlanarSurface:
    return PlanarSurface(
        int(d["surface_id"]),
        d["kind"],
        dec_array(d["normal_w"]),
        dec_array(d["point_w"]),
        dec_array(d["polygon_w"]),
        tuple(d["geom_names"]),
    )


def truth_to_dict(t: EpisodeTruth) -> dict[str, Any]:
    return {
        "scene": {
            "kind": t.scene.kind,
            "params": plain(t.scene.params),
            "surfaces": [_surface_to_dict(s) for s in t.scene.surfaces],
            "geom_surfaces": {k: list(v) for k, v in t.scene.geom_surfaces.items()},
            "geom_materials": dict(t.scene.geom_materials),
            "objects": plain(list(t.scene.objects)),
        },
        "T_world_estimator": enc_array(t.T_world_estimator),
        "stairs": None if t.stairs is None else {
            "stance_side": t.stairs.stance_side,
            "touchdown_w": enc_array(t.stairs.touchdown_w),
            "foot_track_w": enc_array(t.stairs.foot_track_w),
        },
        "body_tracks": {k: enc_array(v) for k, v in t.body_tracks.items()},
        "max_penetration_m": enc_float(t.max_penetration_m),
        "events": {k: enc_float(v) for k, v in t.events.items()},
        "trajectory_w": enc_array(np.asarray(t.trajectory_w)),
        "n_lidar": len(t.lidar),
        "steps": [_step_to_dict(s) for s in t.steps],
        "extra": {str(k): plain(v) for k, v in t.extra.items() if not isinstance(v, np.ndarray)},
        "extra_arrays": sorted(str(k) for k, v in t.extra.items() if isinstance(v, np.ndarray)),
    }


def _step_to_dict(s: StepTruth) -> dict[str, Any]:
    return {
        "index": int(s.index), "side": s.side, "liftoff_s": enc_float(s.liftoff_s), "heel_strike_s": enc_float(s.heel_strike_s),
        "footprint_w": enc_array(s.footprint_w), "terrain": s.terrain, "mode": s.mode,
    }  # fmt: skip


def _step_from_dict(d: dict[str, Any]) -> StepTruth:
    return StepTruth(
        index=int(d["index"]), side=d["side"], liftoff_s=dec_float(d["liftoff_s"]), heel_strike_s=dec_float(d["heel_strike_s"]),
        footprint_w=dec_array(d["footprint_w"]), terrain=d["terrain"], mode=d["mode"],
    )  # fmt: skip


def tof_truth_to_dict(t: ToFTruth) -> dict[str, Any]:
    return {
        "stamp_s": t.stamp_s,
        "sensor_id": t.sensor_id,
        "true_range_m": enc_float(t.true_range_m),
        "hit_w": enc_array(t.hit_w),
        "surface_id": int(t.surface_id),
        "T_world_sensor": enc_array(t.T_world_sensor),
    }


def tof_truth_from_dict(d: dict[str, Any]) -> ToFTruth:
    return ToFTruth(
        float(d["stamp_s"]),
        d["sensor_id"],
        dec_float(d["true_range_m"]),
        dec_array(d["hit_w"]),
        int(d["surface_id"]),
        dec_array(d["T_world_sensor"]),
    )


def lidar_truth_arrays(t: LidarTruth) -> dict[str, np.ndarray]:
    """The arrays of a LiDAR truth file: every field, ``material`` as indices into a name table."""
    arrays = {n: np.asarray(getattr(t, n)) for n in LIDAR_TRUTH_FIELDS if n != "material"}
    arrays["stamp_s"] = np.asarray(float(t.stamp_s))
    arrays["sensor_id"] = np.asarray(str(t.sensor_id))
    names, index = np.unique(np.asarray(t.material).reshape(-1), return_inverse=True)
    arrays["material_names"] = names  # sorted distinct names, same dtype as the field
    arrays["material_index"] = index.astype(np.uint8 if len(names) <= 256 else np.uint16)
    pred = _predicted_hit(arrays)
    if pred is not None and arrays["hit_w"].dtype == np.float64 and arrays["hit_w"].shape == pred.shape:
        arrays["hit_w_xor"] = arrays.pop("hit_w").view(np.uint64) ^ pred.view(np.uint64)
    return arrays


def _predicted_hit(a: dict[str, np.ndarray]) -> np.ndarray | None:
    """``origin_w + true_range_m * dir_w`` (float64, elementwise IEEE operations: the same bits
    on every machine), which is ``hit_w`` for the points seen directly; None if the shapes or
    dtypes do not allow it. The file keeps ``hit_w`` as the XOR of its bits with this prediction
    (``hit_w_xor``, almost all zeros)."""
    o, r, d = a["origin_w"], a["true_range_m"], a["dir_w"]
    if not (o.dtype == r.dtype == d.dtype == np.float64 and o.ndim == 2 and o.shape == d.shape
            and o.shape[1:] == (3,) and r.shape == o.shape[:1]):  # fmt: skip
        return None
    return np.ascontiguousarray(o + r[:, None] * d)


def read_lidar_truth(root: Path, rel: str) -> LidarTruth:
    """A LiDAR truth file, ``material`` rebuilt from its name table (or read as written by
    sessions before the table)."""
    present = npz_names(root, rel)
    if "material_index" not in present:
        a = load_npz(root, rel, LIDAR_TRUTH_FIELDS)
    else:
        fields = tuple(n for n in LIDAR_TRUTH_FIELDS if n != "material" and not (n == "hit_w" and "hit_w_xor" in present))
        a = load_npz(root, rel, fields + ("material_index", "material_names") + (("hit_w_xor",) if "hit_w_xor" in present else ()))
        if "hit_w_xor" in a:
            xor, pred = a.pop("hit_w_xor"), _predicted_hit(a)
            if pred is None or xor.dtype != np.uint64 or xor.shape != pred.shape:
                raise SessionError(f"{root / rel}: hit_w_xor does not fit origin_w, true_range_m and dir_w")
            a["hit_w"] = (pred.view(np.uint64) ^ xor).view(np.float64)
        index, names = a.pop("material_index"), a.pop("material_names")
        if index.ndim != 1 or names.ndim != 1 or (len(index) and int(index.max()) >= len(names)):
            raise SessionError(f"{root / rel}: material_index does not fit its {len(names)} material_names")
        a["material"] = names[index]
    fields = {n: a[n] for n in LIDAR_TRUTH_FIELDS[2:]}
    return LidarTruth(stamp_s=float(a["stamp_s"]), sensor_id=str(a["sensor_id"]), **fields)


def truth_from_dict(
    d: dict[str, Any],
    tof: tuple[ToFTruth, ...],
    lidar: tuple[LidarTruth, ...] = (),
    extra_arrays: dict[str, np.ndarray] | None = None,
    segmentation: tuple[SegmentationTruth, ...] = (),
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
        T_world_estimator=dec_array(d["T_world_estimator"]),
        stairs=_stairs_from_dict(d, tof, scene.kind),
        body_tracks={k: dec_array(v).reshape(-1, 8) for k, v in d["body_tracks"].items()},
        max_penetration_m=dec_float(d["max_penetration_m"]),
        events={k: dec_float(v) for k, v in d["events"].items()},
        lidar=lidar,
        trajectory_w=dec_array(d.get("trajectory_w", [])).reshape(-1, 8),
        steps=tuple(_step_from_dict(s) for s in d.get("steps", ())),
        segmentation=segmentation,
        extra={**dict(d.get("extra", {})), **dict(extra_arrays or {})},
    )


def _stairs_from_dict(d: dict[str, Any], tof: tuple[ToFTruth, ...], scene_kind: str) -> StairTruth | None:
    """The climbing step's truth: the ``stairs`` object of format 3, or (formats 1 and 2, which
    wrote its fields flat for every episode) the flat fields of a staircase episode."""
    if "stairs" in d:
        part = d["stairs"]
    elif scene_kind == "staircase":
        part = d
    else:
        return None
    if part is None:
        return None
    return StairTruth(
        tof=tof,
        stance_side=part["stance_side"],
        touchdown_w=dec_array(part["touchdown_w"]),
        foot_track_w=dec_array(part["foot_track_w"]).reshape(-1, 4),
    )


def _truth_rays(t: EpisodeTruth, scans: list[tuple[str, float, np.ndarray | None]] | None) -> list[np.ndarray | None]:
    """The ray ids of each LiDAR truth's points, from the k-th scan when it is the scan of that
    truth (same sensor, stamp and point count), else None."""
    out: list[np.ndarray | None] = []
    for k, lt in enumerate(t.lidar):
        s = scans[k] if scans is not None and k < len(scans) else None
        ok = s is not None and s[2] is not None and s[0] == lt.sensor_id and s[1] == float(lt.stamp_s)
        out.append(s[2] if ok and len(s[2]) == len(np.asarray(lt.true_range_m)) else None)  # type: ignore[index]
    return out


def write_truth(
    root: Path, t: EpisodeTruth, scans: list[tuple[str, float, np.ndarray | None]] | None = None, stream: bool = True
) -> None:
    """Write ``truth/`` of a session under ``root``; ``scans`` (sensor, stamp, ray id of every
    point) of the LiDAR scans in episode order let the LiDAR truth stream predict each point from
    the same ray's last value (:mod:`.lidar_pack`); ``stream=False`` writes one file per truth
    (format 4)."""
    (root / "truth").mkdir()
    episode = truth_to_dict(t)
    stream = stream and packable_truths(t.lidar)
    if stream:
        episode["lidar_stream"] = LIDAR_STREAM
    if t.segmentation:
        episode["segmentation"] = write_segmentation(root, t.segmentation)
    (root / "truth" / "episode.json").write_text(dumps(episode))
    with open(root / "truth" / "tof.jsonl", "w") as fh:
        for tt in t.stairs.tof if t.stairs is not None else ():
            fh.write(dumps(tof_truth_to_dict(tt)) + "\n")
    if stream:
        save_npz(root / LIDAR_STREAM, pack_truths(t.lidar, _truth_rays(t, scans)), shuffle=TRUTH_SHUFFLED)
    else:
        for k, lt in enumerate(t.lidar):
            save_npz(root / "truth" / "lidar" / f"{k:06d}.npz", lidar_truth_arrays(lt))
    extra_arrays = {str(k): v for k, v in t.extra.items() if isinstance(v, np.ndarray)}
    if extra_arrays:
        save_npz(root / "truth" / "extra.npz", extra_arrays)


def read_truth(root: Path) -> EpisodeTruth:
    """Read ``truth/`` of the session at ``root`` (SessionError naming a missing or malformed file)."""
    tof_path, ep_path = root / "truth" / "tof.jsonl", root / "truth" / "episode.json"
    tof = []
    try:
        lines = tof_path.read_bytes().decode("utf-8").splitlines()
    except FileNotFoundError:
        raise SessionError(f"{tof_path}: missing") from None
    except UnicodeDecodeError:
        raise SessionError(f"{tof_path}: not UTF-8 text") from None
    for n, line in enumerate(lines, 1):
        if not line.strip():
            continue
        try:
            tof.append(tof_truth_from_dict(json.loads(line)))
        except (json.JSONDecodeError, KeyError, TypeError, ValueError, AttributeError) as e:
            raise SessionError(f"{tof_path} line {n}: malformed ToF truth ({type(e).__name__}: {e})") from None
    td = load_json(ep_path)
    try:
        n_lidar = int(td.get("n_lidar", 0))
        names = tuple(td.get("extra_arrays", ()))
    except (TypeError, ValueError) as e:
        raise SessionError(f"{ep_path}: malformed ({type(e).__name__}: {e})") from None
    if td.get("lidar_stream") is not None:
        lidar = _read_lidar_stream(root, td["lidar_stream"])
    else:
        lidar = tuple(read_lidar_truth(root, f"truth/lidar/{k:06d}.npz") for k in range(n_lidar))
    extra_arrays = load_npz(root, "truth/extra.npz", names) if names else {}
    segmentation = read_segmentation(root, td["segmentation"]) if "segmentation" in td else ()
    try:
        return truth_from_dict(td, tuple(tof), lidar, extra_arrays, segmentation)
    except (KeyError, TypeError, ValueError, AttributeError) as e:
        raise SessionError(f"{ep_path}: malformed truth ({type(e).__name__}: {e})") from None


def _read_lidar_stream(root: Path, rel: Any) -> tuple[LidarTruth, ...]:
    names = npz_names(root, rel) if isinstance(rel, str) else []
    missing = [n for n in TRUTH_STREAM_NAMES if n not in names]
    if missing:
        raise SessionError(f"{root / str(rel)}: arrays {missing} missing; present: {sorted(names)}")
    a = load_npz(root, rel, TRUTH_STREAM_NAMES)
    try:
        return tuple(unpack_truths(a))
    except (ValueError, IndexError, KeyError, TypeError) as e:
        raise SessionError(f"{root / rel}: corrupt LiDAR truth stream ({type(e).__name__}: {e})") from None
