"""Configure a flight controller for autonomous flight: mode ranges, then a user's CLI lines.

Facts (``docs/firmware-findings.md``): arming needs an ARM mode range on an AUX channel (stick
arming is off in 4.6); the CLI form ``aux 0 0 0 1700 2100`` with 5 arguments crashes 4.6.0 SITL,
so only the 7-argument form is accepted; MSP_EEPROM_WRITE saves without rebooting (a reboot
ends a SITL process); an interactive CLI session blocks arming until reboot, so CLI lines go
through the non-interactive (STX) mode, a few at a time (that mode ends 2 s after it starts).

Mode ranges are read back after writing and compared; a persisted configuration that already
matches is left alone (nothing written, nothing saved).  ``set`` lines are compared the same
way (``get`` first, in the same non-interactive mode), and so are 4.6's ``serial UARTn ...``
lines (against the ``serial`` listing, which prints that very form); other CLI lines always
run.

Some settings are read only at boot (:data:`BOOT_ONLY_SETTINGS`): saving one does not raise
the firmware's reboot-required flag, yet nothing changes until a reboot, so changing one
reboots the FC as a flagged change does.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable
from dataclasses import dataclass
from pathlib import Path

from bfsitl.errors import ProvisioningError
from bfsitl.fc.cli_session import CliSession
from bfsitl.fc.msp_client import MspClient
from bfsitl.protocol import messages as msg
from bfsitl.protocol.boxes import BoxId

#: ARM while AUX1 is at 1700-2100 us: the default of every bfsitl flight.
ARM_ON_AUX1 = msg.ModeRange.from_us(BoxId.ARM, 0, 1700, 2100)
#: Self-levelling on AUX2, an optional extra.
ANGLE_ON_AUX2 = msg.ModeRange.from_us(BoxId.ANGLE, 1, 1700, 2100)
#: CLI lines per non-interactive batch: well inside the firmware's 2 s session.
_BATCH_LINES = 8
#: ``aux`` takes index, box, channel, start, end, logic, linked box: 7 arguments.
_AUX_ARGUMENTS = 7
#: Settings the firmware applies only at boot, without flagging a reboot when they change:
#: ``serial_update_rate_hz`` is the serial task's rate, set once in ``tasksInit()`` (4.6.0
#: and master fc/tasks.c ``rescheduleTask(TASK_SERIAL, ...)``); the blackbox's device and
#: sample rate are read once in ``blackboxInit()`` (blackbox/blackbox.c: a device of NONE at
#: boot leaves the blackbox DISABLED; measured: set without a reboot, no log was written).
BOOT_ONLY_SETTINGS = frozenset({"serial_update_rate_hz", "blackbox_device", "blackbox_sample_rate"})


@dataclass(frozen=True, slots=True)
class Profile:
    """What to configure: mode ranges in slots 0, 1, ... and CLI lines after them.

    Attributes:
        mode_ranges: Written to the FC's mode range slots 0, 1, ... in order; ARM on AUX1
            (1700 to 2100 microseconds) by default.
        cli_lines: CLI lines run after them (``set name = value``, ...); each is checked
            when the profile is made.
        reboot_when_changed: Reboot after saving whenever something changed: for lines the
            firmware applies at boot without saying so (a feature, a serial port's
            function).

    Raises:
        ProvisioningError: A CLI line the FC must not get (one that crashes, reboots or
            hangs it).
    """

    mode_ranges: tuple[msg.ModeRange, ...] = (ARM_ON_AUX1,)
    cli_lines: tuple[str, ...] = ()
    #: Reboot after saving whenever something changed: for lines the firmware applies at
    #: boot without saying so (a feature, a serial port's function).
    reboot_when_changed: bool = False

    def __post_init__(self) -> None:
        for line in self.cli_lines:
            validate_cli_line(line)

    @classmethod
    def from_file(
        cls, path: str | Path, mode_ranges: tuple[msg.ModeRange, ...] = (ARM_ON_AUX1,)
    ) -> Profile:
        """CLI lines from a file (``#`` comments and blank lines skipped); a file that cannot
        be read, is not text or holds a line the FC must not get is one error naming it.

        Args:
            path: A text file of CLI lines.
            mode_ranges: The profile's mode ranges; ARM on AUX1 by default.

        Returns:
            The profile.

        Raises:
            ProvisioningError: The file cannot be read or holds a line the FC must not get
                (the message names the file and the line).
        """
        from bfsitl.toml_file import read_text_file

        text = read_text_file(Path(path), "profile", ProvisioningError)
        lines = []
        for number, raw in enumerate(text.splitlines(), start=1):
            line = raw.strip()
            if line and not line.startswith("#"):
                try:
                    lines.append(validate_cli_line(line))
                except ProvisioningError as exc:
                    raise ProvisioningError(f"{path}, line {number}: {exc}") from None
        return cls(mode_ranges, tuple(lines))


@dataclass(frozen=True, slots=True)
class ProvisionResult:
    changed: bool  # something was written and saved
    mode_ranges_written: int
    cli_lines_run: int
    rebooted: bool


def validate_cli_line(line: str) -> str:
    """Refuse what would crash, reboot or hang the FC; return the line."""
    words = line.split()
    if not words:
        raise ProvisioningError("empty CLI line in the profile")
    control = next((c for c in line if ord(c) < 0x20 or ord(c) == 0x7F), None)
    if control is not None:
        # 0x02 and 0x03 switch the port in and out of the non-interactive CLI; any control
        # byte in a line is a mistake the FC would act on.
        raise ProvisioningError(f"{line!r}: holds the control character 0x{ord(control):02x}")
    command = words[0].lower()
    if command == "aux" and len(words) - 1 != _AUX_ARGUMENTS:
        raise ProvisioningError(
            f"{line!r}: aux needs {_AUX_ARGUMENTS} arguments (index box channel start end "
            f"logic linked), e.g. 'aux 0 0 0 1700 2100 0 0'; the 5-argument form crashes "
            f"Betaflight 4.6.0 SITL"
        )
    if command in ("save", "exit", "defaults", "bl", "dfu", "msc", "reboot"):
        raise ProvisioningError(
            f"{line!r}: provisioning saves by itself (without a reboot); remove this line"
        )
    return line


def _batches(lines: Iterable[str], size: int) -> Iterable[list[str]]:
    batch: list[str] = []
    for line in lines:
        batch.append(line)
        if len(batch) == size:
            yield batch
            batch = []
    if batch:
        yield batch


def provision(
    client: MspClient,
    profile: Profile = Profile(),
    *,
    reboot: Callable[[], object] | None = None,
) -> ProvisionResult:
    """Apply ``profile``, verify it, save it; skip what the FC already holds.

    ``reboot`` is called when a CLI line needs a reboot to take effect (the FC reports it in
    STATUS); it must reboot the FC and reconnect (for a SITL: MSP_REBOOT, then
    ``SitlProcess.restart_after_reboot``, whose ``client`` is the new connection).

    Args:
        client: The FC's MSP client; its link carries the CLI lines too.
        profile: What to configure; ARM on AUX1 by default.
        reboot: Called with no arguments when a reboot is needed; None makes that an error.

    Returns:
        Whether anything was written and saved, how much, and whether the FC rebooted.

    Raises:
        ProvisioningError: More mode ranges than the FC has slots, a slot that reads back
            otherwise, or a needed reboot without ``reboot``.
        CliCommandError: A CLI line failed.
        MspError: The FC stopped answering, or refused a write.
    """
    current = client.mode_ranges().ranges
    if len(profile.mode_ranges) > len(current):
        raise ProvisioningError(
            f"{len(profile.mode_ranges)} mode ranges asked, the FC has {len(current)} slots"
        )
    written = 0
    for index, wanted in enumerate(profile.mode_ranges):
        if current[index] != wanted:
            client.set_mode_range(index, wanted)
            written += 1
    if written:
        read_back = client.mode_ranges().ranges
        for index, wanted in enumerate(profile.mode_ranges):
            if read_back[index] != wanted:
                raise ProvisioningError(
                    f"mode range slot {index} reads back {read_back[index]} after writing "
                    f"{wanted}: is the box available on this FC (MSP_BOXIDS)?"
                )
    lines_run = 0
    boot_setting_changed = False
    if profile.cli_lines:
        cli = CliSession(client.link)
        lines = _lines_to_run(cli, profile.cli_lines)
        boot_setting_changed = any(set_name(line) in BOOT_ONLY_SETTINGS for line in lines)
        for batch in _batches(lines, _BATCH_LINES):
            cli.batch(batch)
            lines_run += len(batch)
    changed = bool(written or lines_run)
    rebooted = False
    if changed:
        client.eeprom_write()
        flagged = msg.StatusEx.decode(client.request(msg.StatusEx.COMMAND)).config_state & 1
        if flagged or boot_setting_changed or profile.reboot_when_changed:
            if reboot is None:
                raise ProvisioningError(
                    "the configuration was saved but needs a reboot to take effect; pass "
                    "reboot= (for a SITL: reboot, then restart the process)"
                )
            reboot()
            rebooted = True
    return ProvisionResult(changed, written, lines_run, rebooted)


def set_name(line: str) -> str | None:
    """The setting a ``set NAME = VALUE`` line sets (lower case), else None."""
    words = line.replace("=", " = ").split()
    if len(words) >= 4 and words[0].lower() == "set" and words[2] == "=":
        return words[1].lower()
    return None


def set_value(line: str) -> str:
    """The value of a line :func:`set_name` names a setting of (as written)."""
    return line.split("=", 1)[1].strip()


def _serial_line(line: str) -> str | None:
    """A ``serial UARTn ...`` line with single spaces (lower case), else None."""
    words = line.lower().split()
    if len(words) >= 3 and words[0] == "serial" and words[1].startswith("uart"):
        return " ".join(words)
    return None


def _lines_to_run(cli: CliSession, lines: tuple[str, ...]) -> list[str]:
    """``lines`` without the ``set`` lines whose setting already holds that value, nor the
    ``serial`` lines the port already has.  A setting set twice keeps its last line only: the
    later line wins, as it would typed in order (a scenario's lines after bfsitl's own, a
    comparison side's changed default); compared with the FC's value one by one, an earlier
    line could be run while the later, equal to the old value, was dropped.

    The current values come from one ``get`` per setting, in non-interactive batches (which
    leave no CLI arming flag); ``get NAME`` prints ``NAME = VALUE`` (4.6.0 and master
    cli.c ``cliGet``).  A value that does not read back the same way (case, a number's
    form) is simply set again.
    """
    last_set = {
        name: index for index, line in enumerate(lines) if (name := set_name(line)) is not None
    }
    lines = tuple(
        line
        for index, line in enumerate(lines)
        if (name := set_name(line)) is None or last_set[name] == index
    )
    names = [name for name in (set_name(line) for line in lines) if name is not None]
    current: dict[str, str] = {}
    for batch in _batches(names, _BATCH_LINES):
        output = cli.batch([f"get {name}" for name in batch], check=False)
        for raw in output.splitlines():
            name, sep, value = raw.partition(" = ")
            if sep and name.strip().lower() in batch:
                current[name.strip().lower()] = value.strip()
    held_ports: set[str] = set()
    if any(_serial_line(line) for line in lines):
        listing = cli.batch(["serial"], check=False)
        held_ports = {form for raw in listing.splitlines() if (form := _serial_line(raw))}
    return [
        line
        for line in lines
        if ((setting := set_name(line)) is None or current.get(setting) != set_value(line))
        and _serial_line(line) not in held_ports
    ]
