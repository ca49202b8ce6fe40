"""Lossless residual coding of float arrays for the compact LiDAR streams (format 5).

A value is stored as the difference of its IEEE bit pattern and the bit pattern of a prediction,
as an unsigned integer (two's-complement wrap-around, zigzag-ordered so that small differences of
either sign have zero high bytes). Reading adds the difference back to the same prediction, so
every bit comes back (NaN payloads, -0.0, infinities, denormals included) whatever the prediction
is: a good prediction only makes the residual small. Predictions are computed with elementwise
IEEE operations (or copied values), which give the same bits on every machine.
"""

from __future__ import annotations

import numpy as np

_UINT = {2: np.uint16, 4: np.uint32, 8: np.uint64}


def _bits(a: np.ndarray) -> np.ndarray:
    a = np.ascontiguousarray(a)
    return a.view(_UINT[a.dtype.itemsize])


def zigzag(d: np.ndarray) -> np.ndarray:
    """Signed int64 -> uint64 with small magnitudes of either sign small: 0, -1, 1, -2 -> 0, 1, 2, 3."""
    d = d.astype(np.int64, copy=False)
    return ((d << 1) ^ (d >> 63)).view(np.uint64)


def unzigzag(u: np.ndarray) -> np.ndarray:
    u = u.astype(np.uint64, copy=False)
    return ((u >> np.uint64(1)) ^ (np.uint64(0) - (u & np.uint64(1)))).view(np.int64)


def residual(actual: np.ndarray, pred: np.ndarray) -> np.ndarray:
    """The zigzag difference of the bit patterns of float64 ``actual`` and ``pred`` (same shape), uint64."""
    with np.errstate(over="ignore"):
        return zigzag((_bits(actual) - _bits(pred)).view(np.int64))


def restore(res: np.ndarray, pred: np.ndarray) -> np.ndarray:
    """The float64 values whose :func:`residual` against ``pred`` is ``res``."""
    with np.errstate(over="ignore"):
        return (_bits(pred) + unzigzag(res).view(np.uint64)).view(np.float64)


def narrow(a: np.ndarray) -> np.ndarray:
    """An integer array in the smallest integer dtype holding its values (the caller keeps the dtype)."""
    if a.size == 0:
        return a
    lo, hi = int(a.min()), int(a.max())
    for dt in (np.uint8, np.int8, np.uint16, np.int16, np.uint32, np.int32):
        info = np.iinfo(dt)
        if info.min <= lo and hi <= info.max:
            return a.astype(dt)
    return a


def widen(a: np.ndarray, dtype: str) -> np.ndarray:
    """``a`` back in ``dtype``; ValueError if a value does not fit (a damaged file)."""
    out = a.astype(dtype)
    if a.size and not np.array_equal(out.astype(np.int64) if a.dtype.kind in "iu" else out, a):
        raise ValueError(f"values do not fit {dtype}")
    return out


def delta(ids: np.ndarray) -> np.ndarray:
    """Zigzag differences of consecutive integers (the first against 0)."""
    return zigzag(np.diff(ids.astype(np.int64), prepend=np.int64(0)))


def undelta(u: np.ndarray) -> np.ndarray:
    return np.cumsum(unzigzag(u))


def by_last_seen(values: np.ndarray, ids: np.ndarray, counts: np.ndarray, n_ids: int) -> np.ndarray:
    """Residuals of ``values`` (N, k) float64 against the value the same id had in the latest
    earlier group (groups of ``counts`` rows: the scans; 0.0 before an id is first seen)."""
    state = np.zeros((n_ids, values.shape[1]))
    out = np.empty(values.shape, dtype=np.uint64)
    start = 0
    for c in counts.tolist():
        sl, i = slice(start, start + c), ids[start : start + c]
        out[sl] = residual(values[sl], state[i])
        state[i] = values[sl]
        start += c
    return out


def from_last_seen(res: np.ndarray, ids: np.ndarray, counts: np.ndarray, n_ids: int) -> np.ndarray:
    """The values whose :func:`by_last_seen` residuals are ``res``."""
    state = np.zeros((n_ids, res.shape[1]))
    out = np.empty(res.shape)
    start = 0
    for c in counts.tolist():
        sl, i = slice(start, start + c), ids[start : start + c]
        out[sl] = restore(res[sl], state[i])
        state[i] = out[sl]
        start += c
    return out


def by_previous_row(values: np.ndarray) -> np.ndarray:
    """``values`` (N, k) float64 as the XOR of each row's bits with the row before (the first
    with 0.0): repeated rows become zeros."""
    b = _bits(values)
    out = b.copy()
    out[1:] ^= b[:-1]
    return out


def from_previous_row(res: np.ndarray) -> np.ndarray:
    return np.bitwise_xor.accumulate(res.astype(np.uint64, copy=False), axis=0).view(np.float64)
