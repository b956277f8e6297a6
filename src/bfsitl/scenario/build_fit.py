"""Whether a build can fly a scenario, decided before anything starts: a GPS scenario needs
a GPS build, a replay a lockstep build, and the build features the scenario and its faults
name (scanned from the binary's bytes).  Each answer is a skip's reason, or None."""

from __future__ import annotations

from pathlib import Path

from bfsitl.build.binary_scan import binary_traits
from bfsitl.protocol.firmware_profile import FirmwareProfile
from bfsitl.scenario.faults import Fault
from bfsitl.scenario.spec import Scenario

#: What each build feature a scenario can need is, for a skip's reason.
FEATURE_WHY = {
    "flight_plan": "master's flight plans (the FC's own waypoint missions, AUTOPILOT mode, "
    "ap_rx_loss_policy); Betaflight 4.6.0 has none",
    "geofence": "master's geofence (ap_max_distance_from_home, ap_geofence_action), part of "
    "its flight plans",
    "gps_rescue": "GPS Rescue",
    "altitude_hold": "ALTHOLD",
    "position_hold": "POSHOLD",
    "gps": "a GPS (`bfsitl firmware build --gps`)",
}


def unfit_reason(
    scenario: Scenario, profile: FirmwareProfile, binary: Path, firmware: str
) -> str | None:
    """Why ``firmware`` (at ``binary``) cannot fly ``scenario`` at all, before its faults
    are made; None when it can."""
    if scenario.requires_gps and not profile.has_gps:
        return f"needs a firmware with GPS; {firmware} has none (`bfsitl firmware build --gps`)"
    if scenario.replay is not None and not _lockstep(binary):
        return (
            f"a replay needs a lockstep build, so that each frame reaches the FC when it "
            f"is due; {firmware} is not one (`bfsitl firmware build --lockstep`)"
        )
    return None


def missing_features_reason(
    scenario: Scenario,
    faults: tuple[Fault, ...],
    binary: Path,
    firmware: str,
    profile: FirmwareProfile,
) -> str | None:
    """Why ``firmware`` lacks a build feature the scenario or its faults need; None when it
    has them all."""
    missing = missing_features(scenario, faults, binary)
    if not missing:
        return None
    return (
        f"needs {', '.join(missing)}, which {firmware} "
        f"({profile.firmware_version or profile.generation.value}) was built "
        f"without: {'; '.join(FEATURE_WHY.get(m, m) for m in missing)}"
    )


def _lockstep(binary: Path) -> bool:
    try:
        return binary_traits(binary).lockstep
    except OSError:
        return False  # unreadable here: the skip's reason says what to build


def missing_features(scenario: Scenario, faults: tuple[Fault, ...], binary: Path) -> list[str]:
    """The build features the scenario and its faults need that ``binary`` lacks (its
    CLI's setting names, scanned from its bytes)."""
    needed = dict.fromkeys(
        (*scenario.requires, *(f.needs_feature for f in faults if f.needs_feature))
    )
    if not needed:
        return []
    try:
        have = set(binary_traits(binary).features)
    except OSError:
        return []  # unreadable here: the run says so when it starts the binary
    return [feature for feature in needed if feature not in have]
