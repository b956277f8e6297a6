"""``bfsitl fly --policy``: what is wrong with the policy or its options is said before a
SITL starts (nothing is made on disk), and the summary says how the policy flew."""

from __future__ import annotations

from pathlib import Path

import pytest

from bfsitl.cli.fly_command import render_summary
from bfsitl.cli.main import main


def refused(tmp_path: Path, capsys: pytest.CaptureFixture[str], *argv: str) -> str:
    """The command's error, after checking it exits 1 and starts nothing."""
    run = tmp_path / "run"
    assert main(["fly", "--workdir", str(run), *argv]) == 1
    assert not run.exists()
    return capsys.readouterr().err


def test_a_policy_target_without_a_policy_is_refused(tmp_path, capsys) -> None:
    assert "give --policy FILE" in refused(tmp_path, capsys, "--policy-target", "1,2,3")


@pytest.mark.parametrize(
    ("given", "said"),
    [("1,2", "expected N,E,UP"), ("1,x,2", "must be numbers"), ("1,2,0", "above the ground")],
)
def test_a_policy_target_that_is_not_north_east_up_is_a_usage_error(
    given: str, said: str, capsys
) -> None:
    with pytest.raises(SystemExit) as exited:
        main(["fly", "--policy-target", given])
    assert exited.value.code == 2
    assert said in capsys.readouterr().err


def test_a_missing_policy_file_is_said_before_anything_starts(tmp_path, capsys) -> None:
    pytest.importorskip("onnxruntime")
    err = refused(tmp_path, capsys, "--policy", str(tmp_path / "nowhere.onnx"))
    assert "no such policy file" in err


class TestWithAPolicyFile:
    @pytest.fixture
    def policy(self, tmp_path: Path) -> Path:
        pytest.importorskip("onnxruntime")
        pytest.importorskip("onnx")
        from support.onnx_policies import go_to_target_weights, linear_policy_file

        return linear_policy_file(tmp_path / "hover.onnx", go_to_target_weights())

    def test_another_rate_than_the_policys_is_refused(self, policy, tmp_path, capsys) -> None:
        err = refused(tmp_path, capsys, "--policy", str(policy), "--rate", "100")
        assert "trained at 50 Hz" in err and "leave --rate out" in err

    def test_an_angle_policy_without_angle_is_refused(self, policy, tmp_path, capsys) -> None:
        err = refused(tmp_path, capsys, "--policy", str(policy), "--no-angle")
        assert "trained in ANGLE" in err

    def test_a_policy_does_not_fly_a_mission_file(self, policy, tmp_path, capsys) -> None:
        err = refused(tmp_path, capsys, "--policy", str(policy), "--mission", "square")
        assert "cannot be combined with --mission" in err

    def test_a_file_that_is_not_a_bfsitl_policy_is_said(self, tmp_path, capsys) -> None:
        pytest.importorskip("onnxruntime")
        pytest.importorskip("onnx")
        from support.onnx_policies import go_to_target_weights, linear_policy_file

        other = linear_policy_file(
            tmp_path / "other.onnx", go_to_target_weights(), policy_format="someone-else-1"
        )
        assert "not a bfsitl policy" in refused(tmp_path, capsys, "--policy", str(other))


def test_the_summary_says_how_the_policy_flew() -> None:
    policy = {
        "file": "runs/hover/policy.onnx",
        "steps": 500,
        "rate_hz_kept": 49.96,
        "rate_hz_asked": 50.0,
        "inference_us_median": 18.2,
        "inference_us_p99": 41.0,
        "judged_s": 5.0,
        "true_distance_rms_m": 0.081,
        "fc_distance_rms_m": 0.064,
    }
    text = render_summary(
        {"outcome": "landed", "reason": "landed", "controller": "fused", "policy": policy}
    )
    assert (
        "policy         policy.onnx: 500 steps at 50.0 Hz (asked 50), inference 18 us "
        "median, 41 us p99; last 5 s 8 cm RMS (truth), 6 cm RMS (FC) from the target"
    ) in text
    board = render_summary(
        {
            "outcome": "landed",
            "reason": "landed",
            "controller": "fused",
            "policy": {**policy, "true_distance_rms_m": None},
        }
    )
    assert "last 5 s 6 cm RMS (FC) from the target" in board
