"""The wheel holds every module: the packages setup.py discovers are the package's folders.

The repository root is the package ``exobench`` (``package-dir = {"exobench" = "."}``);
``setup.py`` names every package folder below it ``exobench.<folder>``. An editable install finds
a folder that is not a package anyway (no ``__init__.py``), a wheel does not: these tests compare
the discovered list with the folders that hold modules, and the package data with the files,
without building anything.
"""

from __future__ import annotations

import importlib.util
from pathlib import Path

try:
    import tomllib
except ModuleNotFoundError:  # Python 3.10: tomli, which pytest depends on there, is the same parser
    import tomli as tomllib

ROOT = Path(__file__).resolve().parents[1]
NOT_PACKAGES = {"tests", "docs", "build", "dist", "runs", ".venv", ".git", "__pycache__"}


def _setup_module():
    spec = importlib.util.spec_from_file_location("exobench_setup", ROOT / "setup.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)  # setup() runs only as __main__
    return module


def package_folders(root: Path) -> dict[str, Path]:
    """Dotted name -> folder of every folder of ``root`` (the package ``exobench``) that holds
    Python modules, outside :data:`NOT_PACKAGES` and hidden or ``*.egg-info`` folders (this
    file's own walk, independent of setuptools)."""
    out = {}
    for path in sorted(root.rglob("*.py")):
        rel = path.parent.relative_to(root)
        if NOT_PACKAGES & set(rel.parts) or any(p.endswith(".egg-info") or p.startswith(".") for p in rel.parts):
            continue
        out[".".join(("exobench", *rel.parts))] = path.parent
    return out


def check_packaging(root: Path) -> list[str]:
    """What a wheel of ``root`` would miss or hold in error (empty when nothing)."""
    folders = package_folders(root)
    found = set(_setup_module().packages(root))
    problems = [f"{folders[n].relative_to(root)} has modules but is not packaged (no __init__.py)" for n in sorted(set(folders) - found)]
    problems += [f"package {n} has no modules" for n in sorted(found - set(folders))]
    data = tomllib.loads((root / "pyproject.toml").read_text()).get("tool", {}).get("setuptools", {}).get("package-data", {})
    for package, patterns in data.items():
        folder = root.joinpath(*package.split(".")[1:])
        problems += [f"package data {package}: {p!r} matches no file" for p in patterns if not any(folder.glob(p))]
    return problems


def _tree(root: Path, files: list[str], data: dict[str, list[str]] | None = None) -> Path:
    for f in files:
        (root / f).parent.mkdir(parents=True, exist_ok=True)
        (root / f).write_text("")
    text = "[tool.setuptools.package-data]\n" + "".join(f'"{k}" = {v!r}\n'.replace("'", '"') for k, v in (data or {}).items())
    (root / "pyproject.toml").write_text(text)
    return root


def test_a_new_folder_is_packaged_and_the_check_names_what_a_wheel_would_miss(tmp_path):
    files = ["__init__.py", "core/__init__.py", "core/a.py", "new/__init__.py", "new/deep/__init__.py",
             "tests/__init__.py", "tests/test_a.py", "docs/conf.py", "README.md"]  # fmt: skip
    good = _tree(tmp_path / "good", files, {"exobench": ["README.md"]})
    assert _setup_module().packages(good) == ["exobench", "exobench.core", "exobench.new", "exobench.new.deep"]
    assert check_packaging(good) == []
    bad = _tree(tmp_path / "bad", [*files, "loose/b.py"], {"exobench.core": ["assets/*"]})
    assert check_packaging(bad) == [
        "loose has modules but is not packaged (no __init__.py)",
        "package data exobench.core: 'assets/*' matches no file",
    ]


def test_every_folder_with_modules_is_packaged_and_the_data_exists():
    assert check_packaging(ROOT) == []
