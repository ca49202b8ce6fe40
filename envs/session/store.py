"""How values reach a session's files: lossless JSON numbers and arrays, and per-frame .npz files.

Floats in JSON are written with Python's shortest round-trip repr, so reading gives back the same
float64 values bit for bit; NaN is written as ``null``. The .npz files are zip-compressed numpy
arrays (``np.savez_compressed``): dtypes and values come back exactly, object arrays are refused.
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
def save_npz(path: Path, arrays: dict[str, np.ndarray]) -> None:
    for name, a in arrays.items():
        if a.dtype.hasobject:
            raise SessionError(
                f"{path.name}: array {name!r} has dtype object; sessions store plain numpy dtypes only"
            )
    path.parent.mkdir(parents=True, exist_ok=True)
    with open(path, "wb") as fh:
        np.savez_compressed(fh, **arrays)


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
            return {n: z[n] for n in names}
    except FileNotFoundError:
        raise SessionError(f"{path}: binary file missing") from None
    except NPZ_ERRORS as e:
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
    """Writes the per-frame .npz files of one session, ``<kind>/<sensor_id>/<k>.npz``, numbered per sensor."""

    def __init__(self, root: Path) -> None:
        self.root = root
        self.count: dict[tuple[str, str], int] = {}

    def put(self, kind: str, sensor_id: str, arrays: dict[str, np.ndarray]) -> tuple[str, int]:
        key = (kind, check_id(sensor_id))
        k = self.count.get(key, 0)
        self.count[key] = k + 1
        rel = f"{kind}/{sensor_id}/{k:06d}.npz"
        save_npz(self.root / rel, arrays)
        return rel, k
