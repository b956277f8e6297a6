"""The lockstep exchange through shared memory: the same datagram and reply as over UDP,
handed over through a mapped file and a futex instead of sockets.

A lockstep step is a strict hand-over (bfsitl writes, the FC answers, bfsitl goes on), so the
transport's cost is paid twice per simulated millisecond.  Over UDP that is a ``sendto``, a
``select`` and a ``recv`` on each side; here each side writes into the region, bumps a
sequence word and wakes the other with one ``FUTEX_WAKE``, and a waiter polls the word for the
spin time and then sleeps in ``FUTEX_WAIT`` on it.  From layout version 3 a waiter also says
whether it sleeps, and the wake (a system call) is made only then: two sides that both poll
hand over without one.  The layout is the FC's (its header says where the datagram and the
reply are; ``sitl_lockstep.c`` point 6); this side only checks it.

Used for lockstep builds that carry it (:func:`bfsitl.build.binary_scan.binary_traits`), on
x86-64 Linux: there stores become visible in program order, so the datagram is complete
before the sequence word that announces it (other processors would need a barrier that
Python cannot issue).  Anywhere else, and when asked (``lockstep_exchange="udp"``), UDP.
"""

from __future__ import annotations

import ctypes
import mmap
import os
import platform
import sys
import tempfile
import uuid
import weakref
from collections.abc import Callable
from pathlib import Path

from bfsitl.errors import SitlError
from bfsitl.owned_temp import left_by_gone_processes

#: The variable that names the region to the FC.
SHM_ENV = "BFSITL_LOCKSTEP_SHM"
#: A region's file name: this prefix, the owner's pid, a random part.
_PREFIX = "bfsitl-lockstep-"
_MAGIC = 0x6D736662  # "bfsm", written last by the FC
#: The layouts this side reads: version 1 (builds before the TCP word) services TCP after
#: every packet whatever this side says; before version 3 every hand-over wakes the other
#: side, whether it sleeps or polls.
_VERSIONS = (1, 2, 3)
#: The header's words: magic, version, requestSeq, replySeq, datagramBytes, datagramOffset,
#: replyOffset, regionBytes; from version 2 tcpUntilSeq; from version 3 fcSleeping (1 while
#: the FC sleeps on requestSeq) and simPolling (1 while the compiled loop polls replySeq).
_HEADER_WORDS = {1: 8, 2: 9, 3: 11}
_MAGIC_WORD, _VERSION_WORD, _REQUEST_WORD, _REPLY_WORD, _BYTES_WORD = 0, 1, 2, 3, 4
_DATAGRAM_OFFSET_WORD, _REPLY_OFFSET_WORD, _REGION_WORD, _TCP_UNTIL_WORD = 5, 6, 7, 8
_FC_SLEEPING_WORD, _SIM_POLLING_WORD = 9, 10
#: Room for the FC's region (240 bytes today) and anything a later layout adds.
REGION_BYTES = 4096
#: Reply size: the servo packet and the timestamp it answers (sim/lockstep.py REPLY_FORMAT).
_REPLY_BYTES = 24
#: The largest datagram: an fdm packet and an RC packet.
_DATAGRAM_BYTES = 144 + 40
_FUTEX_WAIT, _FUTEX_WAKE = 0, 1
_SYS_FUTEX = {"x86_64": 202}


def shm_exchange_supported() -> bool:
    """This machine can use the exchange (x86-64 Linux and a 64-bit Python, see the module
    docstring)."""
    return platform.system() == "Linux" and platform.machine() in _SYS_FUTEX and sys.maxsize > 2**32


def _region_directory() -> Path:
    # tmpfs where there is one: the region is never written back to a disk.
    shm = Path("/dev/shm")
    return shm if shm.is_dir() and os.access(shm, os.W_OK) else Path(tempfile.gettempdir())


