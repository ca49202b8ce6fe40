"""How values reach a session's files: lossless JSON numbers and arrays, and per-frame .npz files.

Floats in JSON are written with Python's shortest round-trip repr, so reading gives back the same
float64 values bit for bit; NaN is written as ``null``. The .npz files are zip-compressed numpy
arrays (``np.savez_compressed``), float arrays byte-shuffled first (about a third smaller): dtypes
and values come back exactly, object arrays are refused.
"""

from __future__ import annotations

import json
import math
import re
import zipfile
import zlib
from pathlib import Path
from typing import Any

import numpy as np

from exobench.core import SessionError

_SAFE_ID = re.compile(r"[A-Za-z0-9_\-][A-Za-z0-9_.\-]*")
NPZ_ERRORS = (OSError, ValueError, KeyError, EOFError, zipfile.BadZipFile, zlib.error)


# --- JSON values ------------------------------------------------------------------------------
def enc_float(x: float) -> float | None:
    """A float for JSON (NaN -> None)."""
    x = float(x)
    return None if math.isnan(x) else x


def dec_float(x: float | None) -> float:
    return float("nan") if x is None else float(x)


def enc_array(a: np.ndarray) -> list:
    """Nested lists of floats (NaN -> None) of an array of any rank."""
    return [enc_array(r) for r in a] if np.ndim(a) > 1 else [enc_float(v) for v in np.asarray(a, dtype=float)]


def dec_array(v: list) -> np.ndarray:
    return np.array(v, dtype=float)  # None (written for NaN) becomes NaN


