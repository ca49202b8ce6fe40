"""The frame codecs: how every frame kind is written to and read from a session, in one table.

A ``frames.jsonl`` line is ``{"kind", "stamp_s", "sensor_id", ...}`` followed by the fields of the
kind's :class:`FrameCodec`. Scalar kinds (ToF, IMU, joints, contact, odometry) are written whole
into their line. Kinds with large arrays write them to ``<kind>/<sensor_id>/<k>.npz`` (numbered per
sensor) through the session's :class:`~exobench.envs.session.store.BinaryStore`, and their line
refers to the file:

- ``lidar``: ``sweep_start_s``, the point count ``n``, ``file``, ``index``; the file holds
  ``points_xyz`` (N, 3), ``intensity`` (N,), ``ring`` (N,), ``time_offset_s`` (N,);
- ``rgbd``: ``shape`` [H, W], ``file``, ``index``; the file holds ``rgb``, ``depth_m`` and ``K``.

The codecs of the shipped kinds are defined and registered here (the on-disk format in one
place), so reading a session needs no other import; a new kind defines its codec in its sensor
folder, and its line in the sensor kind table (:mod:`exobench.envs.sensors.kinds`) registers it
into :data:`CODECS`. The dependency is one way: the sensor kind table imports this module, never
the reverse.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from exobench.core import (
    ContactSample,
    Frame,
    ImuSample,
    JointState,
    LidarScan,
    OdometrySample,
    PlaceLabel,
    RgbdFrame,
    SessionError,
    SessionStart,
    ToFReading,
    TofStatus,
)

from .lidar_pack import packable_scan, unpack_scans
from .store import BinaryStore, dec_array, dec_float, enc_array, enc_float, load_npz, npz_names

LIDAR_FIELDS = ("points_xyz", "intensity", "ring", "time_offset_s")
RGBD_FIELDS = ("rgb", "depth_m", "K")


@dataclass(frozen=True)
class FrameCodec:
    """How one frame kind is written to and read from a session.

    Attributes:
        kind: the ``kind`` of its ``frames.jsonl`` lines (and the folder of its binary files).
        frame_type: the frame class (:mod:`exobench.core.frames`).
        encode: ``(frame, store) -> fields`` of its line after ``kind``, ``stamp_s`` and
            ``sensor_id``; binary kinds put their arrays in ``store``.
        decode: ``(fields, stamp_s, sensor_id, root) -> frame``; ``root`` (the session directory)
            resolves binary files.
        example: ``rng -> frame``, a small frame with non-trivial values (NaN where the format
            keeps it) for the round-trip conformance test.
        binary: its frames need the binary store to be written and the session root to be read.
    """

    kind: str
    frame_type: type
    encode: Callable[[Any, BinaryStore | None], dict[str, Any]]
    decode: Callable[[dict[str, Any], float, str, Path | None], Any]
    example: Callable[[np.random.Generator], Any]
    binary: bool = False


CODECS: dict[str, FrameCodec] = {}
"""Every frame kind a session reads and writes, by kind name (the shipped ones registered at the
end of this module, others by the sensor kind table)."""


def codec_table() -> dict[str, FrameCodec]:
    """:data:`CODECS`: every registered codec by frame kind name."""
    return CODECS


def register_codec(codec: FrameCodec) -> FrameCodec:
    """Add a kind to :data:`CODECS`; a kind name or frame type registered twice is refused.
    A sensor kind registers its codec with :func:`exobench.envs.sensors.kinds.register_sensor_kind`."""
    if codec.kind in CODECS or any(c.frame_type is codec.frame_type for c in CODECS.values()):
        raise ValueError(f"frame kind {codec.kind!r} ({codec.frame_type.__name__}) has a codec already")
    CODECS[codec.kind] = codec
    return codec


def codec_of(frame: Frame) -> FrameCodec:
    """The codec of a frame, by its type."""
    for codec in codec_table().values():
        if isinstance(frame, codec.frame_type):
            return codec
    raise TypeError(f"not an exobench frame: {type(frame).__name__}")


def frame_to_dict(frame: Frame, store: BinaryStore | None = None) -> dict[str, Any]:
    """The ``frames.jsonl`` object of a frame; binary kinds put their arrays in ``store``'s files."""
    codec = codec_of(frame)
    if codec.binary and store is None:
        raise SessionError(f"{codec.kind!r} frames are stored in binary files; write them with write_session")
    return {
        "kind": codec.kind,
        "stamp_s": frame.stamp_s,
        "sensor_id": frame.sensor_id,
        **codec.encode(frame, store),
    }


