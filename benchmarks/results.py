"""The result store of a run folder: ``run_config.json`` and ``results.jsonl``.

``results.jsonl`` holds one JSON object per (episode, pipeline). The records of one episode are
appended together with a single write, then flushed and fsync'ed, so a stopped run loses at most
the episode in flight. Each record carries ``records_in_episode``; on reading, a trailing
partial line and a trailing episode with fewer records than announced are ignored, and
:func:`repair_results` cuts them off before a resumed run appends. A corrupt line in the middle
is named on stderr and costs only its own episode (which ``--resume`` runs again); every record
after it is kept. NaN is stored as ``null``.
"""

from __future__ import annotations

import json
import math
import os
import platform
import sys
import tempfile
from collections.abc import Iterable
from importlib import metadata
from pathlib import Path
from typing import Any

RESULTS_FILE = "results.jsonl"
RUN_CONFIG_FILE = "run_config.json"
VERSIONED = {"exobench": "exobench", "mujoco": "mujoco", "numpy": "numpy", "pinocchio": "pin", "open3d": "open3d"}


def versions() -> dict[str, str]:
    """Versions of exobench, the engines, Python and the platform (from package metadata)."""
    out = {}
    for key, dist in VERSIONED.items():
        try:
            out[key] = metadata.version(dist)
        except metadata.PackageNotFoundError:
            out[key] = "not installed"
    out["python"] = platform.python_version()
    out["platform"] = platform.platform()
    return out


def json_safe(value: Any) -> Any:
    """Plain JSON values: NaN/inf -> None, numpy scalars/arrays -> Python, tuples -> lists."""
    if isinstance(value, dict):
        return {str(k): json_safe(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [json_safe(v) for v in value]
    if hasattr(value, "tolist") and not isinstance(value, (str, bytes)):
        return json_safe(value.tolist())
    if isinstance(value, bool) or value is None or isinstance(value, (int, str)):
        return value
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    return str(value)


def _umask() -> int:
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


def write_json_atomic(path: Path, obj: Any) -> None:
    """Write JSON to a temporary sibling, fsync, and rename it over ``path``. The file gets the
    permissions of an ordinary new file (0666 less the umask), not mkstemp's private 0600."""
    path = Path(path)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", dir=path.parent)
    try:
        os.fchmod(fd, 0o666 & ~_umask())
        with os.fdopen(fd, "w") as f:
            json.dump(json_safe(obj), f, indent=2, allow_nan=False)
            f.write("\n")
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def append_records(path: Path, records: list[dict[str, Any]]) -> None:
    """Append one episode's records with a single write, then flush and fsync."""
    n = len(records)
    text = "".join(json.dumps(json_safe({**r, "records_in_episode": n}), allow_nan=False) + "\n" for r in records)
    with open(path, "a", encoding="utf-8") as f:
        f.write(text)
        f.flush()
        os.fsync(f.fileno())


def _scan(data: bytes) -> tuple[list[dict[str, Any]], int, list[str]]:
    """(records of complete episodes, byte length up to the end of the last complete episode,
    one problem text per corrupt line or broken episode).

    A corrupt line (not JSON, not an object) costs only its own episode: that episode counts as
    unfinished (``--resume`` runs it again) and every record after it is kept.
    """
    records: list[dict[str, Any]] = []
    problems: list[str] = []
    good_end = 0
    pending: list[dict[str, Any]] = []
    broken: Any = _NONE  # episode key whose records are being skipped after a corrupt line
    after_corrupt = False  # the pending episode began right after a corrupt line (named already)
    pos, line_no = 0, 0
    while True:
        nl = data.find(b"\n", pos)
        if nl < 0:
            break  # a trailing partial line (or nothing): a stopped write
        raw = data[pos:nl].strip()
        pos, line_no = nl + 1, line_no + 1
        if not raw:
            continue
        try:
            rec = json.loads(raw)
            if not isinstance(rec, dict) or "episode" not in rec:
                raise ValueError("not a record object")
            n_in = int(rec.get("records_in_episode", 1))
        except (ValueError, TypeError, UnicodeDecodeError) as e:
            what = pending[0].get("episode") if pending else None
            problems.append(f"line {line_no} is not a valid record ({type(e).__name__}); skipped"
                            + (f" with the rest of episode {what!r}" if what is not None else ""))
            if pending:
                broken, pending = pending[0].get("episode"), []
            after_corrupt = True
            continue
        if broken is not _NONE and rec.get("episode") == broken:
            continue  # the rest of an episode that had a corrupt line
        broken = _NONE
        if pending and rec.get("episode") != pending[0].get("episode"):
            if not after_corrupt:
                problems.append(f"episode {pending[0].get('episode')!r} before line {line_no} is incomplete; skipped")
            pending, after_corrupt = [], False
        pending.append(rec)
        if len(pending) >= n_in:
            records += pending
            pending, after_corrupt = [], False
            good_end = pos
    return records, good_end, problems


_NONE = object()
_WARNED: set[tuple[str, str]] = set()


def _complete_prefix(data: bytes) -> tuple[list[dict[str, Any]], int]:
    """Records of complete episodes and the byte length up to the last of them."""
    records, end, _ = _scan(data)
    return records, end


def read_records(path: Path) -> list[dict[str, Any]]:
    """Records of the complete episodes in ``results.jsonl`` (empty if the file is missing).

    Each corrupt line is named once on stderr (``exobench: warning: <file> line N ...``); the
    records around it are kept.
    """
    path = Path(path)
    if not path.exists():
        return []
    records, _, problems = _scan(path.read_bytes())
    for text in problems:
        key = (str(path.resolve()), text)
        if key not in _WARNED:
            _WARNED.add(key)
            print(f"exobench: warning: {path} {text}", file=sys.stderr)
    return records


def repair_results(path: Path) -> int:
    """Cut off a partial trailing write; returns the number of bytes removed."""
    path = Path(path)
    if not path.exists():
        return 0
    data = path.read_bytes()
    _, end = _complete_prefix(data)
    if end < len(data):
        with open(path, "r+b") as f:
            f.truncate(end)
            f.flush()
            os.fsync(f.fileno())
    return len(data) - end


def sort_records(records: Iterable[dict[str, Any]], pipeline_order: list[str] | None = None) -> list[dict[str, Any]]:
    """Records ordered by episode key, then pipeline (in ``pipeline_order`` if given)."""
    order = {p: i for i, p in enumerate(pipeline_order or [])}
    return sorted(records, key=lambda r: (r["episode"], order.get(r["pipeline"], len(order)), r["pipeline"]))
