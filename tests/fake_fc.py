"""An in-memory flight controller for fast unit tests of the MSP client and CLI session.

It behaves like the firmware where the client's logic depends on it: one request answered per
"tick" (here: per read call), replies in request order, no reply to a bad checksum, ``!`` for
unknown commands, and CLI mode that echoes bytes as text.  Knobs let a test drop, corrupt or
delay replies.  The real SITL runs the same client code in tests/integration.
"""

from __future__ import annotations

import time
from collections import deque
from collections.abc import Callable

from bfsitl.link.base import Link
from bfsitl.protocol.msp_frame import Direction, MspFrame, MspParser, encode_frame

Handler = Callable[[MspFrame], bytes | None]


class FakeFcLink(Link):
    def __init__(self, handlers: dict[int, Handler] | None = None) -> None:
        super().__init__("fake://fc", timeout_s=0.2)
        self.handlers: dict[int, Handler] = dict(handlers or {})
        self._parser = MspParser()
        self._pending: deque[MspFrame] = deque()   # requests received, not yet answered
        self._out = bytearray()
        self.received: list[MspFrame] = []
        self.raw_written = bytearray()
        self.drop_next: set[int] = set()           # command ids whose next request is lost
        self.cli_mode = False
        self.max_unanswered_bytes = 0
        self._unanswered_bytes = 0
        self.answers_per_read = 1
        self.closed_by_peer = False

    def _write_bytes(self, data: bytes) -> None:
        self.raw_written += data
        if self.cli_mode:
            self._out += data.replace(b"\r", b"\r\n")  # echo, as the CLI does
            return
        for event in self._parser.feed(data):
            if not isinstance(event, MspFrame):
                continue
            if event.command in self.drop_next:
                self.drop_next.discard(event.command)
                continue
            self.received.append(event)
            self._pending.append(event)
            self._unanswered_bytes += len(encode_frame(event))
            self.max_unanswered_bytes = max(self.max_unanswered_bytes, self._unanswered_bytes)

    def _read_bytes(self, max_bytes: int, timeout_s: float) -> bytes | None:
        for _ in range(self.answers_per_read):
            if not self._pending:
                break
            request = self._pending.popleft()
            self._unanswered_bytes -= len(encode_frame(request))
            handler = self.handlers.get(request.command)
            if handler is None:
                reply = MspFrame(request.command, b"", Direction.ERROR, request.version)
            else:
                payload = handler(request)
                if payload is None:
                    continue  # the FC sends nothing
                reply = MspFrame(request.command, payload, Direction.REPLY, request.version)
            self._out += encode_frame(reply)
        if not self._out:
            if self.closed_by_peer:
                return None
            time.sleep(min(timeout_s, 0.002))  # like a real read: nothing came in the wait
            return b""
        data = bytes(self._out[:max_bytes])
        del self._out[:max_bytes]
        return data

    def inject(self, data: bytes) -> None:
        """Bytes the FC sends unprompted (garbage, CLI text)."""
        self._out += data

    def _close(self) -> None:
        pass
