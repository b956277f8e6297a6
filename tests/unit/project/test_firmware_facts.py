"""Citations of firmware facts point into the repository: at a section of
``docs/firmware-facts.md``, never at notes that live beside the checkout (a facts file, numbered
research sections, the steering folder), which a reader of the repository cannot open."""

from __future__ import annotations

import re
import unicodedata
from pathlib import Path

REPO = Path(__file__).resolve().parents[3]
FACTS_PAGE = REPO / "docs" / "firmware-facts.md"
#: Where code, tests and docs cite facts.
SCANNED = ("src", "tests", "benchmarks", "examples", "tools", "docs")
SUFFIXES = {".py", ".md", ".toml", ".c", ".h", ".sdf", ".txt", ".yml", ".yaml"}
#: Files that spell the forbidden forms out in order to forbid them.
DESCRIBES_THE_RULE = {
    Path(__file__).resolve(),
    REPO / "tests" / "unit" / "project" / "test_docs_site.py",
}
# A citation of notes outside the repository: the facts file, a numbered section of the
# research notes ("research 3.5", "Research 4.5:", "research §2.9"), the notes by name, or the
# folder beside the clone.
_OUTSIDE_CITATION = re.compile(
    r"(?-i:FIRMWARE_FACTS)"
    r"|\bresearch\s+(?:§\s*)?\d+(?:\.\d+)*"
    r"|\bresearch notes\b"
    r"|\bthe research(?:'s)?\b"
    r"|physics-and-timing\.md|msp-and-cli\.md"
    r"|\.\./shared\b",
    re.IGNORECASE,
)
_FACTS_CITATION = re.compile(r"firmware-facts\.md#([A-Za-z0-9_-]+)")
_HEADING = re.compile(r"^#{1,6}\s+(.*?)\s*(?:\{#([A-Za-z0-9_-]+)\})?\s*$")


def _scanned_files() -> list[Path]:
    found = []
    for name in SCANNED:
        root = REPO / name
        if not root.is_dir():
            continue
        for path in sorted(root.rglob("*")):
            if (
                path.is_file()
                and path.suffix in SUFFIXES
                and "__pycache__" not in path.parts
                and not any(part.endswith(".egg-info") for part in path.parts)
                and path.resolve() not in DESCRIBES_THE_RULE
            ):
                found.append(path)
    return found


def _lines(path: Path) -> list[tuple[int, str]]:
    try:
        return list(enumerate(path.read_text().splitlines(), start=1))
    except UnicodeDecodeError:
        return []


def _slug(text: str) -> str:
    """The anchor mkdocs' toc extension gives a heading without an explicit ``{#id}``."""
    text = unicodedata.normalize("NFKD", text).encode("ascii", "ignore").decode("ascii")
    text = re.sub(r"[^\w\s-]", "", text).strip().lower()
    return re.sub(r"[-\s]+", "-", text)


def page_anchors(markdown: str) -> list[str]:
    """Every heading anchor of a page, outside fenced code."""
    anchors, fenced = [], False
    for line in markdown.splitlines():
        if line.lstrip().startswith("```"):
            fenced = not fenced
            continue
        match = None if fenced else _HEADING.match(line)
        if match:
            anchors.append(match.group(2) or _slug(match.group(1)))
    return anchors


def outside_citations(files: list[Path], root: Path = REPO) -> list[str]:
    return [
        f"{path.relative_to(root)}:{number}: {line.strip()}"
        for path in files
        for number, line in _lines(path)
        if _OUTSIDE_CITATION.search(line)
    ]


def dangling_facts_citations(files: list[Path], anchors: set[str], root: Path = REPO) -> list[str]:
    return [
        f"{path.relative_to(root)}:{number}: #{anchor}"
        for path in files
        for number, line in _lines(path)
        for anchor in _FACTS_CITATION.findall(line)
        if anchor not in anchors
    ]


def test_nothing_cites_notes_outside_the_repository() -> None:
    offenders = outside_citations(_scanned_files())
    assert not offenders, (
        "cite a section of docs/firmware-facts.md instead "
        "(write the fact there first):\n" + "\n".join(offenders)
    )


def test_every_cited_section_of_the_facts_page_exists() -> None:
    anchors = page_anchors(FACTS_PAGE.read_text())
    duplicated = sorted({anchor for anchor in anchors if anchors.count(anchor) > 1})
    assert not duplicated, f"docs/firmware-facts.md repeats anchors: {duplicated}"
    files = _scanned_files()
    cited = [
        anchor
        for path in files
        for _, line in _lines(path)
        for anchor in _FACTS_CITATION.findall(line)
    ]
    assert len(cited) >= 20, "the scan found too few citations of the facts page to be working"
    dangling = dangling_facts_citations(files, set(anchors))
    assert not dangling, (
        "these sections are not on docs/firmware-facts.md (renamed? rename the "
        "citations too):\n" + "\n".join(dangling)
    )


def test_the_checks_catch_what_they_are_for(tmp_path: Path) -> None:
    """Each check fails on the mistake it exists for (so a broken pattern cannot pass quietly)."""
    page = (
        "# Facts\n\n## Packets {#packets}\n\n## Plain heading, no id\n\n"
        "```\n## not a heading\n```\n"
    )
    assert page_anchors(page) == ["facts", "packets", "plain-heading-no-id"]
    source = tmp_path / "example.py"
    source.write_text(
        "# kept: docs/firmware-facts.md#packets and docs/firmware-facts.md#plain-heading-no-id\n"
        "# renamed: docs/firmware-facts.md#packet-layout\n"
        "# (research 3.5)\n# Research 4.5: mu = 1\n# research §2.9\n"
        '# FIRMWARE_FACTS.md "Arming"\n'
        "# see ../"
        "shared/notes\n"  # split, or test_docs_site would flag this file
        "# the research's 50 N s/m\n"
        "# research/physics-and-timing.md\n# the research notes, appendix A\n"
        "# docs/research/scenarios-groundwork.md is in the repository\n"
    )
    outside = outside_citations([source], tmp_path)
    dangling = dangling_facts_citations([source], set(page_anchors(page)), tmp_path)
    assert [entry.split(":")[1] for entry in outside] == [str(n) for n in range(3, 11)]
    assert dangling == ["example.py:2: #packet-layout"]
