"""Building the compiled kernel: a missing or failing C compiler is a KernelUnavailableError
that says what to do (and the pure-Python step goes on without it); a build lands whole
under its hash's name in the cache."""

from __future__ import annotations

import ctypes
from pathlib import Path

import pytest

from bfsitl.errors import KernelUnavailableError
from bfsitl.kernel import compiler


def test_no_compiler_says_what_to_install(monkeypatch: pytest.MonkeyPatch,
                                          tmp_path: Path) -> None:
    monkeypatch.delenv("CC", raising=False)
    monkeypatch.setenv("PATH", str(tmp_path))  # nothing to run in it
    with pytest.raises(KernelUnavailableError, match=r"no C compiler.*apt install gcc.*python"):
        compiler.build_kernel(tmp_path / "kernel.so")
    assert not list(tmp_path.iterdir())


def test_a_compiler_that_fails_is_reported_with_its_words(monkeypatch: pytest.MonkeyPatch,
                                                          tmp_path: Path) -> None:
    script = tmp_path / "broken-cc"
    script.write_text("#!/bin/sh\necho 'broken-cc: no, not today' >&2\nexit 3\n")
    script.chmod(0o755)
    monkeypatch.setenv("CC", str(script))
    with pytest.raises(KernelUnavailableError, match=r"(?s)exited 3.*not today"):
        compiler.build_kernel(tmp_path / "out" / "kernel.so")
    assert not list((tmp_path / "out").iterdir())  # no half-written library left


@pytest.mark.skipif(compiler.find_compiler() is None, reason="no C compiler here")
def test_a_build_is_cached_under_its_hash_and_loads(monkeypatch: pytest.MonkeyPatch,
                                                   tmp_path: Path) -> None:
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


def test_doctor_says_whether_lockstep_runs_get_the_compiled_step(
        monkeypatch: pytest.MonkeyPatch) -> None:
    from bfsitl.cli.doctor import compiled_step_check

    def no_compiler() -> None:
        raise KernelUnavailableError("no C compiler for the compiled kernel (looked for $CC)")

    monkeypatch.setattr(compiler, "load_kernel", no_compiler)
    finding = compiled_step_check()
    assert finding.status == "WARN" and "no C compiler" in finding.detail
    assert "the same in Python" in finding.detail
    monkeypatch.setattr(compiler, "load_kernel", lambda: None)
    finding = compiled_step_check()
    assert finding.status == "ok" and "kernel" in finding.detail
