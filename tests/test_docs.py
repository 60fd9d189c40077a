"""The docs as a manual: links between them resolve, and manual pages carry no dates, commit
hashes or links outside the repository (docs/design.md; history lives in docs/decisions/)."""

import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
MANUAL = sorted([ROOT / "README.md", ROOT / "CHANGELOG.md", *(ROOT / "docs").glob("*.md"),
                 *(ROOT / "docs" / "decisions").glob("*.md")])
LINKED = sorted(set(MANUAL) | set((ROOT / "benchmarks").rglob("*.md")))
LINK = re.compile(r"\]\(([^)\s]+)\)")
DATE = re.compile(r"\b20\d\d-\d\d(-\d\d)?\b|\b\d{1,2} (Jan|Feb|Mar|Apr|May|Jun|Jul|Aug|Sep|Oct|Nov|Dec)[a-z]* 20\d\d\b")
HASH = re.compile(r"\b(?=[0-9a-f]*\d)(?=[0-9a-f]*[a-f])[0-9a-f]{7,40}\b")


def github_slug(heading: str) -> str:
    """The anchor GitHub gives a Markdown heading."""
    return re.sub(r"[^\w\- ]", "", heading.strip().lower()).replace(" ", "-")


def anchors(path: Path) -> set[str]:
    """Anchors of every heading outside code blocks (repeated headings get -1, -2, ...)."""
    found, seen, in_code = set(), {}, False
    for line in path.read_text().splitlines():
        if line.startswith("```"):
            in_code = not in_code
        heading = None if in_code else re.match(r"#{1,6} (.*)", line)
        if heading:
            slug = github_slug(heading.group(1))
            found.add(slug if slug not in seen else f"{slug}-{seen[slug]}")
            seen[slug] = seen.get(slug, 0) + 1
    return found


def test_slug_follows_github():
    assert github_slug("Work–precision") == "workprecision"
    assert github_slug("Runs and case files (`plugsim run`, `engine.run_case`)") == \
        "runs-and-case-files-plugsim-run-enginerun_case"


@pytest.mark.parametrize("path", LINKED, ids=lambda p: str(p.relative_to(ROOT)))
def test_relative_links_resolve(path):
    broken = []
    for link in LINK.findall(path.read_text()):
        if re.match(r"[a-z]+:", link):
            continue
        target, _, anchor = link.partition("#")
        file = (path.parent / target).resolve() if target else path
        if not file.exists():
            broken.append(link)
        elif anchor and file.suffix == ".md" and anchor not in anchors(file):
            broken.append(link)
    assert not broken, f"{path.relative_to(ROOT)}: links that do not resolve: {broken}"


@pytest.mark.parametrize("path", MANUAL, ids=lambda p: str(p.relative_to(ROOT)))
def test_manual_pages_have_no_dates_hashes_or_outside_links(path):
    text = path.read_text()
    assert not DATE.search(text), f"{path.relative_to(ROOT)}: a date: {DATE.search(text).group(0)}"
    assert not HASH.search(text), f"{path.relative_to(ROOT)}: a commit hash: {HASH.search(text).group(0)}"
    assert "../shared" not in text, f"{path.relative_to(ROOT)}: a link outside the repository"


def test_decision_records_are_indexed_with_their_sections():
    index = (ROOT / "docs" / "decisions" / "README.md").read_text()
    records = sorted((ROOT / "docs" / "decisions").glob("[0-9][0-9][0-9][0-9]-*.md"))
    assert records
    for number, record in enumerate(records, start=1):
        assert record.name.startswith(f"{number:04d}-"), f"records are numbered without gaps: {record.name}"
        assert f"({record.name})" in index, f"{record.name} is not in docs/decisions/README.md"
        text = record.read_text()
        assert text.startswith(f"# {number:04d} ")
        for section in ("## Context", "## Decision", "## Evidence", "## Consequences"):
            assert section in text, f"{record.name} lacks {section}"
