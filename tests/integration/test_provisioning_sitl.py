"""Provisioning the real SITL: verified, saved without a reboot, persisted, skipped next time."""

from __future__ import annotations

import pytest

from bfsitl.fc.cli_session import CliSession
from bfsitl.fc.provisioning import ANGLE_ON_AUX2, ARM_ON_AUX1, Profile, provision

pytestmark = pytest.mark.sitl


def test_provisioning_persists_and_is_skipped_in_the_same_run_directory(sitl):
    profile = Profile((ARM_ON_AUX1, ANGLE_ON_AUX2), cli_lines=("set small_angle = 30",))
    first = provision(sitl.client, profile)
    assert first.changed and first.mode_ranges_written == 2 and first.cli_lines_run == 1
    assert not first.rebooted  # MSP_EEPROM_WRITE saved it; the SITL process lives on
    pid = sitl.pid
    # Non-interactive CLI: the CLI arming flag was not set.
    assert "CLI" not in {b.cli_name for b in sitl.client.status().arming_blockers}

    sitl.restart()  # a new process on the same eeprom.bin
    assert sitl.pid != pid
    ranges = sitl.client.mode_ranges().ranges
    assert ranges[:2] == (ARM_ON_AUX1, ANGLE_ON_AUX2)
    with CliSession(sitl.client.link) as cli:
        assert cli.get("small_angle") == "30"
    sitl.restart()  # drop the CLI flag that session set

    again = provision(sitl.client, Profile((ARM_ON_AUX1, ANGLE_ON_AUX2)))
    assert not again.changed and again.mode_ranges_written == 0
