"""Scenarios against the real firmware: the shipped library on both generations, a wrong
expectation through the pytest plugin, and faults reaching the FC where they should.

The library run is the product's own path: ``bfsitl scenario run`` with two jobs, its JUnit
XML read back by ``junitparser`` (a parser from the registry, not ours), its report page and
each run's blackbox.  Speed is ``benchmarks/scenarios.py``'s business.
"""

from __future__ import annotations

import csv
import json
import os
import signal
import subprocess
import sys
import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pytest
from firmware_builds import master_source_given
from junitparser import Failure, JUnitXml, Skipped
from mcap.reader import make_reader
from plugin_runs import pytest_with_the_plugin

from bfsitl.autopilot import Autopilot
from bfsitl.blackbox import decode_blackbox
from bfsitl.build import FirmwareCache
from bfsitl.cli.doctor import stale_sitl_processes
from bfsitl.fc.rc_link import RcFault
from bfsitl.library import scenarios_dir
from bfsitl.mission.session import (
    FLY_PROFILE,
    FcSetup,
    FlightSession,
    SessionConfig,
    SitlLaunch,
    with_fast_serial,
)
from bfsitl.protocol import messages as msg
from bfsitl.scenario.load import find_scenarios
from bfsitl.scenario.result import Verdict
from bfsitl.scenario.run import RunOptions, run_scenario

pytestmark = pytest.mark.sitl

REPO = Path(__file__).resolve().parents[2]
LIBRARY = scenarios_dir()
WRONG = REPO / "tests" / "data" / "scenarios" / "wrong-expectation.toml"
BUILDS = ("master-lockstep", "4.6.0-gps-lockstep")
#: The build every run here uses when no master source is given (CI has none).
ALWAYS = "4.6.0-gps-lockstep"
FIXTURE_OF = {
    "master-lockstep": "lockstep_master_firmware",
    "4.6.0-gps-lockstep": "lockstep_gps_46_firmware",
}


def available_builds(request: pytest.FixtureRequest) -> tuple[str, ...]:
    """4.6.0-gps-lockstep, and master-lockstep too when ``BFSITL_MASTER_SOURCE`` names one;
    each built (or found in the session's cache) before it is returned."""
    builds = BUILDS if master_source_given() else (ALWAYS,)
    for build in builds:
        request.getfixturevalue(FIXTURE_OF[build])
    return builds


def firmware_args(builds: tuple[str, ...]) -> list[str]:
    return [arg for build in builds for arg in ("--firmware", build)]


def env_for(cache: FirmwareCache) -> dict[str, str]:
    env = {**os.environ, "BFSITL_CACHE_DIR": str(cache.root)}
    env.pop("BFSITL_FIRMWARE", None)
    return env


