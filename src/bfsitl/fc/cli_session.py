"""The Betaflight CLI over an MSP port: enter, run commands, diff, save.

How the firmware behaves (``cli/cli.c``, ``msp/msp_serial.c``, measured on 4.6.0 SITL):

* The CLI is entered by a lone ``#`` followed by at least 100 ms of silence; ``"#\\r\\n"`` in one
  write does not enter it.  The banner is followed by the prompt ``"\\r\\n# "``.
* The prompt alone cannot end a command's output: ``diff all`` prints many lines that start
  with ``# ``.  After each command we therefore send a comment line ``#bfsync-N``; the CLI
  ignores comments but echoes the characters, and it echoes them only once the command before
  has finished printing.  Seeing the echo is a deterministic end-of-output marker.
* CLI mode belongs to the port, not the connection: a port left in CLI by a dropped client
  echoes MSP bytes as text.  :meth:`CliSession.enter` works in both states, and
  :meth:`CliSession.leave` returns the port to MSP without rebooting.
* An interactive session sets the ``CLI`` arming-disable flag until the next reboot;
  :meth:`CliSession.batch` uses the non-interactive (STX/ETX) mode, which does not.
* ``save``, ``exit`` and ``defaults`` reboot, and a SITL *process* exits on reboot: pass a
  ``restart`` callback to :meth:`CliSession.save` (``SitlProcess.restart_after_reboot``).
"""

from __future__ import annotations

import itertools
import os
import time
from collections.abc import Callable, Iterable
from pathlib import Path

from bfsitl.errors import CliCommandError, CliError, LinkClosedError
from bfsitl.link.base import Link

PROMPT = b"\r\n# "
BANNER = b"Entering CLI Mode"
#: The FC's line buffer is 256 bytes; keep well inside it.
MAX_COMMAND_LENGTH = 200
_ENTER_SILENCE_S = 0.15
#: The second try's silence, when the first '#' was not taken (a starved SITL).
_ENTER_RETRY_SILENCE_S = 0.6
_STX, _ETX = b"\x02", b"\x03"
#: Commands after which the FC reboots (and a SITL process exits).
_REBOOTING = ("save", "exit", "defaults", "bl", "dfu", "msc")


