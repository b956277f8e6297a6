"""`--speed max`, the lockstep switch and the build option, without a SITL."""

from __future__ import annotations

import argparse
import math

import pytest

from bfsitl.build.binary_scan import LOCKSTEP_MARKER, binary_traits, clear_cache
from bfsitl.build.lockstep import MARKER
from bfsitl.cli.fly_command import parse_speed
from bfsitl.errors import BfsitlError
from bfsitl.mission.session import FlightSession, RealTimeClock, SessionConfig


def test_speed_takes_a_positive_number_or_max() -> None:
    assert parse_speed("max") == math.inf and parse_speed("MAX") == math.inf
    assert parse_speed("2.5") == 2.5
    for bad in ("0", "-1", "fast", "inf", "nan"):
        with pytest.raises(argparse.ArgumentTypeError):
            parse_speed(bad)


def test_a_stock_session_refuses_lockstep_speeds_and_says_what_would_work() -> None:
    assert FlightSession(SessionConfig()).real_time_speed == 1.0
    assert FlightSession(SessionConfig(speed=0.5)).real_time_speed == 0.5
    with pytest.raises(BfsitlError, match="firmware build --lockstep"):
        _ = FlightSession(SessionConfig(speed=math.inf)).real_time_speed
    with pytest.raises(BfsitlError, match="positive"):
        FlightSession(SessionConfig(speed=-1.0))


def test_a_session_waits_on_a_real_time_clock_until_lockstep_starts() -> None:
    assert isinstance(FlightSession().clock, RealTimeClock)
    assert not FlightSession().lockstep


def test_the_binary_scan_finds_the_lockstep_marker(tmp_path) -> None:
    assert LOCKSTEP_MARKER == MARKER.encode()
    plain, patched = tmp_path / "plain", tmp_path / "patched"
    plain.write_bytes(b"\x00" * 64 + b"--ip <address>\x00")
    patched.write_bytes(b"\x00" * 64 + MARKER.encode() + b": FC time follows\x00")
    clear_cache()
    assert not binary_traits(plain).lockstep and binary_traits(plain).takes_ip_flag
    assert binary_traits(patched).lockstep and not binary_traits(patched).takes_ip_flag
