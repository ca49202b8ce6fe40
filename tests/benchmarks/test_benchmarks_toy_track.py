"""The toy track of docs/adding-a-track.md (tests/toy_track.py) weighs the walker within 0.5 kg.

Its conformance (registry members, counters, faults, scoring of failures) is checked by
``tests/test_conformance.py`` with the shipped tracks; here its estimate meets the truth the
scenario sets (user mass + the device's 14 kg), which the pipeline never sees.
"""

from __future__ import annotations

import pytest
from toy_track import ToyScale, ToyScaleTrack

from exobench.benchmarks.runner import PipelineRun, run_pipelines


@pytest.mark.parametrize("user_mass_kg", [55.0, 110.0])
def test_toy_scale_weighs_the_walker(user_mass_kg):
    track = ToyScaleTrack()
    episode = track.simulate(track.validate_scenario({**track.smoke_scenario, "user_mass_kg": user_mass_kg}), 0)
    _, metrics, _, _ = run_pipelines(track, episode, [PipelineRun("toy-scale", f"{ToyScale.__module__}:ToyScale", ToyScale.Config())])
    m = metrics["toy-scale"]
    assert not m["failed"], m.get("failed_reason")
    assert m["true_mass_kg"] == user_mass_kg + 14.0
    assert abs(m["mass_kg"] - (user_mass_kg + 14.0)) < 0.5
    assert m["frames.contact.used"] > 100 and m["frames.contact.nan"] == 0
