"""Output paths of the command line checked before anything runs, and the locks of the folders
exobench writes.

:func:`check_out_dir` (``--out``, ``record OUT_DIR``, ``report RUN_DIR``) and
:func:`check_out_file` (``--rerun``) refuse, as a :class:`ConfigError` the command line prints
as one line with exit status 2: an empty path, a file in the way, a dangling symbolic link, a
name longer than the file system allows, and a folder that cannot be written. Writability is
tried, not asked (``os.access`` says yes to root on a read-only mount): a probe file is created
and removed, an existing file is opened for appending.

:func:`exclusive_lock` is the one-writer rule of a run folder (and of a session being recorded,
:func:`reserve_dir`): an ``fcntl.flock`` held while the folder is written. The operating system
releases it when the process ends, however it ends, so a killed run never leaves a stale lock.
"""

from __future__ import annotations

import contextlib
import errno
import fcntl
import os
import stat
import tempfile
from collections.abc import Iterator
from pathlib import Path

from exobench.core.errors import ConfigError, FolderError

LOCK_FILE = ".exobench.lock"
_NAME_MAX, _PATH_MAX = 255, 4096  # Linux's, when the file system does not say


def _limit(folder: Path, name: str, default: int) -> int:
    try:
        return int(os.pathconf(folder, name))
    except (OSError, ValueError):
        return default


def _nearest_folder(option: str, path: str, start: Path) -> Path:
    """The nearest existing folder at or above ``start``; ConfigError for a file in the way, a
    dangling (or looping) symbolic link, or a name longer than the file system allows. Nothing
    here may call Path.exists(), which raises on a name that is too long."""
    absolute = Path(os.path.abspath(start))
    chain = [*reversed(absolute.parents), absolute]
    found = Path("/")
    missing: list[str] = []
    for i, p in enumerate(chain):
        try:
            st = os.stat(p)
        except OSError as e:
            if e.errno == errno.ENAMETOOLONG:
                raise ConfigError(option, path, f"a path the file system allows ({p.name[:40]}...: {e.strerror})") from None
            if os.path.islink(p):
                raise ConfigError(option, path, f"a path without a dangling symbolic link ({p} -> {os.readlink(p)})") from None
            if e.errno != errno.ENOENT:
                raise ConfigError(option, path, f"a path that can be reached ({p}: {e.strerror})") from None
            missing = [q.name for q in chain[i:]]
            break
        if not stat.S_ISDIR(st.st_mode):
            raise ConfigError(option, path, f"a path with no file in the way ({p} is a file)")
        found = p
    name_max = _limit(found, "PC_NAME_MAX", _NAME_MAX)
    for name in missing:
        if len(os.fsencode(name)) > name_max:
            raise ConfigError(option, path, f"names of at most {name_max} bytes (one has {len(os.fsencode(name))})")
    path_max = _limit(found, "PC_PATH_MAX", _PATH_MAX)
    if len(os.fsencode(str(absolute))) >= path_max:
        raise ConfigError(option, path, f"a path shorter than {path_max} bytes")
    return found


def _check_target_name(option: str, path: str, target: Path, folder: Path) -> None:
    """The last name of a file path (not walked by :func:`_nearest_folder`) fits the file system."""
    name_max = _limit(folder, "PC_NAME_MAX", _NAME_MAX)
    if len(os.fsencode(target.name)) > name_max:
        raise ConfigError(option, path, f"names of at most {name_max} bytes (one has {len(os.fsencode(target.name))})")


def probe_writable(folder: Path) -> OSError | None:
    """Create and remove a file in ``folder``: None if that works, else the error it raised."""
    try:
        fd, name = tempfile.mkstemp(prefix=".exobench-probe-", dir=folder)
    except OSError as e:
        return e
    os.close(fd)
    os.unlink(name)
    return None


def probe_appendable(path: Path) -> OSError | None:
    """Open an existing file for appending (writing nothing): None if that works, else the error."""
    try:
        fd = os.open(path, os.O_WRONLY | os.O_APPEND)
    except OSError as e:
        return e
    os.close(fd)
    return None


