"""Test configuration: headless rendering for every test, and the order in which the workers
take the test files."""

import os

import pytest

os.environ.setdefault("MUJOCO_GL", "egl")
os.environ.setdefault("PYOPENGL_PLATFORM", os.environ["MUJOCO_GL"])


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    """The order of the work units of pytest-xdist's workers (``--dist loadfile``: a test file
    each, its module fixtures built once; pyproject's addopts): the files marked
    ``long(seconds)`` first, the longest first, then the others, the one with most tests first
    (xdist's own order, which ``--no-loadscope-reorder`` turns off so that this one holds). A
    file of a minute with few tests comes last in xdist's order, and leaves the other worker
    idle for that minute; longest first, the workers finish within a short file of each other.
    So every file of about 5 CPU-seconds or more carries the mark, with its measured time (one of
    28 CPU-s and three tests left unmarked came last, and its worker ended ~15 s after the other
    in a simulation of ``--dist loadfile`` on a ``-n 0`` run's per-test times).

    Only under xdist: a run in one process keeps the collection order.
    """
    if config.getoption("dist", "no") == "no" and not os.environ.get("PYTEST_XDIST_WORKER"):
        return
    size: dict[str, int] = {}
    first: dict[str, int] = {}
    seconds: dict[str, float] = {}
    for i, item in enumerate(items):
        path = item.nodeid.split("::")[0]
        size[path] = size.get(path, 0) + 1
        first.setdefault(path, i)
        mark = item.get_closest_marker("long")
        if mark is not None:
            seconds[path] = float(mark.kwargs.get("seconds", mark.args[0] if mark.args else 60))

    def unit_order(item: pytest.Item) -> tuple[float, int, int]:
        path = item.nodeid.split("::")[0]
        return -seconds.get(path, 0.0), -size[path], first[path]

    items.sort(key=unit_order)  # stable: a file's tests keep their order
