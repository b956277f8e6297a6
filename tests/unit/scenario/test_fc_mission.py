"""The FC's own mission, mode switches, build features and per-generation lines in scenario
files: read, checked, and turned into what the FC is given."""

from __future__ import annotations

import math
from pathlib import Path

import pytest
from support.scenario_files import MASTER, V46

from bfsitl.build.binary_scan import FEATURE_MARKERS
from bfsitl.errors import FaultNotSupportedError, ScenarioError
from bfsitl.physics.frames import GeoPoint, geodetic_to_ned
from bfsitl.protocol.boxes import AUTOPILOT_BOX_ID, BoxId
from bfsitl.scenario.build_fit import missing_features
from bfsitl.scenario.faults import make_faults, read_fault_spec
from bfsitl.scenario.fc_mission import FcWaypoint, fc_mission_cli, read_fc_waypoints
from bfsitl.scenario.setup_lines import scenario_profile
from bfsitl.scenario.spec import scenario_from_dict

BASE = {"duration_s": 60, "flight": {"takeoff_alt_m": 10.0}, "expect": {"mode_seen": "AUTOPILOT"}}


def scenario(**extra: object):
    return scenario_from_dict({**BASE, **extra}, name="mission")


def test_waypoints_become_the_cli_lines_of_the_fcs_flight_plan() -> None:
    waypoints = read_fc_waypoints(
        [
            {"north_m": 150.0, "east_m": 0.0, "alt_m": 10.0},
            {
                "north_m": 40.0,
                "east_m": -25.0,
                "alt_m": 12.5,
                "speed_m_s": 3.0,
                "type": "LAND",
                "duration_s": 5.0,
            },
            {
                "north_m": 40.0,
                "east_m": 0.0,
                "alt_m": 10.0,
                "type": "hold",
                "duration_s": 60,
                "pattern": "figure8",
            },
        ],
        where="f.toml",
    )
    lines = fc_mission_cli(waypoints)
    assert lines[0] == "waypoint clear"
    first, land, hold = (line.split() for line in lines[1:])
    assert first[:3] == ["waypoint", "insert", "0"]
    assert first[5:] == ["1000", "500", "flyover", "0", "none"]  # cm, cm/s, type, ds, pattern
    assert land[5:] == ["1250", "300", "land", "50", "none"]
    assert hold[7:] == ["hold", "600", "figure8"]
    # The latitude and longitude are where the simulator puts 150 m north of home.
    north, east, _ = geodetic_to_ned(
        GeoPoint(float(first[3]), float(first[4]), 10.0), GeoPoint(0.0, 0.0, 0.0)
    )
    assert north == pytest.approx(150.0, abs=0.01) and east == pytest.approx(0.0, abs=0.01)
    assert float(land[4]) < 0  # west is negative
    assert fc_mission_cli(()) == ()


@pytest.mark.parametrize(
    ("table", "message"),
    [
        ({"north_m": 1.0, "east_m": 0.0}, "alt_m is missing"),
        ({"north_m": 1.0, "east_m": 0.0, "alt_m": 5.0, "type": "loiter"}, "type = 'loiter' is not"),
        ({"north_m": 1.0, "east_m": 0.0, "alt_m": 5.0, "pattern": "spiral"}, "pattern"),
        ({"north_m": 1.0, "east_m": 0.0, "alt_m": 5.0, "heading": 3}, "unknown key"),
        ({"north_m": 1e6, "east_m": 0.0, "alt_m": 5.0}, "north_m = 1000000.0 must be"),
    ],
)
def test_a_bad_waypoint_names_the_file_the_waypoint_and_the_key(table: dict, message: str) -> None:
    with pytest.raises(ScenarioError, match=message) as caught:
        read_fc_waypoints([table], where="f.toml")
    assert "f.toml, fc_waypoint 1" in str(caught.value)


def test_a_scenario_with_the_fcs_waypoints_needs_gps_and_flight_plans() -> None:
    mission = scenario(fc_waypoint=[{"north_m": 50.0, "east_m": 0.0, "alt_m": 10.0}])
    assert mission.requires_gps and mission.requires == ("flight_plan",)
    assert mission.fc_waypoints == (FcWaypoint(50.0, 0.0, 10.0),)
    with pytest.raises(ScenarioError, match="unknown feature.*known: .*geofence"):
        scenario(requires=["warp_drive"])
    assert set(FEATURE_MARKERS) >= {"flight_plan", "geofence", "gps_rescue"}


