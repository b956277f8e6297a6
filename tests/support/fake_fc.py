"""An in-memory flight controller for fast unit tests of the MSP client and CLI session.

It behaves like the firmware where the client's logic depends on it: one request answered per
"tick" (here: per read call), replies in request order, no reply to a bad checksum, ``!`` for
unknown commands, and CLI mode that echoes bytes as text.  Knobs let a test drop, corrupt or
delay replies.  The real SITL runs the same client code in tests/integration.

:class:`FakeCliLink` adds the port's CLI as Betaflight 4.6 implements it (``cli/cli.c``
``processCharacter``/``cliEnter``/``cliExit``, ``msp/msp_serial.c`` ``mspSerialProcess``): a lone
``#`` followed by silence enters the interactive CLI, ``0x02`` the non-interactive one until
``0x03``, and ``save``/``exit`` reboot, which for a SITL process means end of stream.
"""

from __future__ import annotations

import errno
import time
from collections import deque
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

from bfsitl.link.base import Link
from bfsitl.protocol import messages as msg
from bfsitl.protocol.msp_codes import MspCommand
from bfsitl.protocol.msp_frame import Direction, MspFrame, MspParser, encode_frame

Handler = Callable[[MspFrame], bytes | None]


def _printable(byte: int) -> bool:
    return 32 <= byte <= 126


def _cli_echo(data: bytes) -> bytes:
    """What the interactive CLI echoes for typed bytes: printable ones, and CR/LF as CRLF."""
    out = bytearray()
    for byte in data:
        if byte in (0x0D, 0x0A):
            out += b"\r\n"
        elif _printable(byte):
            out.append(byte)
    return bytes(out)


@dataclass
class _Received:
    frame: MspFrame
    at_s: float
    size: int


class FakeFcLink(Link):
    """An FC that answers MSP from ``handlers`` (command id -> payload, or None for silence)."""

    def __init__(self, handlers: Mapping[int, Handler] | None = None) -> None:
        super().__init__("fake://fc", timeout_s=0.2)
        self.handlers: dict[int, Handler] = dict(handlers or {})
        self._parser = MspParser()
        self._pending: deque[_Received] = deque()  # requests received, not yet answered
        self._out = bytearray()
        self.received: list[MspFrame] = []  # requests that reached the FC
        self.sent_commands: list[int] = []  # every request parsed, dropped ones too
        self.raw_written = bytearray()
        self.drop_next: set[int] = set()  # command ids whose next request is lost
        self.corrupt_next: set[int] = set()  # command ids whose next reply is corrupted
        self.reply_delay_s: dict[int, float] = {}  # command id -> time before it is answered
        self.cli_mode = False  # echo like a port left in CLI mode
        self.echo_requests = False  # a half-duplex line hears its own bytes
        self.max_unanswered_bytes = 0
        self.max_unanswered_requests = 0
        self._unanswered_bytes = 0
        self.answers_per_read = 1
        self.closed_by_peer = False  # the FC closed the stream (SITL exited)

    # -- Link hooks --------------------------------------------------------------------------
    def _write_bytes(self, data: bytes) -> None:
        self.raw_written += data
        if self.echo_requests:
            self._out += data
        if self.cli_mode:
            # The CLI echoes printable characters only (cli.c processCharacter), so an MSP
            # request comes back as e.g. "$M<ll": never a valid frame.
            self._out += _cli_echo(data)
            return
        self._feed_msp(data)

    def _read_bytes(self, max_bytes: int, timeout_s: float) -> bytes | None:
        if not self.closed_by_peer:  # a closed peer answers nothing more: buffered bytes, EOF
            self._answer_pending()
        return self._serve(max_bytes, timeout_s)

    def _close(self) -> None:
        pass

    # -- test API ----------------------------------------------------------------------------
    def inject(self, data: bytes) -> None:
        """Bytes the FC sends unprompted (garbage, CLI text)."""
        self._out += data

    # -- internals ---------------------------------------------------------------------------
    def _feed_msp(self, data: bytes) -> None:
        for event in self._parser.feed(data):
            if not isinstance(event, MspFrame) or event.direction is not Direction.REQUEST:
                continue
            self.sent_commands.append(event.command)
            if event.command in self.drop_next:
                self.drop_next.discard(event.command)
                continue
            self.received.append(event)
            size = len(encode_frame(event))
            self._pending.append(_Received(event, time.monotonic(), size))
            self._unanswered_bytes += size
            self.max_unanswered_bytes = max(self.max_unanswered_bytes, self._unanswered_bytes)
            self.max_unanswered_requests = max(self.max_unanswered_requests, len(self._pending))

    def _answer_pending(self) -> None:
        for _ in range(self.answers_per_read):
            if not self._pending:
                break
            head = self._pending[0]
            request = head.frame
            if time.monotonic() < head.at_s + self.reply_delay_s.get(request.command, 0.0):
                break  # in order: a slow head holds back everything behind it
            self._pending.popleft()
            self._unanswered_bytes -= head.size
            handler = self.handlers.get(request.command)
            if handler is None:
                reply = MspFrame(request.command, b"", Direction.ERROR, request.version)
            else:
                payload = handler(request)
                if payload is None:
                    continue  # the FC sends nothing
                reply = MspFrame(request.command, payload, Direction.REPLY, request.version)
            frame = bytearray(encode_frame(reply))
            if request.command in self.corrupt_next:
                self.corrupt_next.discard(request.command)
                frame[-1] ^= 0xFF
            self._out += frame

    def _serve(self, max_bytes: int, timeout_s: float) -> bytes | None:
        if not self._out:
            if self.closed_by_peer:
                return None
            time.sleep(min(timeout_s, 0.002))  # like a real read: nothing came in the wait
            return b""
        data = bytes(self._out[:max_bytes])
        del self._out[:max_bytes]
        return data


