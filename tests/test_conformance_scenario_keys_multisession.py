"""Every scenario key of the multisession track changes the simulation or is refused
(``test_conformance_scenario_keys.py``, whose check this runs): a file of its own, so that the
workers run it beside the other tracks' keys instead of after them (tests/conftest.py)."""

import pytest
from test_conformance_scenario_keys import OWN_FILES, check_scenario_keys

pytestmark = pytest.mark.long(seconds=10)  # the workers take it first (tests/conftest.py); 10: the file at -n 0 in one run at load 12-15, scaled to that run's CPU


def test_every_multisession_scenario_key_changes_the_simulation_or_is_refused(monkeypatch):
    assert "multisession" in OWN_FILES  # and so left out of the other tracks' file
    check_scenario_keys("multisession", monkeypatch)