def plain(value: Any) -> Any:
    """JSON-ready copy of scenario/params values (numpy scalars and tuples included)."""
    if isinstance(value, dict):
        return {str(k): plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [plain(v) for v in value]
    if isinstance(value, np.ndarray):
        return enc_array(value)
    if isinstance(value, (np.floating, float)):
        return enc_float(value)
    if isinstance(value, np.integer):
        return int(value)
    return value


def load_json(path: Path) -> dict[str, Any]:
    """The JSON object in the file ``path``; SessionError naming the file when it is missing,
    empty, not UTF-8, truncated or malformed JSON, or holds something other than an object."""
    try:
        data = Path(path).read_bytes()
    except FileNotFoundError:
        raise SessionError(f"{path}: missing") from None
    except OSError as e:
        raise SessionError(f"{path}: unreadable ({e.strerror})") from None
    if not data.strip():
        raise SessionError(f"{path}: empty")
    try:
        obj = json.loads(data.decode("utf-8"))
    except UnicodeDecodeError:
        raise SessionError(f"{path}: not UTF-8 text") from None
    except json.JSONDecodeError as e:
        raise SessionError(f"{path}: malformed or truncated JSON ({e})") from None
    if not isinstance(obj, dict):
        raise SessionError(f"{path}: a JSON {type(obj).__name__}, not an object")
    return obj


def dumps(obj: Any) -> str:
    """Compact JSON of one line (NaN refused: write it as None)."""
    return json.dumps(obj, separators=(",", ":"), allow_nan=False)


# --- binary arrays ----------------------------------------------------------------------------
SHUFFLED = "__shuffled__"  # the name of a .npz entry listing the byte-shuffled arrays
_SHUFFLE_MIN = 256  # float arrays of at least this many values are byte-shuffled


def _shuffle(a: np.ndarray) -> np.ndarray:
    """The bytes of ``a`` (2-D: column by column) grouped by byte position, (itemsize, n) uint8:
    the exponent and high mantissa bytes of neighbouring floats repeat, so zlib finds them."""
    cols = np.ascontiguousarray(a.T) if a.ndim == 2 else np.ascontiguousarray(a)
    return np.ascontiguousarray(cols.reshape(-1).view(np.uint8).reshape(-1, a.dtype.itemsize).T)


def _unshuffle(b: np.ndarray, dtype: str, shape: list[int]) -> np.ndarray:
    dt = np.dtype(dtype)
    flat = np.ascontiguousarray(b.T).reshape(-1).view(dt)
    return np.ascontiguousarray(flat.reshape(shape[::-1]).T) if len(shape) == 2 else flat.reshape(shape)


def save_npz(path: Path, arrays: dict[str, np.ndarray], shuffle: tuple[str, ...] = ()) -> None:
    """Write ``arrays`` zip-compressed; float arrays of :data:`_SHUFFLE_MIN` values or more, and
    the arrays named in ``shuffle`` (integer residuals), are stored byte-shuffled (listed with
    dtype and shape in the ``__shuffled__`` entry) and come back with their dtype and every bit
    by :func:`load_npz`."""
    out: dict[str, np.ndarray] = {}
    shuffled: dict[str, list[Any]] = {}
    for name, a in arrays.items():
        a = np.asarray(a)
        if a.dtype.hasobject:
            raise SessionError(
                f"{path.name}: array {name!r} has dtype object; sessions store plain numpy dtypes only"
            )
        if a.ndim in (1, 2) and a.size >= _SHUFFLE_MIN and a.dtype.itemsize > 1 and (
            a.dtype.kind == "f" or (name in shuffle and a.dtype.kind in "iu")
        ):
            shuffled[name] = [a.dtype.str, list(a.shape)]
            out[name] = _shuffle(a)
        else:
            out[name] = a
    if shuffled:
        out[SHUFFLED] = np.asarray(json.dumps(shuffled))
    path.parent.mkdir(parents=True, exist_ok=True)
    with open(path, "wb") as fh:
        np.savez_compressed(fh, **out)


def _read(z: Any, names: tuple[str, ...], path: Path) -> dict[str, np.ndarray]:
    shuffled = json.loads(str(z[SHUFFLED])) if SHUFFLED in z.files else {}
    out = {}
    for n in names:
        if n in shuffled:
            dtype, shape = shuffled[n]
            b = z[n]
            if b.dtype != np.uint8 or b.shape != (np.dtype(dtype).itemsize, int(np.prod(shape))):
                raise SessionError(f"{path}: shuffled array {n!r} does not fit {dtype} {shape}")
            out[n] = _unshuffle(b, dtype, shape)
        else:
            out[n] = z[n]
    return out


def load_npz(root: Path, rel: str, names: tuple[str, ...]) -> dict[str, np.ndarray]:
    """The named arrays of ``root/rel``; SessionError naming the file if it is missing or corrupt."""
    if not isinstance(rel, str) or rel.startswith("/") or ".." in Path(rel).parts:
        raise SessionError(f"{root}: binary reference {rel!r} is not a relative path inside the session")
    path = root / rel
    try:
        with np.load(path, allow_pickle=False) as z:
            missing = [n for n in names if n not in z.files]
            if missing:
                raise SessionError(f"{path}: arrays {missing} missing; present: {sorted(z.files)}")
            return _read(z, names, path)
    except FileNotFoundError:
        raise SessionError(f"{path}: binary file missing") from None
    except (*NPZ_ERRORS, TypeError) as e:
        raise SessionError(f"{path}: corrupt binary file ({type(e).__name__}: {e})") from None


def npz_names(root: Path, rel: str) -> list[str]:
    """The array names stored in ``root/rel``; SessionError if it is missing or corrupt."""
    try:
        with np.load(root / rel, allow_pickle=False) as z:
            return list(z.files)
    except FileNotFoundError:
        raise SessionError(f"{root / rel}: binary file missing") from None
    except NPZ_ERRORS as e:
        raise SessionError(f"{root / rel}: corrupt binary file ({type(e).__name__}: {e})") from None


def check_id(sensor_id: str) -> str:
    if not isinstance(sensor_id, str) or not _SAFE_ID.fullmatch(sensor_id):
        raise SessionError(
            f"sensor id {sensor_id!r} cannot name a session folder; use letters, digits, '_', '-', '.'"
        )
    return sensor_id


class BinaryStore:
    """Writes the binary files of one session: per-frame .npz files, ``<kind>/<sensor_id>/<k>.npz``,
    numbered per sensor, and (format 5) one LiDAR stream per sensor, ``lidar/<sensor_id>.npz``,
    written by :meth:`finish` once every scan is in."""

    def __init__(self, root: Path, streams: bool = True) -> None:
        self.root, self.streams = root, streams  # streams=False: every scan in its own file (format 4)
        self.count: dict[tuple[str, str], int] = {}
        self.scans: dict[str, list[Any]] = {}
        self.lidar_log: list[tuple[str, float, int, int | None]] = []  # every scan: sensor, stamp, n, stream index

    def add_scan(self, scan: Any) -> tuple[str, int]:
        """Queue a LiDAR scan for its sensor's stream; (stream file, index in the stream)."""
        sid = check_id(scan.sensor_id)
        queue = self.scans.setdefault(sid, [])
        queue.append(scan)
        self.lidar_log.append((sid, float(scan.stamp_s), len(scan.points_xyz), len(queue) - 1))
        return f"lidar/{sid}.npz", len(queue) - 1

    def log_scan(self, scan: Any) -> None:
        """Note a scan written in its own file (it has no rays in a stream)."""
        self.lidar_log.append((scan.sensor_id, float(scan.stamp_s), len(scan.points_xyz), None))

    def finish(self) -> list[tuple[str, float, np.ndarray | None]]:
        """Write the queued LiDAR streams; the ray ids of every scan's points, in the order the
        scans came (None for scans in their own files), for the truth stream."""
        from .lidar_pack import SCAN_SHUFFLED, pack_scans

        ids: dict[str, list[np.ndarray]] = {}
        for sid, scans in self.scans.items():
            arrays, ids[sid] = pack_scans(scans)
            save_npz(self.root / f"lidar/{sid}.npz", arrays, shuffle=SCAN_SHUFFLED)
        self.scans = {}
        return [(sid, stamp, None if k is None else ids[sid][k]) for sid, stamp, _, k in self.lidar_log]

    def put(self, kind: str, sensor_id: str, arrays: dict[str, np.ndarray]) -> tuple[str, int]:
        key = (kind, check_id(sensor_id))
        k = self.count.get(key, 0)
        self.count[key] = k + 1
        rel = f"{kind}/{sensor_id}/{k:06d}.npz"
        save_npz(self.root / rel, arrays)
        return rel, k