# --- MSP reply helpers --------------------------------------------------------------------------


def fixed(payload: bytes) -> Handler:
    """A handler that always answers ``payload``."""
    return lambda _request: payload


def multiple_msp(handlers: Mapping[int, Handler], limit: int | None = None) -> Handler:
    """An MSP_MULTIPLE_MSP handler built from per-command handlers (msp.c:2406-2437).

    Unknown commands contribute an empty sub-reply; ``limit`` truncates the list of sub-replies
    as the FC does when its output buffer is full.
    """

    def handle(request: MspFrame) -> bytes:
        commands = msg.MultipleMspRequest.decode(request.payload).commands
        parts: list[bytes] = []
        for command in commands:
            handler = handlers.get(command)
            sub = handler(MspFrame(command, b"", Direction.REQUEST)) if handler else None
            parts.append(sub or b"")
        if limit is not None:
            parts = parts[:limit]
        return msg.MultipleMspReply(tuple(parts)).encode()

    return handle


def telemetry_handlers(
    *,
    attitude: msg.Attitude,
    altitude: msg.Altitude,
    status: msg.StatusEx,
    analog: msg.Analog,
    rc: msg.Rc,
    motor: msg.Motor,
    imu: msg.RawImu,
    box_ids: tuple[int, ...],
) -> dict[int, Handler]:
    """Handlers answering each telemetry read with its codec's encoding, plus BOXIDS.

    Install MSP_MULTIPLE_MSP with ``link.handlers[MULTIPLE_MSP] = multiple_msp(link.handlers)``
    so that it follows later changes to the link's handlers.
    """
    messages = (attitude, altitude, status, analog, rc, motor, imu, msg.BoxIds(box_ids))
    return {int(m.COMMAND): fixed(m.encode()) for m in messages}


def telemetry_link(**messages: Any) -> FakeFcLink:
    """A FakeFcLink that answers the telemetry reads, BOXIDS and MSP_MULTIPLE_MSP.

    Takes the keyword arguments of :func:`telemetry_handlers`.
    """
    link = FakeFcLink(telemetry_handlers(**messages))
    link.handlers[MspCommand.MULTIPLE_MSP] = multiple_msp(link.handlers)
    return link


# --- the CLI ------------------------------------------------------------------------------------

CLI_BANNER = b"\r\nEntering CLI Mode, type 'exit' to reboot, or 'help'\r\n\r\n# "
CLI_PROMPT = b"\r\n# "
UNKNOWN_COMMAND = "###ERROR IN input: UNKNOWN COMMAND, TRY 'HELP'###"