@pytest.mark.timeout(1500)
def test_the_shipped_library_passes_on_every_firmware(
    request: pytest.FixtureRequest, firmware_build_cache: FirmwareCache, tmp_path: Path
) -> None:
    """The whole library on 4.6.0-gps-lockstep, and on master-lockstep when one is given."""
    builds = available_builds(request)
    junit, report, out = tmp_path / "results.xml", tmp_path / "report", tmp_path / "runs"
    run = subprocess.run(
        [
            sys.executable,
            "-m",
            "bfsitl.cli.main",
            "scenario",
            "run",
            str(LIBRARY),
            *firmware_args(builds),
            "--jobs",
            "2",
            "--junit",
            str(junit),
            "--report",
            str(report),
            "--out",
            str(out),
        ],
        capture_output=True,
        text=True,
        timeout=1400,
        cwd=tmp_path,
        env=env_for(firmware_build_cache),
    )
    assert run.returncode == 0, run.stdout + run.stderr[-3000:]
    names = {s.name for s in find_scenarios([LIBRARY])}

    xml = JUnitXml.fromfile(str(junit))
    suites = {suite.name: suite for suite in xml}
    assert len(suites) == len(builds)
    skipped: list[str] = []
    known: list[str] = []
    for build in builds:
        suite = next(s for name, s in suites.items() if build in name)
        cases = list(suite)
        assert {case.name for case in cases} == names
        assert suite.failures == 0 and suite.errors == 0
        for case in cases:
            assert not any(isinstance(r, Failure) for r in case.result)
            for r in case.result:
                if isinstance(r, Skipped):
                    kind = known if r.type == "known failure" else skipped
                    kind.append(f"{case.name}[{build}]")
    # Only what the firmware cannot express is skipped: on 4.6.0, GPS loss and master's
    # flight plans (the FC's own missions, its RC-loss policies, the geofence).
    scenarios = find_scenarios([LIBRARY])
    cannot_46 = {
        s.name
        for s in scenarios
        if "flight_plan" in s.requires or any(f.kind == "gps_loss" for f in s.faults)
    }
    assert len(cannot_46) >= 15 and "gps-loss-during-rescue" in cannot_46
    assert sorted(skipped) == sorted(f"{name}[4.6.0-gps-lockstep]" for name in cannot_46)
    # The firmware defects the library flies into on purpose happened, each on its build: a
    # known failure, never a pass (docs/firmware-findings.md).
    declared = {
        f"{s.name}[{build}]"
        for s in scenarios
        for build in builds
        if (s.name not in cannot_46 or not build.startswith("4.6"))
        and any(
            k.applies_to("4.6" if build.startswith("4.6") else "master") for k in s.known_failures
        )
    }
    assert sorted(known) == sorted(declared)
    assert "rc-loss-hover-autoland[4.6.0-gps-lockstep]" in declared

    index = (report / "index.html").read_text()
    assert all(name in index for name in names)
    # The FC's own log: written, collected and decoded for every flown run; a drop's
    # disarm reason read from it.
    for build in builds:
        for name in names - cannot_46 if build.startswith("4.6") else names:
            logs = list((out / build / name / "blackbox").glob("LOG*"))
            assert logs, f"no blackbox for {name}[{build}]"
            # --report asks for every run's plots (by default only a run that did not pass
            # draws them).
            for plot in ("plot.png", "blackbox.png"):
                drawn = out / build / name / plot
                assert drawn.is_file() and drawn.stat().st_size, f"no {plot} for {name}[{build}]"
        assert (
            "blackbox_disarm_reason = 'FAILSAFE'"
            in (out / build / "rc-loss-hover-drop" / "result.json").read_text()
        )
        # The analysers watched every run, asked or not: the drop's crash is in result.json,
        # in the suite's JUnit properties and on the report.
        drop = json.loads((out / build / "rc-loss-hover-drop" / "result.json").read_text())
        crash = next(f for f in drop["findings"] if f["analyser"] == "crash")
        assert crash["severity"] == "failure" and crash["evidence"]["touchdown_speed_m_s"] > 5
        assert len(drop["analysers"]["watched"]) >= 10
        suite = next(s for name, s in suites.items() if build in name)
        properties = {p.name: p.value for p in suite.properties()}
        assert properties["rc-loss-hover-drop.finding.crash"].startswith("failure at t=")
    assert 'class="finding failure"' in index


@pytest.mark.timeout(300)
def test_a_run_flies_the_same_flight_whether_it_made_the_fc_s_prepared_state_or_found_it(
    lockstep_gps_46_firmware: Path, tmp_path: Path
) -> None:
    """The first run on an empty cache prepares the FC's configuration in a SITL of
    its own; the next finds it; a third, into the first one's directory, does not start
    from the configuration that run left there.  All three fly the same flight and the FC
    logs the same bytes; none reboots the FC to configure it."""

    def fly(out: Path) -> subprocess.CompletedProcess[str]:
        env = {**os.environ, "BFSITL_CACHE_DIR": str(tmp_path / "cache")}
        env.pop("BFSITL_FIRMWARE", None)
        return subprocess.run(
            [sys.executable, "-m", "bfsitl.cli.main", "scenario", "run", "motor-weak"]
            + ["--firmware", str(lockstep_gps_46_firmware), "--out", str(out), "--timings"],
            capture_output=True,
            text=True,
            timeout=240,
            cwd=tmp_path,
            env=env,
        )

    def flown(out: Path) -> tuple[list[dict[str, str]], bytes]:
        run_dir = next(out.glob("*/motor-weak"))
        with (run_dir / "flight.csv").open() as rows:
            table = [
                {k: v for k, v in row.items() if k != "wall_s"} for row in csv.DictReader(rows)
            ]
        return table, next((run_dir / "blackbox").glob("LOG*")).read_bytes()

    first = fly(tmp_path / "a")
    made = flown(tmp_path / "a")
    second, again = fly(tmp_path / "b"), fly(tmp_path / "a")
    for run in (first, second, again):
        assert run.returncode == 0, run.stdout + run.stderr[-3000:]
        assert "rebooted" not in run.stderr.split("[sitl] provisioned:")[1].splitlines()[0]
    assert "preparing the FC's configuration" in first.stderr
    assert "preparing" not in second.stderr + again.stderr
    assert len(list((tmp_path / "cache" / "prepared-fc").glob("*.bin"))) == 1
    # The timings say what the first paid for it.
    head = next(line for line in first.stdout.splitlines() if line.startswith("run "))
    assert head.split()[1] == "prepare", first.stdout

    for found in (flown(tmp_path / "b"), flown(tmp_path / "a")):
        assert made[0] == found[0] and len(made[0]) > 1000
        assert made[1] == found[1]


