"""A run's folder (:func:`.runner.execute`, :mod:`.run_tracks`): checked against its plan, created,
locked for the whole run, with its ``run_config.json``; and an episode's figure in it. Nothing
here runs an episode."""

from __future__ import annotations

import contextlib
import os
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np

from exobench.core.errors import ConfigError, FolderError

from .out_paths import LOCK_FILE, exclusive_lock, probe_appendable, probe_writable
from .results import (
    RESULTS_FILE,
    RUN_CONFIG_FILE,
    json_safe,
    read_run_config,
    repair_results,
    write_json_atomic,
)

FIGURES_DIR = "figures"


def check_resume(out: str | os.PathLike, plan: Any) -> None:
    """ConfigError unless ``plan`` is the run whose folder ``out`` is (same track, suite,
    pipelines and their configs, seeds, overrides, --case patterns); FolderError if the folder
    is damaged."""
    old = read_run_config(out)
    new = json_safe(plan.run_config())
    for key in ("track", "suite", "pipelines", "seeds", "overrides", "pipeline_overrides", "cases"):
        if old.get(key) != new.get(key):
            raise ConfigError(f"--resume {key}", new.get(key), f"the value of the run being resumed: {old.get(key)!r}")


def holds_only_lock(out: Path) -> bool:
    return all(p.name == LOCK_FILE for p in out.iterdir())


def prepare_output(out_dir: str | os.PathLike, plan: Any, *, resume: bool, executor: dict[str, Any] | None = None) -> Path:
    """Check the run folder (resuming: its run_config.json matches the plan, its results can be
    appended to; else: it is new or empty) and write run_config.json. Call it holding the
    folder's lock (see :func:`execute`); it runs nothing."""
    out = Path(out_dir)
    if resume:
        if not (out / RUN_CONFIG_FILE).exists():
            raise ConfigError("--resume", str(out), "a run folder with run_config.json")
        check_resume(out, plan)
        results = out / RESULTS_FILE
        if results.exists() or results.is_symlink():
            if not results.is_file():
                raise FolderError(f"{results}: not a file; a run folder's {RESULTS_FILE} is a file of records")
            err = probe_appendable(results)
            if err is not None:
                raise FolderError(f"{results}: cannot be written ({err.strerror})")
        err = probe_writable(out)
        if err is not None:
            raise FolderError(f"{out}: cannot be written ({err.strerror})")
        repair_results(results)
        return out
    if not holds_only_lock(out):
        again = " (or --resume to continue the run in it)" if (out / RUN_CONFIG_FILE).exists() else ""
        raise ConfigError("--out", str(out), f"a new or empty folder{again}")
    write_json_atomic(out / RUN_CONFIG_FILE, {**plan.run_config(), **({"executor": executor} if executor else {})})
    return out


def save_figure(out: Path, key: str, figure: dict[str, Any]) -> None:
    """Write an episode's figure data; on failure (disk full) nothing of it stays behind."""
    folder = out / FIGURES_DIR
    folder.mkdir(exist_ok=True)
    target = folder / (key.replace("/", "__") + ".npz")
    tmp = folder / (".tmp-" + target.name)
    try:
        with open(tmp, "wb") as f:
            np.savez(f, **figure)
        os.replace(tmp, target)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise


@contextlib.contextmanager
def run_folder(plan: Any, out_dir: str | os.PathLike, *, resume: bool, executor: dict[str, Any]) -> Iterator[Path]:
    """The plan's run folder for the block: checked (refused before it is touched), created,
    locked, with its run_config.json (:func:`prepare_output`)."""
    out = Path(out_dir)
    if resume and not out.is_dir():
        raise ConfigError("--resume", str(out), "a run folder with run_config.json")
    if not resume:
        if out.is_dir() and not holds_only_lock(out):  # refused before the folder is touched
            prepare_output(out, plan, resume=False)
        out.mkdir(parents=True, exist_ok=True)
    with exclusive_lock(out, "run"):
        prepare_output(out, plan, resume=resume, executor=executor)
        yield out
