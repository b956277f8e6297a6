"""Port-holder lookup: literal /proc/net text, then real sockets held by this test process."""

from __future__ import annotations

import os
import socket
import sys
from collections.abc import Iterator

import pytest

from bfsitl.errors import PortInUseError, SitlError
from bfsitl.sitl.ports import (
    SITL_TCP_PORTS,
    SITL_UART_TCP_PORTS,
    SITL_UDP_PORTS,
    PortHolder,
    ProcNetSocket,
    check_ports_free,
    decode_address,
    find_port_holders,
    format_port_conflict,
    parse_proc_net,
    select_sockets,
    uart_tcp_port,
)

LITTLE = sys.byteorder == "little"
needs_little_endian = pytest.mark.skipif(not LITTLE, reason="samples were taken on x86 (LE)")
needs_proc = pytest.mark.skipif(not os.path.exists("/proc/self/net/tcp"), reason="needs Linux")

# Taken from a 4.6.0 SITL in its own namespace, plus a client connection and a TIME_WAIT row.
PROC_NET_TCP = """\
  sl  local_address rem_address   st tx_queue rx_queue tr tm->when retrnsmt   uid  timeout inode
   0: 00000000:1681 00000000:0000 0A 00000000:0000000B 00:00000000 00000000     0        0 8423 1 0000000022ca58bd 100 0 0 10 0
   1: 0100007F:1682 00000000:0000 0A 00000000:00000000 00:00000000 00000000  1000        0 9001 1 0000000000000000 100 0 0 10 0
   2: 0100007F:D2F0 0100007F:1681 01 00000000:00000000 00:00000000 00000000     0        0 8500 1 0000000000000000 20 4 30 10 -1
   3: 0100007F:1681 0100007F:D2EE 06 00000000:00000000 03:00000E5A 00000000     0        0 0 3 0000000000000000
"""  # noqa: E501

PROC_NET_TCP6 = """\
  sl  local_address                         remote_address                        st tx_queue rx_queue tr tm->when retrnsmt   uid  timeout inode
   0: 00000000000000000000000001000000:1681 00000000000000000000000000000000:0000 0A 00000000:00000000 00:00000000 00000000  1000        0 4242 1 0000000000000000 100 0 0 10 0
   1: 0000000000000000FFFF00000100007F:1683 00000000000000000000000000000000:0000 0A 00000000:00000000 00:00000000 00000000  1000        0 4243 1 0000000000000000 100 0 0 10 0
   2: B80D0120000000000000000001000000:0050 00000000000000000000000000000000:0000 0A 00000000:00000000 00:00000000 00000000  1000        0 4244 1 0000000000000000 100 0 0 10 0
"""  # noqa: E501

PROC_NET_UDP = """\
   sl  local_address rem_address   st tx_queue rx_queue tr tm->when retrnsmt   uid  timeout inode ref pointer drops
 8901: 00000000:DBDA 00000000:0000 07 00000000:00000000 00:00000000 00000000     0        0 8418 2 00000000426640de 0
10774: 00000000:232B 00000000:0000 07 00000000:00000000 00:00000000 00000000     0        0 8419 2 00000000b6f05181 0
10775: 00000000:232C 00000000:0000 07 00000000:00000000 00:00000000 00000000     0        0 8420 2 000000007665ef0f 0
10773: 0100007F:232A 0100007F:232B 01 00000000:00000000 00:00000000 00000000  1000        0 9100 2 0000000000000000 0
"""  # noqa: E501


# --- pure parsing -------------------------------------------------------------------------


def test_decode_ipv4_in_both_byte_orders() -> None:
    assert decode_address("0100007F:1681", byteorder="little") == ("127.0.0.1", 5761)
    assert decode_address("7F000001:1681", byteorder="big") == ("127.0.0.1", 5761)
    assert decode_address("00000000:232B", byteorder="little") == ("0.0.0.0", 9003)


