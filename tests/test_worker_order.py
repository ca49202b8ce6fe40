"""The order in which pytest-xdist's workers take the test files (tests/conftest.py): the files
marked ``long`` first, the longest first, then the others by their number of tests; in one
process, the collection order."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import conftest
import pytest


@dataclass
class _Item:
    nodeid: str
    marks: dict[str, Any] = field(default_factory=dict)

    def get_closest_marker(self, name: str) -> Any:
        return self.marks.get(name)


@dataclass
class _Config:
    dist: str

    def getoption(self, name: str, default: Any = None) -> Any:
        return self.dist if name == "dist" else default


def _items() -> list[_Item]:
    short = [_Item(f"tests/a.py::t{i}") for i in range(3)]
    many = [_Item(f"tests/d.py::t{i}") for i in range(5)]
    return [*short, _Item("tests/b.py::t", {"long": pytest.mark.long(seconds=30).mark}),
            _Item("tests/c.py::t", {"long": pytest.mark.long(seconds=90).mark}), *many]  # fmt: skip


def test_long_files_first_longest_first_then_most_tests(monkeypatch):
    monkeypatch.delenv("PYTEST_XDIST_WORKER", raising=False)
    items = _items()
    conftest.pytest_collection_modifyitems(_Config("loadfile"), items)
    assert [i.nodeid for i in items] == ["tests/c.py::t", "tests/b.py::t", *(f"tests/d.py::t{i}" for i in range(5)),
                                         *(f"tests/a.py::t{i}" for i in range(3))]  # fmt: skip


def test_a_worker_orders_as_its_controller(monkeypatch):
    """xdist sets a worker's own ``dist`` to "no"; every worker must still order the same way."""
    monkeypatch.setenv("PYTEST_XDIST_WORKER", "gw1")
    items = _items()
    conftest.pytest_collection_modifyitems(_Config("no"), items)
    assert [i.nodeid for i in items][:2] == ["tests/c.py::t", "tests/b.py::t"]


def test_one_process_keeps_the_collection_order(monkeypatch):
    monkeypatch.delenv("PYTEST_XDIST_WORKER", raising=False)
    items = _items()
    before = [i.nodeid for i in items]
    conftest.pytest_collection_modifyitems(_Config("no"), items)
    assert [i.nodeid for i in items] == before
