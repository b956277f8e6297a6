"""A TCP port like a SITL's UART1 (one client at a time, MSP_API_VERSION answered), and a
wait for a condition another thread makes true."""

from __future__ import annotations

import contextlib
import socket
import threading
import time

from bfsitl.bridges import Upstream
from bfsitl.protocol.msp_codes import MspCommand
from bfsitl.protocol.msp_frame import Direction, MspFrame, MspParser, encode_frame

API_VERSION_REPLY = encode_frame(MspFrame(MspCommand.API_VERSION, bytes((0, 1, 47))))


class FakeSitl:
    """A TCP port like the SITL's UART1: one client, MSP_API_VERSION answered."""

    def __init__(self) -> None:
        self._server = socket.create_server(("127.0.0.1", 0))
        self.port = self._server.getsockname()[1]
        self.connections = 0
        self.closed_connections = 0
        self.refused = 0
        self.received = bytearray()
        self.other_client_present = False  # as if another program held the port
        self._client: socket.socket | None = None
        self._lock = threading.Lock()
        threading.Thread(target=self._accept_loop, daemon=True).start()

    @property
    def upstream(self) -> Upstream:
        return Upstream("127.0.0.1", self.port, busy_wait_s=0.3)

    def _accept_loop(self) -> None:
        while True:
            try:
                conn, _addr = self._server.accept()
            except OSError:
                return
            with self._lock:
                if self._client is not None or self.other_client_present:
                    self.refused += 1
                    conn.close()
                    continue
                self._client = conn
                self.connections += 1
            threading.Thread(target=self._serve, args=(conn,), daemon=True).start()

    def _serve(self, conn: socket.socket) -> None:
        parser = MspParser()
        try:
            while data := conn.recv(4096):
                self.received += data
                for frame in parser.feed(data):
                    if isinstance(frame, MspFrame) and frame.direction is Direction.REQUEST:
                        if frame.command == MspCommand.API_VERSION:
                            conn.sendall(API_VERSION_REPLY)
                        else:
                            conn.sendall(
                                encode_frame(MspFrame(frame.command, b"", Direction.ERROR))
                            )
        except OSError:
            pass
        finally:
            conn.close()
            with self._lock:
                self._client = None
                self.closed_connections += 1

    def drop_client(self) -> None:
        """End the current connection from the SITL's side (as a reboot does)."""
        with self._lock, contextlib.suppress(OSError):  # it may be closing by itself
            if self._client is not None:
                self._client.shutdown(socket.SHUT_RDWR)

    def close(self) -> None:
        self._server.close()
        self.drop_client()


def wait_until(condition, timeout_s: float = 3.0) -> None:
    deadline = time.monotonic() + timeout_s
    while not condition():
        if time.monotonic() > deadline:
            raise AssertionError("condition not met in time")
        time.sleep(0.01)
