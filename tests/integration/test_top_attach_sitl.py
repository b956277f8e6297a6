"""``bfsitl top`` attached to a running ``bfsitl fly``: the real SITL in its own network
namespace, the flight's second MSP port (UART2) reached from a second process.

The flight flies a lockstep 4.6.0 GPS build paced to real time, so it is still in the air
when ``top`` looks; ``top`` must see it armed with its motors above idle, name the flight it
attached to, and leave it undisturbed: the flight lands, and its advert is gone afterwards.
"""

from __future__ import annotations

import json
import subprocess
import sys
import time
from pathlib import Path

import pytest

from bfsitl.sitl.running_flights import flights_dir

pytestmark = pytest.mark.sitl

BFSITL = [sys.executable, "-m", "bfsitl.cli.main"]
#: The hold, simulated seconds (= wall seconds at --speed 1): long enough for two looks.
HOLD_S = 8


def read_stderr_until(process: subprocess.Popen[str], needle: str, timeout_s: float) -> str:
    """The flight's stderr up to the first line holding ``needle`` (asserted to come)."""
    assert process.stderr is not None
    deadline = time.monotonic() + timeout_s
    seen: list[str] = []
    while time.monotonic() < deadline:
        line = process.stderr.readline()
        seen.append(line)
        if needle in line or not line:
            break
    text = "".join(seen)
    assert needle in text, text
    return text


def top_once(cwd: Path, *args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [*BFSITL, "top", "--once", *args], capture_output=True, text=True, timeout=60, cwd=cwd
    )


def motor_values(frame: str) -> list[int]:
    """M1..M4 in microseconds, from the frame's motors panel (``│ M1 1542 ███...``)."""
    values = []
    for line in frame.splitlines():
        words = line.replace("│", " ").split()
        for index, word in enumerate(words[:-1]):
            if word in ("M1", "M2", "M3", "M4") and words[index + 1].isdigit():
                values.append(int(words[index + 1]))
    return values


@pytest.mark.timeout(240)
def test_top_attaches_to_a_running_flight_and_sees_it_fly(
    lockstep_gps_46_firmware: Path, tmp_path: Path
) -> None:
    summary_path = tmp_path / "summary.json"
    flight = subprocess.Popen(
        [
            *BFSITL,
            "fly",
            "--firmware",
            str(lockstep_gps_46_firmware),
            "--workdir",
            str(tmp_path / "run"),
            "--speed",
            "1",
            "--hold",
            str(HOLD_S),
            "--summary",
            str(summary_path),
        ],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        cwd=tmp_path,
    )
    try:
        started = read_stderr_until(flight, "`bfsitl top` can watch this flight", 120)
        assert "isolated network namespace" in started
        read_stderr_until(flight, f"for {HOLD_S} s", 60)  # in the air, holding
        adverts = sorted(flights_dir().glob("*.json"))
        assert [path.stem for path in adverts] == [str(flight.pid)]
        assert json.loads(adverts[0].read_text())["netns_pid"] is not None

        first = top_once(tmp_path)
        time.sleep(1.0)
        second = top_once(tmp_path, "--attach", str(flight.pid))
        stdout, stderr = flight.communicate(timeout=120)
    finally:
        if flight.poll() is None:
            flight.kill()
            flight.wait()

    for look in (first, second):
        assert look.returncode == 0, look.stdout + look.stderr
        assert f"attaching to flight {flight.pid}: `" in look.stderr
        assert "in its private network namespace" in look.stderr
        assert "1 frame(s), 1 update(s), 0 error(s)" in look.stderr
        assert f"(flight {flight.pid}, UART2)" in look.stdout
        assert "ARMED" in look.stdout and "ANGLE" in look.stdout
        motors = motor_values(look.stdout)
        assert len(motors) == 4 and all(m > 1100 for m in motors), look.stdout
    # Undisturbed: the flight went on, landed, and took its advert away.
    assert flight.returncode == 0, stdout + stderr
    assert json.loads(summary_path.read_text())["outcome"] == "landed"
    assert list(flights_dir().glob("*.json")) == []
