"""Keyframe resources on disk, pose graphs in memory (seeds/000 III-B.2, memory management).

LT-Exosense keeps each session's images, point clouds and descriptors in the file system and
loads only the pose graphs; a resource is read when an operation needs it. :class:`KeyframeStore`
is that file system part for one pipeline run: a temporary folder of its own (under the system's
temporary directory or a given parent), one ``.npy`` per keyframe and array (so features computed
later join a keyframe without rewriting its image), removed by :meth:`close`
(or on leaving a ``with`` block), and otherwise when the store is collected or the process
exits (:func:`weakref.finalize`): a pipeline that made its store in ``reset`` and never reached
``finalize`` (the runner's planning instance, a failed episode) left empty folders behind.
Nothing of it is kept after the run.

Outputs too large to hold (every session's points, the merged map) are written to the folder a
piece at a time (:meth:`KeyframeStore.append_rows`) and handed out as read-only maps of their
files (:meth:`KeyframeStore.mapped`): the reader pages them in from disk, and a map stays
readable after :meth:`close` removed its file (POSIX keeps a removed file's data while it is
mapped; the space is freed with the last map).
"""

from __future__ import annotations

import os
import shutil
import tempfile
import weakref
from pathlib import Path

import numpy as np

from exobench.core.errors import ConfigError, FolderError

__all__ = ["KeyframeId", "KeyframeStore"]

KeyframeId = tuple[int, int]
"""A keyframe of the multi-session map: (session id, keyframe index in its session), both >= 0."""


def _check_id(key: KeyframeId) -> tuple[int, int]:
    if (not isinstance(key, tuple) or len(key) != 2
            or not all(isinstance(k, (int, np.integer)) and not isinstance(k, bool) and k >= 0 for k in key)):
        raise ConfigError("keyframe_id", key, "a (session, index) pair of integers >= 0")
    return int(key[0]), int(key[1])


def _remove(root: Path, pid: int) -> None:
    # only in the process that made the folder: a forked worker that collects its copy of the
    # store must not remove the parent's folder
    if os.getpid() == pid:
        shutil.rmtree(root, ignore_errors=True)


class KeyframeStore:
    """Arrays of keyframes (image, depth, cloud, ...) in a temporary folder of this store's own.

    Args:
        parent: folder in which the store makes its own temporary folder (default: the system's
            temporary directory).
    """

    def __init__(self, parent: str | Path | None = None) -> None:
        self.root: Path = Path(tempfile.mkdtemp(prefix="exobench-keyframes-", dir=parent))
        self._names: dict[tuple[int, int], set[str]] = {}
        self._closed = False
        self._remove = weakref.finalize(self, _remove, self.root, os.getpid())

    def __enter__(self) -> KeyframeStore:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def __len__(self) -> int:
        return len(self._names)

    def __contains__(self, key: object) -> bool:
        return key in self._names

    @property
    def closed(self) -> bool:
        return self._closed

    def _path(self, key: tuple[int, int], name: str) -> Path:
        return self.root / f"s{key[0]:04d}_k{key[1]:06d}_{name}.npy"

    def put(self, key: KeyframeId, **arrays: np.ndarray) -> None:
        """Write the named arrays of keyframe ``key`` (an array of the same name is replaced)."""
        if self._closed:
            raise FolderError(f"{self.root}: keyframe store closed (put after close)")
        k = _check_id(key)
        for name, a in arrays.items():
            if not name.isidentifier():
                raise ConfigError("keyframe_array", name, "a name of letters, digits and underscores")
            np.save(self._path(k, name), np.asarray(a), allow_pickle=False)
            self._names.setdefault(k, set()).add(name)

    def has(self, key: KeyframeId, name: str) -> bool:
        """Whether keyframe ``key`` has an array ``name``."""
        return name in self._names.get(_check_id(key), ())

    def get(self, key: KeyframeId, name: str) -> np.ndarray:
        """Read array ``name`` of keyframe ``key`` back from disk."""
        if self._closed:
            raise FolderError(f"{self.root}: keyframe store closed (get after close)")
        k = _check_id(key)
        if k not in self._names:
            raise ConfigError("keyframe_id", key, f"one of the {len(self._names)} keyframes stored")
        if name not in self._names[k]:
            raise ConfigError("keyframe_array", name, f"one of {sorted(self._names[k])}")
        return np.load(self._path(k, name), allow_pickle=False)

    def _output(self, name: str) -> Path:
        if not name.isidentifier():
            raise ConfigError("output_file", name, "a name of letters, digits and underscores")
        return self.root / f"{name}.bin"

    def append_rows(self, name: str, rows: np.ndarray) -> None:
        """Append the raw bytes of ``rows`` (C order) to the output file ``name``."""
        if self._closed:
            raise FolderError(f"{self.root}: keyframe store closed (append after close)")
        with open(self._output(name), "ab") as fh:
            np.ascontiguousarray(rows).tofile(fh)

    def mapped(self, name: str, dtype: np.dtype | type, shape: tuple[int, ...]) -> np.ndarray:
        """Output file ``name`` as a read-only array of ``shape``, mapped from disk; bytes not
        appended read as zeros (a mask padded with False). An empty shape needs no file."""
        if self._closed:
            raise FolderError(f"{self.root}: keyframe store closed (mapped after close)")
        path = self._output(name)
        size = int(np.prod(shape)) * np.dtype(dtype).itemsize
        have = path.stat().st_size if path.exists() else 0
        if have > size:
            raise ConfigError(f"output_file.{name}", shape, f"a shape of at least {have} bytes of {np.dtype(dtype)}")
        if size == 0:
            return np.zeros(shape, dtype=dtype)
        with open(path, "ab") as fh:
            fh.truncate(size)
        return np.memmap(path, dtype=dtype, mode="r", shape=shape)

    def keys(self, session: int | None = None) -> list[tuple[int, int]]:
        """Stored keyframes (of ``session`` only when given), in order."""
        return sorted(k for k in self._names if session is None or k[0] == session)

    def close(self) -> None:
        """Remove the store's folder and everything in it (idempotent)."""
        if not self._closed:
            self._remove.detach()
            shutil.rmtree(self.root, ignore_errors=True)
            self._names.clear()
            self._closed = True
