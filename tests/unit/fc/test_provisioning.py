"""Provisioning against a fake FC that stores mode ranges like the firmware does."""

from __future__ import annotations

import pytest
from support.storing_fc import StoringFc

from bfsitl.errors import ProvisioningError
from bfsitl.fc.msp_client import MspClient
from bfsitl.fc.provisioning import (
    ANGLE_ON_AUX2,
    ARM_ON_AUX1,
    Profile,
    provision,
    validate_cli_line,
)


def test_default_profile_arms_on_aux1_and_a_second_run_changes_nothing():
    fc = StoringFc()
    client = MspClient(fc.link, timeout_s=0.1)
    first = provision(client)
    assert first.changed and first.mode_ranges_written == 1
    assert fc.slots[0] == ARM_ON_AUX1 and fc.eeprom_writes == 1
    second = provision(client)
    assert not second.changed and second.mode_ranges_written == 0
    assert fc.eeprom_writes == 1  # nothing saved when nothing changed


def test_extra_modes_go_in_the_next_slots():
    fc = StoringFc()
    provision(MspClient(fc.link, timeout_s=0.1), Profile((ARM_ON_AUX1, ANGLE_ON_AUX2)))
    assert fc.slots[:2] == [ARM_ON_AUX1, ANGLE_ON_AUX2]


def test_a_range_that_does_not_read_back_is_an_error():
    fc = StoringFc(accept_writes=False)
    with pytest.raises(ProvisioningError, match="reads back"):
        provision(MspClient(fc.link, timeout_s=0.1))
    assert fc.eeprom_writes == 0  # nothing saved after a failed verification


@pytest.mark.parametrize("line", ["aux 0 0 0 1700 2100", "aux 0 0 0 1700 2100 0"])
def test_the_five_argument_aux_form_is_refused(line):
    with pytest.raises(ProvisioningError, match="crashes"):
        validate_cli_line(line)
    with pytest.raises(ProvisioningError):
        Profile(cli_lines=(line,))


@pytest.mark.parametrize("line", ["save", "exit", "defaults"])
def test_rebooting_lines_are_refused(line):
    with pytest.raises(ProvisioningError, match="saves by itself"):
        validate_cli_line(line)


def test_profile_file_skips_comments(tmp_path):
    path = tmp_path / "profile.txt"
    path.write_text("# my quad\n\naux 1 1 1 1700 2100 0 0\nset small_angle = 30\n")
    profile = Profile.from_file(path)
    assert profile.cli_lines == ("aux 1 1 1 1700 2100 0 0", "set small_angle = 30")
    assert profile.mode_ranges == (ARM_ON_AUX1,)


class GetOnlyCli:
    """CliSession.batch for ``get`` lines, answering as cli.c's cliGet prints."""

    def __init__(self, values: dict[str, str]) -> None:
        self.values = values
        self.batches: list[list[str]] = []

    def batch(self, commands: list[str], *, check: bool = True) -> str:
        self.batches.append(list(commands))
        out = []
        for command in commands:
            name = command.split()[1]
            if name in self.values:
                out.append(f"{name} = {self.values[name]}\r\nAllowed range: 0 - 9\r\n")
            else:
                out.append(f"###ERROR IN get: INVALID NAME: {name}###\r\n")
        return "".join(out)


def test_set_lines_whose_value_is_held_are_skipped_and_others_kept():
    from bfsitl.fc.provisioning import _lines_to_run

    cli = GetOnlyCli({"small_angle": "30", "serial_update_rate_hz": "100"})
    lines = (
        "set small_angle = 30",
        "set serial_update_rate_hz=1000",
        "feature GPS",
        "set no_such_setting = 1",
    )
    assert _lines_to_run(cli, lines) == [  # type: ignore[arg-type]
        "set serial_update_rate_hz=1000",
        "feature GPS",
        "set no_such_setting = 1",
    ]
    # One batch of gets, only for the set lines.
    assert cli.batches == [["get small_angle", "get serial_update_rate_hz", "get no_such_setting"]]


