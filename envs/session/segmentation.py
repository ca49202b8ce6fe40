"""The per-pixel segmentation truth of a session (``EpisodeTruth.segmentation``), one file a camera.

``truth/segmentation/<sensor_id>.npz`` holds every :class:`~exobench.core.SegmentationTruth` of
that camera: ``index`` (N,) their places in the episode's tuple (the cameras' frames interleave),
``stamp_s`` (N,) float64, and ``surface_id``, ``geom_id``, ``object_index`` stacked (N, H, W) in
the narrowest signed integer type that holds their values (int8, int16 or int32), read back as
int32. ``truth/episode.json`` lists the files under ``segmentation`` (sensor id -> file) only when
the episode has segmentation truth; sessions without the entry read with an empty part.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from exobench.core import SegmentationTruth, SessionError

from .store import check_id, load_npz, save_npz

LABELS = ("surface_id", "geom_id", "object_index")
NAMES = ("index", "stamp_s", *LABELS)


def narrow_int(a: np.ndarray) -> np.ndarray:
    """``a`` in the narrowest of int8, int16, int32 that holds its values exactly."""
    lo, hi = (int(a.min()), int(a.max())) if a.size else (0, 0)
    for dt in (np.int8, np.int16, np.int32):
        info = np.iinfo(dt)
        if info.min <= lo and hi <= info.max:
            return a.astype(dt)
    raise SessionError(f"segmentation labels {lo}..{hi} do not fit int32")


def write_segmentation(root: Path, truths: tuple[SegmentationTruth, ...]) -> dict[str, str]:
    """Write one file per camera under ``root/truth/segmentation``; the ``episode.json`` entry."""
    by_sensor: dict[str, list[int]] = {}
    for k, t in enumerate(truths):
        by_sensor.setdefault(check_id(t.sensor_id), []).append(k)
    files = {}
    for sid, ks in by_sensor.items():
        arrays = {"index": np.asarray(ks, dtype=np.int32), "stamp_s": np.array([float(truths[k].stamp_s) for k in ks])}
        for name in LABELS:
            arrays[name] = narrow_int(np.stack([np.asarray(getattr(truths[k], name), dtype=np.int32) for k in ks]))
        rel = f"truth/segmentation/{sid}.npz"
        save_npz(root / rel, arrays)
        files[sid] = rel
    return files


def read_segmentation(root: Path, files: Any) -> tuple[SegmentationTruth, ...]:
    """The segmentation truths of the files an ``episode.json`` lists, in episode order."""
    if not isinstance(files, dict):
        raise SessionError(f"{root / 'truth' / 'episode.json'}: 'segmentation' is not an object")
    out: dict[int, SegmentationTruth] = {}
    for sid, rel in files.items():
        a = load_npz(root, rel, NAMES)
        n = len(a["index"])
        shapes = {a[name].shape for name in LABELS}
        if a["stamp_s"].shape != (n,) or len(shapes) != 1 or len(next(iter(shapes))) != 3 or next(iter(shapes))[0] != n:
            raise SessionError(f"{root / rel}: arrays of mismatched shapes {[a[m].shape for m in NAMES]}")
        for j, k in enumerate(a["index"].tolist()):
            if k in out:
                raise SessionError(f"{root / rel}: segmentation truth {k} stored twice")
            out[k] = SegmentationTruth(stamp_s=float(a["stamp_s"][j]), sensor_id=str(sid),
                                       **{m: a[m][j].astype(np.int32) for m in LABELS})  # fmt: skip
    if sorted(out) != list(range(len(out))):
        raise SessionError(f"{root / 'truth' / 'segmentation'}: segmentation truths missing from the episode's order")
    return tuple(out[k] for k in range(len(out)))