#: Shaped like the real ``diff all`` of 4.6 (cli.c printConfig): many lines start with "# ",
#: and the last line, "save", has no line break.
DIFF_ALL = (
    "\r\n# version\r\n"
    "# Betaflight / SITL (SITL) 4.6.0 Jan  1 2025 / 00:00:00 (norevision) MSP API: 1.47\r\n"
    "\r\n# start the command batch\r\n"
    "batch start\r\n"
    "\r\n# reset configuration to default settings\r\n"
    "defaults nosave\r\n"
    "\r\n"
    "board_name SITL\r\n"
    "\r\n# name: -\r\n"
    "\r\n# aux\r\n"
    "aux 0 0 0 1700 2100 0 0\r\n"
    "\r\n# master\r\n"
    "set small_angle = 180\r\n"
    "\r\n# profile 0\r\n"
    "\r\n# restore original profile selection\r\n"
    "profile 0\r\n"
    "\r\n# rateprofile 0\r\n"
    "\r\n# restore original rateprofile selection\r\n"
    "rateprofile 0\r\n"
    "\r\n# save configuration\r\n"
    "save"
)

#: name -> (value, minimum, maximum), as ``get`` and ``set`` see them.
DEFAULT_SETTINGS: dict[str, tuple[int, int, int]] = {
    "small_angle": (25, 0, 180),
    "rc_smoothing_auto_factor": (30, 0, 250),
    "rc_smoothing_auto_factor_throttle": (30, 0, 250),
    "serial_update_rate_hz": (100, 100, 2000),
}


