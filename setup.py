"""The package list of the wheel, discovered: every folder below the repository root that is a
package (has an ``__init__.py``), as ``exobench.<folder>``.

The repository root is the package ``exobench`` (``package-dir`` in pyproject.toml, where the
rest of the configuration is). setuptools' own discovery would name the folders ``core``,
``envs``, ... at the top of site-packages; this names them under ``exobench``, so a new folder is
packaged without a line anywhere. ``tests/test_packaging.py`` checks the result.
"""

from __future__ import annotations

from pathlib import Path

from setuptools import find_packages, setup
from setuptools.command.build_py import build_py

NOT_PACKAGES = ("tests", "tests.*", "docs", "docs.*", "build", "build.*", "dist", "runs")


def packages(root: str | Path = ".") -> list[str]:
    """``exobench`` and every package folder below ``root`` as ``exobench.<dotted path>``."""
    return ["exobench", *(f"exobench.{p}" for p in sorted(find_packages(str(root), exclude=NOT_PACKAGES)))]


class BuildPy(build_py):
    """build_py without this file: the root folder is the package, and setup.py is not one of its modules."""

    def find_package_modules(self, package: str, package_dir: str) -> list[tuple[str, str, str]]:
        modules = super().find_package_modules(package, package_dir)
        return [m for m in modules if (m[0], m[1]) != ("exobench", "setup")]


if __name__ == "__main__":
    setup(packages=packages(Path(__file__).resolve().parent), cmdclass={"build_py": BuildPy})
