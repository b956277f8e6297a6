"""Which process holds the SITL's ports, read from /proc (Linux only, no privileges needed).

Betaflight 4.6.0 SITL fixes its ports at compile time.  Before starting one we check that
nobody else holds them, because a clash does not fail loudly: the SITL binds its UDP ports
with ``SO_REUSEADDR``, so a second SITL (or a stale one) silently *shares* UDP 9003/9004 and
each gets part of the physics and RC packets.  The TCP port is only noticed as a
``bind port 5761 for UART1 failed!!`` line in the firmware log, after which MSP reaches the
wrong FC.

``/proc/<pid>/net/{tcp,tcp6,udp,udp6}`` lists the sockets of *that process's* network
namespace, so passing ``netns_pid`` checks inside an isolated namespace (``unshare -rn``)
from outside it.  Socket inodes are global, so ``/proc/*/fd`` maps them to processes in any
namespace we are allowed to look into.

Parsing is kept in pure functions (:func:`parse_proc_net`, :func:`decode_address`,
:func:`select_sockets`) so tests can feed literal /proc text.
"""

from __future__ import annotations

import ipaddress
import os
import sys
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from pathlib import Path

from bfsitl.errors import PortInUseError

TCP_BASE_PORT = 5760
"""``BASE_PORT`` in ``drivers/serial_tcp.c``: UART *n* listens on ``TCP_BASE_PORT + n``."""

SITL_UART_COUNT = 8
"""The SITL target defines UART1..UART8 (``USE_UART1``..``USE_UART8``, no VCP)."""

SITL_TCP_PORTS: tuple[int, ...] = (5761,)
"""TCP ports a freshly started 4.6.0 SITL listens on: only UART1 (MSP and CLI).

Each UART is emulated by a TCP listener on ``5760 + n``, but ``serTcpOpen`` is only called
for a UART that has a serial function assigned.  The default serial config
(``pgResetFn_serialConfig``) gives ``FUNCTION_MSP`` to port 0 (UART1) only, and the SITL
target defines no MSP_UART / SERIALRX_UART / GPS_UART extras.  Measured on 4.6.0 with a fresh
``eeprom.bin``: ``/proc/net/tcp`` showed a single LISTEN socket, ``0.0.0.0:5761``.  Ports
5762..5768 (UART2..8) appear only after ``serial`` is configured in the CLI and saved; see
:data:`SITL_UART_TCP_PORTS` and :func:`uart_tcp_port`.
"""

SITL_UART_TCP_PORTS: tuple[int, ...] = tuple(
    TCP_BASE_PORT + uart for uart in range(1, SITL_UART_COUNT + 1)
)
"""Every TCP port the SITL can listen on (UART1..8 -> 5761..5768), for configured FCs."""

SITL_UDP_PORTS: tuple[int, ...] = (9003, 9004)
"""UDP ports the SITL binds: 9003 fdm_packet (physics state in), 9004 rc_packet (RC in).

Its two outgoing sockets (to 9002 and 9001) are unbound and get ephemeral ports.
"""

SIM_UDP_PORTS: tuple[int, ...] = (9002, 9001)
"""UDP ports the physics side binds: 9002 servo_packet (motors), 9001 servo_packet_raw."""

TCP_LISTEN_STATE = 0x0A
"""``TCP_LISTEN`` in the kernel's ``st`` column."""

PROC_ROOT = Path("/proc")

_PROTOCOLS = ("tcp", "udp")


@dataclass(frozen=True)
class ProcNetSocket:
    """One row of /proc/<pid>/net/{tcp,tcp6,udp,udp6}: a socket and its local address."""

    protocol: str
    address: str
    port: int
    state: int
    inode: int
    #: Bytes waiting to be read; for a LISTEN socket, connections waiting to be accepted.
    rx_queue: int = 0


@dataclass(frozen=True)
class PortHolder:
    """A process (``pid`` None when we may not see it) holding a port the SITL needs."""

    protocol: str
    port: int
    address: str
    pid: int | None
    command: str | None

    def describe(self) -> str:
        """One line for an error message, e.g. ``tcp 5761 held by pid 1234 (betaflight_...)``."""
        where = f"{self.protocol} {self.port}"
        if self.pid is None:
            return f"{where} held by a process we cannot see (another user or namespace)"
        if self.command:
            return f"{where} held by pid {self.pid} ({self.command})"
        return f"{where} held by pid {self.pid}"


def uart_tcp_port(uart: int) -> int:
    """The TCP port emulating UART ``uart`` (1-based, as in the CLI): 1 -> 5761."""
    if not 1 <= uart <= SITL_UART_COUNT:
        raise ValueError(f"SITL has UART1..UART{SITL_UART_COUNT}, got UART{uart}")
    return TCP_BASE_PORT + uart


