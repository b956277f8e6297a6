"""The transports (:mod:`bfsitl.link`) against real sockets and a real pty, no SITL: bytes
both ways, deadlines, what the peer's close looks like, every OS error as a LinkError that
says what to do, and the URI a user types picking the right one."""

from __future__ import annotations

import os
import select
import socket
import threading
import time
from collections.abc import Iterator

import pytest

from bfsitl.errors import LinkClosedError, LinkError, LinkTimeoutError
from bfsitl.link import SerialLink, TcpLink, open_link
from bfsitl.link.base import Link


@pytest.fixture
def server() -> Iterator[socket.socket]:
    """A listening TCP socket on a free loopback port."""
    listener = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
    listener.bind(("127.0.0.1", 0))
    listener.listen(1)
    yield listener
    listener.close()


def connect(server: socket.socket, timeout_s: float = 0.5) -> tuple[TcpLink, socket.socket]:
    port = server.getsockname()[1]
    link = open_link(f"tcp://127.0.0.1:{port}", timeout_s=timeout_s)
    peer, _ = server.accept()
    assert isinstance(link, TcpLink)
    return link, peer


def test_bytes_go_both_ways_and_are_counted(server: socket.socket) -> None:
    link, peer = connect(server)
    with link, peer:
        link.write(b"$M<\x00\x01\x01")
        assert peer.recv(100) == b"$M<\x00\x01\x01"
        peer.sendall(b"\x01\x02\x03")
        got = b""
        while len(got) < 3:
            got += link.read_some(0.5)
        assert got == b"\x01\x02\x03"
        assert (link.bytes_written, link.bytes_read) == (6, 3)
        # Nagle off: an MSP request must not wait for the previous one's ACK.
        assert link._sock.getsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY)


def test_nothing_to_read_is_empty_after_the_timeout_and_a_zero_timeout_polls(
    server: socket.socket,
) -> None:
    link, peer = connect(server)
    with link, peer:
        started = time.monotonic()
        assert link.read_some(0.1) == b""
        waited_s = time.monotonic() - started
        assert 0.08 <= waited_s < 1.0
        started = time.monotonic()
        assert link.read_some(0.0) == b""
        assert time.monotonic() - started < 0.05


def test_max_bytes_is_respected_and_drain_takes_the_rest(server: socket.socket) -> None:
    link, peer = connect(server)
    with link, peer:
        peer.sendall(bytes(range(10)))  # one segment on loopback
        select.select([link._sock], [], [], 1.0)
        assert link.read_some(0.5, max_bytes=4) == bytes(range(4))
        assert link.drain_input(0.05) == bytes(range(4, 10))


def test_the_peer_closing_is_a_closed_link_that_says_why(server: socket.socket) -> None:
    link, peer = connect(server)
    with link:
        peer.close()
        with pytest.raises(LinkClosedError, match="closed the connection .*reboots or exits"):
            for _ in range(20):
                link.read_some(0.1)


def test_a_closed_link_refuses_reads_and_writes_and_closes_once(server: socket.socket) -> None:
    link, peer = connect(server)
    peer.close()
    link.close()
    link.close()
    assert link.closed and "closed" in repr(link)
    with pytest.raises(LinkClosedError, match="link is closed"):
        link.write(b"x")
    with pytest.raises(LinkClosedError, match="link is closed"):
        link.read_some(0.0)


def test_nobody_listening_says_to_start_a_sitl() -> None:
    probe = socket.socket()
    probe.bind(("127.0.0.1", 0))
    port = probe.getsockname()[1]
    probe.close()  # the port is free again, and nobody listens on it
    with pytest.raises(
        LinkError,
        match=r"connection refused: nothing listens there.*"
        r"bfsitl status --start",
    ):
        open_link(f"tcp://127.0.0.1:{port}")


def test_the_socket_factory_makes_the_socket(server: socket.socket) -> None:
    made: list[tuple[int, int]] = []

    def factory(family: int, kind: int) -> socket.socket:
        made.append((family, kind))
        return socket.socket(family, kind)

    port = server.getsockname()[1]
    with open_link(f"tcp://127.0.0.1:{port}", socket_factory=factory):
        server.accept()[0].close()
    assert made == [(socket.AF_INET, socket.SOCK_STREAM)]


