"""Temporary directories named for their process: what a killed run left is removed by the
next, and nothing of a live process, a symlink or a name without a pid is touched."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from bfsitl.owned_temp import owned_temp_dir, process_running, remove_stale_dirs
from bfsitl.sitl.firmware import FirmwareBinary
from bfsitl.sitl.process import RUN_DIR_PREFIX, SitlProcess

PREFIX = "bfsitl-test-"


def ended_pid() -> int:
    """The pid of a process that has ended (and been reaped)."""
    done = subprocess.run(
        [sys.executable, "-c", "import os; print(os.getpid())"],
        check=True,
        capture_output=True,
        text=True,
    )
    pid = int(done.stdout)
    assert not process_running(pid)
    return pid


def left_behind(folder: Path, pid: int, prefix: str = PREFIX) -> Path:
    """A directory as a run with ``pid`` leaves it when killed: with a file inside."""
    stale = folder / f"{prefix}{pid}-abc123"
    (stale / "inner").mkdir(parents=True)
    (stale / "inner" / "eeprom.bin").write_bytes(b"\xff" * 16)
    return stale


def test_a_new_directory_names_its_process_and_removes_a_dead_ones(tmp_path: Path) -> None:
    stale = left_behind(tmp_path, ended_pid())
    made = owned_temp_dir(PREFIX, tmp_path)
    assert made.is_dir() and not any(made.iterdir())
    assert made.name.startswith(f"{PREFIX}{os.getpid()}-")
    assert not stale.exists()


def test_a_live_process_a_foreign_name_a_file_and_a_symlink_are_left(tmp_path: Path) -> None:
    dead = ended_pid()
    live = left_behind(tmp_path, os.getpid())
    parent = left_behind(tmp_path, os.getppid())
    foreign = tmp_path / f"{PREFIX}notapid-x"
    foreign.mkdir()
    a_file = tmp_path / f"{PREFIX}{dead}-file"
    a_file.write_text("not a directory")
    target = tmp_path / "elsewhere"
    target.mkdir()
    link = tmp_path / f"{PREFIX}{dead}-link"
    link.symlink_to(target)
    other_kind = left_behind(tmp_path, dead, prefix="bfsitl-other-")
    assert remove_stale_dirs(PREFIX, tmp_path) == []
    for kept in (live, parent, foreign, a_file, link, target, other_kind):
        assert kept.exists() or kept.is_symlink()


def test_only_the_dead_are_removed_and_named(tmp_path: Path) -> None:
    dead = left_behind(tmp_path, ended_pid())
    live = left_behind(tmp_path, os.getpid())
    assert remove_stale_dirs(PREFIX, tmp_path) == [dead]
    assert live.exists() and not dead.exists()


def test_a_missing_folder_is_nothing_to_remove(tmp_path: Path) -> None:
    assert remove_stale_dirs(PREFIX, tmp_path / "absent") == []


def test_no_pid_of_its_own_is_never_called_gone() -> None:
    assert process_running(0) and process_running(-1)


def test_a_sitl_run_directory_is_owned_and_clears_a_killed_runs(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv("TMPDIR", str(tmp_path))
    monkeypatch.setattr("tempfile.tempdir", None)  # read TMPDIR again
    stale = left_behind(tmp_path, ended_pid(), prefix=RUN_DIR_PREFIX)
    binary = tmp_path / "betaflight_4.6.0_SITL"
    binary.write_bytes(b"\x00")
    process = SitlProcess(FirmwareBinary(binary, "test"))
    try:
        assert process.workdir.parent == tmp_path
        assert process.workdir.name.startswith(f"{RUN_DIR_PREFIX}{os.getpid()}-")
        assert not stale.exists()
    finally:
        process.stop()
    assert not process.workdir.exists()
