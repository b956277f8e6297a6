"""Controllers by name, with gain overrides, and clear errors for what does not exist."""

from __future__ import annotations

import pytest

from bfsitl.control import (
    CONTROLLERS,
    DEFAULT_CONTROLLER,
    AltitudeController,
    CascadeGains,
    ControllerConfigError,
    gain_names,
    make_controller,
)
from bfsitl.errors import BfsitlError


def test_the_four_names_and_the_default():
    assert set(CONTROLLERS) == {"fused", "cascade", "tutorial-pid", "open-loop"}
    assert DEFAULT_CONTROLLER == "fused"
    for name in CONTROLLERS:
        controller = make_controller(name, {})
        assert isinstance(controller, AltitudeController)
        assert controller.name == name


def test_gain_names_lists_defaults_in_order():
    names = gain_names("cascade")
    assert list(names)[0] == "hover_guess_us"
    assert names["rate_kp"] == CascadeGains().rate_kp
    assert "kp" in gain_names("tutorial-pid") and "climb_us" in gain_names("open-loop")


def test_overrides_are_applied():
    pid = make_controller("tutorial-pid", {"kp": 150, "kd": "12.5"})
    assert pid.gains.kp == 150.0 and pid.gains.kd == 12.5


@pytest.mark.parametrize(
    "name, gains, message",
    [
        (
            "pid",
            {},
            "unknown controller 'pid'; choose one of: cascade, fused, open-loop, tutorial-pid",
        ),
        ("tutorial-pid", {"kq": 1.0}, "has no gain 'kq'; its gains are: hover_base_us, kp"),
        ("tutorial-pid", {"kp": "fast"}, "must be a number"),
        ("tutorial-pid", {"kp": float("inf")}, "must be finite"),
        ("cascade", {"rate_kp": -5}, "rate_kp must be >= 0"),
    ],
)
def test_bad_names_and_values_raise_a_clear_value_error(name, gains, message):
    with pytest.raises(ControllerConfigError, match=message.replace("(", r"\(")) as caught:
        make_controller(name, gains)
    assert isinstance(caught.value, BfsitlError) and isinstance(caught.value, ValueError)
    with pytest.raises(ControllerConfigError):
        gain_names("pid")