def decode_address(hex_address: str, *, byteorder: str = sys.byteorder) -> tuple[str, int]:
    """Decode ``0100007F:1F90`` (or a 32-hex-digit IPv6 address) into ``("127.0.0.1", 8080)``.

    The kernel prints the address as 32-bit words in host byte order (so reversed on x86),
    the port as plain big hex.  ``byteorder`` exists so tests can check both orders.
    """
    addr_hex, sep, port_hex = hex_address.partition(":")
    if not sep or len(addr_hex) not in (8, 32):
        raise ValueError(f"not a /proc/net address: {hex_address!r}")
    raw = bytes.fromhex(addr_hex)
    if byteorder == "little":
        raw = b"".join(raw[i : i + 4][::-1] for i in range(0, len(raw), 4))
    return _format_ip(ipaddress.ip_address(raw)), int(port_hex, 16)


def _format_ip(ip: ipaddress.IPv4Address | ipaddress.IPv6Address) -> str:
    """Text form; v4-mapped IPv6 spelt ``::ffff:127.0.0.1`` on every Python version."""
    if isinstance(ip, ipaddress.IPv6Address) and ip.ipv4_mapped is not None:
        return f"::ffff:{ip.ipv4_mapped}"
    return str(ip)


def parse_proc_net(text: str, protocol: str) -> list[ProcNetSocket]:
    """Parse the text of /proc/net/{tcp,tcp6,udp,udp6}; ``protocol`` is ``"tcp"`` or ``"udp"``.

    IPv4 and IPv6 files share one layout (``sl local_address rem_address st ... inode``), so
    the family follows from the address length.  Malformed lines are skipped: the files are
    written by the kernel and a partial read must not stop the check.
    """
    if protocol not in _PROTOCOLS:
        raise ValueError(f"protocol must be one of {_PROTOCOLS}, got {protocol!r}")
    sockets: list[ProcNetSocket] = []
    for line in text.splitlines():
        row = _parse_row(line, protocol)
        if row is not None:
            sockets.append(row)
    return sockets


def _parse_row(line: str, protocol: str) -> ProcNetSocket | None:
    """One data line, or None for the header and anything malformed."""
    fields = line.split()
    if len(fields) < 10 or not fields[0].endswith(":"):
        return None
    try:
        address, port = decode_address(fields[1])
        rx_queue = int(fields[4].partition(":")[2], 16)  # the column is tx_queue:rx_queue
        return ProcNetSocket(protocol, address, port, int(fields[3], 16), int(fields[9]), rx_queue)
    except ValueError:
        return None


def select_sockets(
    sockets: Iterable[ProcNetSocket], tcp_ports: Iterable[int], udp_ports: Iterable[int]
) -> list[ProcNetSocket]:
    """Sockets that would clash: TCP listeners and any bound UDP socket on the given ports.

    Only LISTEN matters for TCP (the SITL's ``SO_REUSEADDR`` listener ignores TIME_WAIT
    leftovers); for UDP every bound socket counts, since UDP has no listen state.
    """
    tcp, udp = set(tcp_ports), set(udp_ports)
    chosen = []
    for sock in sockets:
        if sock.protocol == "tcp" and sock.port in tcp and sock.state == TCP_LISTEN_STATE:
            chosen.append(sock)
        elif sock.protocol == "udp" and sock.port in udp:
            chosen.append(sock)
    return chosen


def read_proc_net(
    netns_pid: int | None = None, *, proc_root: Path = PROC_ROOT
) -> list[ProcNetSocket]:
    """All TCP and UDP sockets of the network namespace of ``netns_pid`` (default: ours).

    A missing file (IPv6 disabled) is skipped; a missing process is an error, because
    silently reporting "free" for a namespace that is gone would be a lie.
    """
    base = proc_root / ("self" if netns_pid is None else str(netns_pid))
    if netns_pid is not None and not base.exists():
        raise ProcessLookupError(f"no process {netns_pid}: cannot read its network namespace")
    sockets: list[ProcNetSocket] = []
    for name, protocol in (("tcp", "tcp"), ("tcp6", "tcp"), ("udp", "udp"), ("udp6", "udp")):
        try:
            text = (base / "net" / name).read_text()
        except (FileNotFoundError, PermissionError):
            continue
        sockets.extend(parse_proc_net(text, protocol))
    return sockets


