"""The wheel holds every module: pyproject's package list matches the package's folders.

The repository root is the package ``exobench`` (``package-dir = {"exobench" = "."}``), which
setuptools' package discovery cannot express, so the list in pyproject.toml is written out. An
editable install finds a folder left out of it anyway, a wheel does not: these tests compare
the list with the folders, and the package data with the files, without building anything.
"""

from __future__ import annotations

from pathlib import Path

try:
    import tomllib
except ModuleNotFoundError:  # Python 3.10: tomli, which pytest depends on there, is the same parser
    import tomli as tomllib

ROOT = Path(__file__).resolve().parents[1]
NOT_PACKAGES = {"tests", "docs", "build", "dist", "runs", ".venv", ".git", "__pycache__"}


def package_folders(root: Path) -> dict[str, Path]:
    """Dotted name -> folder of every folder of ``root`` (the package ``exobench``) that holds
    Python modules, outside :data:`NOT_PACKAGES` and the ``*.egg-info`` folders."""
    out = {}
    for path in sorted(root.rglob("*.py")):
        rel = path.parent.relative_to(root)
        if NOT_PACKAGES & set(rel.parts) or any(p.endswith(".egg-info") or p.startswith(".") for p in rel.parts):
            continue
        out[".".join(("exobench", *rel.parts))] = path.parent
    return out


def declared(root: Path) -> dict:
    return tomllib.loads((root / "pyproject.toml").read_text())["tool"]["setuptools"]


def check_packaging(root: Path) -> list[str]:
    """What a wheel of ``root`` would miss or hold in error (empty when nothing)."""
    setup = declared(root)
    folders = package_folders(root)
    listed = set(setup["packages"])
    problems = [f"folder {folders[n].relative_to(root)} ({n}) is not in pyproject's packages" for n in sorted(set(folders) - listed)]
    problems += [f"package {n} in pyproject has no folder with modules" for n in sorted(listed - set(folders))]
    problems += [f"{d.relative_to(root)} has modules but no __init__.py" for d in folders.values() if not (d / "__init__.py").is_file()]
    for package, patterns in setup.get("package-data", {}).items():
        folder = root.joinpath(*package.split(".")[1:])
        problems += [f"package data {package}: {p!r} matches no file" for p in patterns if not any(folder.glob(p))]
    return problems


def _tree(root: Path, packages: list[str], files: list[str], data: dict[str, list[str]] | None = None) -> Path:
    for f in files:
        (root / f).parent.mkdir(parents=True, exist_ok=True)
        (root / f).write_text("")
    setup = f"[tool.setuptools]\npackages = {packages!r}\n".replace("'", '"')
    if data:
        setup += "[tool.setuptools.package-data]\n" + "".join(f'"{k}" = {v!r}\n'.replace("'", '"') for k, v in data.items())
    (root / "pyproject.toml").write_text(setup)
    return root


def test_the_check_names_what_a_wheel_would_miss(tmp_path):
    files = ["__init__.py", "core/__init__.py", "core/a.py", "tests/test_a.py", "docs/conf.py", "README.md"]
    good = _tree(tmp_path / "good", ["exobench", "exobench.core"], files, {"exobench": ["README.md"]})
    assert check_packaging(good) == []
    bad = _tree(tmp_path / "bad", ["exobench", "exobench.gone"], [*files, "new/b.py"], {"exobench.core": ["assets/*"]})
    assert check_packaging(bad) == [
        "folder core (exobench.core) is not in pyproject's packages",
        "folder new (exobench.new) is not in pyproject's packages",
        "package exobench.gone in pyproject has no folder with modules",
        "new has modules but no __init__.py",
        "package data exobench.core: 'assets/*' matches no file",
    ]


def test_pyproject_lists_every_package_folder_and_existing_data():
    assert check_packaging(ROOT) == []
