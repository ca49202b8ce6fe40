"""The result store of a run folder: ``run_config.json`` and ``results.jsonl``.

``results.jsonl`` holds one JSON object per (episode, pipeline). The records of one episode are
appended together with a single write, then flushed and fsync'ed, so a stopped run loses at most
the episode in flight. Each record carries ``records_in_episode``; on reading, a trailing
partial line and a trailing episode with fewer records than announced are ignored, and
:func:`repair_results` cuts them off before a resumed run appends. A corrupt line in the middle
is named on stderr and costs only its own episode (which ``--resume`` runs again); every record
after it is kept. An episode stored twice (two writers before the run folder was locked) is
counted once: its first complete copy is kept. NaN is stored as ``null``.

A damaged store (``run_config.json`` not JSON or without a field, ``results.jsonl`` a folder)
and a write that fails (disk full) raise :class:`FolderError` naming the file; an append that
fails is cut off again, so the file holds whole episodes only.
"""

from __future__ import annotations

import contextlib
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

from exobench.core.errors import FolderError

RESULTS_FILE = "results.jsonl"
RUN_CONFIG_FILE = "run_config.json"
RUN_ALL_FILE = "run_all.json"  # the top folder of a run of every track (one run folder per track)
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
    text = json.dumps(json_safe(obj), indent=2, allow_nan=False) + "\n"
    try:
        fd, tmp = tempfile.mkstemp(prefix=f".{path.name[:32]}.", dir=path.parent)
    except OSError as e:
        raise FolderError(f"{path}: cannot be written ({e.strerror})") from None
    try:
        os.fchmod(fd, 0o666 & ~_umask())
        with os.fdopen(fd, "w") as f:
            f.write(text)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    except OSError as e:
        Path(tmp).unlink(missing_ok=True)
        raise FolderError(f"{path}: cannot be written ({e.strerror})") from None
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def append_records(path: Path, records: list[dict[str, Any]]) -> None:
    """Append one episode's records with a single write, then flush and fsync. A write that
    fails (disk full) is cut off again and raises FolderError: the file keeps whole episodes."""
    n = len(records)
    text = "".join(json.dumps(json_safe({**r, "records_in_episode": n}), allow_nan=False) + "\n" for r in records)
    data = text.encode("utf-8")
    try:
        fd = os.open(path, os.O_WRONLY | os.O_APPEND | os.O_CREAT, 0o666)
    except OSError as e:
        raise FolderError(f"{path}: cannot be written ({e.strerror})") from None
    try:
        start = os.lseek(fd, 0, os.SEEK_END)
        try:
            view = memoryview(data)
            while view:
                view = view[os.write(fd, view) :]
            os.fsync(fd)
        except OSError as e:
            with contextlib.suppress(OSError):  # cutting a file frees space, so this works on a full disk
                os.ftruncate(fd, start)
            raise FolderError(f"{path}: cannot be written ({e.strerror})") from None
    finally:
        os.close(fd)


def _scan(data: bytes) -> tuple[list[dict[str, Any]], int, list[str]]:
    """(records of complete episodes, byte length up to the end of the last complete episode,
    one problem text per corrupt line or broken episode).

    A corrupt line (not JSON, not an object) costs only its own episode: that episode counts as
    unfinished (``--resume`` runs it again) and every record after it is kept.
    """
    records: list[dict[str, Any]] = []
    problems: list[str] = []
    seen: set[tuple[Any, Any]] = set()  # (episode, pipeline) of the records kept
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
            keys = [(r.get("episode"), r.get("pipeline")) for r in pending]
            if seen.isdisjoint(keys):
                records += pending
                seen.update(keys)
            else:
                problems.append(f"episode {pending[0].get('episode')!r} ending at line {line_no} is stored again; the first copy is kept")
            pending, after_corrupt = [], False
            good_end = pos
    return records, good_end, problems


_NONE = object()
_WARNED: set[tuple[str, str]] = set()


def _complete_prefix(data: bytes) -> tuple[list[dict[str, Any]], int]:
    """Records of complete episodes and the byte length up to the last of them."""
    records, end, _ = _scan(data)
    return records, end