def socket_owners(inodes: Iterable[int], *, proc_root: Path = PROC_ROOT) -> dict[int, list[int]]:
    """Map socket inodes to the pids that have them open, via ``/proc/<pid>/fd`` symlinks.

    Processes come and go during the scan and other users' fds are unreadable, so those
    errors are skipped; an inode nobody visible holds is simply absent from the result.
    """
    wanted = {f"socket:[{inode}]": inode for inode in inodes}
    owners: dict[int, list[int]] = {}
    if not wanted:
        return owners
    for pid in _pids(proc_root):
        for inode in _process_socket_inodes(proc_root / str(pid) / "fd", wanted):
            pids = owners.setdefault(inode, [])
            if pid not in pids:
                pids.append(pid)
    return owners


def _pids(proc_root: Path) -> list[int]:
    """Numeric /proc entries, i.e. every process visible to us."""
    try:
        return sorted(int(name) for name in os.listdir(proc_root) if name.isdigit())
    except OSError:
        return []


def _process_socket_inodes(fd_dir: Path, wanted: Mapping[str, int]) -> list[int]:
    """Wanted socket inodes among one process's fds; [] if it vanished or is not ours."""
    try:
        fds = os.listdir(fd_dir)
    except OSError:  # PermissionError, FileNotFoundError, ProcessLookupError
        return []
    found = []
    for fd in fds:
        try:
            target = os.readlink(fd_dir / fd)
        except OSError:
            continue
        inode = wanted.get(target)
        if inode is not None:
            found.append(inode)
    return found


def process_command(pid: int, *, proc_root: Path = PROC_ROOT) -> str | None:
    """Short name of a process for messages: basename of argv[0], else ``comm``, else None.

    ``comm`` is cut at 15 characters ("betaflight_4.6."), so argv[0] is tried first.
    """
    try:
        argv0 = (proc_root / str(pid) / "cmdline").read_bytes().split(b"\0", 1)[0]
        if argv0:
            return os.path.basename(argv0.decode(errors="replace"))
    except OSError:
        pass
    try:
        return (proc_root / str(pid) / "comm").read_text().strip() or None
    except OSError:
        return None


def find_port_holders(
    tcp_ports: Iterable[int],
    udp_ports: Iterable[int],
    *,
    netns_pid: int | None = None,
) -> list[PortHolder]:
    """Every TCP listener and bound UDP socket on the given ports, with its process if visible.

    Looks in the network namespace of ``netns_pid`` (default: our own).  A socket shared by
    several processes (after fork) gives one holder per process.
    """
    clashes = select_sockets(read_proc_net(netns_pid), tcp_ports, udp_ports)
    owners = socket_owners(sock.inode for sock in clashes)
    holders: list[PortHolder] = []
    for sock in clashes:
        pids: list[int | None] = [*owners.get(sock.inode, [])] or [None]
        for pid in pids:
            command = None if pid is None else process_command(pid)
            holders.append(PortHolder(sock.protocol, sock.port, sock.address, pid, command))
    return sorted(holders, key=_holder_key)


def _holder_key(holder: PortHolder) -> tuple[str, int, int, str]:
    return (holder.protocol, holder.port, -1 if holder.pid is None else holder.pid, holder.address)


def format_port_conflict(held_by: Iterable[PortHolder]) -> str:
    """The PortInUseError message: who holds what, then what to do about it."""
    holders = list(held_by)
    lines = list(dict.fromkeys(holder.describe() for holder in holders))
    pids = sorted({holder.pid for holder in holders if holder.pid is not None})
    held_udp = sorted({holder.port for holder in holders if holder.protocol == "udp"})
    advice = []
    if pids:
        advice.append(f"stop that process (kill {' '.join(str(pid) for pid in pids)})")
    if any(holder.pid is None for holder in holders):
        advice.append("find the hidden holder with `sudo ss -ltnup` and stop it")
    advice.append("or run the SITL isolated in its own network namespace (--isolate)")
    text = "ports the SITL needs are already in use:\n"
    text += "\n".join(f"  {line}" for line in lines)
    text += "\nTo fix: " + ", ".join(advice) + "."
    listed = "/".join(str(port) for port in (held_udp or SITL_UDP_PORTS))
    text += (
        f"\nDo not just start another SITL anyway: it binds with SO_REUSEADDR, so it would "
        f"silently share UDP {listed} with the holder and each would get part of the packets."
    )
    return text


def check_ports_free(
    tcp_ports: Iterable[int] = SITL_TCP_PORTS,
    udp_ports: Iterable[int] = SITL_UDP_PORTS,
    *,
    netns_pid: int | None = None,
) -> None:
    """Raise :class:`PortInUseError` if any of the ports is held; the error carries ``holders``.

    Checks before starting, because the SITL itself would not fail (see module docstring).
    """
    holders = find_port_holders(tcp_ports, udp_ports, netns_pid=netns_pid)
    if holders:
        error = PortInUseError(format_port_conflict(holders))
        error.holders = holders  # type: ignore[attr-defined]
        raise error