@pytest.mark.timeout(300)
def test_a_wrong_expectation_fails_naming_the_value_and_the_time_and_python_tests_fly(
    request: pytest.FixtureRequest, firmware_build_cache: FirmwareCache, tmp_path: Path
) -> None:
    build = available_builds(request)[0]  # master when given, else 4.6.0
    (tmp_path / "test_weak_motor.py").write_text(
        "from bfsitl import Autopilot\n"
        "def test_a_weak_motor_holds(bfsitl_vehicle):\n"
        "    pilot = Autopilot(bfsitl_vehicle)\n"
        "    pilot.takeoff(2.0)\n"
        "    bfsitl_vehicle.disturbances.set_motor_thrust(3, 0.8)\n"
        "    pilot.hold(3.0)\n"
        "    assert abs(bfsitl_vehicle.sample().sim_alt_m - 2.0) < 0.5\n"
    )
    (tmp_path / "wrong-expectation.toml").write_text(WRONG.read_text())
    # A file of the shipped library runs through the plugin too.
    (tmp_path / "rc-loss-hover-drop.toml").write_text(
        (LIBRARY / "rc-loss-hover-drop.toml").read_text()
    )
    run = pytest_with_the_plugin(
        tmp_path,
        "--bfsitl-firmware",
        build,
        "--bfsitl-out",
        str(tmp_path / "runs"),
        env=env_for(firmware_build_cache),
    )
    output = run.stdout
    assert run.returncode == 1, output + run.stderr
    assert "1 failed, 2 passed" in output
    assert "PASS disarmed = true" in output
    line = next(x for x in output.splitlines() if "FAIL disarmed_within_s = 0.2" in x)
    # The expectation, the measured value, the time.
    assert "disarmed 0.5" in line and "after the fault (expected within 0.2 s) at t=6.5" in line
    # The failed run drew its plots, to be looked at; the passing one did not spend the time.
    drawn = {path.parent.name for path in (tmp_path / "runs").glob("*/plot.png")}
    assert drawn == {f"{build}_wrong-expectation"}, drawn


@pytest.mark.parametrize("build", BUILDS)
@pytest.mark.timeout(240)
def test_faults_reach_the_fc_where_they_should(
    build: str, request: pytest.FixtureRequest, tmp_path: Path
) -> None:
    """A weak motor is made up for by that motor (right motor order under a fault); a GPS
    glitch moves the FC's GPS and not the truth (right axis and sign); a delayed RC command
    arrives that much later; RC silence is a lost link on both (frames at the RC link's
    rate, counted as a receiver's)."""
    firmware = request.getfixturevalue(FIXTURE_OF[build])
    config = SessionConfig(
        sitl=SitlLaunch(firmware=firmware, workdir=tmp_path / "sitl"),
        fc=FcSetup(profile=with_fast_serial(FLY_PROFILE)),
    )
    with FlightSession(config) as vehicle:
        pilot = Autopilot(vehicle)
        pilot.takeoff(3.0)
        pilot.hold(2.0)
        before = vehicle.sample().motors
        vehicle.disturbances.set_motor_thrust(3, 0.7)  # rear left
        pilot.hold(3.0)
        after = vehicle.sample()
        # The FC commands motor 3 up to make up its lost thrust: the others stay near hover.
        assert after.motors[2] > max(after.motors[0], after.motors[1], after.motors[3]) + 0.05
        assert after.motors[2] > before[2] + 0.05
        assert abs(after.sim_alt_m - 3.0) < 0.5 and after.sim_tilt_deg < 15

        vehicle.disturbances.set_motor_thrust(3, 1.0)
        gps_before, truth_before = vehicle.gps_position(), vehicle.sample()
        sensors = vehicle.disturbances.change_sensors(gps_offset_ne_m=(6.0, -4.0))
        vehicle.clock.sleep_s(0.5)
        gps_after, truth_after = vehicle.gps_position(), vehicle.sample()
        moved = (gps_after.north_m - gps_before.north_m) - (
            truth_after.sim_north_m - truth_before.sim_north_m
        )
        moved_east = (gps_after.east_m - gps_before.east_m) - (
            truth_after.sim_east_m - truth_before.sim_east_m
        )
        assert moved == pytest.approx(6.0, abs=0.5) and moved_east == pytest.approx(-4.0, abs=0.5)
        vehicle.disturbances.set_sensors(sensors)

        assert vehicle.rc is not None
        # RC latency: AUX4 (no mode on it) raised under a 0.2 s delay reaches the FC 0.2 s
        # later (MSP_RC: roll, pitch, yaw, throttle, AUX1.., so AUX4 is channel 8).
        vehicle.rc.fault = RcFault(delay_s=0.2)
        vehicle.set_rc(vehicle.rc_command.with_aux(3, 1900))
        vehicle.clock.sleep_s(0.1)
        assert vehicle.client.get(msg.Rc).channels_us[7] != 1900
        vehicle.clock.sleep_s(0.2)
        assert vehicle.client.get(msg.Rc).channels_us[7] == 1900
        vehicle.rc.fault = RcFault(silent=True)
        vehicle.clock.sleep_s(0.3)
        assert "RXLOSS" in {b.cli_name for b in vehicle.client.status().arming_blockers}
        vehicle.rc.fault = None
        assert vehicle.sitl is not None and vehicle.sitl.profile.rc.rxloss_after_silence_s