def test_decode_ipv6_words_are_swapped_one_by_one() -> None:
    assert decode_address("00000000000000000000000001000000:1681", byteorder="little") == (
        "::1",
        5761,
    )
    assert decode_address("B80D0120000000000000000001000000:0050", byteorder="little") == (
        "2001:db8::1",
        80,
    )
    assert decode_address("20010DB8000000000000000000000001:0050", byteorder="big") == (
        "2001:db8::1",
        80,
    )


@pytest.mark.parametrize("bad", ["", "0100007F", "0100:1681", "zz00007F:1681"])
def test_decode_rejects_garbage(bad: str) -> None:
    with pytest.raises(ValueError):
        decode_address(bad)


@needs_little_endian
def test_parse_tcp_rows() -> None:
    rows = parse_proc_net(PROC_NET_TCP, "tcp")
    # rx_queue of a listener: 11 connections never accepted (a SITL whose TCP server was lost).
    assert rows[0] == ProcNetSocket("tcp", "0.0.0.0", 5761, 0x0A, 8423, rx_queue=11)
    assert rows[1] == ProcNetSocket("tcp", "127.0.0.1", 5762, 0x0A, 9001, rx_queue=0)
    assert [row.state for row in rows] == [0x0A, 0x0A, 0x01, 0x06]
    assert rows[2].port == 0xD2F0


@needs_little_endian
def test_parse_tcp6_rows_including_v4_mapped() -> None:
    rows = parse_proc_net(PROC_NET_TCP6, "tcp")
    assert [(row.address, row.port, row.inode) for row in rows] == [
        ("::1", 5761, 4242),
        ("::ffff:127.0.0.1", 5763, 4243),
        ("2001:db8::1", 80, 4244),
    ]


@needs_little_endian
def test_parse_udp_rows() -> None:
    rows = parse_proc_net(PROC_NET_UDP, "udp")
    assert [(row.address, row.port) for row in rows] == [
        ("0.0.0.0", 56282),
        ("0.0.0.0", 9003),
        ("0.0.0.0", 9004),
        ("127.0.0.1", 9002),
    ]
    assert rows[1].inode == 8419


def test_parse_skips_header_blank_and_broken_lines() -> None:
    text = PROC_NET_UDP + "\n   9: not a row\n  10: 0100007F:XYZ 00000000:0000 07 0 0 0 0 0 77\n"
    assert len(parse_proc_net(text, "udp")) == 4
    assert parse_proc_net("", "tcp") == []


def test_parse_rejects_unknown_protocol() -> None:
    with pytest.raises(ValueError, match="protocol"):
        parse_proc_net(PROC_NET_TCP, "tcp6")


@needs_little_endian
def test_select_keeps_tcp_listeners_and_every_bound_udp_socket() -> None:
    sockets = parse_proc_net(PROC_NET_TCP, "tcp") + parse_proc_net(PROC_NET_UDP, "udp")
    chosen = select_sockets(sockets, SITL_TCP_PORTS, SITL_UDP_PORTS + (9002,))
    # The TIME_WAIT row on 5761 does not count; the connected UDP socket on 9002 does.
    assert [(s.protocol, s.port, s.inode) for s in chosen] == [
        ("tcp", 5761, 8423),
        ("udp", 9003, 8419),
        ("udp", 9004, 8420),
        ("udp", 9002, 9100),
    ]


def test_constants_match_the_firmware() -> None:
    assert SITL_TCP_PORTS == (5761,)
    assert SITL_UART_TCP_PORTS == tuple(range(5761, 5769))
    assert uart_tcp_port(1) == 5761
    assert uart_tcp_port(8) == 5768
    with pytest.raises(ValueError):
        uart_tcp_port(0)


# --- messages -----------------------------------------------------------------------------