def test_a_setting_set_twice_ends_at_its_last_value_even_when_that_is_the_current_one():
    from bfsitl.fc.provisioning import _lines_to_run

    # The FC holds 1275; bfsitl's profile sets 1545, a later line (a scenario's, a
    # comparison's changed default) sets 1275 again: the last line wins, so nothing is run.
    cli = GetOnlyCli({"ap_hover_throttle": "1275"})
    lines = ("set ap_hover_throttle = 1545", "set ap_hover_throttle = 1275")
    assert _lines_to_run(cli, lines) == []  # type: ignore[arg-type]
    # And when the last differs from the FC's, only it is run.
    lines = ("set ap_hover_throttle = 1275", "set AP_HOVER_THROTTLE = 1600")
    assert _lines_to_run(cli, lines) == ["set AP_HOVER_THROTTLE = 1600"]  # type: ignore[arg-type]
    assert cli.batches[-1] == ["get ap_hover_throttle"]


def test_set_name_reads_both_spellings_and_nothing_else():
    from bfsitl.fc.provisioning import set_name

    assert set_name("set Serial_Update_Rate_Hz = 1000") == "serial_update_rate_hz"
    assert set_name("set small_angle=30") == "small_angle"
    assert set_name("feature GPS") is None
    assert set_name("set small_angle") is None  # no value: not a comparable set


class SerialListingCli:
    """CliSession.batch answering ``serial`` as 4.6.0's cli.c lists the ports."""

    def __init__(self, functions: dict[int, int]) -> None:
        self.functions = functions
        self.batches: list[list[str]] = []

    def batch(self, commands: list[str], *, check: bool = True) -> str:
        self.batches.append(list(commands))
        assert commands == ["serial"]
        return "".join(
            f"serial UART{n}  {self.functions.get(n, 0)} 115200 57600 0 115200\r\n"
            for n in range(1, 9)
        )


def test_serial_lines_a_port_already_has_are_skipped():
    """A run directory that keeps MSP on UART2 is not rebooted again on every flight."""
    from bfsitl.fc.provisioning import _lines_to_run
    from bfsitl.protocol.firmware_profile import GPS_SERIAL_4_6, MSP_SERIAL_4_6

    held = SerialListingCli({1: 1, 2: 1, 3: 2})
    assert _lines_to_run(held, (MSP_SERIAL_4_6, GPS_SERIAL_4_6)) == []  # type: ignore[arg-type]
    # An older run directory with the GPS on UART2: both lines run (MSP there, GPS to UART3).
    older = SerialListingCli({1: 1, 2: 2})
    assert _lines_to_run(older, (MSP_SERIAL_4_6, GPS_SERIAL_4_6)) == [  # type: ignore[arg-type]
        MSP_SERIAL_4_6,
        GPS_SERIAL_4_6,
    ]
    # No serial line: the port listing is not asked for at all.
    untouched = SerialListingCli({})
    assert _lines_to_run(untouched, ("feature GPS",)) == ["feature GPS"]  # type: ignore[arg-type]
    assert untouched.batches == []


def test_each_generation_serves_a_second_msp_port_its_own_way():
    from bfsitl.protocol.firmware_profile import BuildOptions, profile_for

    plain, gps = profile_for("1.47", "4.6.0"), profile_for("1.47", "4.6.0", BuildOptions(gps=True))
    master = profile_for("1.49", "2026.12.0-alpha")
    assert plain.second_msp_cli == ("serial UART2 1 115200 57600 0 115200",)
    # GPS and MSP may not share a port (4.6 isSerialConfigValid): the GPS is on UART3.
    assert "serial UART3 2 115200 57600 0 115200" in gps.gps_setup_cli
    assert gps.second_msp_cli[-1] == "serial UART3 2 115200 57600 0 115200"
    assert master.second_msp_cli == ("set msp_uart_2 = UART2",)  # `serial` is read-only there