@pytest.mark.timeout(120)
def test_without_an_rc_link_rate_46_holds_the_last_sticks_when_rc_stops(
    lockstep_gps_46_firmware: Path, tmp_path: Path
) -> None:
    """A frame in every packet (no RC link rate) leaves 4.6.0 its stock SITL receiver, which
    calls every check a frame: silence is no lost link, as on a stock SITL (the fault
    catalogue's rc_loss uses the switch there).  The test above, at the link's rate, sees
    RXLOSS 0.3 s after the same silence."""
    config = SessionConfig(
        sitl=SitlLaunch(firmware=lockstep_gps_46_firmware, workdir=tmp_path / "sitl"),
        fc=FcSetup(rc_rate_hz=None),
    )
    with FlightSession(config) as vehicle:
        assert vehicle.sitl is not None  # its profile: no silence, so rc_loss's auto = switch
        assert vehicle.sitl.profile.rc.rxloss_after_silence_s is None
        vehicle.arm()
        assert vehicle.rc is not None
        vehicle.rc.fault = RcFault(silent=True)
        vehicle.clock.sleep_s(0.3)
        status = vehicle.client.status()
        assert "RXLOSS" not in {b.cli_name for b in status.arming_blockers}
        assert status.armed


@dataclass
class ThreeNodes:
    """A Ray cluster of a head with no CPUs and two worker nodes of one CPU each, every
    worker node with its own (empty) bfsitl cache and temporary directory."""

    cluster: Any
    workers: list[Any]
    caches: list[Path]
    temps: list[Path]

    @property
    def address(self) -> str:
        return str(self.cluster.address)


@pytest.fixture
def three_nodes(tmp_path: Path):  # type: ignore[no-untyped-def]
    pytest.importorskip("ray")
    from ray.cluster_utils import Cluster

    cluster = Cluster(
        initialize_head=True,
        head_node_args={
            "num_cpus": 0,
            "include_dashboard": False,
            "object_store_memory": 100_000_000,
        },
    )
    try:
        caches, temps, workers = [], [], []
        for index in range(2):
            cache, temp = tmp_path / f"node{index}-cache", tmp_path / f"node{index}-tmp"
            temp.mkdir()
            caches.append(cache)
            temps.append(temp)
            workers.append(
                cluster.add_node(
                    num_cpus=1,
                    object_store_memory=100_000_000,
                    env_vars={"BFSITL_CACHE_DIR": str(cache), "TMPDIR": str(temp)},
                )
            )
        cluster.wait_for_nodes()
        yield ThreeNodes(cluster, workers, caches, temps)
    finally:
        cluster.shutdown()