def frame_from_dict(d: dict[str, Any], root: str | os.PathLike | None = None) -> Frame:
    """A frame from its ``frames.jsonl`` object; ``root`` (the session) resolves binary files."""
    kind, stamp, sid = d["kind"], float(d["stamp_s"]), d["sensor_id"]
    codec = codec_table().get(kind)
    if codec is None:
        raise SessionError(f"frames.jsonl: unknown frame kind {kind!r}; valid: {', '.join(CODECS)}")
    if codec.binary and root is None:
        raise SessionError(f"{kind!r} frame at {stamp} s refers to {d['file']!r}; pass the session root")
    return codec.decode(d, stamp, sid, None if root is None else Path(root))


# --- scalar kinds: every field in the line ----------------------------------------------------
FieldCodec = tuple[Callable[[Any], Any], Callable[[Any], Any]]
FLOAT: FieldCodec = (enc_float, dec_float)
ARRAY: FieldCodec = (enc_array, dec_array)
INT: FieldCodec = (int, int)
BOOL: FieldCodec = (bool, bool)
NAMES: FieldCodec = (list, tuple)
TEXT: FieldCodec = (str, str)


def line_codec(
    kind: str, frame_type: type, example: Callable[[np.random.Generator], Any], **fields: FieldCodec
) -> FrameCodec:
    """The codec of a kind whose fields (after ``stamp_s`` and ``sensor_id``) are all written in its line,
    each by its (encode, decode) pair, in the order given."""

    def encode(frame: Any, store: BinaryStore | None) -> dict[str, Any]:
        return {name: enc(getattr(frame, name)) for name, (enc, _) in fields.items()}

    def decode(d: dict[str, Any], stamp: float, sid: str, root: Path | None) -> Any:
        return frame_type(stamp, sid, **{name: dec(d[name]) for name, (_, dec) in fields.items()})

    return FrameCodec(kind, frame_type, encode, decode, example)


def _nan_at(a: np.ndarray, k: int = 0) -> np.ndarray:
    a.reshape(-1)[k] = np.nan
    return a


TOF = line_codec(
    "tof", ToFReading, lambda rng: ToFReading(0.02, "tof_r_med", float("nan"), int(TofStatus.NO_TARGET)),
    range_m=FLOAT, status=INT,
)  # fmt: skip
IMU = line_codec(
    "imu", ImuSample,
    lambda rng: ImuSample(0.005, "imu_trunk", rng.normal(size=4), _nan_at(rng.normal(size=3), 1), rng.normal(size=3)),
    quat_wxyz=ARRAY, gyro_rad_s=ARRAY, accel_m_s2=ARRAY,
)  # fmt: skip
JOINTS = line_codec(
    "joints", JointState,
    lambda rng: JointState(0.005, "encoders", ("hip_l", "knee_l", "ankle_l"), _nan_at(rng.normal(size=3), 2)),
    names=NAMES, position_rad=ARRAY,
)  # fmt: skip
CONTACT = line_codec(
    "contact", ContactSample, lambda rng: ContactSample(0.01, "contact_l_heel", float("nan"), True),
    force_n=FLOAT, in_contact=BOOL,
)  # fmt: skip
ODOMETRY = line_codec(
    "odometry", OdometrySample,
    lambda rng: OdometrySample(0.1, "odom_head", rng.normal(size=(4, 4)), _nan_at(rng.normal(size=3))),
    T_odom_body=ARRAY, v_odom_m_s=ARRAY,
)  # fmt: skip

SESSION = line_codec(
    "session", SessionStart, lambda rng: SessionStart(12.5, "session", 2, 1), session=INT, day=INT,
)  # fmt: skip
PLACE_LABEL = line_codec(
    "place_label", PlaceLabel, lambda rng: PlaceLabel(12.6, "place_label", "meeting"), label=TEXT,
)  # fmt: skip


# --- binary kinds: arrays in per-frame .npz files ------------------------------------------------
def _lidar_encode(frame: LidarScan, store: BinaryStore | None) -> dict[str, Any]:
    assert store is not None
    arrays = {n: np.asarray(getattr(frame, n)) for n in LIDAR_FIELDS}
    n = len(arrays["points_xyz"])
    if arrays["points_xyz"].shape != (n, 3) or any(arrays[f].shape != (n,) for f in LIDAR_FIELDS[1:]):
        raise SessionError(f"LiDAR scan of {frame.sensor_id!r} at {frame.stamp_s} s: array shapes disagree")
    if store.streams and packable_scan(frame):
        rel, k = store.add_scan(frame)
        return {"sweep_start_s": enc_float(frame.sweep_start_s), "n": n, "file": rel, "index": k, "packed": True}
    rel, k = store.put("lidar", frame.sensor_id, arrays)
    store.log_scan(frame)
    return {"sweep_start_s": enc_float(frame.sweep_start_s), "n": n, "file": rel, "index": k}


