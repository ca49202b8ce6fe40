"""Every file the docs, READMEs and docstrings cite exists in the repository.

A citation is a Markdown file name (``docs/tracks/odometry.md``, ``adding-a-track.md``) or a
back-quoted Python file name (``runner.py``, ``benchmarks/tracks/spec.py``). A Markdown name
must resolve from the citing file's folder, the repository root or ``docs/``; a Python file name
must name a file of the repository. Paths outside the repository (``/work/...``) never count:
a reader of the package does not have them.
"""

from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SKIP_DIRS = {".venv", ".git", "__pycache__", "build", "dist"}
OUTPUTS = {"report.md", "leaderboard.md"}  # files exobench writes (a run folder, a leaderboard), not part of the repository
MD = re.compile(r"[\w./-]*[\w-]+\.md\b")
PY = re.compile(r"`{1,2}([\w./-]*\w\.py)`{1,2}")


def _files(root: Path) -> list[Path]:
    return [
        p for p in root.rglob("*")
        if p.is_file() and p.suffix in (".py", ".md") and not SKIP_DIRS & set(p.relative_to(root).parts)
    ]  # fmt: skip


def dangling(text: str, where: Path, root: Path, names: set[str]) -> list[str]:
    """The citations of ``text`` (the content of ``where``) that name no file of ``root``."""
    out = []
    for m in MD.finditer(text):
        ref = m.group(0)
        if ref.rsplit("/", 1)[-1] in OUTPUTS:
            continue
        local = not ref.startswith("/") and any(
            (base / ref).resolve().is_relative_to(root) and (base / ref).is_file() for base in (where.parent, root, root / "docs")
        )
        if not local:
            out.append(ref)
    for m in PY.finditer(text):
        ref = m.group(1)
        if ref.startswith("/") or ref.rsplit("/", 1)[-1] not in names:
            out.append(ref)
    return out


def test_the_checker_finds_what_is_missing_and_accepts_what_exists(tmp_path):
    (tmp_path / "docs").mkdir()
    (tmp_path / "docs" / "guide.md").write_text("x")
    (tmp_path / "pkg").mkdir()
    (tmp_path / "pkg" / "run.py").write_text("x")
    (tmp_path / "outside.md").write_text("x")
    text = "see guide.md, docs/guide.md, ``run.py``, `pkg/run.py` and report.md; not TRACKS.md, `bench.py`, "
    text += f"{tmp_path / 'outside.md'} nor ../elsewhere.md"
    names = {p.name for p in _files(tmp_path)}
    got = dangling(text, tmp_path / "pkg" / "mod.py", tmp_path / "docs", names)
    assert got == ["docs/guide.md", "TRACKS.md", str(tmp_path / "outside.md"), "../elsewhere.md", "bench.py"]
    assert dangling(text, tmp_path / "pkg" / "mod.py", tmp_path, names) == [
        "TRACKS.md", str(tmp_path / "outside.md"), "../elsewhere.md", "bench.py"]


def test_every_cited_file_exists():
    files = _files(ROOT)
    names = {p.name for p in files}
    cited = [p for p in files if p != Path(__file__).resolve()]  # this file's examples are made up
    missing = {
        f"{p.relative_to(ROOT)}: {ref}" for p in cited for ref in dangling(p.read_text(errors="replace"), p, ROOT, names)
    }
    assert not missing, "cited files that do not exist:\n" + "\n".join(sorted(missing))