def start_driver(
    names: Sequence[str],
    builds: Sequence[str],
    address: str,
    junit: Path,
    out: Path,
    cache: FirmwareCache,
    cwd: Path,
) -> subprocess.Popen[str]:
    """`bfsitl scenario run` of library scenarios on the cluster, running in the background."""
    return subprocess.Popen(
        [
            sys.executable,
            "-m",
            "bfsitl.cli.main",
            "scenario",
            "run",
            *(str(LIBRARY / f"{name}.toml") for name in names),
            *firmware_args(tuple(builds)),
            "--ray",
            address,
            "--junit",
            str(junit),
            "--out",
            str(out),
            "--no-plot",
        ],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        cwd=cwd,
        env=env_for(cache),
    )


def sitl_pids() -> set[int]:
    return {pid for pid, _name in stale_sitl_processes()}


@pytest.mark.timeout(600)
def test_runs_on_a_three_node_cluster_bring_their_firmware_and_their_files_home(
    request: pytest.FixtureRequest,
    firmware_build_cache: FirmwareCache,
    three_nodes: ThreeNodes,
    tmp_path: Path,
) -> None:
    builds = available_builds(request)
    junit, report, out = tmp_path / "ray.xml", tmp_path / "report", tmp_path / "runs"
    run = subprocess.run(
        [
            sys.executable,
            "-m",
            "bfsitl.cli.main",
            "scenario",
            "run",
            str(LIBRARY / "rc-loss-hover-drop.toml"),
            str(WRONG),
            *firmware_args(builds),
            "--ray",
            three_nodes.address,
            "--junit",
            str(junit),
            "--report",
            str(report),
            "--out",
            str(out),
            "--mcap",
        ],
        capture_output=True,
        text=True,
        timeout=500,
        cwd=tmp_path,
        env=env_for(firmware_build_cache),
    )
    assert run.returncode == 1, run.stdout + run.stderr[-3000:]  # the wrong one fails
    assert f"{2 * len(builds)} runs on the Ray cluster" in run.stderr
    assert "travels as" in run.stderr
    # The build travelled: the workers had no cache, and kept what they received by hash.
    received = [p for cache in three_nodes.caches for p in cache.glob("received/*/*_SITL*")]
    assert received and all(p.stat().st_mode & 0o111 for p in received)
    xml = JUnitXml.fromfile(str(junit))
    cases = {(suite.name, case.name): case for suite in xml for case in suite}
    assert len(cases) == 2 * len(builds)
    for (suite, name), case in cases.items():
        failed = any(isinstance(r, Failure) for r in case.result)
        assert failed == (name == "wrong-expectation"), (suite, name)
    # The files came home: every run's artefacts under the driver's --out, and the summary
    # names them there.
    for build in builds:
        for scenario in ("rc-loss-hover-drop", "wrong-expectation"):
            run_dir = out / build / scenario
            summary = json.loads((run_dir / "result.json").read_text())
            assert summary["firmware"] == build and summary["retried"] == []
            for kind, path in summary["artifacts"].items():
                assert Path(path).is_file() and Path(path).is_relative_to(run_dir), kind
            assert {"log", "sitl_log"} <= set(summary["artifacts"])
    html = (report / "index.html").read_text()
    assert 'class="missing"' not in html  # every link in the report has its file
    # Nothing stays behind on the nodes: their run directories are gone.
    assert not [p for temp in three_nodes.temps for p in temp.glob("bfsitl-ray-run-*")]
    # --mcap: each run's flight as MCAP too, one message per CSV row, the events with it.
    run_dir = out / builds[0] / "rc-loss-hover-drop"
    with (run_dir / "flight.csv").open() as file:
        rows = len(file.readlines()) - 1
    with (run_dir / "flight.mcap").open("rb") as file:
        summary = make_reader(file).get_summary()
    assert summary is not None and summary.statistics is not None
    counts = {
        c.topic: summary.statistics.channel_message_counts.get(c.id, 0)
        for c in summary.channels.values()
    }
    assert counts["/flight/altitude"] == rows > 100
    assert counts["/events"] >= 4  # armed, RC lost, the FC disarmed, its failsafe phase


