"""`bfsitl log fit` on a log the real firmware wrote while flying a known quad: the 5-inch
profile flies a square through the lockstep SITL (4.6.0 with GPS; master when given), and the
fit of its blackbox log must give the profile back.

What would fail: a motor value read on the wrong scale (the SITL logs PWM 1000-2000, real
boards DShot 48-2047), the log's gyro read in the wrong frame or a frame late, a lag or an
effectiveness the firmware's own loop hides, a profile that hovers at another command than
the log's.
"""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import pytest

from bfsitl.cli.main import main
from bfsitl.fit.fitted_profile import effectiveness_of
from bfsitl.scenario.load import load_scenario
from bfsitl.scenario.result import Verdict
from bfsitl.scenario.run import RunOptions, run_scenario
from bfsitl.vehicles import shipped_profiles

pytestmark = pytest.mark.sitl

SCENARIO = Path(__file__).resolve().parents[1] / "data" / "fit" / "excite-5inch.toml"


#: Each generation logs at 1 kHz: 4.6.0's SITL loops at 8 kHz, master's at 1 kHz (its
#: header's looptime), so the same 1/8 would give master 125 Hz.
SAMPLE_RATE = {"4.6.0-gps": "1/8", "master": "1/1"}


@pytest.fixture(params=["4.6.0-gps", "master"])
def gps_lockstep_firmware(request: pytest.FixtureRequest) -> tuple[Path, str]:
    name = (
        "lockstep_gps_46_firmware" if request.param == "4.6.0-gps" else "lockstep_master_firmware"
    )
    return request.getfixturevalue(name), request.param


def test_a_sitl_flight_of_a_known_quad_is_fitted_back(
    gps_lockstep_firmware: tuple[Path, str], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    firmware, generation = gps_lockstep_firmware
    rate = f"set blackbox_sample_rate = {SAMPLE_RATE[generation]}"
    scenario = dataclasses.replace(load_scenario(SCENARIO), cli=(rate,))
    result = run_scenario(scenario, str(firmware), RunOptions(tmp_path / "run", plot=False))
    assert result.verdict is Verdict.PASSED, result.reason
    out = tmp_path / "fit"
    code = main(
        ["log", "fit", str(result.artifacts["blackbox"]), "--mass-g", "650", "--out", str(out)]
    )
    printed = capsys.readouterr()
    assert code == 0, printed.err
    report = json.loads((out / "fit-report.json").read_text())
    assert report["log_interval_ms"] == pytest.approx(1.0, abs=0.01)
    fitted = report["fitted"]
    spec = shipped_profiles()["5inch-freestyle"]
    truth = dict(zip(("roll", "pitch", "yaw"), effectiveness_of(spec), strict=True))
    for axis, value in truth.items():
        assert fitted[axis]["effectiveness_rad_s2"]["value"] == pytest.approx(value, rel=0.05)
    assert fitted["motor_time_constant_ms"] == pytest.approx(spec.motor_time_constant_ms, rel=0.05)
    assert fitted["thrust_to_weight"]["value"] == pytest.approx(spec.thrust_to_weight, rel=0.05)
    assert not fitted["props_out"]
    hover = report["hover_command"]
    assert abs(hover["model"] - hover["logged"]) < 0.02
    # The replay of what the fit did not see: far better than no change, and no worse than
    # the true profile by more than a little.
    score = report["score"]
    for axis in ("roll", "pitch", "yaw"):
        assert score["fitted"][axis] < 0.25, score
        assert score["fitted"][axis] < 0.3 * max(score["hold"][axis], 0.05), score
        assert score["fitted"][axis] <= score["shipped"]["5inch-freestyle"][axis] + 0.03, score
    assert report["trusted"] is True
    assert "motor time constant" in printed.out and "hold (no change)" in printed.out
