"""The docs' sample outputs are made by tools/regenerate_docs.py: every marked block names an
output and every output has a block, the block editing touches only what it marks, and the
outputs that need no firmware are what the commands print today (a change to such a command's
output fails here until the docs are made again)."""

from __future__ import annotations

import contextlib
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[3]
sys.path.insert(0, str(REPO / "tools"))

import docs_figures  # noqa: E402
import docs_outputs  # noqa: E402
import regenerate_docs  # noqa: E402
from docs_running import Context  # noqa: E402


@pytest.fixture
def context(tmp_path: Path) -> Iterator[Context]:
    with contextlib.ExitStack() as stack:
        yield Context("4.6.0-gps-lockstep", "master-lockstep", tmp_path, None, stack)


def test_every_marked_block_names_an_output_and_every_output_has_one() -> None:
    assert docs_outputs.marker_problems() == []
    assert regenerate_docs.main(["--check"]) == 0


def test_a_figure_and_an_output_never_share_a_name() -> None:
    names = [item.name for item in regenerate_docs.ALL]
    assert len(names) == len(set(names))
    assert len(docs_figures.FIGURES) + len(docs_outputs.OUTPUTS) == len(names)


PAGE = """# A page

<!-- output: one -->
```
old one
```

```
written by hand
```

<!-- output: two -->
```text
old two
```
"""


def test_filling_a_block_changes_that_block_only() -> None:
    filled = docs_outputs.fill(PAGE, "one", "new one\nsecond line")
    assert docs_outputs.block_text(filled, "one") == ["new one\nsecond line"]
    assert docs_outputs.block_text(filled, "two") == ["old two"]
    assert "written by hand" in filled
    assert docs_outputs.fill(filled, "one", "old one") == PAGE
    assert docs_outputs.markers(PAGE) == ["one", "two"]


@pytest.mark.parametrize(
    ("page", "problem"),
    [
        ("<!-- output: one -->\ntext\n", "is not followed by a ``` block"),
        ("<!-- output: one -->\n```\nnever closed\n", "is not closed"),
    ],
)
def test_a_marker_without_its_block_is_refused(page: str, problem: str) -> None:
    with pytest.raises(ValueError, match=problem):
        docs_outputs.fill(page, "one", "text")


def test_an_unknown_marker_and_an_unshown_output_are_problems(
    monkeypatch: pytest.MonkeyPatch, tmp_path: Path
) -> None:
    (tmp_path / "docs").mkdir()
    (tmp_path / "README.md").write_text(PAGE)
    monkeypatch.setattr(docs_outputs, "REPO", tmp_path)
    problems = docs_outputs.marker_problems()
    assert "README.md: <!-- output: one --> names no output" in problems
    assert "no page shows the output vehicle-list" in problems


def test_runs_of_dropped_lines_read_as_one_ellipsis() -> None:
    lines = ["keep 1", "drop", "drop", "keep 2", "drop"]
    assert docs_outputs.elide(lines, lambda line: line == "drop") == "keep 1\n...\nkeep 2\n..."


def test_a_command_is_quoted_as_the_page_shows_it() -> None:
    argv = [sys.executable, "-m", "bfsitl.cli.main", "fly", "--b-cli", "set f_roll = 0"]
    assert docs_outputs.shown(argv) == "$ bfsitl fly --b-cli 'set f_roll = 0'"
    bench = [sys.executable, str(REPO / "benchmarks" / "vehicles.py")]
    assert docs_outputs.shown(bench) == "$ python benchmarks/vehicles.py"


@pytest.mark.parametrize(
    "output", [o for o in docs_outputs.OUTPUTS if not o.needs], ids=lambda o: o.name
)
def test_an_output_that_needs_no_firmware_is_what_the_command_prints(
    output: docs_outputs.Output, context: Context, tmp_path: Path
) -> None:
    made = output.make(context, tmp_path).rstrip("\n")
    pages = docs_outputs.pages_with(output.name)
    assert pages
    for page in pages:
        shown = docs_outputs.block_text((REPO / page).read_text(), output.name)
        assert shown == [made] * len(shown), (
            f"{page}'s block {output.name} is stale: python tools/regenerate_docs.py "
            f"--only {output.name}"
        )


def test_regenerating_writes_the_block_and_the_home_page_elsewhere(tmp_path: Path) -> None:
    """--out elsewhere: the page is copied there and filled; the repository is untouched."""
    before = (REPO / "docs" / "vehicles.md").read_text()
    (tmp_path / "README.md").write_text("see [a page](docs/vehicles.md)\n")
    assert regenerate_docs.main(["--only", "vehicle-list", "--out", str(tmp_path)]) == 0
    written = (tmp_path / "docs" / "vehicles.md").read_text()
    assert docs_outputs.block_text(written, "vehicle-list")[0].startswith("NAME ")
    assert (tmp_path / "docs" / "index.md").read_text() == "see [a page](vehicles.md)\n"
    assert (REPO / "docs" / "vehicles.md").read_text() == before
