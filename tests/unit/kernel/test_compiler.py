"""Building the compiled physics: a missing or failing C compiler is a KernelUnavailableError
that says what to install, where a user meets it (a simulator, bfsitl fly, bfsitl doctor); a
build lands whole under its hash's name in the cache."""

from __future__ import annotations

import ctypes
from pathlib import Path

import pytest

from bfsitl.errors import KernelUnavailableError
from bfsitl.kernel import compiler


def test_no_compiler_says_what_to_install(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    monkeypatch.delenv("CC", raising=False)
    monkeypatch.setenv("PATH", str(tmp_path))  # nothing to run in it
    with pytest.raises(KernelUnavailableError, match=r"no C compiler.*apt-get install gcc"):
        compiler.build_kernel(tmp_path / "kernel.so")
    assert not list(tmp_path.iterdir())


def no_compiler_anywhere(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    """A machine without a C compiler and without a built library in its cache."""
    monkeypatch.delenv("CC", raising=False)
    monkeypatch.setenv("PATH", str(tmp_path / "empty"))
    monkeypatch.setenv("BFSITL_CACHE_DIR", str(tmp_path / "cache"))
    monkeypatch.setattr(compiler, "_library", None)
    monkeypatch.setattr(compiler, "_failure", None)


def test_a_simulator_without_a_compiler_says_what_to_install(
    monkeypatch: pytest.MonkeyPatch, tmp_path: Path
) -> None:
    from bfsitl.physics import Simulator

    no_compiler_anywhere(monkeypatch, tmp_path)
    with pytest.raises(KernelUnavailableError, match=r"apt-get install gcc"):
        Simulator()


def test_a_session_without_a_compiler_says_what_to_install(
    monkeypatch: pytest.MonkeyPatch, tmp_path: Path
) -> None:
    from bfsitl.backend.factory import make_simulator
    from bfsitl.backend.options import World

    no_compiler_anywhere(monkeypatch, tmp_path)
    # What `bfsitl fly` and every session build first for the embedded physics.
    with pytest.raises(KernelUnavailableError, match=r"no C compiler.*apt-get install gcc"):
        make_simulator(World())


def test_a_compiler_that_fails_is_reported_with_its_words(
    monkeypatch: pytest.MonkeyPatch, tmp_path: Path
) -> None:
    script = tmp_path / "broken-cc"
    script.write_text("#!/bin/sh\necho 'broken-cc: no, not today' >&2\nexit 3\n")
    script.chmod(0o755)
    monkeypatch.setenv("CC", str(script))
    with pytest.raises(KernelUnavailableError, match=r"(?s)exited 3.*not today"):
        compiler.build_kernel(tmp_path / "out" / "kernel.so")
    assert not list((tmp_path / "out").iterdir())  # no half-written library left


@pytest.mark.skipif(compiler.find_compiler() is None, reason="no C compiler here")
def test_a_build_is_cached_under_its_hash_and_loads(
    monkeypatch: pytest.MonkeyPatch, tmp_path: Path
) -> None:
    monkeypatch.setenv("BFSITL_CACHE_DIR", str(tmp_path))
    target = compiler.kernel_path()
    assert target.parent == tmp_path / "kernel" and compiler.kernel_key() in target.name
    compiler.build_kernel(target)
    library = ctypes.CDLL(str(target))
    assert library.bk_sim_size() > 0 and library.bk_lockstep_size() > 0
    assert [p.name for p in target.parent.iterdir()] == [target.name]


def test_the_sources_are_shipped_beside_the_loader() -> None:
    names = {p.name for p in compiler.kernel_sources()}
    assert {"physics.c", "physics.h", "lockstep_loop.c"} <= names


def test_doctor_fails_without_a_compiler_and_says_what_to_install(
    monkeypatch: pytest.MonkeyPatch, tmp_path: Path
) -> None:
    from bfsitl.cli.doctor import physics_check

    no_compiler_anywhere(monkeypatch, tmp_path)
    finding = physics_check()
    assert finding.status == "FAIL" and "apt-get install gcc" in finding.detail
    monkeypatch.setattr(compiler, "load_kernel", lambda: None)
    finding = physics_check()
    assert finding.status == "ok" and "kernel" in finding.detail
