"""`bfsitl log replay` on a log the real firmware wrote: the 5-inch profile flies a square
through the lockstep SITL (4.6.0 with GPS; master when given) in still air, and its blackbox
log is replayed through the same firmware with the same profile.

The same quad, settings and sticks must give the same flight: the setpoints agree, each axis
rises and overshoots as the original did.  And a change must show: the same log replayed
again (A/B) with a quarter of the roll P gain rises more slowly on roll, and the report says
so.

What would fail: a stick sent with the wrong sign, centre or scale (the setpoints part), the
throttle sent through the wrong curve (the motors part), a frame sent late or at every step
(feedforward and RC smoothing see another receiver), a 4.6.0 header setting carried over
wrongly, the self-levelling switch lost, the two logs misaligned.
"""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import numpy as np
import pytest

from bfsitl.cli.main import main
from bfsitl.errors import BfsitlError
from bfsitl.scenario.load import load_scenario
from bfsitl.scenario.result import Verdict
from bfsitl.scenario.run import RunOptions, run_scenario

pytestmark = pytest.mark.sitl

SCENARIO = Path(__file__).resolve().parents[1] / "data" / "fit" / "excite-5inch.toml"
#: The original flight logs at 1 kHz on each generation (see test_log_fit_sitl.py).
SAMPLE_RATE = {"4.6.0-gps": "1/8", "master": "1/1"}


@pytest.fixture(params=["4.6.0-gps", "master"])
def flown_log(request: pytest.FixtureRequest, tmp_path: Path) -> tuple[Path, Path]:
    """(the firmware, the blackbox log of the 5-inch square it flew)."""
    name = (
        "lockstep_gps_46_firmware" if request.param == "4.6.0-gps" else "lockstep_master_firmware"
    )
    firmware: Path = request.getfixturevalue(name)
    rate = f"set blackbox_sample_rate = {SAMPLE_RATE[request.param]}"
    # Still air: the log does not say what the wind was, so a replay flies without one.
    scenario = dataclasses.replace(load_scenario(SCENARIO), cli=(rate,), wind=None)
    result = run_scenario(scenario, str(firmware), RunOptions(tmp_path / "run", plot=False))
    assert result.verdict is Verdict.PASSED, result.reason
    return firmware, Path(result.artifacts["blackbox"])


def _replay(log: Path, firmware: Path, out: Path, *extra: str) -> tuple[int, dict]:
    code = main(
        [
            "log", "replay", str(log), "--vehicle", "5inch-freestyle",
            "--firmware", str(firmware), "--out", str(out), *extra,
        ]
    )  # fmt: skip
    return code, json.loads((out / "replay-report.json").read_text())