class CliSession:
    """An interactive CLI session on one link (TCP to a SITL, or a serial port).

    Nothing is sent when it is made: :meth:`enter` (or entering the ``with`` block) enters
    the CLI, and leaving the block returns the port to MSP.

    Args:
        link: The open transport to the FC's MSP port; the session does not close it.
        timeout_s: Seconds to wait for a command's output (``diff all`` and ``save`` take at
            least 10).
    """

    def __init__(self, link: Link, *, timeout_s: float = 5.0) -> None:
        self.link = link
        self.timeout_s = timeout_s
        self.active = False
        self.banner = ""
        self._sync_ids = itertools.count(1)

    # -- entering and leaving --------------------------------------------------------------
    def enter(self) -> CliSession:
        """Put the port in CLI mode (also works when it was left in CLI mode)."""
        # 0x03 ends a non-interactive session a stray 0x02 may have started; it is ignored
        # in MSP and interactive CLI states.  Then let the line go quiet.
        self.link.write(_ETX)
        self.link.drain_input(quiet_s=_ENTER_SILENCE_S)
        self.link.write(b"#")
        # The firmware enters the CLI only after this much silence following the '#'.
        self.link.pause(_ENTER_SILENCE_S)
        try:
            text = self._sync()
        except CliError:
            # A SITL starved of CPU may not run its serial task within that silence: it then
            # reads the '#' together with the sync line and stays in MSP (seen in loaded test
            # runs: no output at all). Once more, with a longer silence.
            self.link.drain_input(quiet_s=_ENTER_SILENCE_S)
            self.link.write(b"#")
            self.link.pause(_ENTER_RETRY_SILENCE_S)
            text = self._sync()
        self.banner = text.decode("ascii", "replace").strip()
        self.active = True
        return self

    def leave(self) -> str:
        """Return the port to MSP without rebooting (``exit noreboot``).

        The ``CLI`` arming-disable flag stays set until the next reboot.
        """
        self._require_active()
        self.link.write(b"exit noreboot\r")
        output = self._read_until(b"leaving CLI mode", self.timeout_s)
        self.link.drain_input(quiet_s=0.05)
        self.active = False
        return output.decode("ascii", "replace")

    def __enter__(self) -> CliSession:
        return self.enter()

    def __exit__(self, *exc_info: object) -> None:
        if self.active and not self.link.closed:
            try:
                self.leave()
            except (CliError, LinkClosedError):
                pass

    # -- running commands ------------------------------------------------------------------
    def run(self, command: str, *, check: bool = True, timeout_s: float | None = None) -> str:
        """Run one command and return its output (without the echo and the prompt).

        Use :meth:`save` / :meth:`leave` for commands that reboot or leave the CLI.

        Args:
            command: One CLI command, printable, without a line break.
            check: Raise when the output holds ``###ERROR``.
            timeout_s: Seconds to wait for its output; None takes the session's.

        Returns:
            What the command printed.

        Raises:
            CliCommandError: The output holds ``###ERROR`` and ``check`` is on.
            CliError: The session is not in the CLI, the command reboots or leaves it, holds
                a control character or is too long, or the output did not come in time.
        """
        self._require_active()
        command = command.strip()
        _validate(command)
        word = command.split(" ", 1)[0].lower()
        if word == "exit":
            raise CliError(f"{command!r} leaves the CLI: use leave()")
        _refuse_reboot(command)
        self.link.write(command.encode("ascii") + b"\r")
        raw = self._sync(timeout_s)
        output = _strip_echo(raw, command)
        if check and "###ERROR" in output:
            raise CliCommandError(command, output)
        return output

    def run_many(self, commands: Iterable[str], *, check: bool = True) -> list[str]:
        """Run several commands in order; blank lines and ``#`` comments are skipped.

        Args:
            commands: CLI lines, one command each.
            check: Raise at the first output holding ``###ERROR``.

        Returns:
            Each command's output, in order (skipped lines give none).

        Raises:
            CliCommandError: A command failed and ``check`` is on; the ones before it ran.
            CliError: As :meth:`run`.
        """
        outputs = []
        for line in commands:
            line = line.strip()
            if line and not line.startswith("#"):
                outputs.append(self.run(line, check=check))
        return outputs

    def get(self, name: str) -> str:
        """The value of one setting (``get`` matches substrings; this picks the exact name).

        Args:
            name: The setting's name, as ``get`` prints it.

        Returns:
            Its value as the CLI prints it.

        Raises:
            CliCommandError: There is no setting of that exact name.
        """
        output = self.run(f"get {name}")
        for line in output.splitlines():
            key, sep, value = line.partition(" = ")
            if sep and key.strip() == name:
                return value.strip()
        raise CliCommandError(f"get {name}", f"###ERROR no setting named {name!r}###\n{output}")

    def set(self, name: str, value: object) -> None:
        """``set name = value``, checked; not saved until :meth:`save`.

        Args:
            name: The setting's name.
            value: Its new value, written as ``str(value)``.

        Raises:
            CliCommandError: The CLI did not confirm the change (an unknown setting, a
                value out of range).
        """
        output = self.run(f"set {name} = {value}")
        if "set to" not in output:
            raise CliCommandError(f"set {name} = {value}", output)

    def diff_all(self) -> str:
        return self.run("diff all", timeout_s=max(self.timeout_s, 10.0))

    def backup(self, path: str | Path) -> Path:
        """Write ``diff all`` to ``path`` atomically (a crash never leaves half a backup).

        Args:
            path: The file to write; replaced if it exists.

        Returns:
            The path written.

        Raises:
            CliError: The CLI did not answer in time.
            OSError: The file cannot be written.
        """
        path = Path(path)
        text = self.diff_all()
        tmp = path.with_name(path.name + ".partial")
        tmp.write_text(text.replace("\r\n", "\n").strip() + "\n")
        os.replace(tmp, path)
        return path

    def save(self, restart: Callable[[], object] | None = None) -> str:
        """``save``: write the EEPROM and reboot.

        A SITL process exits on reboot; ``restart`` (for example
        ``sitl.restart_after_reboot``) is called once the FC has gone, and this session ends.

        Args:
            restart: Called with no arguments once the FC has gone; None calls nothing.

        Returns:
            What the FC printed before rebooting.

        Raises:
            CliError: The session is not in the CLI, or the FC did not answer in time.
        """
        self._require_active()
        self.link.write(b"save\r")
        output = b""
        try:
            output = self._read_until(b"Rebooting", max(self.timeout_s, 10.0))
            self.link.drain_input(quiet_s=0.2)
        except LinkClosedError:
            pass  # the SITL exits as it reboots; the socket closes under us
        self.active = False
        if restart is not None:
            restart()
        return _strip_echo(output, "save")

    # -- non-interactive batch (STX) -------------------------------------------------------
    def batch(self, commands: Iterable[str], *, check: bool = True) -> str:
        """Run commands in non-interactive mode (``0x02 ... 0x03``), from MSP state.

        No echo, no prompt, and no ``CLI`` arming flag afterwards.  The firmware ends the
        session 2 s after it began, so keep batches short.

        Args:
            commands: CLI lines; blank lines and ``#`` comments are skipped.
            check: Raise when the output holds ``###ERROR`` or ``ERR_CMD_NA``.

        Returns:
            Everything the batch printed.

        Raises:
            CliCommandError: A command failed and ``check`` is on.
            CliError: The interactive CLI is active, a line reboots the FC or is not
                printable, or the output did not come in time.
        """
        if self.active:
            raise CliError("batch() runs from MSP state; leave() the interactive CLI first")
        lines = [ln.strip() for ln in commands if ln.strip() and not ln.strip().startswith("#")]
        for line in lines:
            _validate(line)
            _refuse_reboot(line)
        self.link.drain_input(quiet_s=0.05)
        self.link.write(_STX + "".join(f"{ln}\n" for ln in lines).encode("ascii") + _ETX)
        raw = self._read_until(_ETX, self.timeout_s)
        start = raw.find(_STX)
        output = raw[start + 1 if start >= 0 else 0 : -1].decode("ascii", "replace")
        if check and ("###ERROR" in output or "ERR_CMD_NA" in output):
            raise CliCommandError("; ".join(lines), output)
        return output

    # -- internals -------------------------------------------------------------------------
    def _require_active(self) -> None:
        if not self.active:
            raise CliError("not in CLI mode: call enter() first")

    def _sync(self, timeout_s: float | None = None) -> bytes:
        """Send a comment marker and return everything the FC printed before its echo."""
        token = f"bfsync-{os.getpid()}-{next(self._sync_ids)}".encode()
        self.link.write(b"#" + token + b"\r")
        # Matched on its tail only: a loaded CI machine once saw the echo's first byte change
        # on the SITL's TCP path ("#ifsync-..."); pid and counter keep the tail unique.
        marker = token[2:] + b"\r\n"
        data = self._read_until(marker, timeout_s or self.timeout_s)
        at = data.rfind(marker)
        # Wait for the prompt that follows the marker's own (empty) command.
        tail = data[at + len(marker) :]
        if PROMPT not in tail:
            self._read_until(PROMPT, timeout_s or self.timeout_s, initial=tail)
        # The marker was typed after the prompt: keep the prompt, drop from the echoed '#'.
        line_start = data.rfind(b"\n", 0, at) + 1
        echoed_hash = data.rfind(b"#", line_start, at)
        return data[:echoed_hash] if echoed_hash >= 0 else data[:line_start]

    def _read_until(self, needle: bytes, timeout_s: float, initial: bytes = b"") -> bytes:
        deadline = time.monotonic() + timeout_s
        data = bytearray(initial)
        while needle not in data:
            remaining_s = deadline - time.monotonic()
            if remaining_s <= 0:
                shown = bytes(data[-200:]).decode("ascii", "replace")
                raise CliError(
                    f"CLI did not answer within {timeout_s} s on {self.link.uri} "
                    f"(waiting for {needle!r}; last output: {shown!r}). Is the port an MSP "
                    f"port, and is the FC running?"
                )
            data += self.link.read_some(min(remaining_s, 0.1))
        return bytes(data)