def test_describe_known_and_unknown_holders() -> None:
    seen = PortHolder("tcp", 5761, "0.0.0.0", 1234, "betaflight_4.6.0_SITL")
    assert seen.describe() == "tcp 5761 held by pid 1234 (betaflight_4.6.0_SITL)"
    assert PortHolder("udp", 9003, "0.0.0.0", 77, None).describe() == "udp 9003 held by pid 77"
    hidden = PortHolder("udp", 9003, "0.0.0.0", None, None)
    assert hidden.describe() == (
        "udp 9003 held by a process we cannot see (another user or namespace)"
    )


def test_conflict_message_says_who_and_what_to_do() -> None:
    message = format_port_conflict(
        [
            PortHolder("tcp", 5761, "0.0.0.0", 1234, "betaflight_4.6.0_SITL"),
            PortHolder("udp", 9003, "0.0.0.0", 1234, "betaflight_4.6.0_SITL"),
            PortHolder("udp", 9004, "0.0.0.0", None, None),
        ]
    )
    assert "tcp 5761 held by pid 1234 (betaflight_4.6.0_SITL)" in message
    assert "udp 9004 held by a process we cannot see" in message
    assert "kill 1234" in message
    assert "--isolate" in message
    assert "SO_REUSEADDR" in message
    assert "9003/9004" in message


# --- live sockets in this process --------------------------------------------------------


@pytest.fixture
def tcp_listener() -> Iterator[int]:
    sock = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
    sock.bind(("127.0.0.1", 0))
    sock.listen(1)
    try:
        yield sock.getsockname()[1]
    finally:
        sock.close()


@pytest.fixture
def udp_socket() -> Iterator[int]:
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sock.bind(("127.0.0.1", 0))
    try:
        yield sock.getsockname()[1]
    finally:
        sock.close()


def _free_port(kind: int) -> int:
    """A port nobody holds right now: bind to 0, note it, let it go."""
    with socket.socket(socket.AF_INET, kind) as sock:
        sock.bind(("127.0.0.1", 0))
        return int(sock.getsockname()[1])


@needs_proc
def test_live_holders_are_this_process(tcp_listener: int, udp_socket: int) -> None:
    holders = find_port_holders([tcp_listener], [udp_socket])
    found = {(h.protocol, h.port, h.address, h.pid) for h in holders}
    assert ("tcp", tcp_listener, "127.0.0.1", os.getpid()) in found
    assert ("udp", udp_socket, "127.0.0.1", os.getpid()) in found
    assert all(h.command for h in holders if h.pid == os.getpid())


@needs_proc
def test_live_lookup_through_an_explicit_netns_pid(tcp_listener: int) -> None:
    holders = find_port_holders([tcp_listener], [], netns_pid=os.getpid())
    assert [(h.port, h.pid) for h in holders] == [(tcp_listener, os.getpid())]


@needs_proc
def test_bound_but_not_listening_tcp_is_not_a_holder() -> None:
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as sock:
        sock.bind(("127.0.0.1", 0))
        port = sock.getsockname()[1]
        assert find_port_holders([port], []) == []


@needs_proc
def test_check_ports_free_names_the_pid(tcp_listener: int, udp_socket: int) -> None:
    with pytest.raises(PortInUseError) as caught:
        check_ports_free([tcp_listener], [udp_socket])
    message = str(caught.value)
    assert f"tcp {tcp_listener} held by pid {os.getpid()}" in message
    assert f"udp {udp_socket} held by pid {os.getpid()}" in message
    assert f"kill {os.getpid()}" in message
    assert isinstance(caught.value, SitlError)
    assert {h.port for h in caught.value.holders} == {tcp_listener, udp_socket}


@needs_proc
def test_free_ports_have_no_holder() -> None:
    tcp_port = _free_port(socket.SOCK_STREAM)
    udp_port = _free_port(socket.SOCK_DGRAM)
    assert find_port_holders([tcp_port], [udp_port]) == []
    check_ports_free([tcp_port], [udp_port])


def test_vanished_namespace_process_is_an_error() -> None:
    with pytest.raises(ProcessLookupError):
        find_port_holders([5761], [], netns_pid=2**22 + 12345)
