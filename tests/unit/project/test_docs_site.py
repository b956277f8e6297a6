"""The front door and the docs site: the README stays short, the site builds with every link
resolved (``mkdocs build --strict``), and nothing names a path outside the repository."""

from __future__ import annotations

import importlib.util
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[3]
README_MAX_LINES = 300
#: Text the project reads or shows; a path outside the checkout must not appear in it.
CHECKED = (
    "README.md",
    "Makefile",
    "mkdocs.yml",
    "pyproject.toml",
    "docs",
    "src",
    "tests",
    "benchmarks",
    "tools",
    ".ci",
)
TEXT_SUFFIXES = {".md", ".py", ".toml", ".yml", ".yaml", ".txt", ".c", ".sdf", ""}
# A path to the steering folder beside the clone, spelled out or put together from parts
# (``Path(...).parents[2] / "shared" / "firmware"``).
_OUTSIDE = re.compile(
    r"(\.\./shared\b|(?<![\w.-])shared/(FIRMWARE_FACTS|research|firmware|"
    r"configurator|DESIGN)|[\"']shared[\"']\s*/)"
)


def test_the_readme_is_read_in_five_minutes() -> None:
    lines = (REPO / "README.md").read_text().splitlines()
    assert len(lines) <= README_MAX_LINES, f"README.md has {len(lines)} lines"
    text = "\n".join(lines)
    # The two quick-start commands and master the way users get it.
    assert "make demo" in text and "make test" in text
    assert (
        "bfsitl firmware build --git https://github.com/betaflight/betaflight --ref master" in text
    )


def _text_files() -> list[Path]:
    found = []
    for name in CHECKED:
        path = REPO / name
        candidates = [path] if path.is_file() else sorted(path.rglob("*"))
        for candidate in candidates:
            if (
                candidate.is_file()
                and candidate.suffix in TEXT_SUFFIXES
                and not any(
                    part.endswith(".egg-info") or part == "__pycache__" for part in candidate.parts
                )
                and candidate != Path(__file__).resolve()
            ):
                found.append(candidate)
    return found


def test_nothing_names_a_path_outside_the_repository() -> None:
    offenders = []
    for path in _text_files():
        try:
            text = path.read_text()
        except UnicodeDecodeError:
            continue
        for number, line in enumerate(text.splitlines(), start=1):
            if _OUTSIDE.search(line):
                offenders.append(f"{path.relative_to(REPO)}:{number}: {line.strip()}")
    assert not offenders, "\n".join(offenders)


def test_the_docs_site_builds_strictly(tmp_path: Path) -> None:
    if importlib.util.find_spec("mkdocs") is None:
        if os.environ.get("BFSITL_REQUIRE_SITL") == "1":
            pytest.fail("BFSITL_REQUIRE_SITL=1 but mkdocs is missing: pip install -e '.[docs]'")
        pytest.skip("mkdocs is not installed: pip install -e '.[docs]'")
    env = {**os.environ, "NO_MKDOCS_2_WARNING": "1"}
    run = subprocess.run(
        [sys.executable, "-m", "mkdocs", "build", "--strict", "--site-dir", str(tmp_path / "site")],
        cwd=REPO,
        capture_output=True,
        text=True,
        timeout=300,
        env=env,
    )
    assert run.returncode == 0, run.stdout + run.stderr
    assert (tmp_path / "site" / "index.html").is_file()
    api = (tmp_path / "site" / "api" / "index.html").read_text()
    # The API reference is generated from the docstrings, not written by hand.
    assert "launch_sitl" in api and "fetch_git_source" in api
    # With their Args sections as tables (docstring_style: google): one row per parameter.
    start = api.index('id="bfsitl.autopilot.launch_sitl"')
    table = api[api.index("<table", start) : api.index("</table>", start)]
    assert re.search(r"<td>\s*<code>gps_noise</code>\s*</td>", table), table


def test_the_sites_home_page_is_the_readme() -> None:
    """docs/index.md is the README with its links made relative to docs/: one text, two
    doors (regenerate it from the README when this fails)."""
    readme = (REPO / "README.md").read_text()
    expected = readme.replace("](docs/", "](").replace(
        "The docs site builds from `docs/` with `mkdocs build --strict` "
        "(`pip install -e '.[docs]'`):",
        "Pages of this site:",
    )
    assert (REPO / "docs" / "index.md").read_text() == expected
