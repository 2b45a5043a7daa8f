"""The documentation site: a home page, every page in the nav, no reference to files the
repository does not have, and a strict build (CI runs it too)."""

from __future__ import annotations

import re
import shutil
import subprocess
import sys
from html.parser import HTMLParser
from pathlib import Path
from urllib.parse import unquote, urlsplit

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


class _Links(HTMLParser):
    """The hrefs and srcs of one built page, and the ids it defines (anchors)."""

    def __init__(self) -> None:
        super().__init__()
        self.links: list[str] = []
        self.ids: set[str] = set()

    def handle_starttag(self, tag: str, attrs: list[tuple[str, str | None]]) -> None:
        for key, value in attrs:
            if key in ("href", "src") and value:
                self.links.append(value)
            elif key in ("id", "name") and value:
                self.ids.add(value)


def _page(path: Path) -> Path | None:
    """The file a link resolves to in the built site (a folder only through its index.html)."""
    if path.is_dir():
        return path / "index.html" if (path / "index.html").is_file() else None
    return path if path.is_file() else None


def broken_links(site: Path) -> tuple[list[str], list[str]]:
    """Internal links of a built site that resolve to no file or no anchor; external links."""
    pages = {p: _Links() for p in site.rglob("*.html")}
    for page, parser in pages.items():
        parser.feed(page.read_text(encoding="utf-8"))
    broken, external = [], []
    for page, parser in pages.items():
        where = page.relative_to(site).as_posix()
        for link in parser.links:
            parts = urlsplit(link)
            if parts.scheme or parts.netloc:
                if parts.scheme in ("http", "https"):
                    external.append(link)
                continue
            base = site if parts.path.startswith("/") else page.parent  # 404.html's are rooted
            target = page if not parts.path else _page(base / unquote(parts.path).lstrip("/"))
            if target is None:
                broken.append(f"{where}: {link} (no such page)")
            elif parts.fragment and target.suffix == ".html":
                ids = pages[target.resolve()].ids if target.resolve() in pages else set()
                if unquote(parts.fragment) not in ids:
                    broken.append(f"{where}: {link} (no anchor #{parts.fragment})")
    return broken, sorted(set(external))


def test_the_link_checker_finds_a_folder_link_and_a_missing_anchor(tmp_path):
    (tmp_path / "a").mkdir()
    (tmp_path / "a" / "index.html").write_text('<h2 id="here">x</h2><a href="#here">ok</a>')
    (tmp_path / "b").mkdir()
    (tmp_path / "b" / "index.html").write_text(
        '<a href="../a/">ok</a><a href="../a/#here">ok</a><a href="../a/#gone">no anchor</a>'
        '<a href="confirmatory/">folder of b</a><a href="https://example.org/">external</a>'
        '<a href="/a/#here">rooted</a>'
    )
    (tmp_path / "b" / "confirmatory").mkdir()  # a folder without index.html: a 404 when served
    broken, external = broken_links(tmp_path)
    assert broken == [
        "b/index.html: ../a/#gone (no anchor #gone)",
        "b/index.html: confirmatory/ (no such page)",
    ]
    assert external == ["https://example.org/"]


@pytest.mark.skipif(
    shutil.which("mkdocs", path=str(Path(sys.executable).parent)) is None,
    reason='mkdocs is not installed (pip install ".[docs]")',
)
def test_site_builds_strictly_and_its_internal_links_resolve(tmp_path):
    site = tmp_path / "site"
    done = subprocess.run(
        ["bash", str(ROOT / ".ci" / "docs"), str(site)],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=300,
        env={"PATH": "/usr/bin:/bin"},
    )
    assert done.returncode == 0, done.stderr[-3000:]
    assert (site / "index.html").is_file()
    assert 'id="strol_gym.learners.protocol.OnlineRewardLearner"' in (
        site / "api" / "index.html"
    ).read_text(encoding="utf-8")
    broken, external = broken_links(site)
    assert not broken, "\n".join(broken)
    print("external links, listed, not fetched:", *external, sep="\n  ")


# The site says what holds now; how a number was obtained (the runs, their dates, commits and
# machine load) lives in lab/notes/. The pre-registered protocols stay frozen as committed.
FROZEN = ("confirmatory.md", "confirmatory-held-out.md")
AUTHORS_REFS = {"d383bef"}  # the authors' repository: the commit before their logs' removal
HASH = r"(?=[0-9a-f]*\d)(?=[0-9a-f]*[a-f])([0-9a-f]{7,12})"  # hex with a digit and a letter
NOTEBOOK = {
    "an issue number": re.compile(r"\bissues?\s+#?\d+", re.I),
    "a commit hash": re.compile(rf"\bcommits?\s+`?{HASH}\b|`{HASH}\^?`"),
    "a load-average note": re.compile(
        r"\bload(?: average)?\s*(?:of\s*)?[≈~]?\s*\d|\bload average\b", re.I
    ),
    "a lab-notebook stop": re.compile(
        r"\b(?:first|second|third|fourth|fifth|last|previous)\s+stop\b", re.I
    ),
}


def notebook_lines(text: str) -> list[tuple[int, str, str]]:
    """(line number, what, line) for every line of a page that reads like a lab notebook."""
    found = []
    for number, line in enumerate(text.splitlines(), 1):
        for what, pattern in NOTEBOOK.items():
            for match in pattern.finditer(line):
                if any(g in AUTHORS_REFS for g in match.groups()):
                    continue
                found.append((number, what, line.strip()))
    return found


def test_the_notebook_detector_finds_each_kind_and_spares_the_authors_ref():
    text = (
        "fixed in issue 33\nat commit `140c631`\ncode of `a413042` (clean)\n"
        "load average 1.6\nunder load 12\nissue 33's fourth stop\n"
        "git archive `d383bef^` of the authors\nthe robot stops at the plate\n"
    )
    kinds = [what for _, what, _ in notebook_lines(text)]
    assert kinds.count("an issue number") == 2
    assert kinds.count("a commit hash") == 2
    assert kinds.count("a load-average note") == 2
    assert kinds.count("a lab-notebook stop") == 1
    assert all(n <= 6 for n, _, _ in notebook_lines(text))


def test_no_page_reads_like_a_lab_notebook():
    bad = [
        f"{page.relative_to(DOCS)}:{n}: {what}: {line[:100]}"
        for page in sorted(DOCS.rglob("*.md"))
        if page.relative_to(DOCS).as_posix() not in FROZEN
        and not page.relative_to(DOCS).as_posix().startswith("confirmatory/")
        for n, what, line in notebook_lines(page.read_text(encoding="utf-8"))
    ]
    assert not bad, "move these to lab/notes/:\n" + "\n".join(bad)