#: The option that makes a rebooting command stay up (``cli.c``).
_NO_REBOOT_OPTION = {"save": "noreboot", "exit": "noreboot", "defaults": "nosave"}


def _refuse_reboot(command: str) -> None:
    words = command.lower().split()
    if words and words[0] in _REBOOTING and _NO_REBOOT_OPTION.get(words[0]) not in words[1:]:
        raise CliError(
            f"{command!r} reboots the FC (a SITL process exits): use save(restart=...), or "
            f"'save noreboot' to write without rebooting"
        )


def _validate(command: str) -> None:
    # Control characters act as keys in the CLI: CTRL-D on an empty line exits and reboots,
    # TAB completes, DEL erases; 0x02/0x03 switch the port's mode.
    if any(ord(ch) < 0x20 or ord(ch) == 0x7F for ch in command):
        raise CliError(
            f"one printable command per call, without line breaks or control characters: "
            f"{command!r}"
        )
    if len(command) > MAX_COMMAND_LENGTH:
        raise CliError(
            f"command of {len(command)} characters exceeds the {MAX_COMMAND_LENGTH}-character "
            f"limit (the FC's line buffer is 256 bytes)"
        )
    try:
        command.encode("ascii")
    except UnicodeEncodeError as exc:
        raise CliError(f"the CLI takes ASCII only: {command!r}") from exc


def _strip_echo(raw: bytes, command: str) -> str:
    text = raw.decode("ascii", "replace")
    echo = command + "\r\n"
    start = text.find(echo)
    if start >= 0:
        text = text[start + len(echo) :]
    # Drop the trailing prompt the FC printed after the output.
    text = text.rstrip()
    if text.endswith("\r\n#") or text == "#":
        text = text[:-1]
    return text.strip("\r\n").rstrip()
