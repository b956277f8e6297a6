"""``bfsitl firmware build --git``: refs resolved to commits, shallow clones cached by commit,
and every failure one clear line.  Against small local repositories (``file://``), no network."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from bfsitl.build import git_source
from bfsitl.build.git_source import (
    COMPLETE_MARKER,
    fetch_git_source,
    is_git_url,
    parse_ls_remote,
    pick_ref,
)
from bfsitl.errors import FirmwareSourceError

pytestmark = pytest.mark.skipif(shutil.which("git") is None, reason="git is not installed")

GIT_ID = ["-c", "user.name=bfsitl tests", "-c", "user.email=tests@bfsitl.invalid"]


def git(cwd: Path, *args: str) -> str:
    return subprocess.run(
        ["git", *GIT_ID, *args], cwd=cwd, check=True, capture_output=True, text=True
    ).stdout.strip()


@pytest.fixture
def remote(tmp_path: Path) -> tuple[str, dict[str, str]]:
    """A repository with two commits on ``main``, a branch, a light and an annotated tag."""
    repo = tmp_path / "remote"
    repo.mkdir()
    git(repo, "init", "--quiet", "--initial-branch", "main")
    (repo / "Makefile").write_text("first\n")
    git(repo, "add", "-A")
    git(repo, "commit", "--quiet", "-m", "first")
    first = git(repo, "rev-parse", "HEAD")
    git(repo, "tag", "light")
    git(repo, "tag", "-a", "annotated", "-m", "an annotated tag")
    git(repo, "branch", "old")
    (repo / "Makefile").write_text("second\n")
    git(repo, "commit", "--quiet", "-am", "second")
    second = git(repo, "rev-parse", "HEAD")
    return f"file://{repo}", {"first": first, "second": second}


def test_what_counts_as_a_git_url() -> None:
    assert is_git_url("https://github.com/betaflight/betaflight")
    assert is_git_url("file:///srv/betaflight.git")
    assert is_git_url("git@github.com:betaflight/betaflight.git")
    assert not is_git_url("betaflight-master.tar.xz")
    assert not is_git_url("/home/me/src/betaflight")
    assert not is_git_url("../betaflight")


def test_ls_remote_lines_and_which_ref_wins() -> None:
    listing = (
        "ref: refs/heads/master\tHEAD\n"
        f"{'a' * 40}\tHEAD\n{'a' * 40}\trefs/heads/master\n"
        f"{'b' * 40}\trefs/tags/master\n{'c' * 40}\trefs/tags/v1\n"
        f"{'d' * 40}\trefs/tags/v1^{{}}\nnot a line\n"
    )
    refs = parse_ls_remote(listing)
    assert refs["HEAD"] == "a" * 40 and len(refs) == 5
    assert pick_ref(refs, None) == ("a" * 40, "HEAD")
    assert pick_ref(refs, "master") == ("a" * 40, "refs/heads/master")  # branch before tag
    assert pick_ref(refs, "v1") == ("d" * 40, "refs/tags/v1")  # the commit, not the tag
    assert pick_ref(refs, "refs/tags/master") == ("b" * 40, "refs/tags/master")
    assert pick_ref(refs, "nope") is None


@pytest.mark.parametrize(
    ("ref", "expected"),
    [
        (None, "second"),
        ("main", "second"),
        ("old", "first"),
        ("light", "first"),
        ("annotated", "first"),
    ],
)
def test_each_kind_of_ref_clones_its_commit(
    remote, tmp_path: Path, ref: str | None, expected: str
) -> None:
    url, commits = remote
    source = fetch_git_source(url, ref, tmp_path / "cache")
    assert source.commit == commits[expected] and source.fetched
    assert source.tree == tmp_path / "cache" / commits[expected]
    assert (source.tree / "Makefile").read_text() == f"{expected}\n"
    assert git(source.tree, "rev-parse", "HEAD") == commits[expected]
    # Shallow: the one commit, no history behind it.
    assert git(source.tree, "rev-list", "--count", "HEAD") == "1"


def test_a_full_commit_hash_is_fetched_as_given(remote, tmp_path: Path) -> None:
    url, commits = remote
    source = fetch_git_source(url, commits["first"], tmp_path / "cache")
    assert (source.tree / "Makefile").read_text() == "first\n"


def test_the_same_commit_again_comes_from_the_cache_without_git_fetching(
    remote, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    url, commits = remote
    lines: list[str] = []
    first = fetch_git_source(url, "main", tmp_path / "cache", note=lines.append)
    assert any(line.startswith("fetching ") for line in lines)
    made = (first.tree / COMPLETE_MARKER).stat().st_mtime_ns

    def no_clone(*_args: object, **_kwargs: object) -> None:
        raise AssertionError("cloned again")

    monkeypatch.setattr(git_source, "_clone_into", no_clone)
    lines.clear()
    again = fetch_git_source(url, "main", tmp_path / "cache", note=lines.append)
    assert again.tree == first.tree and not again.fetched
    assert (again.tree / COMPLETE_MARKER).stat().st_mtime_ns == made
    assert any("is cached" in line for line in lines)


def test_an_interrupted_clone_leaves_nothing_behind(
    remote, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    url, _commits = remote
    real_clone = git_source._clone_into

    def interrupted(
        git: str, url: str, ref: str, commit: str, directory: Path, env: dict[str, str], say: object
    ) -> None:
        real_clone(git, url, ref, commit, directory, env, lambda _line: None)
        raise KeyboardInterrupt  # Ctrl-C after the fetch, before the entry is in place

    monkeypatch.setattr(git_source, "_clone_into", interrupted)
    with pytest.raises(KeyboardInterrupt):
        fetch_git_source(url, "main", tmp_path / "cache")
    assert list((tmp_path / "cache").iterdir()) == []


@pytest.mark.parametrize(
    ("ref", "says"),
    [
        ("no-such-branch", "has no branch, tag or commit 'no-such-branch' (`git ls-remote"),
        ("abc1234", "a short commit hash cannot be fetched shallowly; give all 40 digits"),
    ],
)
def test_a_wrong_ref_is_one_clear_line(remote, tmp_path: Path, ref: str, says: str) -> None:
    url, _commits = remote
    with pytest.raises(FirmwareSourceError) as raised:
        fetch_git_source(url, ref, tmp_path / "cache")
    assert says in str(raised.value) and "\n" not in str(raised.value)
    assert not (tmp_path / "cache").exists()  # nothing written before the ref resolved


def test_an_unreachable_repository_is_one_clear_line(tmp_path: Path) -> None:
    with pytest.raises(FirmwareSourceError) as raised:
        fetch_git_source(f"file://{tmp_path}/nowhere", "master", tmp_path / "cache")
    message = str(raised.value)
    assert message.startswith(f"listing file://{tmp_path}/nowhere failed: fatal:")
    assert "\n" not in message


def test_without_git_the_error_says_how_to_get_it(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(git_source.shutil, "which", lambda _name: None)
    with pytest.raises(FirmwareSourceError, match=r"apt-get install git"):
        fetch_git_source("file:///x", None, tmp_path / "cache")


def test_git_never_waits_for_a_password() -> None:
    env = git_source._git_environment({"PATH": os.environ.get("PATH", "")})
    assert env["GIT_TERMINAL_PROMPT"] == "0"


def test_progress_lines_become_a_few_notes() -> None:
    notes: list[str] = []
    relay = git_source._progress_relay(notes.append)
    for percent in range(0, 101):
        relay(f"Receiving objects:  {percent}% ({percent}/100), 1.00 MiB | 2.00 MiB/s")
    relay("remote: Enumerating objects: 12, done.")
    assert notes == [f"git: receiving objects {p}%" for p in (0, 25, 50, 75, 100)]


def _bfsitl(*args: str, cwd: Path) -> subprocess.CompletedProcess[str]:
    env = {**os.environ, "BFSITL_CACHE_DIR": str(cwd / "fw-cache")}
    return subprocess.run(
        [sys.executable, "-m", "bfsitl.cli.main", *args],
        capture_output=True,
        text=True,
        cwd=cwd,
        env=env,
        timeout=60,
    )


def test_the_command_refuses_ref_without_git_and_git_with_source(tmp_path: Path) -> None:
    alone = _bfsitl("firmware", "build", "--ref", "master", cwd=tmp_path)
    assert alone.returncode == 1 and "--ref goes with --git URL" in alone.stderr
    both = _bfsitl("firmware", "build", "--git", "file:///x", "--source", ".", cwd=tmp_path)
    assert both.returncode == 2 and "not allowed with argument" in both.stderr


def test_the_command_says_a_wrong_ref_in_one_line(remote, tmp_path: Path) -> None:
    url, _commits = remote
    run = _bfsitl("firmware", "build", "--git", url, "--ref", "nope", cwd=tmp_path)
    assert run.returncode == 1 and "Traceback" not in run.stderr
    assert run.stderr.strip().splitlines()[-1] == (
        f"bfsitl: error: {url} has no branch, tag or commit 'nope' (`git ls-remote {url}` "
        f"lists them)"
    )
