"""Writing and reading session directories: atomic writes, version checks, self-checks, streaming reads.

Every file a session reads is checked before it is used: a missing, empty, truncated or
non-UTF-8 file, or one holding something other than the expected JSON object, is a
:class:`SessionError` naming the file. From version 4, ``meta.json`` lists every other file with
its size and SHA-256 (``files``), the track it was recorded for (``track``) and the number of
truths (``truth_counts``); :func:`read_session` checks them all, and the frame counts of every
version, before anything is scored. Older versions have no hashes (:func:`content_checked`):
since a forger edits ``meta.json`` with the files, the frames are also checked against the
truth they are scored with (:mod:`.checks`), whatever the version.
"""

from __future__ import annotations

import hashlib
import json
import os
import shutil
import tempfile
from collections.abc import Iterator
from pathlib import Path
from typing import Any

from exobench.core import Episode, Frame, SessionError

from .calibration import calibration_from_dict, calibration_to_dict
from .checks import check_truth_matches_frames
from .codecs import codec_of, frame_from_dict, frame_to_dict
from .store import BinaryStore, dumps, load_json, plain
from .truth import read_truth, write_truth

FORMAT = "exobench-session"
VERSION = 5
SUPPORTED_VERSIONS = (1, 2, 3, 4, 5)
HASHED_FROM = 4  # the first version whose meta.json lists every file's SHA-256
_CHUNK = 1 << 20


def file_digest(path: Path) -> dict[str, Any]:
    """``{"bytes", "sha256"}`` of a file."""
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        while chunk := fh.read(_CHUNK):
            h.update(chunk)
    return {"bytes": path.stat().st_size, "sha256": h.hexdigest()}


def write_session(
    episode: Episode,
    path: str | os.PathLike,
    *,
    include_truth: bool = True,
    track: str | None = None,
    compact: bool = True,
) -> Path:
    """Write ``episode`` as a session directory at ``path`` (which must not exist yet, or be an
    empty folder, which the session replaces);
    ``track`` (the track that simulated it) is recorded so a replay on another track is refused.
    ``compact`` writes format 5 (LiDAR scans and truths in one stream file each, see
    :mod:`.lidar_pack`); ``compact=False`` writes format 4 (one file per scan and per truth)."""
    from exobench import __version__

    final = Path(path)
    # an empty folder is taken: `exobench record` reserves (and locks) its folder before simulating
    if final.exists() and not (final.is_dir() and not any(final.iterdir())):
        raise SessionError(f"session path {str(final)!r} exists already; choose a new directory")
    final.parent.mkdir(parents=True, exist_ok=True)
    # a short prefix: the temporary name must fit where the final one just fits
    tmp = Path(tempfile.mkdtemp(prefix=f".{final.name[:32]}.", dir=final.parent))
    try:
        counts: dict[str, int] = {}
        store = BinaryStore(tmp, streams=compact)
        with open(tmp / "frames.jsonl", "w") as fh:
            for fr in episode.frames:
                d = frame_to_dict(fr, store)
                counts[d["kind"]] = counts.get(d["kind"], 0) + 1
                fh.write(dumps(d) + "\n")
        ray_ids = store.finish()
        (tmp / "calibration.json").write_text(
            json.dumps(calibration_to_dict(episode.calibration), allow_nan=False)
        )
        if include_truth:
            write_truth(tmp, episode.truth, ray_ids, stream=compact)
        files = {
            f.relative_to(tmp).as_posix(): file_digest(f) for f in sorted(tmp.rglob("*")) if f.is_file()
        }
        meta = {
            "format": FORMAT,
            "version": VERSION if compact else 4,
            "exobench_version": __version__,
            "track": track,
            "scenario": plain(episode.scenario),
            "seed": int(episode.seed),
            "frame_counts": counts,
            "has_truth": include_truth,
            "truth_counts": _truth_counts(episode) if include_truth else None,
            "files": files,
        }
        (tmp / "meta.json").write_text(json.dumps(meta, indent=1, allow_nan=False))
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(tmp, 0o777 & ~umask)  # mkdtemp's 0700 is for the name race only
        os.rename(tmp, final)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    return final


def _truth_counts(episode: Episode) -> dict[str, int]:
    """Truths of each part (``segmentation`` only when there are some, as sessions before it)."""
    stairs = episode.truth.stairs
    out = {"lidar": len(episode.truth.lidar), "tof": 0 if stairs is None else len(stairs.tof)}
    if episode.truth.segmentation:
        out["segmentation"] = len(episode.truth.segmentation)
    return out


def read_meta(path: str | os.PathLike) -> dict[str, Any]:
    """``meta.json`` of the session at ``path``, its format, version and field types checked."""
    p = Path(path)
    if not (p / "meta.json").exists():
        raise SessionError(f"{str(p)!r} is not a session: meta.json missing")
    meta = load_json(p / "meta.json")
    if meta.get("format") != FORMAT:
        raise SessionError(f"{p / 'meta.json'}: format {meta.get('format')!r}, expected {FORMAT!r}")
    if meta.get("version") not in SUPPORTED_VERSIONS:
        raise SessionError(
            f"{p / 'meta.json'}: version {meta.get('version')!r} unsupported; supported: {list(SUPPORTED_VERSIONS)}"
        )
    kinds = {"scenario": dict, "seed": int, "frame_counts": dict}
    if content_checked(meta):
        kinds["files"] = dict
    for key, kind in kinds.items():
        if not isinstance(meta.get(key), kind) or isinstance(meta.get(key), bool):
            raise SessionError(f"{p / 'meta.json'}: {key!r} missing or not a {kind.__name__}")
    return meta


