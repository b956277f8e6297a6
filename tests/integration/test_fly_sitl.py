"""`bfsitl fly` end to end: the real SITL, the embedded physics, a real process, real files.

Each flight starts its own SITL in its own network namespace.  Hold times are shortened to
keep CI quick; the altitude and outcome checks are the issue's own.
"""

from __future__ import annotations

import csv
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from bfsitl.mission.flight_row import COLUMNS

pytestmark = pytest.mark.sitl

BFSITL = [sys.executable, "-m", "bfsitl.cli.main"]
HOLD_TOLERANCE_M = 0.10
#: The stock SITL's flight runs at the faithful speed of a busy 2-core machine.
STOCK_SPEED = 0.5


def fly(tmp_path: Path, *args: str, timeout_s: float = 120.0) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [*BFSITL, "fly", *args], capture_output=True, text=True, timeout=timeout_s, cwd=tmp_path
    )


def read_rows(path: Path) -> list[dict[str, str]]:
    with path.open(newline="") as file:
        reader = csv.DictReader(file)
        assert tuple(reader.fieldnames or ()) == COLUMNS
        return list(reader)


def read_until_line(
    process: subprocess.Popen[str], needle: str, timeout_s: float = 60.0
) -> list[str]:
    """The process's stderr lines up to the first holding ``needle`` (asserted to come)."""
    assert process.stderr is not None
    deadline = time.monotonic() + timeout_s
    seen = []
    while time.monotonic() < deadline:
        line = process.stderr.readline()
        seen.append(line)
        if needle in line or not line:
            break
    assert any(needle in line for line in seen), "".join(seen)
    return seen


def processes_in(directory: Path) -> list[str]:
    """Processes whose working directory is inside ``directory`` (a SITL, its agent)."""
    found = []
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit() or int(entry.name) == os.getpid():
            continue
        try:
            cwd = Path(os.readlink(entry / "cwd"))
            state = (entry / "stat").read_text().split(")")[-1].split()[0]
            cmdline = (entry / "cmdline").read_bytes().replace(b"\0", b" ").decode()
        except OSError:
            continue
        if state != "Z" and (cwd == directory or directory in cwd.parents):
            found.append(f"{entry.name}: {cmdline}")
    return found


@pytest.mark.timeout(300)
def test_default_mission_lands_and_holds_then_a_second_flight_in_the_same_workdir(
    firmware, lockstep_46_firmware, tmp_path
):
    """The first flight is the default one: the package's stock SITL on the wall clock, at
    half speed (the faithful speed on a busy 2-core machine: at 1x, during full test runs,
    it answered 55 % of fdm packets and oscillated past the take-off's time limit)."""
    lockstep = lockstep_46_firmware
    workdir = tmp_path / "quad"
    log, plot, summary_path = tmp_path / "f1.csv", tmp_path / "f1.png", tmp_path / "f1.json"
    first = fly(
        tmp_path,
        "--workdir",
        str(workdir),
        "--hold",
        "4",
        "--speed",
        str(STOCK_SPEED),
        "--log",
        str(log),
        "--plot",
        str(plot),
        "--summary",
        str(summary_path),
        timeout_s=200,
    )
    assert first.returncode == 0, first.stdout + first.stderr
    summary = json.loads(summary_path.read_text())
    assert summary["outcome"] == "landed"
    assert summary["hold"]["max_abs_error_m"] <= HOLD_TOLERANCE_M, summary["hold"]
    # Wall seconds: the firmware's 5 s boot grace is FC time, which runs at STOCK_SPEED.
    assert summary["armed_after_s"] < 10.0 / STOCK_SPEED
    rows = read_rows(log)
    assert len(rows) == summary["rows"]
    phases = [r["phase"] for r in rows]
    assert phases[0] == "ground" and phases[-1] == "landed"
    assert {"ground", "takeoff", "hold", "land"} <= set(phases)
    # Armed at idle on the ground first (the fused controller learns the barometer's zero).
    ground = [r for r in rows if r["phase"] == "ground"]
    assert all(r["rc_throttle_us"] == "1000" and r["armed"] == "1" for r in ground)
    assert float(ground[-1]["time_s"]) - float(ground[0]["time_s"]) >= 1.9
    assert summary["controller"] == "fused"
    holding = [r for r in rows if r["phase"] == "hold"]
    assert all(abs(float(r["sim_alt_m"]) - 2.0) <= HOLD_TOLERANCE_M for r in holding)
    # The FC's own altitude agrees with the truth within its barometer's resolution.
    assert all(abs(float(r["fc_alt_m"]) - float(r["sim_alt_m"])) < 0.3 for r in holding)
    last = rows[-1]
    assert last["armed"] == "0" and last["rc_aux1_us"] == "1000"
    assert float(last["sim_alt_m"]) < 0.05
    assert plot.stat().st_size > 10_000 and plot.read_bytes()[:4] == b"\x89PNG"
    assert "outcome        landed" in first.stdout

    # The same run directory with 4.6.0's lockstep build: it reads the same eeprom.bin.
    second = fly(
        tmp_path, "--workdir", str(workdir), "--hold", "1", "--json", "--firmware", str(lockstep)
    )
    assert second.returncode == 0, second.stdout + second.stderr
    assert json.loads(second.stdout)["outcome"] == "landed"
    assert "already configured" in second.stderr  # the persisted eeprom.bin held the ranges


