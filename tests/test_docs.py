"""The documentation site: a home page, every page in the nav, no reference to files the
repository does not have, and a strict build (CI runs it too)."""

from __future__ import annotations

import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
DOCS = ROOT / "docs"


def _nav_pages() -> set[str]:
    return set(re.findall(r":\s*([\w/.-]+\.md)\s*$", (ROOT / "mkdocs.yml").read_text(), re.M))


def test_every_page_is_in_the_nav_and_the_home_page_shows_a_figure():
    pages = {p.relative_to(DOCS).as_posix() for p in DOCS.rglob("*.md")}
    assert "index.md" in pages
    assert pages == _nav_pages()
    home = (DOCS / "index.md").read_text()
    figures = re.findall(r"!\[[^\]]*\]\(([^)]+)\)", home)
    assert figures and all((DOCS / f).is_file() for f in figures)
    readme = (ROOT / "README.md").read_text()
    commands = re.findall(r"```bash\n(.*?)```", readme, flags=re.S)[:2]
    assert all(c in home for c in commands)  # the README's two commands


def test_no_reference_to_files_outside_the_repository():
    tracked = subprocess.run(
        ["git", "ls-files"], cwd=ROOT, capture_output=True, text=True, check=True
    ).stdout.split()
    if not tracked:
        pytest.skip("not a git checkout")
    for name in tracked:
        if Path(name).suffix in (".md", ".py", ".yml", ".cfg", ".toml"):
            text = (ROOT / name).read_text(encoding="utf-8")
            for missing in ("DESIGN" + ".md", "CONVENTIONS" + ".md"):
                assert missing not in text, f"{name} cites {missing}, which is not in the repo"


@pytest.mark.skipif(
    shutil.which("mkdocs", path=str(Path(sys.executable).parent)) is None,
    reason='mkdocs is not installed (pip install ".[docs]")',
)
def test_site_builds_strictly(tmp_path):
    mkdocs = shutil.which("mkdocs", path=str(Path(sys.executable).parent))
    done = subprocess.run(
        [mkdocs, "build", "--strict", "-q", "-d", str(tmp_path / "site")],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=300,
        env={"NO_MKDOCS_2_WARNING": "1", "PATH": "/usr/bin:/bin"},
    )
    assert done.returncode == 0, done.stderr[-3000:]
    assert (tmp_path / "site" / "index.html").is_file()