_STREAMS: dict[tuple[str, int, int], list[dict[str, np.ndarray]]] = {}
_STREAM_NAMES = (
    "scan_n", "ray_time_offset_s", "ray_ring", "ray_dir", "ray_id_delta", "range_quantum", "points_res", "intensity",
)  # fmt: skip


def _stream_scan(root: Path, rel: str, k: int) -> dict[str, np.ndarray]:
    """Scan ``k`` of the LiDAR stream ``root/rel`` (the last few streams read stay decoded)."""
    path = root / rel
    try:
        st = path.stat()
    except FileNotFoundError:
        raise SessionError(f"{path}: binary file missing") from None
    key = (str(path.resolve()), st.st_mtime_ns, st.st_size)
    if key not in _STREAMS:
        present = npz_names(root, rel)
        a = load_npz(root, rel, _STREAM_NAMES + (("range_k",) if "range_k" in present else ("range_m",)))
        try:
            scans = unpack_scans(a)
        except (ValueError, IndexError, KeyError) as e:
            raise SessionError(f"{path}: corrupt LiDAR stream ({e})") from None
        while len(_STREAMS) >= 4:
            _STREAMS.pop(next(iter(_STREAMS)))
        _STREAMS[key] = scans
    scans = _STREAMS[key]
    if not 0 <= k < len(scans):
        raise SessionError(f"{path}: no scan {k} in a stream of {len(scans)}")
    return scans[k]


def _lidar_decode(d: dict[str, Any], stamp: float, sid: str, root: Path | None) -> LidarScan:
    assert root is not None
    a = _stream_scan(root, d["file"], int(d["index"])) if d.get("packed") else load_npz(root, d["file"], LIDAR_FIELDS)
    n = int(d["n"])
    if a["points_xyz"].shape != (n, 3) or any(a[f].shape != (n,) for f in LIDAR_FIELDS[1:]):
        raise SessionError(
            f"{root / d['file']}: array shapes do not match the {n} points of its frames.jsonl line"
        )
    return LidarScan(
        stamp,
        sid,
        a["points_xyz"],
        a["intensity"],
        a["ring"],
        a["time_offset_s"],
        dec_float(d["sweep_start_s"]),
    )


def _lidar_example(rng: np.random.Generator) -> LidarScan:
    n = 7
    return LidarScan(
        0.1, "lidar_trunk", _nan_at(rng.normal(size=(n, 3)), 4), rng.integers(0, 256, n).astype(np.uint8),
        rng.integers(0, 16, n).astype(np.uint16), np.sort(rng.uniform(0, 0.1, n)), 0.0,
    )  # fmt: skip


def _rgbd_encode(frame: RgbdFrame, store: BinaryStore | None) -> dict[str, Any]:
    assert store is not None
    arrays = {n: np.asarray(getattr(frame, n)) for n in RGBD_FIELDS}
    rel, k = store.put("rgbd", frame.sensor_id, arrays)
    return {"shape": list(arrays["depth_m"].shape[:2]), "file": rel, "index": k}


def _rgbd_decode(d: dict[str, Any], stamp: float, sid: str, root: Path | None) -> RgbdFrame:
    assert root is not None
    a = load_npz(root, d["file"], RGBD_FIELDS)
    if list(a["depth_m"].shape[:2]) != list(d["shape"]):
        raise SessionError(
            f"{root / d['file']}: depth shape {a['depth_m'].shape} does not match {d['shape']}"
        )
    return RgbdFrame(stamp, sid, a["rgb"], a["depth_m"], a["K"])


def _rgbd_example(rng: np.random.Generator) -> RgbdFrame:
    depth = _nan_at(rng.uniform(0.2, 5.0, (4, 6)).astype(np.float32), 3)
    depth[0, :2] = 0.0
    K = np.array([[300.0, 0.0, 2.5], [0.0, 301.5, 1.5], [0.0, 0.0, 1.0]])
    return RgbdFrame(1 / 30, "rgbd_head", rng.integers(0, 256, (4, 6, 3)).astype(np.uint8), depth, K)


LIDAR = FrameCodec("lidar", LidarScan, _lidar_encode, _lidar_decode, _lidar_example, binary=True)
RGBD = FrameCodec("rgbd", RgbdFrame, _rgbd_encode, _rgbd_decode, _rgbd_example, binary=True)


for _codec in (TOF, IMU, JOINTS, CONTACT, ODOMETRY, LIDAR, RGBD, SESSION, PLACE_LABEL):  # the shipped kinds
    register_codec(_codec)
