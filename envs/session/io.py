"""Writing and reading session directories: atomic writes, version checks, streaming reads."""

from __future__ import annotations

import json
import os
import shutil
import tempfile
from collections.abc import Iterator
from pathlib import Path
from typing import Any

from exobench.core import Episode, Frame, SessionError

from .calibration import calibration_from_dict, calibration_to_dict
from .codecs import frame_from_dict, frame_to_dict
from .store import BinaryStore, dumps, plain
from .truth import read_truth, write_truth

FORMAT = "exobench-session"
VERSION = 3
SUPPORTED_VERSIONS = (1, 2, 3)


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
        store = BinaryStore(tmp)
        with open(tmp / "frames.jsonl", "w") as fh:
            for fr in episode.frames:
                d = frame_to_dict(fr, store)
                counts[d["kind"]] = counts.get(d["kind"], 0) + 1
                fh.write(dumps(d) + "\n")
        meta = {
            "format": FORMAT,
            "version": VERSION,
            "exobench_version": __version__,
            "scenario": plain(episode.scenario),
            "seed": int(episode.seed),
            "frame_counts": counts,
            "has_truth": include_truth,
        }
        (tmp / "meta.json").write_text(json.dumps(meta, indent=1, allow_nan=False))
        (tmp / "calibration.json").write_text(
            json.dumps(calibration_to_dict(episode.calibration), allow_nan=False)
        )
        if include_truth:
            write_truth(tmp, episode.truth)
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
    truth = read_truth(p)
    return Episode(
        scenario=meta["scenario"], seed=meta["seed"], calibration=calib, frames=frames, truth=truth
    )