def _check_writable(option: str, path: str, folder: Path) -> None:
    err = probe_writable(folder)
    if err is not None:
        raise ConfigError(option, path, f"a path in a folder you can write to ({folder} is not writable: {err.strerror})")


def check_out_dir(option: str, path: str, *, existing: bool | None = None) -> None:
    """Refuse, before anything runs, a folder that cannot be created or written (see the module
    doc). ``existing`` True: it must be an existing folder (resume, report); False: a path that
    does not exist yet or an empty folder (record); None: either."""
    if not str(path).strip():
        raise ConfigError(option, path, "a folder path (not empty)")
    target = Path(path)
    folder = _nearest_folder(option, path, target)
    is_there = folder == Path(os.path.abspath(target))
    if existing is False and is_there and any(folder.iterdir()):
        raise ConfigError(option, path, "a path that does not exist yet (or an empty folder)")
    if existing and not is_there:
        raise ConfigError(option, path, "an existing run folder")
    _check_writable(option, path, folder)


def check_out_file(option: str, path: str) -> None:
    """Refuse, before anything runs, a file that cannot be written (see :func:`check_out_dir`)."""
    if not str(path).strip():
        raise ConfigError(option, path, "a file path (not empty)")
    target = Path(path)
    folder = _nearest_folder(option, path, target.parent)
    _check_target_name(option, path, target, folder)
    if os.path.islink(target) and not os.path.exists(target):
        raise ConfigError(option, path, f"a path without a dangling symbolic link ({target} -> {os.readlink(target)})")
    if target.is_dir():
        raise ConfigError(option, path, "a file path, not a folder")
    if target.exists():
        err = probe_appendable(target)
        if err is not None:
            raise ConfigError(option, path, f"a file you can write to ({err.strerror})")
    _check_writable(option, path, folder)


def _flock(fd: int, folder: Path, what: str) -> None:
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        os.close(fd)
        raise FolderError(f"{folder}: in use by another exobench {what} (one writer per folder); wait for it to end") from None


@contextlib.contextmanager
def exclusive_lock(folder: str | os.PathLike, what: str = "run") -> Iterator[None]:
    """Hold the lock of ``folder`` (its file :data:`LOCK_FILE`, created if missing and never
    removed: removing it would let a second writer lock a fresh file while the first still
    holds the old one). FolderError if another process holds it or the folder is not writable."""
    folder = Path(folder)
    try:
        fd = os.open(folder / LOCK_FILE, os.O_RDWR | os.O_CREAT, 0o666)
    except OSError as e:
        raise FolderError(f"{folder}: cannot be written ({e.strerror})") from None
    _flock(fd, folder, what)
    try:
        yield
    finally:
        os.close(fd)


@contextlib.contextmanager
def reserve_dir(path: str | os.PathLike, what: str = "record") -> Iterator[Path]:
    """Reserve a new folder for a writer that fills it at the end by renaming a finished one
    onto it (``record``): create it (or take an existing empty one) and lock the folder itself,
    so that a second writer is refused before it does any work. An exception removes the folder
    again if it was created here and is still empty."""
    folder = Path(path)
    created = [p for p in (folder, *folder.parents) if not os.path.lexists(p)]  # innermost first
    try:
        folder.mkdir(parents=True)
    except FileExistsError:
        created = []  # another writer made it first: the lock below decides

    def remove_created() -> None:
        for p in created:  # rmdir removes only what is still empty
            with contextlib.suppress(OSError):
                p.rmdir()

    try:
        fd = os.open(folder, os.O_RDONLY | os.O_DIRECTORY)
        _flock(fd, folder, what)
    except BaseException:
        remove_created()
        raise
    try:
        if any(folder.iterdir()):  # filled by a writer that finished between the check and here
            raise FolderError(f"{folder}: exists already and is not empty; choose a new folder")
        yield folder
    except BaseException:
        remove_created()
        raise
    finally:
        os.close(fd)