def test_lines_for_one_generation_go_after_the_common_ones() -> None:
    lines = {
        "cli": ["set failsafe_delay = 10"],
        "cli_for": {"master": ["set ap_yaw_mode = FIXED"], "4.6": ["set x = 1"]},
    }
    spec = scenario(fc_waypoint=[{"north_m": 50.0, "east_m": 0.0, "alt_m": 10.0}], **lines)
    on_master = scenario_profile(spec, MASTER, ()).cli_lines
    assert on_master[-2:] == ("set failsafe_delay = 10", "set ap_yaw_mode = FIXED")
    assert "set x = 1" not in on_master
    # The FC's mission comes before the scenario's own lines (they may change its settings).
    assert on_master.index("waypoint clear") < on_master.index("set failsafe_delay = 10")
    assert scenario_profile(spec, V46, ()).cli_lines[-1] == "set x = 1"
    with pytest.raises(ScenarioError, match=r"\[cli_for\] has unknown generation"):
        scenario(cli_for={"4.5": ["set x = 1"]})


def switch(mode: str):
    return read_fault_spec(
        {"kind": "mode_switch", "mode": mode, "at_s": 12.0}, where="f.toml", number=1, run_s=60.0
    )


def test_a_mode_switch_is_provisioned_on_its_own_channel_and_the_fc_reads_it() -> None:
    (autopilot,) = make_faults((switch("AUTOPILOT"),), MASTER)
    assert autopilot.takes_sticks and autopilot.needs_feature == "flight_plan"
    assert autopilot.switches == ((AUTOPILOT_BOX_ID, 6),)
    (hold,) = make_faults((switch("POSHOLD"),), MASTER)
    assert hold.switches == ((int(BoxId.POSHOLD), 4), (int(BoxId.ALTHOLD), 4))
    profile = scenario_profile(scenario(), MASTER, (autopilot, hold))
    ranges = {(r.box_id, r.aux_channel_index) for r in profile.mode_ranges}
    assert {(AUTOPILOT_BOX_ID, 6), (int(BoxId.POSHOLD), 4), (int(BoxId.ALTHOLD), 4)} <= ranges
    # A SITL reads AUX1-AUX6 only unless told: AUX7 needs max_aux_channels.
    assert "set max_aux_channels = 7" in profile.cli_lines
    (althold,) = make_faults((switch("ALTHOLD"),), V46)
    assert not any(
        "max_aux_channels" in line
        for line in scenario_profile(scenario(), V46, (althold,)).cli_lines
    )


def test_a_mode_switch_must_name_a_mode_it_knows_and_a_firmware_with_gps() -> None:
    with pytest.raises(ScenarioError, match="mode_switch needs mode: one of ALTHOLD"):
        read_fault_spec({"kind": "mode_switch", "at_s": 1.0}, where="f", number=1, run_s=9.0)
    with pytest.raises(ScenarioError, match="mode 'TURTLE' is not one of"):
        switch("TURTLE")
    from dataclasses import replace

    with pytest.raises(FaultNotSupportedError, match="needs a firmware with GPS"):
        make_faults((switch("GPS RESCUE"),), replace(V46, has_gps=False))


def test_missing_features_are_read_from_the_binarys_setting_names(tmp_path: Path) -> None:
    binary = tmp_path / "betaflight_SITL"
    binary.write_bytes(b"\x7fELF" + b"\x00gps_provider\x00" + b"\x00gps_rescue_x\x00" * 2)
    mission = scenario(fc_waypoint=[{"north_m": 50.0, "east_m": 0.0, "alt_m": 10.0}])
    (autopilot,) = make_faults((switch("AUTOPILOT"),), MASTER)
    assert missing_features(mission, (autopilot,), binary) == ["flight_plan"]
    binary.write_bytes(binary.read_bytes() + b"\x00ap_rx_loss_policy\x00")
    assert missing_features(mission, (autopilot,), binary) == []
    assert missing_features(scenario(), (), binary) == []


def test_a_vehicle_may_start_facing_another_way() -> None:
    from bfsitl.backend.factory import make_simulator
    from bfsitl.backend.options import World
    from bfsitl.physics.frames import euler_from_quat_rad

    east = scenario(vehicle={"heading_deg": 90.0})
    assert east.initial_heading_deg == 90.0 and scenario().initial_heading_deg == 0.0
    with pytest.raises(ScenarioError, match=r"vehicle.heading_deg = 400.0 must be"):
        scenario(vehicle={"heading_deg": 400.0})
    simulator = make_simulator(World(initial_heading_deg=90.0))
    _roll, _pitch, yaw = euler_from_quat_rad(simulator.state.quaternion_wxyz)
    assert math.degrees(yaw) == pytest.approx(90.0)
