"""The import rule of docs/architecture.md ("Rules"), checked on the source tree."""

import ast
from pathlib import Path

import pytest

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