@pytest.mark.timeout(600)
def test_a_node_lost_mid_suite_loses_no_run_and_leaves_no_sitl(
    request: pytest.FixtureRequest,
    firmware_build_cache: FirmwareCache,
    three_nodes: ThreeNodes,
    tmp_path: Path,
) -> None:
    builds = available_builds(request)[:1]
    before = sitl_pids()
    junit, out = tmp_path / "lost.xml", tmp_path / "runs"
    names = ("rc-loss-hover-drop", "failsafe-switch", "motor-weak", "rc-loss-forward-drop")
    driver = start_driver(
        names, builds, three_nodes.address, junit, out, firmware_build_cache, tmp_path
    )
    try:
        # Once worker 0 is flying a run (its run directory exists), the node goes: raylet,
        # workers and all, as a machine that is switched off.
        deadline = time.monotonic() + 120
        while not list(three_nodes.temps[0].glob("bfsitl-ray-run-*")):
            assert driver.poll() is None and time.monotonic() < deadline, "no run started"
            time.sleep(0.05)
        three_nodes.cluster.remove_node(three_nodes.workers[0], allow_graceful=False)
        stdout, stderr = driver.communicate(timeout=480)
    finally:
        if driver.poll() is None:
            driver.kill()
    assert driver.returncode == 0, stdout + stderr[-3000:]
    assert "trying again" in stderr
    xml = JUnitXml.fromfile(str(junit))
    cases = [case for suite in xml for case in suite]
    # Every planned run exactly once, none lost, none failed; the lost one says so.
    assert sorted(case.name for case in cases) == sorted(names)
    assert not any(case.result for case in cases)
    retried = [case for case in cases if "retried: attempt 1 was lost" in (case.system_out or "")]
    assert retried
    for case in retried:
        summary = json.loads((out / builds[0] / case.name / "result.json").read_text())
        assert summary["retried"] and "lost" in summary["retried"][0]
    # The lost node's SITL went with it (its namespace agent saw its owner die).
    deadline = time.monotonic() + 10
    while sitl_pids() - before and time.monotonic() < deadline:
        time.sleep(0.2)
    assert not sitl_pids() - before


@pytest.mark.timeout(300)
def test_ctrl_c_on_the_driver_cancels_the_clusters_runs_and_leaves_no_sitl(
    request: pytest.FixtureRequest,
    firmware_build_cache: FirmwareCache,
    three_nodes: ThreeNodes,
    tmp_path: Path,
) -> None:
    builds = available_builds(request)[:1]
    before = sitl_pids()
    junit = tmp_path / "stopped.xml"
    names = ("failsafe-switch", "motor-weak", "gusts")
    driver = start_driver(
        names, builds, three_nodes.address, junit, tmp_path / "runs", firmware_build_cache, tmp_path
    )
    try:
        deadline = time.monotonic() + 120
        while not (sitl_pids() - before):  # a run is flying on a node
            assert driver.poll() is None and time.monotonic() < deadline, "no run started"
            time.sleep(0.05)
        driver.send_signal(signal.SIGINT)
        _stdout, stderr = driver.communicate(timeout=120)
    finally:
        if driver.poll() is None:
            driver.kill()
    assert "interrupted" in stderr, stderr[-3000:]
    # What finished is kept; what did not is marked not run, never lost.
    cases = [case for suite in JUnitXml.fromfile(str(junit)) for case in suite]
    assert sorted(case.name for case in cases) == sorted(names)
    assert any(isinstance(r, Skipped) for case in cases for r in case.result)
    deadline = time.monotonic() + 15
    while sitl_pids() - before and time.monotonic() < deadline:
        time.sleep(0.2)
    assert not sitl_pids() - before, "a SITL outlived the cancelled run"


@pytest.mark.timeout(180)
def test_a_scenario_flies_its_rc_links_rate_and_loses_that_link_on_silence(
    lockstep_gps_46_firmware: Path, tmp_path: Path
) -> None:
    """The shipped RC-loss drop with ``[rc] rate_hz = 50`` (a slow CRSF link): the FC measures
    a 50 Hz receiver (its log's header) and still loses the link on silence and disarms."""
    text = (LIBRARY / "rc-loss-hover-drop.toml").read_text() + "\n[rc]\nrate_hz = 50\n"
    (tmp_path / "rc-loss-slow-link.toml").write_text(text)
    (spec,) = find_scenarios([tmp_path / "rc-loss-slow-link.toml"])
    assert spec.rc_rate_hz == 50.0
    result = run_scenario(
        spec, str(lockstep_gps_46_firmware), RunOptions(tmp_path / "out", plot=False)
    )
    assert result.verdict is Verdict.PASSED, (result.reason, result.checks)
    assert any(e.text.startswith("RC lost (silence)") for e in result.events), result.events
    (log, *_) = decode_blackbox(result.artifacts["blackbox"])
    assert log.headers["rc_smoothing_rx_smoothed"] == "50"
