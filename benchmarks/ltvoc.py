"""The ``lt-exosense`` vocabulary of another office, rendered and trained on first use.

``lt-exosense.vocabulary=other`` reads a bag-of-words vocabulary trained on images of an office
that is not the episode's (:mod:`exobench.mapping.multisession.other_office` says which, and
where it is cached). Mapping code never imports the simulator, so the images are rendered here:
the office walk of :data:`~exobench.mapping.multisession.other_office.OTHER_OFFICE` with a thigh
RGB-D camera at 424 x 240. :func:`ensure_vocabulary` builds it once per user
(``~/.cache/exobench/ltvoc-<hash>.npz``, written atomically, as :mod:`.orbvoc` does ORB-SLAM3's)
and :func:`setup_pipeline` is the registry entries' setup, run before a run's episodes.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterable, Iterator
from pathlib import Path
from typing import Any

import numpy as np

from exobench.mapping.multisession.matching import MatchConfig, PlaceMatcher
from exobench.mapping.multisession.other_office import OTHER_OFFICE, OtherOffice, other_office_vocabulary_path

from .orbvoc import _grey


def training_images(office: OtherOffice = OTHER_OFFICE) -> Iterator[np.ndarray]:
    """The grey images of the other office's walk (module docstring)."""
    from exobench.core.frames import RgbdFrame
    from exobench.envs.sensors import RgbdConfig
    from exobench.envs.sim import OfficeScenario, camera_rig, simulate_office

    sc = OfficeScenario(office_seed=office.office_seed, route=office.route, max_distance_m=office.max_distance_m,
                        surfaces=office.surfaces, furnish=office.furnish)  # fmt: skip
    rig = camera_rig(office.camera, RgbdConfig(width_px=424, height_px=240, rate_hz=office.rate_hz))
    for f in simulate_office(sc, office.office_seed, rig=rig).frames:
        if isinstance(f, RgbdFrame):
            yield _grey(f.rgb)


def build_vocabulary(path: Path, images: Iterable[np.ndarray], config: MatchConfig | None = None) -> dict[str, Any]:
    """Train the vocabulary of ``images`` into ``path``; its figures (images, words, seconds)."""
    t0 = time.perf_counter()
    imgs = list(images)
    t_render = time.perf_counter() - t0
    vocab = PlaceMatcher.train_vocabulary(imgs, config)
    vocab.save(path)
    return {"path": str(path), "images": len(imgs), "words": vocab.n_words, "render_s": t_render,
            "build_s": time.perf_counter() - t0 - t_render}  # fmt: skip


def ensure_vocabulary(path: Path | None = None, images: Callable[[], Iterable[np.ndarray]] | None = None) -> Path:
    """The cached vocabulary at ``path`` (default: the other office's), built from ``images()``
    (default :func:`training_images`) when it is not there yet."""
    path = Path(path) if path is not None else other_office_vocabulary_path()
    if not path.is_file():
        build_vocabulary(path, (images or training_images)())
    return path


def setup_pipeline(config: Any) -> None:
    """The ``lt-exosense`` entries' setup: with ``vocabulary=other`` and no file named, the other
    office's vocabulary exists before the episodes run."""
    if getattr(config, "vocabulary", "session") == "other" and not getattr(config, "vocabulary_file", ""):
        ensure_vocabulary()