class FakeCliLink(FakeFcLink):
    """A port that speaks MSP until a lone ``#`` (then silence) or ``0x02`` puts it in the CLI.

    ``state`` is ``"msp"``, ``"cli"`` (interactive), ``"stx"`` (non-interactive) or
    ``"rebooted"`` (the SITL process exited: reads return what was printed, then EOF).
    Output is handed out ``chunk_size`` bytes per read, so a reader sees it split.
    """

    def __init__(
        self,
        handlers: Mapping[int, Handler] | None = None,
        *,
        state: str = "msp",
        settings: Mapping[str, tuple[int, int, int]] | None = None,
        enter_silence_s: float = 0.1,
        chunk_size: int = 16,
    ) -> None:
        super().__init__(handlers)
        self.uri = "fake://cli"
        self.state = state
        self.settings: dict[str, tuple[int, int, int]] = dict(settings or DEFAULT_SETTINGS)
        self.enter_silence_s = enter_silence_s
        self.chunk_size = chunk_size
        self.overrides: dict[str, str] = {}  # command line -> output, replaces the built-in
        self.commands_run: list[tuple[str, str]] = []  # (mode, line) of every command executed
        self.cli_entries = 0
        self.saves = 0
        self._line = bytearray()
        self._hash_at_s: float | None = None

    # -- Link hooks --------------------------------------------------------------------------
    def _write_bytes(self, data: bytes) -> None:
        if self.state == "rebooted":
            raise BrokenPipeError(errno.EPIPE, "the SITL process has exited")
        self._check_pending_cli()
        self.raw_written += data
        for byte in data:
            if self.state == "cli":
                self._interactive_char(byte)
            elif self.state == "stx":
                self._stx_char(byte)
            elif self.state == "msp":
                self._msp_char(byte)

    def _read_bytes(self, max_bytes: int, timeout_s: float) -> bytes | None:
        self._check_pending_cli()
        if self.state == "msp":
            self._answer_pending()
        if not self._out and self.state == "rebooted":
            return None
        return self._serve(min(max_bytes, self.chunk_size), timeout_s)

    # -- MSP state ---------------------------------------------------------------------------
    def _msp_char(self, byte: int) -> None:
        # msp_serial.c mspSerialProcess: any byte aborts a pending CLI request; outside a
        # frame, '#' starts one and 0x02 enters the non-interactive CLI at once.
        self._hash_at_s = None
        outside_frame = self._parser.pending_bytes == 0
        if outside_frame and byte == ord("#"):
            self._hash_at_s = time.monotonic()
        elif outside_frame and byte == 0x02:
            self.state = "stx"
            self._out += b"\x02"
        else:
            self._feed_msp(bytes((byte,)))

    def _check_pending_cli(self) -> None:
        if self._hash_at_s is None:
            return
        if time.monotonic() - self._hash_at_s >= self.enter_silence_s:
            self._hash_at_s = None
            self.state = "cli"
            self.cli_entries += 1
            self._line.clear()
            self._out += CLI_BANNER

    # -- interactive CLI ---------------------------------------------------------------------
    def _interactive_char(self, byte: int) -> None:
        if byte == 0x04 and not self._line:  # CTRL-D: cliExit(true), a reboot
            self._reboot()
            return
        if byte in (0x0D, 0x0A) and self._line:
            self._out += b"\r\n"
            line = self._take_line()
            if line:
                self._out += self._execute(line, interactive=True).encode("ascii")
            if self.state == "cli":
                self._out += CLI_PROMPT
        elif _printable(byte) and len(self._line) < 256:
            if not self._line and byte == ord(" "):
                return
            self._line.append(byte)
            self._out.append(byte)

    # -- non-interactive CLI (STX .. ETX) ----------------------------------------------------
    def _stx_char(self, byte: int) -> None:
        if byte == 0x03:
            self._out += b"\x03"
            self.state = "msp"
            self._line.clear()
            return
        if byte in (0x0D, 0x0A) and self._line:
            line = self._take_line()
            if line:
                self._out += self._execute(line, interactive=False).encode("ascii")
        elif _printable(byte) and len(self._line) < 256:
            if not self._line and byte == ord(" "):
                return
            self._line.append(byte)

    def _take_line(self) -> str:
        text = self._line.decode("ascii")
        self._line.clear()
        return text.split("#", 1)[0].rstrip(" ")

    # -- commands ----------------------------------------------------------------------------
    def _execute(self, line: str, *, interactive: bool) -> str:
        self.commands_run.append(("cli" if interactive else "stx", line))
        if line in self.overrides:
            return self.overrides[line]
        name, _, args = line.partition(" ")
        name = name.lower()
        args = args.strip()
        if name == "get":
            return self._get(args)
        if name == "set":
            return self._set(args)
        if name == "diff" and args == "all":
            return DIFF_ALL
        if name == "save":
            self.saves += 1
            if args.lower() == "noreboot":
                return "\r\n# saving\r\n"
            self._reboot(prefix=b"\r\n# saving\r\n")
            return ""
        if name == "defaults":  # cli.c cliDefaults: reboots unless "nosave"
            options = args.lower().split()
            if any(option != "nosave" for option in options):
                return "###ERROR IN defaults: PARSING FAILED###\r\n"
            text = "\r\n# resetting to defaults\r\n"
            self.settings = dict(DEFAULT_SETTINGS)
            if options:
                return text
            self._reboot(prefix=text.encode("ascii"))
            return ""
        if name == "exit":
            if args.lower() == "noreboot":
                self.state = "msp"
                self._line.clear()
                return "\r\n# leaving CLI mode, no reboot\r\n"
            self._reboot(prefix=b"\r\n# leaving CLI mode, unsaved changes lost\r\n")
            return ""
        if interactive:
            return UNKNOWN_COMMAND  # cliPrintError: no line break of its own
        return f"ERR_CMD_NA: {line}\r\n"

    def _get(self, pattern: str) -> str:
        blocks = []
        for name, (value, low, high) in self.settings.items():
            if pattern.lower() in name:
                blocks.append(f"{name} = {value}\r\nAllowed range: {low} - {high}\r\n")
        if not blocks:
            return f"###ERROR IN get: INVALID NAME: {pattern}###\r\n"
        return "\r\n".join(blocks)

    def _set(self, args: str) -> str:
        name, eq, raw_value = (part.strip() for part in args.partition("="))
        if not eq:
            return self._get(name)
        if name not in self.settings:
            return f"###ERROR IN set: INVALID NAME: {name}###\r\n"
        _, low, high = self.settings[name]
        try:
            value = int(raw_value)
        except ValueError:
            value = low - 1
        if not low <= value <= high:
            return f"###ERROR IN set: INVALID VALUE###\r\nAllowed range: {low} - {high}\r\n"
        self.settings[name] = (value, low, high)
        return f"{name} set to {value}"

    def _reboot(self, prefix: bytes = b"") -> None:
        self._out += prefix + b"\r\nRebooting"
        self.state = "rebooted"
        self._line.clear()


__all__ = [
    "CLI_BANNER",
    "DIFF_ALL",
    "FakeCliLink",
    "FakeFcLink",
    "Handler",
    "fixed",
    "multiple_msp",
    "telemetry_handlers",
    "telemetry_link",
]
