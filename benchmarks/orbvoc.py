"""exobench's ORB vocabulary for ORB-SLAM3, built from simulated images on first use.

ORB-SLAM3 downloads its ``ORBvoc.txt`` from a host these machines cannot reach; the ``orb-slam3``
pipeline uses this one instead (:mod:`exobench.mapping.odometry.orbslam3.vocabulary`, which
clusters and writes; rendering lives here because mapping code never imports the simulator).

Training images (:func:`training_images`, about 450 grey 424x240 frames, fixed seeds): an office
walk with a head camera, and course walks (stairs, ramp, parallel lanes) with head, chest and
thigh cameras, all with textured surfaces (posters, notice boards, wood, carpet: what a tracker
holds on), at a low frame rate so that the frames spread over the walks. Different textures than
a benchmark's own episodes: the course texture seeds here are not those of the suites' defaults.

:func:`ensure_vocabulary` builds it once per user (``~/.cache/exobench/orbvoc-<hash>.txt``,
atomic write) and returns the cached file afterwards; :func:`setup_pipeline` is the ``orb-slam3``
registry entry's setup, run before a run's episodes. ``exobench orbvoc`` builds it by hand.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterable, Iterator
from pathlib import Path
from typing import Any

import numpy as np

from exobench.mapping.odometry.orbslam3.vocabulary import (
    DEFAULT_PARAMS,
    VocabularyParams,
    build_tree,
    vocabulary_path,
    write_vocabulary,
)

# (terrain, mount, texture seed, walk seconds); 5 frames per second
COURSE_WALKS = (("stairs", "head", 101, 24.0), ("ramp", "chest", 102, 24.0), ("parallel", "thigh", 103, 24.0),
                ("stairs", "chest", 104, 18.0), ("ramp", "head", 105, 18.0))  # fmt: skip
OFFICE_WALK_M = 10.0
FRAME_RATE_HZ = 5.0


def _grey(rgb: np.ndarray) -> np.ndarray:
    import cv2

    return cv2.cvtColor(np.ascontiguousarray(rgb, dtype=np.uint8), cv2.COLOR_RGB2GRAY)


def training_images() -> Iterator[np.ndarray]:
    """The grey training images (module docstring), one walk after the other."""
    from exobench.core.frames import RgbdFrame
    from exobench.envs.sensors import RgbdConfig
    from exobench.envs.sim import OfficeScenario, camera_rig, simulate_office
    from exobench.envs.sim.scenarios.course import LocomotionScenario, simulate_locomotion

    office = OfficeScenario(max_distance_m=OFFICE_WALK_M, surfaces="textured")
    rig = camera_rig("head", RgbdConfig(width_px=424, height_px=240, rate_hz=FRAME_RATE_HZ))
    for f in simulate_office(office, 7, rig=rig).frames:
        if isinstance(f, RgbdFrame):
            yield _grey(f.rgb)
    for terrain, mount, texture_seed, seconds in COURSE_WALKS:
        sc = LocomotionScenario(terrain=terrain, mount=mount, surfaces="textured", texture_seed=texture_seed,
                                rate_hz=FRAME_RATE_HZ, duration_cap_s=seconds)  # fmt: skip
        for f in simulate_locomotion(sc, texture_seed).frames:
            if isinstance(f, RgbdFrame):
                yield _grey(f.rgb)


def build_vocabulary(path: Path, params: VocabularyParams, images: Iterable[np.ndarray]) -> dict[str, Any]:
    """Build the vocabulary of ``images`` into ``path``; its figures (images, words, nodes, seconds)."""
    t0 = time.perf_counter()
    imgs = list(images)
    t_render = time.perf_counter() - t0
    tree = build_tree(imgs, params)
    write_vocabulary(path, tree)
    return {"path": str(path), "images": len(imgs), "words": tree.n_words, "nodes": len(tree.parent) - 1,
            "render_s": t_render, "build_s": time.perf_counter() - t0 - t_render,
            "bytes": path.stat().st_size}  # fmt: skip


def ensure_vocabulary(params: VocabularyParams = DEFAULT_PARAMS,
                      images: Callable[[], Iterable[np.ndarray]] | None = None) -> Path:  # fmt: skip
    """The cached vocabulary of ``params``, built from ``images()`` (default
    :func:`training_images`) when it is not there yet."""
    path = vocabulary_path(params)
    if not path.is_file():
        build_vocabulary(path, params, (images or training_images)())
    return path


def setup_pipeline(config: Any) -> None:
    """The ``orb-slam3`` entry's setup: the default vocabulary exists when the config names none."""
    if not getattr(config, "vocabulary", ""):
        ensure_vocabulary()