def _read_bytes(path: Path) -> bytes:
    if not path.is_file():
        raise FolderError(f"{path}: not a file; a run folder's {path.name} is a file of records")
    try:
        return path.read_bytes()
    except OSError as e:
        raise FolderError(f"{path}: cannot be read ({e.strerror})") from None


def _read_json(path: Path, what: str) -> dict[str, Any]:
    try:
        obj = json.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise FolderError(f"{path}: missing; not {what}") from None
    except (ValueError, UnicodeDecodeError) as e:
        raise FolderError(f"{path}: damaged, not JSON ({type(e).__name__}: {str(e)[:80]})") from None
    except OSError as e:
        raise FolderError(f"{path}: cannot be read ({e.strerror})") from None
    if not isinstance(obj, dict):
        raise FolderError(f"{path}: damaged, a JSON {type(obj).__name__} instead of an object")
    return obj


def _check_fields(path: Path, obj: dict[str, Any], fields: dict[str, Any]) -> None:
    for key, ok in fields.items():
        if key not in obj:
            raise FolderError(f"{path}: damaged, field {key!r} is missing")
        if not ok(obj[key]):
            raise FolderError(f"{path}: damaged, field {key!r} is {str(obj[key])[:60]!r}")


def _str_list(v: Any) -> bool:
    return isinstance(v, list) and all(isinstance(x, str) for x in v)


def _seed_list(v: Any) -> bool:
    return isinstance(v, list) and bool(v) and all(isinstance(x, int) and not isinstance(x, bool) and x >= 0 for x in v)


def read_run_config(folder: str | os.PathLike) -> dict[str, Any]:
    """``run_config.json`` of a run folder, with the fields a report or a resume reads checked
    (FolderError naming the file otherwise). Optional fields get their defaults."""
    path = Path(folder) / RUN_CONFIG_FILE
    config = _read_json(path, "a run folder")
    _check_fields(path, config, {
        "track": lambda v: isinstance(v, str) and bool(v),
        "suite": lambda v: isinstance(v, str) and bool(v),
        "pipelines": lambda v: isinstance(v, list) and bool(v) and all(isinstance(p, dict) and isinstance(p.get("name"), str) for p in v),
        "seeds": _seed_list,
    })  # fmt: skip
    # "cases": the --case patterns of the run (none, and absent before --case existed: every case)
    optional = {"overrides": ({}, dict), "pipeline_overrides": ({}, dict), "episodes": ([], list), "cases": ([], list)}
    for key, (default, kind) in optional.items():
        config.setdefault(key, default)
        if not isinstance(config[key], kind) or (key in ("episodes", "cases") and not _str_list(config[key])):
            raise FolderError(f"{path}: damaged, field {key!r} is {str(config[key])[:60]!r}")
    if not all(isinstance(v, dict) for v in config["pipeline_overrides"].values()):
        raise FolderError(f"{path}: damaged, field 'pipeline_overrides' is {str(config['pipeline_overrides'])[:60]!r}")
    return config


def read_run_all(folder: str | os.PathLike) -> dict[str, Any]:
    """``run_all.json`` of the top folder of a run of every track (see :func:`run_all_config`)."""
    path = Path(folder) / RUN_ALL_FILE
    config = _read_json(path, "the folder of a run of every track")
    _check_fields(path, config, {
        "tracks": lambda v: _str_list(v) and bool(v),
        "suite": lambda v: v is None or (isinstance(v, str) and bool(v)),
        "seeds": _seed_list,
    })  # fmt: skip
    return config


def run_all_config(tracks: list[str], suite: str | None, seeds: list[int]) -> dict[str, Any]:
    """What ``run_all.json`` holds: the settings ``exobench run --resume`` needs to continue a
    run of every track (each track's own settings are in its folder's ``run_config.json``)."""
    return {"format": "exobench-run-all", "version": 1, "tracks": list(tracks), "suite": suite, "seeds": list(seeds)}


def read_records(path: Path) -> list[dict[str, Any]]:
    """Records of the complete episodes in ``results.jsonl`` (empty if the file is missing).

    Each corrupt line is named once on stderr (``exobench: warning: <file> line N ...``); the
    records around it are kept.
    """
    path = Path(path)
    if not path.exists():
        return []
    records, _, problems = _scan(_read_bytes(path))
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
    data = _read_bytes(path)
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
