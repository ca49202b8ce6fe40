"""Every scenario key of the vio track changes the simulation or is refused
(``test_conformance_scenario_keys.py``, whose check this runs): a file of its own, so that the
workers run it beside the other tracks' keys instead of after them (tests/conftest.py)."""

import pytest
from test_conformance_scenario_keys import OWN_FILES, check_scenario_keys

pytestmark = pytest.mark.long(seconds=25)  # the workers take it first (tests/conftest.py); 25: the file's CPU-s alone at -n 0 (31.1 before the batched footholds)


def test_every_vio_scenario_key_changes_the_simulation_or_is_refused(monkeypatch):
    assert "vio" in OWN_FILES  # and so left out of the other tracks' file
    check_scenario_keys("vio", monkeypatch)
