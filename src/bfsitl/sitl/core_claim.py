"""One core for one lockstep run: the run's process and its SITL share it, and runs side by
side each get their own.

A lockstep step is a hand-over: bfsitl sends a packet and waits, the firmware runs its passes
and answers, bfsitl integrates the physics.  Only one of the two works at a time, so they fit
on one core; on one core the hand-over is a plain switch between two processes, while across
cores each packet has to wake an idle core (about three times as long on a VM).  Pinned
this way, N runs on N cores do not take each other's time slices either.

A core is claimed with an advisory lock on a file (``flock``), so the claim ends with the
process that holds it, however that ends: a crashed or killed run leaves no stale claim.
With more runs than cores, the next round of locks spreads them evenly again.  The SITL is
started after the claim and inherits the process's affinity (affinity passes through fork
and exec, as the timer slack does: :mod:`bfsitl.sitl.timer_slack`).
"""

from __future__ import annotations

import contextlib
import fcntl
import os
import tempfile
from dataclasses import dataclass, field
from pathlib import Path

#: Runs sharing one core before the rounds start over (a claim beyond that takes any core).
_MAX_ROUNDS = 64
#: ``BFSITL_PIN_CORES=0`` turns claims off (a container whose affinity lies, a comparison).
PIN_ENV = "BFSITL_PIN_CORES"


def _default_lock_dir() -> Path:
    return Path(tempfile.gettempdir()) / f"bfsitl-cores-{os.getuid()}"


@dataclass(eq=False)
class CoreClaim:
    """A core this process is pinned to, held until :meth:`release` (from the thread that
    claimed it: affinity belongs to a thread) or until the process ends."""

    core: int
    round: int
    _fd: int | None = field(default=None, repr=False)
    _previous: frozenset[int] = field(default=frozenset(), repr=False)

    def release(self) -> None:
        """Give the core back and restore the affinity the process had before the claim."""
        if self not in _HELD:
            return  # released already
        _HELD.remove(self)
        fd, self._fd = self._fd, None
        if fd is not None:
            with contextlib.suppress(OSError):
                os.close(fd)  # closing the file drops its lock
        # Also for a core shared without a lock (every round held): the pin is undone.
        if self._previous:
            with contextlib.suppress(OSError):
                os.sched_setaffinity(0, self._previous)


#: The claims this process holds.  A forked child inherits the list (and learns from it the
#: cores there were before the claim) but not the locks: see _forget_in_child.
_HELD: list[CoreClaim] = []


def _forget_in_child() -> None:
    # The child shares the parent's open lock files; closing its copies keeps the parent's
    # release effective.  The child keeps the parent's pin until it claims a core of its own.
    for claim in _HELD:
        if claim._fd is not None:
            with contextlib.suppress(OSError):
                os.close(claim._fd)
            claim._fd = None


if hasattr(os, "register_at_fork"):
    os.register_at_fork(after_in_child=_forget_in_child)


def available_cores() -> list[int]:
    """The cores this process may run on, in order: those it had before a claim of its own
    or of the parent that forked it pinned it to one."""
    if _HELD and _HELD[0]._previous:
        return sorted(_HELD[0]._previous)
    return sorted(os.sched_getaffinity(0))


def claim_core(lock_dir: Path | None = None) -> CoreClaim | None:
    """Pin the calling thread (and so the processes it starts from now on) to the least
    claimed core and hold the claim; None where pinning is not possible (one core only, or
    no affinity on this system) or is turned off (``BFSITL_PIN_CORES=0``)."""
    if os.environ.get(PIN_ENV, "").strip() == "0":
        return None
    try:
        cores = available_cores()
    except (AttributeError, OSError):
        return None
    if len(cores) < 2:
        return None  # nothing to choose: a run on one core shares it anyway
    directory = lock_dir if lock_dir is not None else _default_lock_dir()
    previous = frozenset(os.sched_getaffinity(0))
    try:
        directory.mkdir(parents=True, exist_ok=True)
        for round_number in range(_MAX_ROUNDS):
            for core in cores:
                fd = _try_lock(directory / f"core{core}-{round_number}.lock")
                if fd is not None:
                    return _pin(core, round_number, fd, previous)
    except OSError:
        return None  # no lock files here (a read-only or foreign directory): no pinning
    # Every slot of every round is held: share the first core, unclaimed.
    return _pin(cores[0], _MAX_ROUNDS, None, previous)


def _try_lock(path: Path) -> int | None:
    fd = os.open(path, os.O_RDWR | os.O_CREAT | os.O_CLOEXEC, 0o600)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError:
        os.close(fd)
        return None
    return fd


def _pin(core: int, round_number: int, fd: int | None, previous: frozenset[int]) -> CoreClaim:
    try:
        os.sched_setaffinity(0, {core})
    except OSError:
        if fd is not None:
            os.close(fd)
        raise
    claim = CoreClaim(core, round_number, fd, previous)
    _HELD.append(claim)
    return claim
