"""The CLI session and the SITL supervisor around save/reboot, against the real SITL."""

from __future__ import annotations

import pytest

from bfsitl.errors import CliCommandError, MspTimeoutError
from bfsitl.fc.cli_session import CliSession
from bfsitl.protocol import messages as msg

pytestmark = pytest.mark.sitl


def test_cli_runs_commands_and_raises_on_error(sitl):
    with CliSession(sitl.client.link) as cli:
        assert "Entering CLI Mode" in cli.banner
        assert cli.get("small_angle") == "25"
        with pytest.raises(CliCommandError, match="UNKNOWN COMMAND"):
            cli.run("bogus_command")
        assert "###ERROR" in cli.run("bogus_command", check=False)
    # leave() ran on exit: MSP works again, and the CLI flag now blocks arming.
    names = {f.cli_name for f in sitl.client.status().arming_blockers}
    assert "CLI" in names


def test_diff_all_contains_an_arm_range_set_over_msp_and_backup_writes_it(sitl, tmp_path):
    arm = msg.ModeRange.from_us(0, 0, 1700, 2100)
    sitl.client.set_mode_range(0, arm)
    with CliSession(sitl.client.link) as cli:
        diff = cli.diff_all()
        backup = cli.backup(tmp_path / "backup.txt")
    assert "# version" in diff and "# Betaflight / SITL" in diff
    assert "aux 0 0 0 1700 2100 0 0" in diff
    text = backup.read_text()
    assert "aux 0 0 0 1700 2100 0 0" in text and "\r" not in text
    assert not (tmp_path / "backup.txt.partial").exists()


def test_save_exits_the_process_restart_and_the_setting_persists(sitl):
    with CliSession(sitl.client.link) as cli:
        cli.set("small_angle", 40)
        cli.run("aux 0 0 0 1700 2100 0 0")  # the 7-argument form; 5 arguments crash 4.6.0
        cli.save(restart=sitl.restart_after_reboot)
    assert sitl.starts == 2
    assert (sitl.workdir / "eeprom.bin").stat().st_size == 32768
    with CliSession(sitl.client.link) as cli:
        assert cli.get("small_angle") == "40"
    assert sitl.client.mode_ranges().ranges[0].start_us == 1700
    # A reboot also clears the CLI flag that the first session set... until this session.


def test_port_left_in_cli_mode_is_detected_and_recovered(sitl):
    cli = CliSession(sitl.client.link).enter()
    assert cli.active
    # The client drops the connection while in CLI: the port stays in CLI mode.
    sitl.client.close()
    client = sitl.connect(timeout_s=0.3, retries=0)
    with pytest.raises(MspTimeoutError, match="CLI mode"):
        client.api_version()
    recovery = CliSession(client.link).enter()
    recovery.leave()
    assert client.api_version().api == (1, 47)
    client.close()


def test_batch_mode_does_not_set_the_cli_arming_flag(sitl):
    output = CliSession(sitl.client.link).batch(["get small_angle"])
    assert "small_angle = 25" in output
    names = {f.cli_name for f in sitl.client.status().arming_blockers}
    assert "CLI" not in names
