"""envs/motion imports in one direction: leg kinematics, then motions, swings, steps, climbing and
walking, then the locomotion track's additions. A module may import only modules of lower layers
(not of its own layer, not of a higher one, not even inside a function)."""

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
MOTION = ROOT / "envs" / "motion"
PACKAGE = "exobench.envs.motion"
LAYERS = (
    ("kinematics", "route"),
    ("motion", "footholds"),
    ("swing",),
    ("step",),
    ("climb", "walk"),
    ("view", "pedestrians", "odometry"),
)
LAYER = {name: i for i, names in enumerate(LAYERS) for name in names}


def _motion_imports(path: Path) -> set[str]:
    """Modules of envs/motion that ``path`` imports (relative or absolute, anywhere in the file)."""
    out: set[str] = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom):
            if node.level == 1:  # from .x import y / from . import x
                mods = [node.module] if node.module else [a.name for a in node.names]
            elif node.level == 0 and node.module and node.module.startswith(PACKAGE):
                rest = node.module[len(PACKAGE) :].lstrip(".")
                mods = [rest] if rest else [a.name for a in node.names]
            else:
                continue
            out.update(m.split(".")[0] for m in mods)
        elif isinstance(node, ast.Import):
            for a in node.names:
                if a.name.startswith(PACKAGE + "."):
                    out.add(a.name[len(PACKAGE) + 1 :].split(".")[0])
    return out


def test_every_module_has_a_layer():
    modules = {p.stem for p in MOTION.glob("*.py")} - {"__init__"}
    assert modules == set(LAYER), "add new modules of envs/motion to LAYERS"


def test_modules_import_only_lower_layers():
    bad = []
    for path in sorted(MOTION.glob("*.py")):
        if path.stem == "__init__":
            continue
        for name in sorted(_motion_imports(path)):
            if name not in LAYER or LAYER[name] >= LAYER[path.stem]:
                bad.append(f"envs/motion/{path.name} (layer {LAYER[path.stem]}) imports {name} (layer {LAYER.get(name)})")
    assert not bad, "\n".join(bad)


def test_the_checker_sees_imports_inside_functions(tmp_path):
    f = tmp_path / "kinematics.py"
    f.write_text("def f():\n    from .walk import plan_walk\n    import exobench.envs.motion.climb\n")
    assert _motion_imports(f) == {"walk", "climb"}


def test_motion_does_not_import_the_simulators_or_the_gym_environment():
    for path in MOTION.glob("*.py"):
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.ImportFrom) and node.level == 2:
                assert node.module == "terrain", f"envs/motion/{path.name} imports ..{node.module}"
