"""What a scenario run configures on the FC, and where each line comes from.

A verdict is only as good as knowing what flew: bfsitl sets the blackbox, the debug mode, the
simulated quad's hover throttle and more before every run, a comparison side adds its own
lines and the scenario its own.  :func:`scenario_profile` is what the runner provisions;
:func:`provisioned_settings` is the same, each line with its source, for the run's
``result.json`` and the comparison report.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Iterable
from dataclasses import dataclass

from bfsitl.fc.provisioning import Profile, set_name, set_value
from bfsitl.mission.session import FAST_SERIAL_LINE, FLY_PROFILE, with_fast_serial
from bfsitl.physics.params import QuadParams
from bfsitl.protocol import messages as msg
from bfsitl.protocol.boxes import BOX_NAMES
from bfsitl.protocol.firmware_profile import FirmwareProfile, Generation
from bfsitl.scenario.faults import Fault
from bfsitl.scenario.fc_mission import fc_mission_cli
from bfsitl.scenario.spec import Scenario
from bfsitl.vehicles.throttle import hover_throttle_us

#: The AUX channels a SITL reads by default (max_aux_channels).
SITL_AUX_CHANNELS = 6

#: Sources, in the order their lines are applied (later lines win).
BFSITL = "bfsitl"
BUILD = "this build"
SIDE = "the side"
SCENARIO = "the scenario"
LOG = "the log's header"


@dataclass(frozen=True, slots=True)
class SettingLine:
    """One line the FC was given, and who asked for it."""

    source: str  # BFSITL, BUILD, SIDE, SCENARIO or LOG
    line: str
    why: str = ""


def hover_throttle_line(quad: QuadParams) -> str:
    """The simulated quad's hover throttle, as a pilot sets it for theirs: the firmware's own
    altitude hold (a failsafe landing, GPS Rescue, ALTHOLD) starts from it.  Its default,
    1275 us, is a light racer's; with it the FC's failsafe landing fell 4 m at nearly free
    fall on IRIS (:mod:`bfsitl.vehicles.throttle` says how another quad's is found)."""
    return f"set ap_hover_throttle = {round(hover_throttle_us(quad))}"


#: The debug mode the runner reads the FC's failsafe phase from (debug[3], over MSP_DEBUG).
FAILSAFE_DEBUG_MODE = "FAILSAFE"


def blackbox_cli(profile: FirmwareProfile) -> tuple[str, ...]:
    """The FC's own log to a file in its run directory, one per armed flight.  4.6.0 runs its
    PID loop at 8 kHz and master at 1 kHz: 1/16 (4.6.0's lowest rate) and 1/4 give a few
    hundred frames a second, plenty to time a failsafe and ten times the accelerometer's
    low-pass (``acc_lpf_hz`` 25), so an impact's peak is kept.

    Decoding the log (orangebox, pure Python) is a run's largest cost after the flight, and
    it grows with the fields: the PID terms and the unfiltered gyro, 14 of 46, are left out
    (nothing of bfsitl reads them).  A scenario that wants them in the log turns them back on
    with its own lines (``set blackbox_disable_pids = OFF``), which come after these."""
    rate = "1/16" if profile.generation is Generation.V4_6 else "1/4"
    return (
        "set blackbox_device = VIRTUAL",
        "set blackbox_mode = NORMAL",
        f"set blackbox_sample_rate = {rate}",
        "set blackbox_disable_pids = ON",
        "set blackbox_disable_gyrounfilt = ON",
        f"set debug_mode = {FAILSAFE_DEBUG_MODE}",
    )


def setting_in_force(lines: Iterable[str], name: str) -> str | None:
    """The value the last ``set NAME = VALUE`` of ``lines`` gives (the FC applies them in
    order, so the last one wins), upper-cased; None when none sets it.  Names compare
    without regard to case, as the CLI's do."""
    value = None
    for line in lines:
        if set_name(line) == name.lower():
            value = set_value(line).upper()
    return value


def failsafe_phase_unread(lines: Iterable[str]) -> str | None:
    """Why the runner cannot read the FC's failsafe phase with the settings ``lines`` (a
    scenario's own ``debug_mode``: debug[] then holds something else, which read as phases
    would be nonsense), or None when it can."""
    mode = setting_in_force(lines, "debug_mode")
    if mode in (None, FAILSAFE_DEBUG_MODE):
        return None
    return (
        f"debug_mode = {mode}: the FC's failsafe phase is not read (it needs "
        f"{FAILSAFE_DEBUG_MODE}); what depends on it has no data in this run"
    )


def _mode_ranges(faults: tuple[Fault, ...]) -> tuple[msg.ModeRange, ...]:
    switches = dict.fromkeys(switch for fault in faults for switch in fault.switches)
    return (
        *with_fast_serial(FLY_PROFILE).mode_ranges,
        *(msg.ModeRange.from_us(box_id, aux_index, 1700, 2100) for box_id, aux_index in switches),
    )


def asked_lines(scenario: Scenario, generation: str) -> tuple[SettingLine, ...]:
    """The lines a comparison side and the scenario ask for, in the order they are applied
    (the side's first, so the scenario's own win; then its ``[cli_for]`` for
    ``generation``): what a flown run and a replay both add after their own."""
    return (
        *(SettingLine(SIDE, line) for line in scenario.side_cli),
        *(SettingLine(SCENARIO, line) for line in scenario.cli),
        *(
            SettingLine(SCENARIO, line, f"[cli_for] {generation}")
            for line in dict(scenario.cli_for).get(generation, ())
        ),
    )


def provisioned_settings(
    scenario: Scenario, profile: FirmwareProfile, faults: tuple[Fault, ...]
) -> tuple[SettingLine, ...]:
    """Every CLI line a run gives the FC, in order, with its source; the build's own setup
    (its virtual GPS, its compass) as the session adds it."""
    ranges = _mode_ranges(faults)
    # A SITL reads AUX1-AUX6 only (max_aux_channels, DEFAULT_AUX_CHANNEL_COUNT in
    # target/common_post.h): a switch above that is never seen unless the FC reads it.
    highest_aux = max((r.aux_channel_index + 1 for r in ranges), default=0)
    lines = [
        *(SettingLine(BFSITL, line, "bfsitl's flight profile") for line in FLY_PROFILE.cli_lines),
        SettingLine(BFSITL, FAST_SERIAL_LINE, "MSP answered within 1 ms of FC time"),
        *(SettingLine(BFSITL, line, "the FC's own log") for line in blackbox_cli(profile)),
        SettingLine(BFSITL, hover_throttle_line(scenario.quad), f"{scenario.quad.name}'s hover"),
    ]
    if highest_aux > SITL_AUX_CHANNELS:
        lines.append(
            SettingLine(BFSITL, f"set max_aux_channels = {highest_aux}", "a fault's switch")
        )
    lines += [
        *(
            SettingLine(SCENARIO, line, "[[fc_waypoint]]")
            for line in fc_mission_cli(scenario.fc_waypoints)
        ),
        *asked_lines(scenario, profile.generation.value),
        *(SettingLine(BUILD, line, "the compass") for line in profile.compass_cli),
        *(SettingLine(BUILD, line, "the virtual GPS") for line in profile.gps_setup_cli),
    ]
    return tuple(lines)


def mode_range_lines(faults: tuple[Fault, ...]) -> tuple[SettingLine, ...]:
    """The mode switches a run sets, as a person reads them (``ARM on AUX1 1700-2100``)."""
    return tuple(
        SettingLine(
            BFSITL,
            f"{BOX_NAMES.get(r.box_id, f'box {r.box_id}')} on AUX{r.aux_channel_index + 1} "
            f"{r.start_us}-{r.end_us}",
            "a mode switch",
        )
        for r in _mode_ranges(faults)
    )


def scenario_profile(
    scenario: Scenario, profile: FirmwareProfile, faults: tuple[Fault, ...]
) -> Profile:
    """What a run provisions: bfsitl's flight profile, the blackbox, the simulated quad's
    hover throttle, the comparison side's lines, the scenario's lines (last, so they win),
    and the mode switches its faults use (the FAILSAFE switch, a ``mode_switch``'s mode).
    The build's own setup lines are the session's to add."""
    settings = provisioned_settings(scenario, profile, faults)
    return dataclasses.replace(
        with_fast_serial(FLY_PROFILE),
        mode_ranges=_mode_ranges(faults),
        cli_lines=tuple(s.line for s in settings if s.source != BUILD),
    )
