"""Output paths of the command line checked before anything runs: a folder to create or write
into (``--out``, ``record OUT_DIR``) and a file to write (``--rerun``). An empty path, a file in
the way, a folder that cannot be written (``os.access``) is a :class:`ConfigError`, which the
command line prints as one line with exit status 2.
"""

from __future__ import annotations

import os
from pathlib import Path

from exobench.core.errors import ConfigError


def _first_existing(option: str, path: Path, start: Path) -> Path:
    """The nearest existing folder at or above ``start``; ConfigError if a file is in the way."""
    for p in (start, *start.parents):
        if p.exists():
            if not p.is_dir():
                raise ConfigError(option, str(path), f"a path with no file in the way ({p} is a file)")
            return p
    return Path.cwd()  # a relative path whose first part does not exist


def _check_writable(option: str, path: Path, folder: Path) -> None:
    if not os.access(folder, os.W_OK | os.X_OK):
        raise ConfigError(option, str(path), f"a path in a folder you can write to ({folder} is not writable)")


def check_out_dir(option: str, path: str, *, existing: bool | None = None) -> None:
    """Refuse, before anything runs, a folder that cannot be created or written: an empty path,
    a file at or above it, an unwritable folder. ``existing`` True: it must be an existing folder
    (resume); False: it must not exist yet (record); None: either."""
    if not str(path).strip():
        raise ConfigError(option, path, "a folder path (not empty)")
    target = Path(path)
    if existing is False and target.exists():
        raise ConfigError(option, path, "a path that does not exist yet")
    if existing and not target.is_dir():
        raise ConfigError(option, path, "an existing run folder")
    _check_writable(option, target, _first_existing(option, target, target))


def check_out_file(option: str, path: str) -> None:
    """Refuse, before anything runs, a file that cannot be written (see :func:`check_out_dir`)."""
    if not str(path).strip():
        raise ConfigError(option, path, "a file path (not empty)")
    target = Path(path)
    if target.is_dir():
        raise ConfigError(option, path, "a file path, not a folder")
    if target.exists() and not os.access(target, os.W_OK):
        raise ConfigError(option, path, "a file you can write to")
    _check_writable(option, target, _first_existing(option, target, target.parent))