# A 60 s flight and two replays: about 50 s on two idle cores, more on a busy machine.
@pytest.mark.timeout(300)
def test_a_flight_replayed_through_its_own_firmware_flies_the_same(
    flown_log: tuple[Path, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    firmware, log = flown_log
    out = tmp_path / "ab"
    # A: the log's own settings; B: a quarter of the roll P gain, the same sticks.
    code, report = _replay(log, firmware, out, "--b-cli", "set p_roll = 12")
    printed = capsys.readouterr()
    assert code == 0, printed.out + printed.err
    axes = report["comparison"]["axes"]
    for name in ("roll", "pitch", "yaw"):
        axis = axes[name]
        assert axis["setpoint_correlation"] >= 0.99, (name, axis)
        assert abs(axis["rise_time_ratio"] - 1.0) <= 0.2, (name, axis)
        assert abs(axis["overshoot_difference_pct"]) <= 5.0, (name, axis)
    assert report["targets"]["met"] is True
    assert report["comparison"]["motor_correlation"] > 0.9
    assert abs(report["comparison"]["motor_level_difference_pct"]) < 3.0
    # Its own firmware's header carries over: nothing flight-relevant is left behind.
    carried = {c["header"] for c in report["settings"]["carried"]}
    assert {"rollPID", "rates", "rc_rates"} <= carried, carried
    lines = [line for c in report["settings"]["carried"] for line in c["cli"]]
    for name in ("p_roll", "i_roll", "d_roll", "d_max_roll", "f_roll", "roll_rc_rate"):
        assert any(line.startswith(f"set {name} =") for line in lines), name
    assert (out / "replay-report.png").stat().st_size > 10_000
    assert "setpoint r" in printed.out and "targets" in printed.out

    # The change shows where it was made: B rises more slowly on roll than A, not on yaw,
    # and misses the real flight's roll.
    weak = json.loads((out / "b" / "replay-report.json").read_text())
    assert weak["comparison"]["axes"]["roll"]["targets"]["rise_time"] is False
    b_against_a = json.loads((out / "b-against-a.json").read_text())["b_against_a"]["axes"]
    assert b_against_a["roll"]["rise_time_ratio"] > 1.2, b_against_a["roll"]
    assert abs(b_against_a["yaw"]["rise_time_ratio"] - 1.0) <= 0.2, b_against_a["yaw"]
    assert "B (" in printed.out and "against A" in printed.out
    assert (out / "b-against-a.png").stat().st_size > 10_000


# The 60 s flight and one replay per side.
@pytest.mark.timeout(300)
def test_a_replay_scenario_in_scenario_compare_says_what_a_change_did_to_the_flight(
    flown_log: tuple[Path, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """The same log as a ``[replay]`` scenario, A against B with a quarter of the roll P:
    A meets its expectations (it is the flight that was flown), B's roll overshoots more and
    rises later, pitch and yaw stay the same, and the verdict fails the comparison."""
    firmware, log = flown_log
    scenario = tmp_path / "flown-square.toml"
    scenario.write_text(
        f'description = "the 5-inch square, replayed"\n[replay]\nlog = "{log}"\n'
        '[vehicle]\nmodel = "5inch-freestyle"\n'
        "[expect]\nreplay_targets_met = true\nmin_setpoint_correlation = 0.99\n"
        'no_finding = ["crash", "loss_of_control"]\n'
    )
    out = tmp_path / "cmp"
    code = main(
        [
            "scenario", "compare", str(scenario), "--firmware", str(firmware),
            "--firmware", str(firmware), "--b-cli", "set p_roll = 12", "--out", str(out),
        ]
    )  # fmt: skip
    printed = capsys.readouterr()
    assert code == 1, printed.out + printed.err
    assert "one seed" in printed.err  # a replay repeats bit for bit
    a_run = json.loads((out / "A" / "flown-square" / "seed-0" / "result.json").read_text())
    assert a_run["verdict"] == "passed", a_run["reason"]
    assert {"crash", "loss_of_control"} <= set(a_run["analysers"]["watched"])
    (compared,) = json.loads((out / "compare.json").read_text())["scenarios"]
    figures = {f["name"]: f for f in compared["figures"]}
    assert figures["roll_overshoot_pct"]["change"] == "worse", figures["roll_overshoot_pct"]
    assert figures["roll_rise_ms"]["b"][0] > 1.2 * figures["roll_rise_ms"]["a"][0]
    for name in ("yaw_tracking_dps", "yaw_rise_ms", "pitch_overshoot_pct", "motor_mean_pct"):
        assert figures[name]["change"] == "same", figures[name]
    assert compared["change"] in ("worse", "changed") and compared["fails"]
    assert (out / "overlays" / "flown-square.png").stat().st_size > 10_000


@pytest.mark.timeout(300)
def test_a_real_logs_receiver_rate_reaches_the_firmware(
    lockstep_gps_46_firmware: Path, tmp_path: Path
) -> None:
    """Every real log whose header says its receiver's rate, replayed with the FC's RX_TIMING
    debug on: the replaying 4.6.0 must measure the frames at that rate (its stock SITL
    receiver would count one at every loop, 8 kHz)."""
    from bfsitl.blackbox import decode_blackbox
    from bfsitl.fit import pick_log
    from bfsitl.replay.sticks import stick_stream
    from tests.support.real_logs import require_real_logs

    checked = 0
    for path in require_real_logs():
        try:
            stream = stick_stream(pick_log(path, None))
        except BfsitlError:
            continue  # too short or no sticks: the replay refuses it (unit-tested)
        if not stream.interval_source.startswith("header"):
            continue
        out = tmp_path / path.stem
        _replay(path, lockstep_gps_46_firmware, out, "--cli", "set debug_mode = RX_TIMING")
        replayed = max(decode_blackbox(out / "replay-LOG00001.BF"), key=lambda log: len(log.frames))
        # debug[0]: the last frame's interval in 10 us units (rx.c, DEBUG_RX_TIMING).
        intervals_ms = np.array([frame.debug[0] / 100.0 for frame in replayed.frames[500:]])
        assert np.median(intervals_ms) == pytest.approx(stream.frame_interval_s * 1000, rel=0.05)
        checked += 1
    if not checked:
        pytest.skip("no real log here states its receiver's rate in its header")


def test_every_setting_a_replay_writes_is_found_in_the_4_6_0_build(
    lockstep_gps_46_firmware: Path,
) -> None:
    """The build's bytes decide what is sent; a name the scan misses is a setting silently
    lost (the linker keeps 4.6.0's d_roll only as the tail of align_board_roll)."""
    from bfsitl.build.binary_scan import names_missing
    from bfsitl.replay.setting_tables import SETTING_CHOICES, SETTING_RANGES

    names = frozenset(SETTING_RANGES) | frozenset(SETTING_CHOICES)
    assert names_missing(lockstep_gps_46_firmware, names) == set()
