"""A stand-in FC for the shared-memory lockstep exchange: a thread maps the region as
sitl_lockstep.c does (header, sequence words, futex wake-ups) and answers each new request;
and a bridge on such a region without any UDP port."""

from __future__ import annotations

import ctypes
import mmap
import socket
import threading
import time
from collections.abc import Callable
from pathlib import Path

import pytest

from bfsitl.errors import SitlExitedError
from bfsitl.link.shm_exchange import REGION_BYTES, ShmExchange, _Futex
from bfsitl.protocol.sitl_packets import FdmPacket, RcPacket
from bfsitl.sim.lockstep import REPLY_FORMAT, LockstepBridge

# The FC's layout (lockstepShm_t): 11 words of header (8 in version 1, without tcpUntilSeq;
# 9 in version 2, without fcSleeping and simPolling), the datagram after them, the reply
# after it.
HEADER_WORDS = {1: 8, 2: 9, 3: 11}
TCP_UNTIL_WORD = 8
FC_SLEEPING_WORD, SIM_POLLING_WORD = 9, 10


class SharedFakeFc:
    """Maps the region, writes the header last, answers every new request (4.6's slot order)
    after ``delay_s``; ``version`` 1 plays a build from before the TCP word, 2 one from before
    the waiting words, any other than 1 to 3 a firmware of another layout.  ``tcp_until``
    keeps the TCP word as it was when each request was taken (version 2 on).  From version 3
    it says when it sleeps and wakes the simulator only when it does not poll (``wakes``
    counts its wake-ups); ``poll`` never sleeps, as an FC spinning all the while."""

    def __init__(
        self,
        path: Path,
        *,
        delay_s: float = 0.0,
        version: int = 3,
        answer: bool = True,
        poll: bool = False,
        motors: Callable[[bytes], tuple[float, float, float, float]] | None = None,
    ) -> None:
        self.file = path.open("r+b")
        self.map = mmap.mmap(self.file.fileno(), REGION_BYTES)
        self.words = memoryview(self.map).cast("I")
        self.delay_s = delay_s
        self.answer = answer
        self.received: list[tuple[float, tuple[int, ...]]] = []
        #: Every datagram taken, as it came.
        self.datagrams: list[bytes] = []
        #: The four slots answered for a datagram (default: the same four for every one).
        self.motors = motors
        #: Added to the timestamp a reply names (not 0: an FC out of step).
        self.stamp_error_s = 0.0
        self.futex = _Futex()
        self.base = ctypes.addressof(ctypes.c_char.from_buffer(self.map))
        self.seen = self.words[2]
        self.version = version
        self.datagram_at = 4 * HEADER_WORDS.get(version, 11)
        self.poll = poll
        self.wakes = 0
        self.reply_at = self.datagram_at + FdmPacket.SIZE + RcPacket.SIZE
        self.tcp_until: list[int] = []
        self.words[1] = version
        self.words[5], self.words[6] = self.datagram_at, self.reply_at
        self.words[7] = self.reply_at + 24
        self.words[0] = 0x6D736662
        self.stop = threading.Event()
        self.thread = threading.Thread(target=self.run, daemon=True)
        self.thread.start()

    def run(self) -> None:
        while not self.stop.is_set():
            seq = self.words[2]
            if seq in (self.seen, 0):  # answered, or being written
                if self.poll:
                    continue
                if self.version < 3:
                    self.futex.wait(self.base + 8, seq, 0.05)
                    continue
                # Said (already with the last reply), then the word read again
                # (sitl_lockstep.c does both sequentially consistent; Python cannot fence, so
                # a lost wake-up here would cost this wait's 50 ms, never a hang).
                self.words[FC_SLEEPING_WORD] = 1
                seq = self.words[2]
                if seq in (self.seen, 0):
                    self.futex.wait(self.base + 8, seq, 0.05)
                continue
            if self.version >= 3:
                self.words[FC_SLEEPING_WORD] = 0
            size = self.words[4]
            data = bytes(self.map[self.datagram_at : self.datagram_at + size])
            if self.words[2] != seq:
                continue  # rewritten while copied: take the new one
            self.seen = seq
            if self.version >= 2:
                self.tcp_until.append(self.words[TCP_UNTIL_WORD])
            fdm = FdmPacket.unpack(data[: FdmPacket.SIZE])
            # A datagram without a trailer is a step between two of the RC link's frames.
            rc = RcPacket.unpack(data[FdmPacket.SIZE :]) if len(data) > FdmPacket.SIZE else None
            self.received.append((fdm.timestamp_s, None if rc is None else rc.channels_us[:6]))
            self.datagrams.append(data)
            if not self.answer:
                continue
            time.sleep(self.delay_s)
            slots = (0.2, 0.3, 0.4, 0.1) if self.motors is None else self.motors(data)
            self.map[self.reply_at : self.reply_at + 24] = REPLY_FORMAT.pack(
                *slots, fdm.timestamp_s + self.stamp_error_s
            )
            if self.version >= 3 and not self.poll:
                # It will sleep until the next request: said before the reply, so that the
                # simulator, which sends that request only once it has the reply, wakes it
                # every time (a stand-in FC slower than the real one to go back to sleep).
                self.words[FC_SLEEPING_WORD] = 1
            if self.version < 3:
                self.wakes += 1  # counted before the reply: the simulator may read it then
                self.words[3] = seq
                self.futex.wake(self.base + 12)
                continue
            self.words[3] = seq
            if not self.words[SIM_POLLING_WORD]:
                self.wakes += 1
                self.futex.wake(self.base + 12)

    def close(self) -> None:
        self.stop.set()
        self.thread.join()
        self.words.release()
        self.map.close()
        self.file.close()


class NoSockets:
    """The bridge's UDP side, unused once the region is ready (and harmless before)."""

    netns_pid = None

    def socket(self, family: int, kind: int) -> socket.socket:
        sock = socket.socket(family, kind)
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        return sock


def bridge_on(exchange: ShmExchange, simulator: object, **options: object) -> LockstepBridge:
    bridge = LockstepBridge(
        simulator,
        NoSockets(),
        exchange=exchange,  # type: ignore[arg-type]
        **options,
    )  # type: ignore[arg-type]
    bridge._sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)  # no port of 9002 needed
    bridge._sock.setblocking(False)
    return bridge.start()


def assert_a_silent_fc_is_asked_about(bridge: LockstepBridge, fc: SharedFakeFc) -> None:
    """The FC stops answering: the bridge's wait asks whether the SITL still runs, and the
    SITL's end (here: it has exited) is what the step raises."""
    fc.answer = False

    def dead() -> None:
        raise SitlExitedError("the SITL exited with code 0", 0, "")

    bridge.alive = dead
    with pytest.raises(SitlExitedError):
        bridge.step()
