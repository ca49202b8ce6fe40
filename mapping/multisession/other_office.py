"""The vocabulary of another office: what it is trained on, and where the harness caches it.

LT-Exosense's default vocabulary is trained on the episode's first session (the building it
mapped first). ``vocabulary=other`` uses one trained on images of a different office instead, as
a deployed system ships a vocabulary trained elsewhere (DBoW2's is trained on outdoor and indoor
sequences that are not the robot's). The images need the simulator, which mapping code never
imports: the benchmark side renders them (:mod:`exobench.benchmarks.ltvoc`, before a run's
episodes, as it builds ORB-SLAM3's vocabulary) and writes the trained tree to
:func:`other_office_vocabulary_path`; the pipeline reads that file. The path hashes everything
that decides the content (:data:`OTHER_OFFICE` and the vocabulary's settings), so a changed
training set is never read from an old file.
"""

from __future__ import annotations

import hashlib
import json
from dataclasses import asdict, dataclass
from pathlib import Path

from exobench.mapping.odometry.orbslam3.vocabulary import cache_dir

from .place_recognition import OrbConfig, VocabularyConfig

__all__ = ["OTHER_OFFICE", "OtherOffice", "other_office_vocabulary_path"]


@dataclass(frozen=True)
class OtherOffice:
    """The office walk whose images train the vocabulary (an office scenario's rows and the
    camera): another layout seed than the suites' offices (seed 0; the general suite draws 0-999,
    so one in a thousand of its cases may share it), the default office's size, its loop route
    (every office entered, the meeting room, every corridor), a thigh camera at 424 x 240."""

    office_seed: int = 4242
    route: str = "loop"
    max_distance_m: float = 40.0
    surfaces: str = "textured_floors"
    furnish: str = "mixed"
    camera: str = "thigh"
    rate_hz: float = 2.0


OTHER_OFFICE = OtherOffice()


def other_office_vocabulary_path(office: OtherOffice = OTHER_OFFICE, orb: OrbConfig | None = None,
                                 vocabulary: VocabularyConfig | None = None) -> Path:  # fmt: skip
    """``<cache>/ltvoc-<hash>.npz``: the cached vocabulary of ``office`` with these settings."""
    key = {"office": asdict(office), "orb": asdict(orb or OrbConfig()), "vocabulary": asdict(vocabulary or VocabularyConfig())}
    digest = hashlib.sha256(json.dumps(key, sort_keys=True).encode()).hexdigest()[:16]
    return cache_dir() / f"ltvoc-{digest}.npz"
