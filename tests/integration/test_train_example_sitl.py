"""examples/train_hover.py end to end in a few hundred steps: PPO through the real 4.6.0 SITL
in bfsitl's vector environment (two workers) seen through Sb3VectorEnv, the learning curve, the
saved policy and its checkpoint judged on an unseen seed, and an evaluation flight written like
``bfsitl fly``'s beside a random and the hand-written policy.  It proves the pipeline, not
the learning (that takes minutes: docs/gym.md has the figures)."""

from __future__ import annotations

import importlib.util
import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

pytestmark = pytest.mark.sitl

EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "train_hover.py"
NEEDS_SB3 = pytest.mark.skipif(
    importlib.util.find_spec("stable_baselines3") is None,
    reason="Stable-Baselines3 not installed: pip install torch "
    "'bfsitl[learn]' to run the training example's smoke test",
)


def run_smoke(
    example: Path, firmware: Path, tmp_path: Path, *options: str, env: dict[str, str] | None = None
) -> Path:
    """``example --smoke`` with ``options`` on ``firmware``; its --out folder, once it
    succeeded."""
    out = tmp_path / "run"
    run = subprocess.run(
        [sys.executable, str(example), "--smoke", *options, "--firmware", str(firmware)]
        + ["--out", str(out)],
        capture_output=True,
        text=True,
        timeout=300,
        cwd=tmp_path,
        env=env,
    )
    assert run.returncode == 0, run.stdout[-2000:] + run.stderr[-4000:]
    return out


@NEEDS_SB3
def test_the_training_example_runs_and_writes_its_outputs(
    lockstep_gps_46_firmware: Path, tmp_path: Path
) -> None:
    scratch = tmp_path / "tmp"
    scratch.mkdir()
    out = run_smoke(
        EXAMPLE, lockstep_gps_46_firmware, tmp_path, env={**os.environ, "TMPDIR": str(scratch)}
    )
    # No SB3 logger folder left in the temporary directory (SB3 makes one unless told).
    # bfsitl-cores-<uid> stays by design: the core claims' lock files, shared by every run.
    assert not list(scratch.glob("SB3-*")), list(scratch.iterdir())
    for name in (
        "policy.zip",
        "policy.onnx",
        "learning_curve.csv",
        "evaluation.csv",
        "evaluation.png",
        "evaluation.json",
    ):
        assert (out / name).is_file(), name
    summary = json.loads((out / "evaluation.json").read_text())
    assert 256 <= summary["training"]["steps"] <= 512 and summary["training"]["envs"] == 2
    assert summary["training"]["method"] == "ppo"
    assert set(summary["evaluation"]) == {"learned", "random", "hand-written"}
    # The one checkpoint (the end of training) was flown from the one evaluation seed.
    (checkpoint,) = summary["checkpoints"]
    assert (out / "checkpoints" / checkpoint["checkpoint"]).is_file()
    assert checkpoint["flights"] == 1 and checkpoint["held"] in (0, 1)
    assert summary["evaluation_seeds"] == [10_000]
    # The evaluation flew the exported file with onnxruntime; its time per call is measured.
    assert 0 < summary["policy_onnx"]["inference_us_median"] < 10_000
    # The hand-written policy flies the whole 2 s evaluation; the CSV has the fly columns.
    assert summary["evaluation"]["hand-written"]["ended_because"] is None
    header = (out / "evaluation.csv").read_text().splitlines()[0].split(",")
    assert header[:3] == ["time_s", "phase", "target_alt_m"] and "target_north_m" in header


RECOVER_EXAMPLE = EXAMPLE.with_name("train_recover.py")


@NEEDS_SB3
def test_the_recovery_example_trains_exports_and_throws(
    lockstep_gps_46_firmware: Path, tmp_path: Path
) -> None:
    # Trained on a quad drawn per episode, thrown also on one it never flew.
    out = run_smoke(
        RECOVER_EXAMPLE,
        lockstep_gps_46_firmware,
        tmp_path,
        *("--mode", "angle", "--vehicles", "iris,5inch-freestyle"),
        *("--eval-vehicles", "3inch-cinewhoop"),
    )
    for name in ("policy.zip", "policy.onnx", "learning_curve.csv", "throws.csv"):
        assert (out / name).is_file(), name
    summary = json.loads((out / "evaluation.json").read_text())
    assert summary["training"]["mode"] == "angle" and summary["training"]["envs"] == 2
    assert summary["training"]["vehicles"] == ["iris", "5inch-freestyle"]
    assert 256 <= summary["training"]["steps"] <= 512
    evaluation = summary["evaluation"]
    unseen = "3inch-cinewhoop, still air"
    assert list(evaluation) == [
        "still air",
        "wind 3 m/s, gusts 1.5 m/s",
        "motor 1 at 75 %",
        unseen,
    ]
    for by_policy in evaluation.values():
        assert set(by_policy) == {"learned", "sticks centred, hover throttle", "hand-written hover"}
        assert all(verdict["throws"] == 2 for verdict in by_policy.values())
    # In ANGLE mode the FC rights the quad itself: the hover throttle recovers both throws.
    # (on the unseen 3-inch too, at its own hover throttle: the quad thrown is the 3-inch).
    for condition in ("still air", unseen):
        assert evaluation[condition]["sticks centred, hover throttle"]["recovered"] == 2
    rows = (out / "throws.csv").read_text().splitlines()
    assert len(rows) == 1 + 4 * 3 * 2 and rows[0].startswith("condition,policy,throw,tilt_deg")
    from bfsitl.gym.onnx_policy import OnnxPolicy

    assert OnnxPolicy(out / "policy.onnx").mode == "angle"


WAYPOINTS_EXAMPLE = EXAMPLE.with_name("train_waypoints.py")


@NEEDS_SB3
def test_the_waypoints_example_trains_and_races_the_autopilot(
    lockstep_gps_46_firmware: Path, tmp_path: Path
) -> None:
    out = run_smoke(WAYPOINTS_EXAMPLE, lockstep_gps_46_firmware, tmp_path)
    for name in ("policy.zip", "policy.onnx", "learning_curve.csv", "laps.csv"):
        assert (out / name).is_file(), name
    summary = json.loads((out / "evaluation.json").read_text())
    assert 256 <= summary["training"]["steps"] <= 512 and summary["training"]["count"] == 4
    evaluation = summary["evaluation"]
    assert list(evaluation) == [
        "still air",
        "wind 3 m/s, gusts 1.5 m/s",
        "motor 1 at 75 %",
        "random courses, still air",
    ]
    for by_pilot in evaluation.values():
        assert set(by_pilot) == {"learned", "hand-written", "Autopilot"}
        assert all(verdict["laps"] == 1 for verdict in by_pilot.values())
    # The Autopilot flies the course in still air: all four points, inside 20 s.
    autopilot = evaluation["still air"]["Autopilot"]
    assert autopilot["completed"] == 1 and autopilot["missed_points"] == 0
    assert 5.0 < autopilot["lap_s_median_p90"][0] < 20.0
    rows = (out / "laps.csv").read_text().splitlines()
    assert len(rows) == 1 + 4 * 3 and rows[0].startswith("condition,pilot,lap,seed,passed")
