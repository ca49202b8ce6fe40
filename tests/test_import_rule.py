"""The import rule of docs/architecture.md ("Rules"), checked on the source tree."""

import ast
from pathlib import Path

import pytest

pytestmark = pytest.mark.long(seconds=5)  # the workers take it first (tests/conftest.py); 5: the file at -n 0 in one run at load 12-15, scaled to that run's CPU

ROOT = Path(__file__).resolve().parents[1]
FORBIDDEN = {
    "core": ("mujoco", "dm_control", "open3d", "pinocchio", "gtsam", "rerun", "scipy", "matplotlib",
             "exobench.models", "exobench.envs", "exobench.perception", "exobench.mapping",
             "exobench.benchmarks"),
    "perception": ("mujoco", "dm_control", "exobench.envs", "exobench.models", "exobench.benchmarks", "exobench.mapping"),
    "mapping": ("mujoco", "dm_control", "exobench.envs", "exobench.models", "exobench.benchmarks"),
    "models": ("exobench.envs", "exobench.perception", "exobench.mapping", "exobench.benchmarks"),
    "envs": ("exobench.perception", "exobench.mapping", "exobench.benchmarks"),
}


def _imports(path: Path, package: str) -> set[str]:
    tree = ast.parse(path.read_text())
    names: set[str] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            names.update(a.name for a in node.names)
        elif isinstance(node, ast.ImportFrom):
            if node.level:  # relative import: resolve against the package
                parts = ["exobench", *path.relative_to(ROOT).parent.parts][: len(path.relative_to(ROOT).parent.parts) + 2 - node.level]
                names.add(".".join(parts + ([node.module] if node.module else [])))
            elif node.module:
                names.add(node.module)
    return names


@pytest.mark.parametrize("package", sorted(FORBIDDEN))
def test_package_imports_respect_the_rule(package):
    bad = []
    for path in sorted((ROOT / package).rglob("*.py")):
        for name in _imports(path, package):
            for prefix in FORBIDDEN[package]:
                if name == prefix or name.startswith(prefix + "."):
                    bad.append(f"{path.relative_to(ROOT)} imports {name}")
    assert not bad, "\n".join(bad)


def test_nothing_outside_benchmarks_and_tests_imports_benchmarks():
    bad = []
    for package in ("core", "models", "envs", "perception", "mapping"):
        for path in (ROOT / package).rglob("*.py"):
            if any(n.startswith("exobench.benchmarks") for n in _imports(path, package)):
                bad.append(str(path.relative_to(ROOT)))
    assert not bad


def test_rule_checker_detects_a_violation(tmp_path):
    # the checker itself must be able to fail
    f = tmp_path / "x.py"
    f.write_text("import mujoco\nfrom exobench.envs import sim\n")
    assert {"mujoco", "exobench.envs"} <= _imports(f, "perception")


GPL_MODULES = ("pyorbslam3",)  # docs/architecture.md: GPL peers run in a separate process, never imported
WORKER = ROOT / "mapping" / "odometry" / "orbslam3" / "orbslam3-worker.py"


def test_no_exobench_module_imports_a_gpl_peer():
    bad = []
    for path in sorted(ROOT.rglob("*.py")):
        rel = path.relative_to(ROOT)
        if rel.parts[0] in ("tests", ".venv", "build") or path == WORKER:
            continue
        names = _imports(path, rel.parts[0])
        bad += [f"{rel} imports {n}" for n in names for m in GPL_MODULES if n == m or n.startswith(m + ".")]
    assert not bad, "\n".join(bad)
    # the worker script does, and cannot be imported as a module: its name is not an identifier
    assert "pyorbslam3" in _imports(WORKER, "mapping")
    assert not WORKER.stem.isidentifier()


def test_importing_the_orbslam3_adapter_and_the_harness_loads_no_gpl_module():
    import subprocess
    import sys

    code = ("import sys, exobench.mapping.odometry.orbslam3, exobench.benchmarks.cli, exobench.benchmarks.orbvoc, "
            f"exobench.benchmarks.runner; print(sorted(m for m in sys.modules if m.split('.')[0] in {GPL_MODULES!r}))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "[]"


def test_gpl_rule_checker_detects_a_violation(tmp_path):
    f = tmp_path / "x.py"
    f.write_text("from pyorbslam3 import Slam\n")
    assert "pyorbslam3" in _imports(f, "mapping")
