"""Core claims: runs spread over the cores in rounds, a claim ends with its holder (however
it ends), and the affinity before the claim comes back on release."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from bfsitl.sitl.core_claim import available_cores, claim_core

CORES = available_cores()
needs_two = pytest.mark.skipif(len(CORES) < 2, reason="core claims need two cores")

HOLDER = """
import sys, time
from pathlib import Path
from bfsitl.sitl.core_claim import claim_core
claim = claim_core(Path(sys.argv[1]))
print(claim.core, flush=True)
time.sleep(60)
"""


def hold_a_core(lock_dir: Path) -> tuple[subprocess.Popen[str], int]:
    """Another process that claims a core and keeps it; (the process, its core)."""
    holder = subprocess.Popen(
        [sys.executable, "-c", HOLDER, str(lock_dir)], stdout=subprocess.PIPE, text=True
    )
    assert holder.stdout is not None
    return holder, int(holder.stdout.readline())


@needs_two
def test_claims_spread_over_the_cores_and_pin_the_process(tmp_path: Path) -> None:
    before = os.sched_getaffinity(0)
    holders = [hold_a_core(tmp_path) for _ in CORES]
    try:
        assert [core for _holder, core in holders] == CORES  # one each first
        claim = claim_core(tmp_path)
        assert claim is not None
        assert (claim.core, claim.round) == (CORES[0], 1)  # then the next round
        assert os.sched_getaffinity(0) == {CORES[0]}  # the claim pinned us
        child = subprocess.run(
            [sys.executable, "-c", "import os; print(sorted(os.sched_getaffinity(0)))"],
            capture_output=True,
            text=True,
            check=True,
        )
        assert child.stdout.strip() == f"[{CORES[0]}]"  # and what we start from now on
        claim.release()
        claim.release()  # twice is harmless
        assert os.sched_getaffinity(0) == before
    finally:
        for holder, _core in holders:
            holder.kill()
            holder.wait()
        os.sched_setaffinity(0, before)


@needs_two
def test_a_killed_holders_claim_is_free_again(tmp_path: Path) -> None:
    holder, core = hold_a_core(tmp_path)
    try:
        assert core == CORES[0]
        mine = claim_core(tmp_path)
        assert mine is not None and mine.core == CORES[1]  # the first core is held
        mine.release()
    finally:
        holder.kill()
        holder.wait()
    mine = claim_core(tmp_path)
    assert mine is not None and mine.core == CORES[0]  # the lock died with its holder
    mine.release()


def _claim_in_child(lock_dir: str, out) -> None:  # type: ignore[no-untyped-def]
    claim = claim_core(Path(lock_dir))
    out.send(None if claim is None else claim.core)


@needs_two
def test_a_forked_child_of_a_pinned_process_claims_among_all_the_cores(tmp_path: Path) -> None:
    import multiprocessing

    before = os.sched_getaffinity(0)
    mine = claim_core(tmp_path)
    assert mine is not None and mine.core == CORES[0]
    try:
        context = multiprocessing.get_context("fork")
        reader, writer = context.Pipe(duplex=False)
        child = context.Process(target=_claim_in_child, args=(str(tmp_path), writer))
        child.start()
        child.join(10)
        assert reader.recv() == CORES[1]  # not the parent's one core, nor "no choice"
    finally:
        mine.release()
    assert os.sched_getaffinity(0) == before
    again = claim_core(tmp_path)  # the child's copy of our lock did not keep it
    assert again is not None and again.core == CORES[0]
    again.release()


def test_a_lock_directory_that_cannot_be_made_means_no_pinning(tmp_path: Path) -> None:
    blocker = tmp_path / "file"
    blocker.write_text("not a directory")
    before = os.sched_getaffinity(0)
    assert claim_core(blocker / "locks") is None
    assert os.sched_getaffinity(0) == before


def test_claims_can_be_turned_off(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("BFSITL_PIN_CORES", "0")
    assert claim_core(tmp_path) is None


def test_on_one_core_nothing_is_claimed(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(os, "sched_getaffinity", lambda _pid: {0})
    assert claim_core(tmp_path) is None