class _Futex:
    """FUTEX_WAIT and FUTEX_WAKE on a word of a shared mapping (not private: two processes)."""

    def __init__(self) -> None:
        libc = ctypes.CDLL(None, use_errno=True)
        self._syscall = libc.syscall
        self._syscall.restype = ctypes.c_long
        self._syscall.argtypes = [
            ctypes.c_long,
            ctypes.c_void_p,
            ctypes.c_int,
            ctypes.c_uint32,
            ctypes.c_void_p,
            ctypes.c_void_p,
            ctypes.c_uint32,
        ]
        self._number = _SYS_FUTEX[platform.machine()]

    def wake(self, address: int) -> None:
        self._syscall(self._number, address, _FUTEX_WAKE, 1, None, None, 0)

    def wait(self, address: int, expected: int, timeout_s: float) -> None:
        """Sleep while the word holds ``expected``, at most ``timeout_s``; returns at once
        if it holds something else (so a wake-up between reading it and sleeping is never
        lost)."""
        seconds = int(timeout_s)
        timeout = (ctypes.c_long * 2)(seconds, int((timeout_s - seconds) * 1e9))
        self._syscall(
            self._number, address, _FUTEX_WAIT, expected, ctypes.addressof(timeout), None, 0
        )


class ShmExchange:
    """bfsitl's side of the region: made before the SITL starts (its path goes into the
    firmware's environment), ready once the FC has written its header."""

    def __init__(self, directory: Path | None = None) -> None:
        folder = directory if directory is not None else _region_directory()
        remove_stale_regions(folder)
        self.path = folder / f"{_PREFIX}{os.getpid()}-{uuid.uuid4().hex[:12]}"
        fd = os.open(self.path, os.O_RDWR | os.O_CREAT | os.O_EXCL | os.O_CLOEXEC, 0o600)
        # Removed when this object goes, or at exit, if close() is never reached.
        self._remove = weakref.finalize(self, _unlink, self.path)
        try:
            os.ftruncate(fd, REGION_BYTES)
            self._map = mmap.mmap(
                fd, REGION_BYTES, mmap.MAP_SHARED, mmap.PROT_READ | mmap.PROT_WRITE
            )
        finally:
            os.close(fd)
        self._words = memoryview(self._map).cast("I")
        self._base = ctypes.addressof(ctypes.c_char.from_buffer(self._map))
        self._futex = _Futex()
        self._datagram_offset = 0
        self._reply_offset = 0
        self._seq = 0
        self._ready = False
        #: The FC services TCP only after the packets this side marks (layout version 2).
        self._tcp_marks = False
        self._waiting_words = (0, 0)
        self.closed = False

    @property
    def env(self) -> dict[str, str]:
        """What the firmware's environment needs to use this region."""
        return {SHM_ENV: str(self.path)}

    @property
    def ready(self) -> bool:
        """The FC has mapped the region and written its layout (checked once it has)."""
        if self._ready:
            return True
        if self._words[_MAGIC_WORD] != _MAGIC:
            return False
        version, datagram_at, reply_at, size = (
            self._words[_VERSION_WORD],
            self._words[_DATAGRAM_OFFSET_WORD],
            self._words[_REPLY_OFFSET_WORD],
            self._words[_REGION_WORD],
        )
        if (
            version not in _VERSIONS
            or size > REGION_BYTES
            or reply_at + _REPLY_BYTES > size
            or datagram_at < 4 * _HEADER_WORDS[version]
            or reply_at < datagram_at + _DATAGRAM_BYTES
        ):
            raise SitlError(
                f"the firmware's shared exchange has layout version {version} ({size} bytes), "
                f"this bfsitl knows versions {' and '.join(map(str, _VERSIONS))}: rebuild the "
                f"firmware with this bfsitl (`bfsitl firmware build --lockstep`), or use the UDP "
                f"exchange"
            )
        self._datagram_offset, self._reply_offset = datagram_at, reply_at
        self._tcp_marks = version >= 2
        self._waiting_words = (_FC_SLEEPING_WORD, _SIM_POLLING_WORD) if version >= 3 else (0, 0)
        self._ready = True
        return True

    @property
    def base_address(self) -> int:
        """The mapping's address in this process (for the compiled loop)."""
        return self._base

    @property
    def offsets(self) -> tuple[int, int]:
        """(datagram, reply) offsets in the region, as the FC wrote them (once ready)."""
        return self._datagram_offset, self._reply_offset

    @property
    def waiting_words(self) -> tuple[int, int]:
        """The words where the FC says it sleeps and the compiled loop that it polls, so
        that a hand-over wakes only a side that sleeps (layout version 3; (0, 0) before:
        every hand-over wakes).  This side's own waits leave its word 0: the FC wakes them."""
        return self._waiting_words

    @property
    def seq(self) -> int:
        """The last request number sent; the compiled loop sends through the region too and
        hands its count back here."""
        return self._seq

    @seq.setter
    def seq(self, value: int) -> None:
        self._seq = value & 0xFFFFFFFF

    def serve_tcp_next(self, requests: int) -> None:
        """Ask the FC to service its TCP ports after each of the next ``requests`` requests
        (bytes were just written to one of them): otherwise it does after a packet during
        which it wrote to a port, and every few milliseconds of its time
        (``sitl_lockstep.c`` point 4).  Nothing to ask of a version 1 FC: it services them
        after every packet."""
        if self._tcp_marks:
            self._words[_TCP_UNTIL_WORD] = (self._seq + requests) & 0xFFFFFFFF

    def send(self, datagram: bytes) -> int:
        """Write ``datagram`` and wake the FC; the sequence number its reply will carry.  The
        word is 0 while the datagram is written (the FC's copy checks it: a seqlock)."""
        offset = self._datagram_offset
        if offset + len(datagram) > self._reply_offset:
            raise SitlError(
                f"a lockstep datagram of {len(datagram)} bytes does not fit the "
                f"firmware's shared exchange ({self._reply_offset - offset} bytes)"
            )
        words = self._words
        words[_REQUEST_WORD] = 0
        self._map[offset : offset + len(datagram)] = datagram
        words[_BYTES_WORD] = len(datagram)
        self._seq = (self._seq + 1) & 0xFFFFFFFF
        if self._seq == 0:
            self._seq = 1  # 0 means "being written": never a request
        words[_REQUEST_WORD] = self._seq
        self._futex.wake(self._base + 4 * _REQUEST_WORD)
        return self._seq

    def wait_reply(
        self, first: int, last: int, timeout_s: float, spin_until: Callable[[], bool]
    ) -> bytes | None:
        """The reply to any of the requests ``first`` to ``last`` (one packet and its
        resends) if it comes within ``timeout_s``; the word is polled while ``spin_until()``
        is true, then slept on."""
        words = self._words
        reply_word = _REPLY_WORD
        span = (last - first) & 0xFFFFFFFF

        def answered(seq: int) -> bool:
            return ((seq - first) & 0xFFFFFFFF) <= span

        while spin_until():
            if answered(words[reply_word]):
                return self._reply()
        now = words[reply_word]
        if not answered(now):
            self._futex.wait(self._base + 4 * reply_word, now, timeout_s)
            if not answered(words[reply_word]):
                return None
        return self._reply()

    def _reply(self) -> bytes:
        offset = self._reply_offset
        return self._map[offset : offset + _REPLY_BYTES]

    def close(self) -> None:
        """Unmap and remove the region (the FC's mapping, if it still runs, stays valid)."""
        self.closed = True  # the compiled loop holds the mapping's address: never again
        try:
            self._words.release()
            self._map.close()
        except (BufferError, ValueError):
            pass
        self._remove()


def _unlink(path: Path) -> None:
    try:
        path.unlink()
    except FileNotFoundError:
        pass


def remove_stale_regions(folder: Path) -> None:
    """Remove regions left by processes that no longer run (a SIGKILLed bfsitl cannot
    clean up after itself); the owner's pid is in the name."""
    for entry in left_by_gone_processes(_PREFIX, folder):
        try:
            entry.unlink()
        except OSError:
            pass  # another user's, or gone already