def content_checked(meta: dict[str, Any]) -> bool:
    """Whether the session's files carry hashes: from version 4 they must (:func:`read_meta`
    refuses one without), and an older version that lists them is checked as well. Without
    hashes a session is still checked for frames without truth (:mod:`.checks`)."""
    return int(meta.get("version", 0)) >= HASHED_FROM or "files" in meta


def check_track(path: str | os.PathLike, meta: dict[str, Any], track: str | None) -> None:
    """SessionError when the session was recorded for another track than ``track``."""
    recorded = meta.get("track")
    if track is not None and recorded is not None and recorded != track:
        raise SessionError(f"{path}: recorded for track {recorded!r}, not {track!r}; replay it with --track {recorded}")


def verify_files(path: str | os.PathLike, meta: dict[str, Any]) -> None:
    """Every file listed in ``meta.json`` is there with its size and SHA-256, and every other
    file of the session is listed (version 4 on, or any version that lists them): an edited
    file taken off the list is not read unchecked."""
    root = Path(path)
    if not content_checked(meta):
        return
    for f in sorted(root.rglob("*")):
        rel = f.relative_to(root).as_posix()
        if f.is_file() and rel != "meta.json" and rel not in meta["files"]:
            raise SessionError(f"{f}: not listed in meta.json 'files' (added or edited after recording)")
    for rel, want in meta["files"].items():
        f = root / rel
        if not isinstance(rel, str) or rel.startswith("/") or ".." in Path(rel).parts or not isinstance(want, dict):
            raise SessionError(f"{root / 'meta.json'}: bad entry {rel!r} in 'files'")
        if not f.is_file():
            raise SessionError(f"{f}: missing (listed in meta.json)")
        got = file_digest(f)
        if got != {"bytes": want.get("bytes"), "sha256": want.get("sha256")}:
            raise SessionError(
                f"{f}: content differs from meta.json ({got['bytes']} bytes, {want.get('bytes')} recorded): damaged or edited"
            )


def iter_frames(path: str | os.PathLike) -> Iterator[Frame]:
    """Stream the frames of a session without loading them all (a scan's file is read with its line)."""
    root = Path(path)
    where = root / "frames.jsonl"
    try:
        fh = open(where, "rb")
    except FileNotFoundError:
        raise SessionError(f"{where}: missing") from None
    with fh:
        for n, raw in enumerate(fh, 1):
            try:
                line = raw.decode("utf-8")
            except UnicodeDecodeError:
                raise SessionError(f"{where} line {n}: not UTF-8 text") from None
            if not line.strip():
                continue
            try:
                d = json.loads(line)
                if not isinstance(d, dict):
                    raise TypeError(f"a JSON {type(d).__name__}, not an object")
                frame = frame_from_dict(d, root)
            except (json.JSONDecodeError, KeyError, TypeError, ValueError, AttributeError) as e:
                raise SessionError(f"{where} line {n}: malformed frame ({type(e).__name__}: {e})") from None
            yield frame


def read_session(path: str | os.PathLike, *, track: str | None = None) -> Episode:
    """Read a whole session back into an :class:`Episode` (truth required), after checking it:
    the track it was recorded for (when ``track`` is given), every file's hash (version 4 on,
    and any older one that lists them), the frame counts per kind and the number of truths
    against ``meta.json``, and, whatever the version, every frame the tracks score against its
    truth (:func:`.checks.check_truth_matches_frames`)."""
    p = Path(path)
    meta = read_meta(p)
    check_track(p, meta, track)
    if not meta.get("has_truth", False):
        raise SessionError(f"{str(p)!r} has no truth/ folder; it can be replayed but not scored")
    verify_files(p, meta)
    cfile = p / "calibration.json"
    if not cfile.exists():
        raise SessionError(f"{cfile}: missing")
    try:
        calib = calibration_from_dict(load_json(cfile))
    except (KeyError, TypeError, ValueError, AttributeError) as e:
        raise SessionError(f"{cfile}: malformed calibration ({type(e).__name__}: {e})") from None
    frames = tuple(iter_frames(p))
    counts: dict[str, int] = {}
    for d in frames:
        kind = codec_of(d).kind
        counts[kind] = counts.get(kind, 0) + 1
    want = {k: v for k, v in meta["frame_counts"].items() if v}
    if counts != want:
        raise SessionError(f"{p / 'frames.jsonl'}: frame counts {counts} differ from meta.json {want} (cut or edited)")
    truth = read_truth(p)
    check_truth_matches_frames(p, frames, truth, meta["scenario"])
    tc = meta.get("truth_counts")
    if isinstance(tc, dict):
        got = {"lidar": len(truth.lidar), "tof": 0 if truth.stairs is None else len(truth.stairs.tof),
               "segmentation": len(truth.segmentation)}  # fmt: skip
        tc = {"segmentation": 0, **tc}
        for part, where in (("tof", "truth/tof.jsonl"), ("lidar", "truth/lidar"), ("segmentation", "truth/segmentation")):
            if got[part] != tc.get(part):
                raise SessionError(f"{p / where}: {got[part]} {part} truths, meta.json says {tc.get(part)} (cut or edited)")
    return Episode(
        scenario=meta["scenario"], seed=meta["seed"], calibration=calib, frames=frames, truth=truth
    )
