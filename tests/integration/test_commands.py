"""The `bfsitl` command end to end: real SITL, real process, exit codes and output."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import textwrap
import time

import pytest

pytestmark = pytest.mark.sitl

BFSITL = [sys.executable, "-m", "bfsitl.cli.main"]


def run(*args: str, timeout_s: float = 60.0) -> subprocess.CompletedProcess[str]:
    return subprocess.run([*BFSITL, *args], capture_output=True, text=True, timeout=timeout_s)


def pid_alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    # A zombie has exited; only its parent has not reaped it yet.
    try:
        with open(f"/proc/{pid}/stat") as stat:
            return stat.read().split(")")[-1].split()[0] != "Z"
    except (FileNotFoundError, ProcessLookupError):  # it ended between the two calls
        return False


def test_status_start_json_reports_identity_and_blockers(firmware):
    result = run("status", "--start", "--json")
    assert result.returncode == 0, result.stderr
    report = json.loads(result.stdout)
    assert report["identity"]["firmware_version"] == "4.6.0"
    names = {b["name"] for b in report["arming_blockers"]}
    assert "RXLOSS" in names
    assert all(b["fix"] for b in report["arming_blockers"])
    assert "SITL ready" in result.stderr  # progress goes to stderr
    assert "lockstep" not in result.stderr  # a stock build is not one


def test_unreachable_fc_is_one_line_error_and_exit_code_1():
    result = run("status", "--uri", "tcp://127.0.0.1:1", "--timeout", "0.2")
    assert result.returncode == 1
    assert result.stdout == ""
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("bfsitl: error: ")
    assert "connection refused" in lines[0]


def test_bad_usage_is_exit_code_2():
    assert run("telemetry", "--rate", "fast").returncode == 2
    assert run("nonsense").returncode == 2


def test_missing_firmware_names_the_fix(tmp_path):
    result = run("status", "--start", "--firmware", str(tmp_path / "no_such_SITL"))
    assert result.returncode == 1
    assert "no_such_SITL" in result.stderr


def test_cli_command_and_error(firmware):
    ok = run("cli", "--start", "get", "small_angle")
    assert ok.returncode == 0 and "small_angle = 25" in ok.stdout
    bad = run("cli", "--start", "bogus_command")
    assert bad.returncode == 1 and "UNKNOWN COMMAND" in bad.stderr


def test_cli_file_with_save_persists_in_workdir(firmware, tmp_path):
    profile = tmp_path / "profile.txt"
    profile.write_text("# ARM on AUX1\naux 0 0 0 1700 2100 0 0\nset small_angle = 33\nsave\n")
    workdir = tmp_path / "run"
    result = run("cli", "--start", "--workdir", str(workdir), "--file", str(profile))
    assert result.returncode == 0, result.stderr
    backup = tmp_path / "backup.txt"
    result = run("backup", str(backup), "--start", "--workdir", str(workdir))
    assert result.returncode == 0, result.stderr
    text = backup.read_text()
    assert "set small_angle = 33" in text and "aux 0 0 0 1700 2100 0 0" in text


def test_telemetry_json_lines_for_a_duration(firmware):
    result = run("telemetry", "--start", "--rate", "20", "--duration", "1.5", "--json")
    assert result.returncode == 0, result.stderr
    records = [json.loads(line) for line in result.stdout.splitlines()]
    assert 15 <= len(records) <= 40
    assert records[-1]["time_s"] > records[0]["time_s"]
    # Disarmed motor outputs, once boot has settled (the very first snapshot can come before
    # the firmware has initialised its motors and read 0).
    assert records[-1]["motors_us"][:4] == [1000, 1000, 1000, 1000]


def test_ctrl_c_stops_the_sitl_and_exits_130(firmware):
    process = subprocess.Popen(
        [*BFSITL, "telemetry", "--start", "--rate", "10", "--json"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    assert process.stdout is not None
    process.stdout.readline()  # streaming: the SITL is up
    sitl_pids = _sitl_pids_of(process.pid)
    process.send_signal(signal.SIGINT)
    _, stderr = process.communicate(timeout=20)
    assert process.returncode == 130, stderr
    assert "interrupted" in stderr
    for pid in sitl_pids:
        assert not pid_alive(pid)


def test_sitl_does_not_outlive_a_killed_host_process(firmware, tmp_path):
    # The run directory is pytest's: a killed process cannot remove its own.
    script = textwrap.dedent("""
        import os, signal, sys
        from bfsitl.sitl.process import SitlProcess
        sitl = SitlProcess(isolate=True, workdir=sys.argv[1]).start()
        print(sitl.pid, flush=True)
        os.kill(os.getpid(), signal.SIGKILL)   # no cleanup code runs
    """)
    result = subprocess.run(
        [sys.executable, "-c", script, str(tmp_path / "run")],
        capture_output=True,
        text=True,
        timeout=60,
    )
    sitl_pid = int(result.stdout.split()[0])
    deadline = time.monotonic() + 10
    while pid_alive(sitl_pid) and time.monotonic() < deadline:
        time.sleep(0.1)
    assert not pid_alive(sitl_pid)


def _sitl_pids_of(root_pid: int) -> list[int]:
    """SITL processes descending from root_pid (through the namespace agent)."""
    found = []
    for entry in os.listdir("/proc"):
        if not entry.isdigit():
            continue
        try:
            with open(f"/proc/{entry}/cmdline", "rb") as cmdline:
                if b"_SITL" not in cmdline.read():
                    continue
            ancestor = int(entry)
            while ancestor > 1:
                with open(f"/proc/{ancestor}/stat") as stat:
                    ancestor = int(stat.read().split(")")[-1].split()[1])
                if ancestor == root_pid:
                    found.append(int(entry))
                    break
        except (FileNotFoundError, ProcessLookupError, ValueError):
            continue
    assert found, "no SITL process found under the bfsitl command"
    return found


def test_sim_json_reports_health_every_second(firmware):
    result = run("sim", "--duration", "3", "--json", timeout_s=90)
    assert result.returncode == 0, result.stderr
    records = [json.loads(line) for line in result.stdout.splitlines()]
    assert len(records) >= 2
    for key in ("fc_clock_ratio", "fc_cycle_us", "answered_ratio", "speed"):
        assert key in records[-1]
    assert records[-1]["fc_clock_ratio"] == pytest.approx(1.0, abs=0.03)
    assert records[-1]["speed"] == pytest.approx(1.0, abs=0.05)
    assert "fdm packets answered" in result.stderr


def test_doctor_probes_explains_blockers_and_arms(firmware):
    result = run("doctor", timeout_s=120)
    assert result.returncode == 0, result.stdout + result.stderr
    assert "[  ok] firmware" in result.stdout
    assert "arming blocker BOOTGRACE" in result.stdout and "fix:" in result.stdout
    assert "armed and disarmed" in result.stdout
    assert result.stdout.rstrip().endswith("ready to fly")


def test_doctor_without_firmware_fails_with_the_fix(tmp_path):
    result = run("doctor", "--firmware", str(tmp_path / "missing_SITL"))
    assert result.returncode == 1
    assert "[FAIL] firmware" in result.stdout and "missing_SITL" in result.stdout
    assert "problem(s) found" in result.stdout