def test_no_arm_range_ends_arming_blocked_naming_it(lockstep_46_firmware, tmp_path):
    result = fly(
        tmp_path, "--no-provision", "--json", "--firmware", str(lockstep_46_firmware), timeout_s=60
    )
    assert result.returncode == 1, result.stderr
    summary = json.loads(result.stdout)
    assert summary["outcome"] == "arming-blocked"
    assert summary["blockers"] == ["NO_ARM_RANGE"]
    assert "aux 0 0 0 1700 2100 0 0" in summary["reason"]


def test_interrupt_leaves_no_process_a_complete_log_and_rc_at_disarm(
    lockstep_46_firmware, tmp_path
):
    """Ctrl-C in lockstep: the interrupt lands between two steps, the disarm is stepped in."""
    log = tmp_path / "flight.csv"
    workdir = tmp_path / "run"
    process = subprocess.Popen(
        [
            *BFSITL,
            "fly",
            "--workdir",
            str(workdir),
            "--hold",
            "600",
            "--log",
            str(log),
            "--firmware",
            str(lockstep_46_firmware),
        ],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        cwd=tmp_path,
    )
    try:
        seen = read_until_line(process, "hold")
        time.sleep(0.5)
        process.send_signal(signal.SIGINT)
        stdout, stderr = process.communicate(timeout=30)
    finally:
        if process.poll() is None:
            process.kill()
    assert process.returncode == 130, stderr
    assert "outcome: interrupted" in "".join(seen) + stderr
    rows = read_rows(log)  # complete: the header and every row parse
    assert rows[-1]["phase"] == "interrupted"
    assert rows[-1]["rc_aux1_us"] == "1000" and rows[-1]["rc_throttle_us"] == "1000"
    assert any(r["phase"] == "hold" for r in rows)
    time.sleep(0.5)  # the namespace agent exits once its SITL has gone
    assert processes_in(tmp_path) == []


def test_scripted_mission_from_python_goes_to_a_second_altitude(lockstep_46_firmware, tmp_path):
    from bfsitl.control import make_controller
    from bfsitl.mission import FlightLoop, FlightSession, SessionConfig, SitlLaunch

    config = SessionConfig(sitl=SitlLaunch(firmware=lockstep_46_firmware, workdir=tmp_path / "run"))
    with FlightSession(config) as s:
        loop = FlightLoop(s, make_controller("cascade"))
        loop.arm()
        loop.takeoff(1.0)
        loop.climb_to(2.5)
        loop.hold(1.0)
        held = [r.sim_alt_m for r in loop.rows if r.phase == "hold"]
        assert held and all(abs(alt - 2.5) <= HOLD_TOLERANCE_M for alt in held)
        loop.land()
        assert not s.client.status().armed
    assert loop.rows[-1].phase == "landed"
    # The take-off ended at its own target, not on the way to the next one.  (Its overshoot
    # on a 1 m step was measured at 1-21 %: the README's controller section says why.)
    assert max(r.sim_alt_m for r in loop.rows if r.phase == "takeoff") < 1.5