def test_an_os_error_becomes_a_link_error_by_its_kind() -> None:
    class Broken(Link):
        def __init__(self, error: OSError) -> None:
            super().__init__("test://broken")
            self.error = error

        def _write_bytes(self, data: bytes) -> None:
            raise self.error

        def _read_bytes(self, max_bytes: int, timeout_s: float) -> bytes | None:
            raise self.error

        def _close(self) -> None:
            raise OSError("already gone")  # closing is best effort

    import errno

    with pytest.raises(LinkTimeoutError, match="write timed out"):
        Broken(TimeoutError()).write(b"x")
    with pytest.raises(LinkClosedError, match="connection lost during read"):
        Broken(OSError(errno.ECONNRESET, "reset")).read_some(0.0)
    with pytest.raises(LinkError, match="write failed") as caught:
        Broken(OSError(errno.EIO, "i/o")).write(b"x")
    assert type(caught.value) is LinkError
    broken = Broken(OSError(errno.EIO, "i/o"))
    broken.close()
    assert broken.closed


def test_writers_on_two_threads_never_interleave_a_frame() -> None:
    class ByteByByte(Link):
        """Writes one byte at a time and lets the other thread run between bytes, as a
        slow UART would: without the link's lock two frames would mix."""

        def __init__(self) -> None:
            super().__init__("test://slow")
            self.wire = bytearray()

        def _write_bytes(self, data: bytes) -> None:
            for byte in data:
                self.wire.append(byte)
                time.sleep(0)  # yield the GIL mid-frame

        def _read_bytes(self, max_bytes: int, timeout_s: float) -> bytes | None:
            return b""

        def _close(self) -> None:
            pass

    link = ByteByByte()
    frames = (b"A" * 64, b"B" * 64)
    threads = [
        threading.Thread(target=lambda f=f: [link.write(f) for _ in range(20)]) for f in frames
    ]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    chunks = {bytes(link.wire[i : i + 64]) for i in range(0, len(link.wire), 64)}
    assert len(link.wire) == 2 * 20 * 64 and chunks == set(frames)


@pytest.mark.parametrize(
    ("uri", "fix"),
    [
        ("tcp://127.0.0.1", "needs a host and a port"),
        ("serial://", "needs a device"),
        ("serial:///dev/ttyACM0?baud=fast", "baud must be an integer"),
        ("udp://127.0.0.1:5761", r"unknown link; use tcp://HOST:PORT .*serial:///dev/ttyACM0"),
    ],
)
def test_a_uri_that_names_no_transport_says_what_would(uri: str, fix: str) -> None:
    with pytest.raises(LinkError, match=fix):
        open_link(uri)


def test_a_serial_port_carries_bytes_both_ways_over_a_pty() -> None:
    pytest.importorskip("serial")
    board, port = os.openpty()  # the board's end, and the device bfsitl opens
    try:
        name = os.ttyname(port)
        import termios
        import tty

        tty.setraw(board)  # no echo, no line discipline: bytes as sent
        tty.setraw(port)
        termios.tcflush(port, termios.TCIOFLUSH)
        link = open_link(f"serial://{name}?baud=57600", timeout_s=0.5)
        assert isinstance(link, SerialLink) and (link.device, link.baud) == (name, 57600)
        with link:
            link.write(b"$X<\x00")
            assert os.read(board, 100) == b"$X<\x00"
            os.write(board, b"reply")
            got = b""
            while len(got) < 5:
                got += link.read_some(0.5)
            assert got == b"reply"
            assert link.read_some(0.05) == b""
    finally:
        os.close(board)
        os.close(port)


def test_a_serial_device_that_cannot_be_opened_says_what_to_check(tmp_path) -> None:  # type: ignore[no-untyped-def]
    pytest.importorskip("serial")
    with pytest.raises(LinkError, match=r"cannot open .*ttyNOPE.*Check the cable.*dialout"):
        open_link(f"serial://{tmp_path}/ttyNOPE")
